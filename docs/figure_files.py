"""The docs' figures (docs/figures/*.png) as files that change only when their picture does (issue 29).

Each report (docs/*_report.py) saves its figures with ``save_figure``, which

- makes the bytes a function of the pixels only: no ``Software`` text chunk naming matplotlib's
  version, no date (PNG has none unless one is written), and the PNG re-encoded by Pillow, which
  writes no metadata;
- makes them small: the image flattened onto white and quantised to a 256-colour palette (median
  cut, no dithering: the plots are a few line colours and their anti-aliasing), then deflated
  with Pillow's ``optimize``; the 63 figures went from 5.5 MB to 2.0 MB, the largest from 224 KB
  to 84 KB;
- writes the file only when those bytes differ from the file's, so a regeneration whose data did
  not change leaves Git nothing to store;
- refuses a figure over ``BUDGET_BYTES`` (tests/test_docs_figures.py checks the committed ones).
"""
from __future__ import annotations

import io
from pathlib import Path

from PIL import Image

from cosim.safeio import write_atomic

BUDGET_BYTES = 150_000
"""The most a docs figure may take (the largest is 84 KB): a figure over it is too detailed for
the page, or lost the palette."""
PNG_METADATA = {"Software": None}
"""matplotlib's savefig metadata: None drops its default entry (the matplotlib version)."""


class FigureTooLarge(ValueError):
    """A figure's PNG is over BUDGET_BYTES."""


def compact(png: bytes) -> bytes:
    """``png`` flattened onto white, quantised to 256 colours and re-encoded without metadata."""
    with Image.open(io.BytesIO(png)) as image:
        rgba = image.convert("RGBA")
    flat = Image.new("RGB", rgba.size, "white")
    flat.paste(rgba, mask=rgba.getchannel("A"))
    palette = flat.quantize(256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    out = io.BytesIO()
    palette.save(out, format="PNG", optimize=True)
    return out.getvalue()


def png_bytes(fig, dpi: int) -> bytes:
    """The compact PNG of matplotlib figure ``fig`` at ``dpi``."""
    rendered = io.BytesIO()
    fig.savefig(rendered, format="png", dpi=dpi, metadata=PNG_METADATA)
    return compact(rendered.getvalue())


def save_figure(fig, path: Path, dpi: int) -> bool:
    """Write ``fig`` to ``path`` as a compact PNG unless the file already holds those bytes;
    whether it was written.  Raises FigureTooLarge (naming the file) over BUDGET_BYTES."""
    data = png_bytes(fig, dpi)
    if len(data) > BUDGET_BYTES:
        raise FigureTooLarge(f"{path}: {len(data)} bytes, over the docs figures' budget of {BUDGET_BYTES} "
                             "(docs/figure_files.py): fewer points or a smaller size")
    if path.is_file() and path.read_bytes() == data:
        return False
    write_atomic(path, data)
    return True
