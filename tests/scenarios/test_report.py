"""``cosim run --report`` / ``cosim report``: one self-contained HTML page per run, rendered in
real headless Chromium (Debian's ``chromium``; .ci/run installs it), and the plot it embeds."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from browser import CHROMIUM, MISSING, chromium

from cosim.cli import main
from cosim.present.plots import default_panels, label, setpoints


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    """pid_fopdt to 250 s (the set-point step at 10 s and the load step at 150 s), with plot and report."""
    out = tmp_path_factory.mktemp("report")
    csv = out / "pid.csv"
    assert main(["run", "ssp/pid_fopdt", "-q", "--stop", "250", "-o", str(csv), "--plot", "--report"]) == 0
    return csv


def test_the_page_is_self_contained_and_holds_metrics_per_event_and_parameters(run):
    page = run.with_suffix(".html").read_text()
    # nothing fetched at view time: the only scripts are inline (Plotly's library and the plot)
    assert not re.search(r"<script[^>]* src=|<link|<img[^>]* src=\"(https?:|//)", page)
    images = re.findall(r'<img[^>]* src="data:image/png;base64,', page)
    assert len(images) == 1
    # the loop's two events, found from the set-point and the signal driving the plant's load input d
    assert "set-point setpoint.y 0 → 1" in page and "disturbance load.y 0 → -1" in page
    assert "has no set-point step" in page                                       # why overshoot is undefined
    assert "controller.Kc</td><td class=t>8.0345</td><td class=t>ssp/pid_fopdt/controller.ssv:7" in page
    assert re.search(r"<td class=t>([\w/]*/)?PID.fmu</td>", page)          # relative: build/fmus/PID.fmu


def test_the_page_is_for_people_and_holds_no_path_of_this_machine(run):
    """Issue 27 item 2: a mode parameter by its item name, metric units, run facts formatted,
    no dump of the metadata JSON and no absolute path (of the FMUs, the result, the scenario)."""
    page = run.with_suffix(".html").read_text()
    assert "controller.integral_mode</td><td class=t>METHOD3 (3)</td>" in page
    assert "controller.Ti</td><td class=t>7.1713 s</td>" in page
    # issue 45: pid_fopdt's connectors are in % of span, so the metrics carry it
    assert "<th>IAE [%·s]</th><th>ISE [%²·s]</th><th>ITAE [%·s²]</th>" in page and "declares no unit" not in page
    assert "<td class=t>step size</td><td class=t>0.1 s</td>" in page
    assert re.search(r"<td class=t>wall time of the stepping loop</td><td class=t>\d(\.\d+)?(e-\d+)? s</td>", page)
    loop = re.search(r"stepping loop</td><td class=t>([^<]*) s<", page).group(1)
    assert len(loop.replace(".", "").lstrip("0").partition("e")[0]) <= 3          # 3 significant digits
    assert "<td class=t>parameter sets</td><td class=t>none</td>" in page and "loop_seconds" not in page
    assert "parameter_origins" not in page and "feedthrough_sequence" not in page    # no JSON dump
    meta = run.with_suffix(".json").read_text()
    for folder in (run.parent, Path.cwd()):
        assert str(folder) not in page and str(folder) not in meta


@pytest.mark.skipif(CHROMIUM is None, reason=MISSING)
def test_chromium_decodes_the_figure_and_the_screenshot_shows_it(run, tmp_path):
    page = run.with_suffix(".html").read_text()
    # a copy of the page with one more script reports what Chromium made of each <img>
    probe = tmp_path / "probe.html"
    probe.write_text(page.replace("</body>", "<script>document.body.setAttribute('data-images', JSON.stringify("
                                  "[...document.images].map(i => [i.complete, i.naturalWidth, i.naturalHeight])))"
                                  "</script></body>"))
    dom = chromium("--dump-dom", probe.as_uri(), tmp=tmp_path).stdout
    found = re.search(r'data-images="([^"]*)"', dom)
    assert found, dom[-2000:]
    (complete, width, height), = json.loads(found.group(1).replace("&quot;", '"'))
    assert complete and width == 900 and height > 400          # 9 in × 100 dpi, the figure decoded
    shot = tmp_path / "shot.png"
    chromium("--window-size=1200,1400", "--virtual-time-budget=10000", f"--screenshot={shot}",
             run.with_suffix(".html").as_uri(), tmp=tmp_path)
    from matplotlib.image import imread
    pixels = (imread(shot)[..., :3] * 255).round().astype(int)
    # the first two line colours (set-point, process output; Plotly's and matplotlib's) are on screen:
    # the interactive plot rendered (the PNG is folded away below it)
    for colour, least in (((0x1f, 0x77, 0xb4), 50), ((0xff, 0x7f, 0x0e), 200)):   # the set-point is dashed
        assert (np.abs(pixels - colour).sum(axis=-1) < 30).sum() > least, colour


def test_plot_labels_set_points_and_default_panels_come_from_the_metadata(run):
    meta = json.loads(run.with_suffix(".json").read_text())
    names = [n for n in meta["units"]]
    assert default_panels(meta, names) == [["setpoint.y", "plant.y"], ["controller.u"], ["load.y"]]
    assert setpoints(meta, names) == {"setpoint.y", "controller.r"}
    # a Step's generic "Step output" gives way to what the signal drives
    assert label("setpoint.y", meta) == "setpoint.y — Set-point"
    assert label("load.y", meta).startswith("load.y — Load disturbance")
    assert label("plant.y", meta) == "plant.y — Process output"
    assert run.with_suffix(".png").stat().st_size > 10_000


def test_default_result_names_carry_the_parameter_sets(tmp_path, monkeypatch, capsys):
    scenario = Path("ssp/pid_fopdt").resolve()
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(scenario), "-q", "--stop", "5"]) == 0
    assert main(["run", str(scenario), "-q", "--stop", "5", "--param-set", str(scenario / "pi_only.ssv"),
                 "--plot"]) == 0
    assert sorted(p.name for p in (tmp_path / "results").iterdir()) == [
        "pid_fopdt.csv", "pid_fopdt.json", "pid_fopdt__pi_only.csv", "pid_fopdt__pi_only.json",
        "pid_fopdt__pi_only.png"]
    meta = json.loads((tmp_path / "results" / "pid_fopdt__pi_only.json").read_text())
    # no absolute path of this machine: outside the working folder, relative to the scenario's folder
    assert meta["parameter_sets"] == ["pid_fopdt/pi_only.ssv"] and meta["system"] == "pid_fopdt/SystemStructure.ssd"
    assert meta["components"]["controller"]["fmu"] == "PID.fmu"           # a provider's, by name
    text = (tmp_path / "results" / "pid_fopdt__pi_only.json").read_text()
    assert str(scenario.parent) not in text and str(tmp_path) not in text and str(Path(__file__).parents[2]) not in text
    assert main(["report", "results/pid_fopdt__pi_only.csv", "-o", "r.html"]) == 0
    assert "<h1>pid_fopdt — pi_only</h1>" in (tmp_path / "r.html").read_text()
    assert main(["report", "results/missing.csv"]) == 2


def test_default_panels_of_a_plant_with_several_loops():
    """The boiler's wiring (ssp/btg_boiler_following): two fuel controllers on one set-point and
    measurement give one loop panel; a connection with a factor shows the controller's own input;
    an unconnected set-point input is still a set-point."""
    meta = {"connections": ["pressure_sp.y -> fuel_pi.r", "p_meas.y -> fuel_pi.y", "pressure_sp.y -> fuel_grey.r",
                            "p_meas.y -> fuel_grey.y", "demand.y -> turbine.r", "plant.E -> turbine.y",
                            "plant.L -> level.y", "fuel_pi.u -> fuel_cmd.u1", "turbine.u -> plant.governor"],
            "transforms": {"plant.L -> level.y": "0.001*plant.L - 0.2"},
            "descriptions": {"pressure_sp.y": "Weighted sum of the inputs", "p_meas.y": "Weighted sum of the inputs",
                             "fuel_pi.r": "Set-point", "fuel_pi.y": "Measured process output"}}
    names = ["pressure_sp.y", "p_meas.y", "demand.y", "plant.E", "plant.L", "fuel_pi.u", "fuel_pi.r", "fuel_pi.y",
             "fuel_grey.u", "fuel_grey.r", "fuel_grey.y", "turbine.u", "turbine.r", "turbine.y", "level.u",
             "level.r", "level.y"]
    assert default_panels(meta, names) == [["pressure_sp.y", "p_meas.y"], ["demand.y", "plant.E"],
                                           ["level.r", "level.y"], ["fuel_pi.u"], ["fuel_grey.u"], ["turbine.u"],
                                           ["level.u"]]
    assert {"pressure_sp.y", "demand.y", "level.r"} <= setpoints(meta, names)
    assert label("p_meas.y", meta) == "p_meas.y — Measured process output"   # not the Sum's generic text


@pytest.mark.skipif(CHROMIUM is None, reason=MISSING)
def test_the_interactive_plot_renders_offline_and_zooms(run, tmp_path):
    """Issue 27 item 3: Plotly written into the page; Chromium with every host name unresolvable
    draws the plot (one trace per signal, the zoom button in its toolbar) and zooms it."""
    page = run.with_suffix(".html").read_text()
    assert not re.search(r"<script[^>]* src=|<link", page)           # the library is inline, nothing fetched
    probe = tmp_path / "probe.html"
    probe.write_text(page.replace("</body>", """<script>
