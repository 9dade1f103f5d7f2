"""Regression tests of a co-simulation, as you would keep them in your own repository.

Copy this folder (test_loop.py, loop/, test_loop/) into your tests, with greyfmu installed
(``pip install greyfmu``: the pytest plugin ``cosim_regression`` and the FMUs the loop uses).
``pytest --cosim-update-references`` writes the references into test_loop/; ``pytest`` checks them.
"""
from pathlib import Path

LOOP = Path(__file__).parent / "loop"


def test_loop_follows_its_reference(cosim_regression):
    """Samples: plant.y and controller.u at the reference's time points.  The controller output may
    switch one communication step (0.1 s) earlier or later, as another machine or a changed step
    order can make it, and still pass; any other change beyond 1e-6 fails."""
    cosim_regression(LOOP, stop=60.0, signals=["plant.y", "controller.u"],
                     tolerances={"controller.u": {"rtol": 1e-6, "atol": 1e-6, "time": 0.1}})


def test_loop_keeps_its_step_response(cosim_regression):
    """Properties of the loop instead of samples: overshoot [%], 10-90 % rise time and ±2 % settling
    time [s] after the set-point step at 10 s, each within a tolerance."""
    cosim_regression(LOOP, stop=120.0, signals=[],
                     metrics={"plant.y": {"overshoot": (33.7, 0.5), "rise_time": (8.8, 0.2),
                                          "settling_time": (72.1, 1.0)}})
