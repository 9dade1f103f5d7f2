"""Text from an FMU or SSD on a plot is shown literally (issue 26, item 6): a description
holding ``$…$`` that is not TeX ended ``--plot`` and ``--report`` with a matplotlib mathtext
traceback."""
from __future__ import annotations

import json

import numpy as np

import pytest

from cosim.cli import main
from cosim.present.plots import plain
from ssdgen import ssd_text, write_system
from testfmus import edited_copy

DESCRIPTIONS = ["cost $\\frac{1}{2$ per unit", "price in $ only", "$x^{$"]


@pytest.mark.parametrize("description", DESCRIPTIONS)
def test_plot_and_report_show_dollar_signs_literally(tmp_path, twin_fmus, capsys, description):
    gain = edited_copy(twin_fmus["Gain"], tmp_path / "fmus" / "Gain.fmu",
                       lambda text: text.replace('description="k times the input"',
                                                 f'description="{description}"'))
    text = ssd_text("dollars $a$b$", {"step": ("Step.fmu", {"y": "output"}),
                                      "gain": ("Gain.fmu", {"u": "input", "y": "output"})},
                    [("step", "y", "gain", "u")], stop=2.0, step=0.5)
    folder = write_system(tmp_path / "sys", {"Step.fmu": twin_fmus["Step"], "Gain.fmu": gain}, text)
    out = tmp_path / "out.csv"
    code = main(["run", str(folder), "-q", "-o", str(out), "--plot", "--report", "--signals", "gain.y"])
    err = capsys.readouterr().err
    assert code == 0, err
    assert out.with_suffix(".png").stat().st_size > 5000 and out.with_suffix(".html").stat().st_size > 5000
    assert json.loads(out.with_suffix(".json").read_text())["descriptions"]["gain.y"] == description


def test_plain_escapes_every_dollar():
    assert plain("a $b$ c $") == r"a \$b\$ c \$" and plain("no math") == "no math"


def test_a_plot_that_cannot_be_finished_leaves_the_earlier_one(tmp_path):
    """The image goes through ``<plot>.part`` and one rename: a save that fails half way (here
    the ``.part`` name is taken by a folder) raises and leaves the earlier plot as it was."""
    from cosim.present.plots import plot

    result = np.array([(0.0, 1.0), (1.0, 2.0)], dtype=[("time", float), ("gain.y", float)])
    path = plot(result, [["gain.y"]], tmp_path / "r.png", scenario="s")
    before = path.read_bytes()
    assert before.startswith(b"\x89PNG") and not (tmp_path / "r.png.part").exists()
    (tmp_path / "r.png.part").mkdir()
    with pytest.raises(OSError):
        plot(result[:1], [["gain.y"]], path, scenario="changed")
    assert path.read_bytes() == before
