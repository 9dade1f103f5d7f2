"""The difference report (cosim compare --report, cosim_regression's failure page, cosim verify):
rendered offline in real headless Chromium (.ci/run installs Debian's chromium), and its PNG."""
from __future__ import annotations

import json
import re

import numpy as np
import pytest

from browser import CHROMIUM, MISSING, chromium

from cosim.cli import main
from cosim.record.results import write

RED = (0xd6, 0x27, 0x28)        # the violations' colour, Plotly's and matplotlib's (tab:red)


@pytest.fixture(scope="module")
def report(tmp_path_factory):
    """A reference and a run whose valve opens 2 steps late and whose flow, one step late, is 3 % low
    from 1.5 s, compared with a one-step time tolerance: both signals fail; the page and the PNG."""
    folder = tmp_path_factory.mktemp("difference")
    t = np.round(np.arange(0, 2.0 + 0.005, 0.01), 12)

    def run(t_valve: float, t_open: float, low: float) -> np.ndarray:
        out = np.zeros(len(t), dtype=[("time", float), ("valve.y", float), ("pipe.q", float), ("ok.y", float)])
        out["time"], out["ok.y"] = t, np.sin(t)
        out["valve.y"] = t >= t_valve - 1e-12
        out["pipe.q"] = np.where(t >= t_open - 1e-12, 1 - np.exp(-(t - t_open) / 0.2), 0.0) * \
            np.where(t >= 1.5, 1 - low, 1.0)
        return out

    ref, candidate = write(run(1.0, 1.0, 0.0), folder / "ref.csv"), write(run(1.02, 1.01, 0.03), folder / "run.csv")
    page = folder / "diff.html"
    assert main(["compare", str(ref), str(candidate), "--time-tolerance", "0.01", "--rtol", "1e-3",
                 "--report", str(page)]) == 1
    return page


def test_the_page_lists_every_signal_with_its_verdict_and_the_png_shows_the_violations(report):
    text = report.read_text()
    assert not re.search(r"<script[^>]* src=|<link", text)       # Plotly inline: nothing fetched
    for row in ("<td>valve.y</td><td>FAILED</td>", "<td>pipe.q</td><td>FAILED</td>", "<td>ok.y</td><td>passed</td>"):
        assert row in text
    assert "rtol 0.001, atol 1e-09, time ±0.01 s" in text and "2 failing of 3 checks" in text
    from matplotlib.image import imread
    pixels = (imread(report.with_suffix(".png"))[..., :3] * 255).round().astype(int)
    assert pixels.shape[0] > 4 * 200                                # 2 failing signals × 2 panels
    assert (np.abs(pixels - RED).sum(axis=-1) < 30).sum() > 50      # the red × of the points outside


@pytest.mark.skipif(CHROMIUM is None, reason=MISSING)
def test_chromium_draws_reference_run_tube_and_violations_offline_and_zooms(report, tmp_path):
    """Every host name unresolvable: Plotly draws 4 panels (values and run − reference for the 2 failing
    signals), each with the tube, the reference, the run and the points outside; a relayout zooms the
    shared time axis; the first and worst violations are labelled."""
    probe = tmp_path / "probe.html"
    probe.write_text(report.read_text().replace("</body>", """<script>
const gd = document.getElementById('difference-plot');
const names = gd.data.map(t => t.name);
Plotly.relayout(gd, {'xaxis.range': [0.9, 1.2]}).then(() => document.body.setAttribute('data-plot',
  JSON.stringify([gd.querySelectorAll('.scatterlayer .trace').length, names,
                  gd._fullLayout.xaxis.range, gd._fullLayout.xaxis4.range,
                  gd.layout.annotations.map(a => a.text)])));
</script></body>"""))
    dom = chromium("--host-resolver-rules=MAP * ~NOTFOUND", "--virtual-time-budget=10000", "--dump-dom",
                   probe.as_uri(), tmp=tmp_path).stdout
    found = re.search(r'data-plot="([^"]*)"', dom)
    assert found, dom[-2000:]
    drawn, names, x1, x4, labels = json.loads(found.group(1).replace("&quot;", '"'))
    assert drawn == len(names) == 2 * 2 * 5                      # per panel: tube edges (2), reference, run, outside
    assert names.count("valve.y run") == 2 and "pipe.q outside (51)" in names    # 1.5 s to 2 s
    assert x1 == [0.9, 1.2] and x4 == [0.9, 1.2]
    assert labels.count("first and worst: t = 1.01 s") == 2                                 # valve.y's
    assert labels.count("first: t = 1.5 s") == labels.count("worst: t = 2 s") == 2        # pipe.q's
    shot = tmp_path / "shot.png"
    chromium("--window-size=1200,1600", "--virtual-time-budget=10000", f"--screenshot={shot}", report.as_uri(),
             tmp=tmp_path)
    from matplotlib.image import imread
    pixels = (imread(shot)[..., :3] * 255).round().astype(int)
    assert (np.abs(pixels - RED).sum(axis=-1) < 30).sum() > 30     # the markers on screen
