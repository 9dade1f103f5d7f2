"""Presenting: results and scenarios handed to people and other tools.  `plots` draws a run as a
control engineer reads a scope, `interactive` and `report` make one self-contained HTML page of it,
`metrics` measures step responses and compares results against references, and `pack` writes a
validated scenario as a standard ``.ssp`` archive other SSP tools load.
"""
