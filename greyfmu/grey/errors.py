"""The one exception the grey models raise for data they cannot model."""

from __future__ import annotations


class GreyModelError(ValueError):
    """The data admit no grey model: too few samples, a singular normal matrix, |a| >= 2, ..."""
