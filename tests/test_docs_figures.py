"""Issue 29: the docs' figures are small, byte-reproducible and rewritten only when they change;
run outputs under ssp/ stay out of Git.

docs/figure_files.py (save_figure) writes every docs figure: a 256-colour palette PNG without
metadata, under a size budget, written only when its bytes differ from the file's.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
sys.path.insert(0, str(DOCS))
from figure_files import BUDGET_BYTES, FigureTooLarge, save_figure  # noqa: E402

# A figure as the reports draw one: two panels of lines, legend, grid, title, non-ASCII labels.
FIGURE_SCRIPT = f"""
import sys
from pathlib import Path
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
sys.path.insert(0, {str(DOCS)!r})
from figure_files import save_figure

gain = float(sys.argv[2])
t = np.linspace(0.0, 60.0, 601)
fig, axes = plt.subplots(2, 1, sharex=True, figsize=(8, 5))
for name, tau in (("PI", 5.0), ("grey PI", 8.0)):
    axes[0].plot(t, gain * (1 - np.exp(-t / tau)), label=name)
    axes[1].step(t, gain * np.exp(-t / tau), where="post", label=name)
for ax, label in zip(axes, ("pressure [kgf/cm²]", "fuel command [%]")):
    ax.set_ylabel(label)
    ax.grid(True)
    ax.legend(fontsize=7)
axes[0].set_title("a report's figure — ssp/example")
fig.tight_layout()
print(save_figure(fig, Path(sys.argv[1]), dpi=110))
"""


def draw(path: Path, gain: float, seed: str) -> bool:
    """The figure drawn in a fresh Python (its own hash seed); whether save_figure wrote it."""
    completed = subprocess.run([sys.executable, "-c", FIGURE_SCRIPT, str(path), repr(gain)], capture_output=True,
                               text=True, timeout=120, env={**os.environ, "PYTHONHASHSEED": seed})
    assert completed.returncode == 0, completed.stderr
    return {"True\n": True, "False\n": False}[completed.stdout]


def test_every_docs_figure_is_a_palette_png_without_metadata_under_the_budget():
    figures = sorted((DOCS / "figures").glob("*.png"))
    assert len(figures) >= 60
    over = [(path.name, path.stat().st_size) for path in figures if path.stat().st_size > BUDGET_BYTES]
    assert not over, f"over {BUDGET_BYTES} bytes: {over}"
    for path in figures:
        with Image.open(path) as image:
            assert (image.mode, image.text) == ("P", {}), path.name  # as save_figure writes them


def test_a_figure_drawn_twice_is_the_same_bytes_and_not_rewritten(tmp_path):
    path = tmp_path / "figure.png"
    assert draw(path, 1.0, seed="0") is True
    first, written = path.read_bytes(), path.stat().st_mtime_ns
    assert draw(path, 1.0, seed="12345") is False  # same picture: the file is left alone
    assert path.read_bytes() == first and path.stat().st_mtime_ns == written
    assert b"Matplotlib" not in first and b"tIME" not in first and len(first) < BUDGET_BYTES
    assert draw(path, 2.0, seed="0") is True and path.read_bytes() != first  # new data: rewritten


def test_a_figure_over_the_budget_is_refused_and_not_written(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig = plt.figure(figsize=(8, 5))
    fig.figimage(np.random.default_rng(0).random((550, 880, 3)))  # noise: no palette compresses it
    path = tmp_path / "noise.png"
    try:
        with pytest.raises(FigureTooLarge, match=f"{path}: \\d+ bytes, over the docs figures' budget"):
            save_figure(fig, path, dpi=110)
    finally:
        plt.close(fig)
    assert not path.exists()


@pytest.mark.skipif(shutil.which("git") is None or not (ROOT / ".git").exists(), reason="not a Git work tree")
def test_run_outputs_under_ssp_are_ignored_and_no_tracked_file_is():
    outputs = ["ssp/python.csv", "ssp/pid_fopdt/results.csv", "ssp/pid_fopdt/results.csv.journal",
               "ssp/pid_fopdt/results.parquet", "ssp/pid_fopdt/report.html", "ssp/pid_fopdt/plot.png"]
    checked = subprocess.run(["git", "check-ignore", "--no-index", *outputs], cwd=ROOT, capture_output=True,
                             text=True)
    assert checked.stdout.split() == outputs
    tracked_but_ignored = subprocess.run(["git", "ls-files", "--cached", "--ignored", "--exclude-standard", "ssp"],
                                         cwd=ROOT, capture_output=True, text=True, check=True)
    assert tracked_but_ignored.stdout == ""
    assert subprocess.run(["git", "check-ignore", "-q", "ssp/pid_fopdt/SystemStructure.ssd"], cwd=ROOT).returncode == 1
