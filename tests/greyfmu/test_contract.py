"""Conformance of every exported greyfmu class to the component contract (greyfmu/contract.py).

As python-control checks the docstrings of everything it exports, this walks the ``__all__`` of
greyfmu.control, .plants, .grey and .signals: every class is a controller, a plant, or listed in
``NOT_COMPONENTS`` with the reason.  Controllers and plants are built, checked against their
``Protocol`` clause by clause (signature, ``Ts``, a returned output, documented methods) and run:
``reset()`` must reproduce the first run exactly.  A documented exception (``DEVIATIONS``) skips
one clause and must still violate it, so the list cannot go stale.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

import greyfmu.control
import greyfmu.grey
import greyfmu.plants
import greyfmu.signals
from greyfmu.contract import Controller, Plant
from greyfmu.control import (
    CARIMA,
    GPC,
    OSMMGPC,
    PID,
    ARXStructure,
    Antecedent,
    Bounds,
    DigitalPI,
    GainSchedule,
    GainScheduledPID,
    GrayPredictivePI,
    OperatingPoint,
    SOPDTPredictive,
    TSModel,
    design_digital_pi,
)
from greyfmu.control.digital_pi.examples import ch47
from greyfmu.plants import (
    FOPDT,
    BoilerTurbine,
    FourTank,
    PiecewiseParameter,
    ScheduledFOPDT,
    SecondOrder,
    SteamHeader,
    StochasticLTI,
    ThirdOrderPlant,
    equilibrium,
)

PACKAGES = [greyfmu.control, greyfmu.plants, greyfmu.grey, greyfmu.signals]
SAMPLES = 12


def _osmm() -> OSMMGPC:
    """Two boilers, one output, one one-rule TS model: small enough to run, adaptive so that reset must undo it."""
    antecedent = Antecedent.from_widths([[0.75]], [[1.0]])
    models = [[TSModel(antecedent, [[0.9, 0.3, 0.02]])], [TSModel(antecedent, [[0.9, 0.1, 0.07]])]]
    return OSMMGPC([(0,), (1,)], models, ARXStructure(1, 1), [0.75, 0.75], N2=5, Nu=2)


# name -> (factory, measurement y(k) for k = 0, 1, ..., extra keyword inputs)
CONTROLLERS: dict[str, tuple[Callable[[], Any], Callable[[int], Any], dict[str, Any]]] = {
    "PID": (lambda: PID(2.0, 10.0, 1.0, 0.5, u_max=3.0), lambda k: 0.1 * k, {}),
    "SOPDTPredictive": (lambda: SOPDTPredictive(1.2, 200.0, 90.0, 40.0), lambda k: 0.05 * k, {}),
    "GainScheduledPID": (
        lambda: GainScheduledPID(GainSchedule([OperatingPoint(86.0, 5.707, 16.383), OperatingPoint(140.0, 3.581, 16.383)])),
        lambda k: 0.1 * k, {"W": 100.0},
    ),
    "GrayPredictivePI": (lambda: GrayPredictivePI(2.0, 10.0, 1.0), lambda k: math.sin(k / 3.0), {}),
    "DigitalPI": (lambda: DigitalPI.from_design(design_digital_pi(
        ch47().plant, ch47().Ts, ch47().tau, ch47().alpha, ch47().beta, ch47().q, ch47().r)),
        lambda k: np.array([0.01 * k, -0.02 * k]), {}),
    "GPC": (lambda: GPC(CARIMA([[1.0, -0.8]], [[[0.2, 0.1]]]), N2=8, Nu=3, bounds=Bounds(-1.0, 1.0, -0.2, 0.2)),
            lambda k: np.array([0.1 * math.sin(k)]), {}),
    "OSMMGPC": (_osmm, lambda k: np.array([8.75 + 0.1 * math.sin(k)]), {}),
}

# name -> (factory, input u(k), disturbance d(k)); the plants are advanced over steps of STEP s
PLANTS: dict[str, tuple[Callable[[], Any], Callable[[int], Any], Callable[[int], Any]]] = {
    "FOPDT": (lambda: FOPDT(1.5, 10.0, 2.5), lambda k: 1.0, lambda k: 0.2 if k > 5 else 0.0),
    "SecondOrder": (lambda: SecondOrder(1.0, 0.5, 0.7, 1.0), lambda k: 1.0, lambda k: 0.0),
    "ThirdOrderPlant": (lambda: ThirdOrderPlant(tau=5.0), lambda k: 1.0, lambda k: 0.1),
    "ScheduledFOPDT": (lambda: ScheduledFOPDT(PiecewiseParameter(0.2, 2.5, 0.76, 7.0, c=-0.72, n=0.5),
                                              PiecewiseParameter.constant(20.0), PiecewiseParameter.constant(1.0), y0=2.0),
                       lambda k: 1.5, lambda k: 0.0),
    "BoilerTurbine": (lambda: BoilerTurbine(equilibrium(76.0)), lambda k: (45.0, 70.0, 52.0), lambda k: 1.0),
    "StochasticLTI": (lambda: StochasticLTI([[-0.5]], [[1.0]], [[1.0]], [[1.0]], 0.7, [[0.01]], seed=3),
                      lambda k: np.array([1.0]), lambda k: 0.0),
    "SteamHeader": (SteamHeader, lambda k: np.full(3, 0.8), lambda k: np.array([0.5, 0.6])),
    "FourTank": (FourTank, lambda k: (0.7, 0.75), lambda k: 0.0),
}
STEP = 2.0

DEVIATIONS: dict[tuple[str, str], str] = {
    ("GPC", "Ts"): "law in samples on the CARIMA model (33); the sample time is the model's and the FMU's Ts",
    ("OSMMGPC", "Ts"): "law in samples on the TS-ARX models (28); the sample time is the models' and the FMU's Ts",
    ("DigitalPI", "Ts"): "built from discrete matrices; the sample time is DigitalPIDesign.Ts and the FMU's Ts",
    ("SteamHeader", "advance"): "advance(t, h, u, v): the valve openings v are the load, a required second input",
    ("FourTank", "advance"): "the paper's (41)-(42) is a difference equation: step(u1, u2) per sample Ts",
}

NOT_COMPONENTS: dict[str, str] = {
    # greyfmu.control: options, designs, schedules, models and estimators the controllers use
    "ControlLaw": "option enum", "DerivativeOn": "option enum", "IntegralMode": "option enum", "PIForm": "option enum",
    "Interpolation": "option enum", "HorizonWarning": "warning category", "ScheduleError": "exception",
    "SOPDTDesign": "off-line design data (paper §2)", "DigitalPIDesign": "off-line design data (Zhou et al. §2-§3)",
    "Gains": "data (Kc, Ti, Td)", "OperatingPoint": "schedule table row / plant operating point (data)",
    "GainSchedule": "a schedule W -> Gains used by GainScheduledPID", "ITAE": "a tuning rule (process -> Gains)",
    "CARIMA": "prediction model of GPC", "Bounds": "constraints (35) of GPC", "ARXStructure": "model orders of OSMM",
    "Antecedent": "fuzzy sets of a TS model", "TSModel": "Takagi-Sugeno model", "FuzzyRLS": "on-line estimator of a TS model",
    # greyfmu.plants
    "PiecewiseParameter": "a parameter schedule of ScheduledFOPDT", "HeaderParameters": "SteamHeader's data",
    "DelayLine": "a dead-time block the plants are built from (push/segments/prune, no input of its own)",
    # greyfmu.grey: models and identifiers, neither controller nor plant
    "GM11": "grey model GM(1,1)", "GM3t1": "grey model GM(3/t,1)", "GreyModelError": "exception",
    "GreyPredictor": "grey predictor (a filter of the measurement inside GrayPredictivePI)",
    "PredictorMode": "option enum", "Threshold": "option enum", "SecondOrderConstants": "identification result",
    "StepIdentifier": "identifier of a step response, neither controller nor plant",
    # greyfmu.signals: sources and blocks of a wiring
    **{name: "signal source or block of a wiring" for name in (
        "BandLimitedWhiteNoise", "FirstOrderFilter", "Gain", "Pulse", "Ramp", "SampleClock", "Step", "Sum",
        "LookupTable", "PRBS")},
}


def exported_classes() -> dict[str, type]:
    classes: dict[str, type] = {}
    for package in PACKAGES:
        for name in package.__all__:
            obj = getattr(package, name)
            if inspect.isclass(obj):
                classes[name] = obj
    return classes


def test_every_exported_class_has_a_role_or_a_reason():
    classes = set(exported_classes())
    roles = set(CONTROLLERS) | set(PLANTS)
    assert not roles & set(NOT_COMPONENTS)
    assert sorted(classes - roles - set(NOT_COMPONENTS)) == [], "classify the new class in this file"
    assert sorted((roles | set(NOT_COMPONENTS)) - classes) == [], "listed here but no longer exported"


def _parameters(method: Callable) -> list[inspect.Parameter]:
    return list(inspect.signature(method).parameters.values())[1:]  # without self


def controller_clauses(cls: type, controller: Any) -> dict[str, bool]:
    step = _parameters(cls.step)
    return {
        "step": [p.name for p in step[:2]] == ["r", "y"]
        and all(p.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD for p in step[:2])
        and all(p.kind in (inspect.Parameter.KEYWORD_ONLY, inspect.Parameter.VAR_KEYWORD) for p in step[2:]),
        "reset": hasattr(cls, "reset") and all(p.default is not inspect.Parameter.empty for p in _parameters(cls.reset)),
        "Ts": isinstance(getattr(controller, "Ts", None), float) and controller.Ts > 0.0,
    }


def plant_clauses(cls: type) -> dict[str, bool]:
    advance = _parameters(cls.advance) if hasattr(cls, "advance") else []
    return {
        "advance": [p.name for p in advance[:4]] == ["t", "h", "u", "d"] and advance[3].default == 0.0
        and all(p.kind is inspect.Parameter.KEYWORD_ONLY for p in advance[4:]),
        "reset": hasattr(cls, "reset") and all(p.default is not inspect.Parameter.empty for p in _parameters(cls.reset)),
    }


def _documented(cls: type, methods: tuple[str, ...]) -> list[str]:
    return [f"{cls.__name__}.{m}" for m in methods if hasattr(cls, m) and not inspect.getdoc(getattr(cls, m))]


def check_clauses(name: str, component: Any, clauses: dict[str, bool], protocol: type, methods: tuple[str, ...]) -> None:
    """Each clause holds, or is a listed deviation that still deviates; the class and its methods are documented."""
    for clause, holds in clauses.items():
        if (name, clause) in DEVIATIONS:
            assert not holds, f"{name} now follows {clause!r}: drop its DEVIATIONS entry"
        else:
            assert holds, f"{name} breaks the {protocol.__name__} clause {clause!r}"
    if not any((name, clause) in DEVIATIONS for clause in clauses):
        assert isinstance(component, protocol)
    cls = type(component)
    assert cls.__doc__ and _documented(cls, methods) == []


def check_reset_restarts(name: str, component: Any, run: Callable[[], list[np.ndarray]]) -> None:
    """The run gives finite, changing outputs, and after ``reset()`` exactly the same ones again."""
    first = run()
    assert all(y is not None and np.all(np.isfinite(y)) for y in first), f"{name} returns no finite output"
    assert any(not np.array_equal(first[0], y) for y in first), f"{name} never moved: the run tests nothing"
    component.reset()
    assert [y.tolist() for y in run()] == [y.tolist() for y in first], f"{name}.reset() does not restart it"


@pytest.mark.parametrize("name", CONTROLLERS)
def test_controller_follows_the_protocol(name):
    factory, measurement, extra = CONTROLLERS[name]
    controller = factory()
    check_clauses(name, controller, controller_clauses(type(controller), controller), Controller, ("step", "reset"))
    check_reset_restarts(name, controller, lambda: [
        np.array(controller.step(np.ones_like(measurement(k)), measurement(k), **extra), dtype=float) for k in range(SAMPLES)
    ])


@pytest.mark.parametrize("name", PLANTS)
def test_plant_follows_the_protocol(name):
    factory, u, d = PLANTS[name]
    plant = factory()
    check_clauses(name, plant, plant_clauses(type(plant)), Plant, ("advance", "step", "reset"))

    def run() -> list[np.ndarray]:
        if name == "FourTank":  # its documented exception: one step(u1, u2) per sample
            return [plant.step(*u(k)) for k in range(SAMPLES)]
        return [np.array(plant.advance(k * STEP, STEP, u(k), d(k)), dtype=float) for k in range(SAMPLES)]

    check_reset_restarts(name, plant, run)


def test_deviations_name_listed_components():
    assert {name for name, _ in DEVIATIONS} <= set(CONTROLLERS) | set(PLANTS)
