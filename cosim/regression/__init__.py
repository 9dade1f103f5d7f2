"""Regression comparison of co-simulation results: one engine (`cosim.regression.engine.compare`)
behind ``cosim compare``, the pytest plugin's ``cosim_regression`` and ``cosim verify``.

- `cosim.regression.tolerances`: per-signal tolerances by glob (absolute floor, relative band, time);
- `cosim.regression.tube`: the tube around a reference (csv-compare's and LBNL funnel's rectangles)
  and the FMI cross-check band;
- `cosim.regression.engine`: a `Verdict` per signal with the first and the worst violation;
- `cosim.regression.targets`: control-loop metrics (`cosim.present.metrics`) as regression targets;
- `cosim.regression.report`: the difference report (HTML, interactive and offline; PNG);
- `cosim.regression.lsref`: FMI-LS-REF reference experiments inside an FMU, and ``cosim verify``.
"""

#: the comparison rules (`cosim.regression.engine`), named here so the command line needs no NumPy to list them
MODES = ("tube", "csv-compare", "fmi-cross-check")
#: csv-compare's default --tolerance
CSV_COMPARE_TOLERANCE = 0.002
