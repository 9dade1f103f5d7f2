"""The one error a digital-PI design raises: it names the condition that failed."""


class DesignError(ValueError):
    """The plant or the design parameters do not meet a condition of Zhou et al. (2006) / Lee & Lee (1986)."""