const gd = document.getElementById('interactive-plot');
const drawn = () => [gd.querySelectorAll('.scatterlayer .trace').length,
                     !!gd.querySelector('.modebar-btn[data-attr="dragmode"][data-val="zoom"]')];
const before = drawn();
Plotly.relayout(gd, {'xaxis.range': [140, 170]}).then(() => document.body.setAttribute('data-plot',
  JSON.stringify([before, gd._fullLayout.xaxis.range, gd._fullLayout.xaxis2.range,
                  gd.querySelectorAll('.hoverlayer').length,
                  gd.layout.shapes.filter(s => s.type === 'rect').map(s => [s.x0, s.x1, s.y0, s.y1])])));
</script></body>"""))
    dom = chromium("--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=10000", "--dump-dom",
                   probe.as_uri(), tmp=tmp_path).stdout
    found = re.search(r'data-plot="([^"]*)"', dom)
    assert found, dom[-2000:]
    (traces, zoom_button), x1, x2, hover, bands = json.loads(found.group(1).replace("&quot;", '"'))
    assert traces >= 4 and zoom_button and hover == 1        # setpoint.y, plant.y, controller.u, load.y + marks
    assert x1 == [140, 170] and x2 == [140, 170]              # zoomed, the panels' time axes shared
    assert bands == [[10, 150, pytest.approx(0.98), pytest.approx(1.02)]]     # the ±2 % settling band
