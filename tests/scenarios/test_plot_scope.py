"""Plots read as a scope (issue 27, item 1): quantity and unit on each y axis ("as wired" where
the FMU declares none), event markers, the disturbance drawn, the settling band and instant,
the overshoot peak, actuator limits, sampled outputs as steps."""
from __future__ import annotations

import json

import pytest
from matplotlib.collections import PolyCollection

from cosim.cli import main
from cosim.present.plots import axis_label, default_panels, figure, limits, sampled, units
from cosim.record.results import read
from peers import gemseo_fmu_dir


@pytest.fixture(scope="module")
def fopdt(tmp_path_factory):
    """pid_fopdt to 250 s: the set-point step at 10 s, the load step at 150 s."""
    csv = tmp_path_factory.mktemp("fopdt") / "pid.csv"
    assert main(["run", "ssp/pid_fopdt", "-q", "--stop", "250", "-o", str(csv)]) == 0
    return read(csv), json.loads(csv.with_suffix(".json").read_text())


@pytest.fixture(scope="module")
def mass_damper(tmp_path_factory):
    """pid_mass_damper (gemseo-fmu's Mass_Damper: f in N, y without unit; the set-point in m)."""
    try:
        fmus = gemseo_fmu_dir()
    except RuntimeError as e:
        pytest.skip(str(e))
    csv = tmp_path_factory.mktemp("md") / "md.csv"
    assert main(["run", "ssp/pid_mass_damper", "-q", "--fmu-dir", str(fmus), "-o", str(csv)]) == 0
    return read(csv), json.loads(csv.with_suffix(".json").read_text())


def _names(result):
    return [n for n in result.dtype.names if n != "time"]


def test_a_signal_without_unit_takes_the_unit_it_is_wired_to(mass_damper):
    result, meta = mass_damper
    assert meta["units"]["controller.u"] is None and meta["units"]["plant.y"] is None
    found = units(meta)
    assert found["controller.u"] == ("N", True)        # drives plant.f [N]
    assert found["plant.y"] == ("m", True)             # compared with the set-point [m] by the controller
    panels = default_panels(meta, _names(result))
    assert [axis_label(p, meta) for p in panels] == ["Measured process output [m]",
                                                     "Controller output [N] (as wired)"]


def test_units_pass_through_gain_and_sum_blocks_both_ways():
    meta = {"units": {"sensor.y": "K", "gain.u": None, "gain.y": None, "sum.u1": None, "sum.y": None, "c.u": None},
            "components": {"gain": {"fmu": "Gain.fmu"}, "sum": {"fmu": "Sum.fmu"}, "sensor": {"fmu": "T.fmu"},
                           "c": {"fmu": "PID.fmu"}},
            "connections": ["sensor.y -> gain.u", "gain.y -> sum.u1", "c.u -> x.u"], "transforms": {"c.u -> x.u": "2*c.u"}}
    found = units(meta)
    assert found["sum.y"] == ("K", True) and found["gain.u"] == ("K", True) and found["sensor.y"] == ("K", False)
    assert "c.u" not in found                          # a scaled connection does not pass a unit
    assert axis_label(["c.u"], meta) == "c.u (no unit declared)"


def test_the_fopdt_plot_marks_events_band_peak_limits_and_draws_the_load(fopdt):
    result, meta = fopdt
    panels = default_panels(meta, _names(result))
    assert panels == [["setpoint.y", "plant.y"], ["controller.u"], ["load.y"]]     # the load drawn
    # issue 45: the scenario's connectors declare % of span, so every axis is in engineering units
    assert [axis_label(p, meta) for p in panels] == ["Process output [%]", "Controller output [%]",
                                                     "Load disturbance [%]"]
    fig = figure(result, panels, scenario="pid_fopdt", metadata=meta)
    loop, output, load = fig.axes
    for ax in fig.axes:   # a marker at the set-point step (10 s) and at the load step (150 s) on every panel
        vertical = {round(line.get_xdata()[0], 6) for line in ax.lines
                    if len(set(line.get_xdata())) == 1 and tuple(line.get_ydata()) == (0, 1)}
        assert vertical == {10.0, 150.0}
    band, = [c for c in loop.collections if isinstance(c, PolyCollection)]
    ys = band.get_paths()[0].vertices[:, 1]
    assert ys.min() == pytest.approx(0.98) and ys.max() == pytest.approx(1.02)    # ±2 % of the step 0 → 1
    texts = [t.get_text() for t in loop.texts]
    assert any(t.startswith("overshoot 33.") for t in texts)
    # issue 45: the settling label says the instant on the time axis and the time since the step (10 s)
    settled, = [t for t in loop.texts if t.get_text().startswith("settled")]
    assert settled.get_text() == "settled at 82.1 s (72.1 s after the step)" and settled.xy[0] == pytest.approx(82.1, abs=0.05)
    assert "load.y 0 → -1" in texts
    # u_min/u_max = ±100 are far off the output's range (0..13): named, not drawn
    assert limits("controller.u", meta) == {"u_min": -100.0, "u_max": 100.0}
    off_scale = {t.get_text() for t in output.get_legend().get_texts()} - {output.lines[0].get_label()}
    assert off_scale == {"u_min = -100 (off scale)", "u_max = 100 (off scale)"} and not output.texts
    # the controller's output is held between samples: steps, not ramps; the process output is not
    steps = {line.get_label().partition(" ")[0]: line.get_drawstyle() for ax in fig.axes for line in ax.lines
             if " — " in line.get_label()}
    assert steps["controller.u"] == "steps-post" and steps["plant.y"] == "default"
    assert "controller.u" in meta["discrete"] and sampled("controller.u", meta) and not sampled("plant.y", meta)


def test_a_saturating_output_shows_its_limits(mass_damper):
    result, meta = mass_damper
    assert result["controller.u"].max() == 2000 and result["controller.u"].min() == -2000
    fig = figure(result, default_panels(meta, _names(result)), scenario="md", metadata=meta)
    output = fig.axes[1]
    horizontal = sorted(line.get_ydata()[0] for line in output.lines
                        if len(set(line.get_ydata())) == 1 and tuple(line.get_xdata()) == (0, 1))
    assert horizontal == [-2000, 2000]
    assert {t.get_text() for t in output.texts} == {"u_min = -2000", "u_max = 2000"}


def test_the_report_gives_metric_units_from_the_signal(mass_damper, tmp_path):
    from cosim.present.report import render

    result, meta = mass_damper
    page = render(result, meta, source=str(tmp_path / "md.csv"))
    assert "<th>IAE [m·s]</th><th>ISE [m²·s]</th><th>ITAE [m·s²]</th>" in page and "<th>peak_error [m]</th>" in page


def test_y_labels_of_stacked_panels_stay_within_their_panels(fopdt):
    """Issue 45: a long y label ("Weighted sum of the inputs [kgf/cm2] (as wired)") ran into the
    next panel's; labels are wrapped to their panel's height and aligned."""
    result, meta = fopdt
    long_meta = {**meta, "descriptions": {**meta["descriptions"],
                                          "controller.u": "A controller output whose description is long, held"}}
    fig = figure(result, [["setpoint.y", "plant.y"], ["controller.u"], ["load.y"]], scenario="x", metadata=long_meta)
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    for ax in fig.axes:
        label, frame = ax.yaxis.label.get_window_extent(renderer), ax.get_window_extent(renderer)
        assert label.y0 >= frame.y0 - 1 and label.y1 <= frame.y1 + 1, ax.yaxis.label.get_text()
