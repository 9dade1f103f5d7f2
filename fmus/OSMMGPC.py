"""OSMM-GPC controller FMU (2 header pressures, 3 boilers), also the fixed-pair GPC; wraps greyfmu.control.OSMMGPC."""

import copy
import functools
from enum import IntEnum
from typing import Any

import numpy as np
from pythonfmu import DefaultExperiment, Fmi2Variability

from _slave import REQUIREMENTS, Estimator, GreyfmuSlave
from greyfmu.control import OSMMGPC as OSMMController
from greyfmu.control import ARXStructure, Bounds, TSModel, boiler_groups, identify_group_models
from greyfmu.plants import SteamHeader, excitation_run
from greyfmu.signals import SampleClock



class ModelGroup(IntEnum):
    """Which boiler pair the GPC drives: OSMM scheduling or one fixed pair (the paper's groups (27))."""

    SCHEDULED = 0
    """The OSMM scheduling picks the pair at every sample (the paper's algorithm)."""
    PAIR_1_2 = 1
    """Boilers 1 and 2, fixed."""
    PAIR_1_3 = 2
    """Boilers 1 and 3, fixed."""
    PAIR_2_3 = 3
    """Boilers 2 and 3, fixed."""


class EfficiencyForm(IntEnum):
    """Which form of the regulating efficiency (31) the scheduling (32) maximises."""

    GAIN = 0
    """Σ ω_j Σ_l B_jl(1)/A_j(1): the steady pressure gain per unit firing (unit-consistent)."""
    PRINTED = 1
    """Σ ω_j A_j(1)/Σ_l B_jl(1): (31) as the paper prints it."""


class Adaptation(IntEnum):
    """Whether the TS models' consequents are estimated on line."""

    FROZEN = 0
    """The initial identified models stay fixed."""
    ONLINE = 1
    """On-line estimation by the chosen estimator (the paper's algorithm)."""


@functools.lru_cache(maxsize=4)
def initial_models(Ts: float, duration: float, rules: int, seed: int) -> tuple[tuple[TSModel, ...], ...]:
    """Initial TS models of the three groups: one open-loop random-firing run of the default
    greyfmu.plants.SteamHeader per group (the group's boilers excited; group g's firing levels
    drawn with seed 3·seed + g), GK clustering + local WLS."""
    structure = ARXStructure(2, 2)
    models = []
    for g, boilers in enumerate(boiler_groups(3, 2)):
        Y, M = excitation_run(SteamHeader(), boilers, duration, Ts, seed=3 * seed + g)
        models.append(tuple(identify_group_models(Y, M, boilers, structure, rules)))
    return tuple(models)


class OSMMGPC(GreyfmuSlave):
    description = (
        "OSMM-GPC of Pan, Shen & Luh (2012), §4: every sample, update the Takagi-Sugeno ARX models of the "
        "C(3,2) boiler groups by MFRLS (our reconstruction), compute the regulating efficiencies (31) "
        "(as printed, or the unit-consistent form: parameter efficiency) and choose the best group (32), solve the 2x2 "
        "constrained GPC (34)-(39) on the active model (33) and add the moves to the chosen boilers; the third "
        "boiler holds its firing. group = PAIR_1_2, PAIR_1_3, PAIR_2_3 fixes that pair: a plain GPC with the same "
        "adaptive models. Initial TS models are identified at initialisation from open-loop runs of "
        "greyfmu.plants.SteamHeader (default parameters; about 5 s). Sampled at Ts with zero-order hold; no "
        "direct feedthrough. Needs the QP solver daqp on the target Python besides numpy/scipy. " + REQUIREMENTS
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=4500.0, step_size=1.0)
    output_dependencies = {"u1": [], "u2": [], "u3": [], "active_group": []}
    sample_time = "Ts"
    wiring = {"r1": "setpoint", "r2": "setpoint", "y1": "measurement", "y2": "measurement", "u1": "manipulated",
              "u2": "manipulated", "u3": "manipulated"}
    requirements = ("numpy", "scipy", "daqp")

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self.parameter("Ts", 10.0, "Sample time", unit="s")
        self.parameter("N1", 1, "Minimum costing horizon", minimum=1)
        self.parameter("N2", 20, "Maximum costing horizon", minimum=1)
        self.parameter("Nu", 5, "Control horizon", minimum=1)
        self.parameter("output_weight", 1.0, "Output-error weight lambda(j) of (34)", minimum=0.0)
        self.parameter("move_weight", 1.0, "Move weight Q(j) of (34)", minimum=0.0)
        self.parameter("alpha", 0.0, "Reference smoothing a of (36)", unit="1", minimum=0.0, maximum=0.999)
        self.parameter("M_min", 0.3, "Lowest firing M_min of (35) (p.u.)", unit="1")
        self.parameter("M_max", 1.2, "Highest firing M_max of (35) (p.u.)", unit="1")
        self.parameter("dM_max", 0.05, "Largest firing move per sample |dM| of (35) (p.u.)", unit="1", minimum=0.0)
        self.parameter("M0", 0.75, "Initial firing of every boiler (p.u.)", unit="1")
        self.parameter("group", ModelGroup.SCHEDULED, "Boiler pair: SCHEDULED by OSMM, or fixed PAIR_1_2, PAIR_1_3 or PAIR_2_3")
        self.parameter("efficiency", EfficiencyForm.PRINTED, "Regulating efficiency (31) maximised by (32): as PRINTED (the paper) or the unit-consistent GAIN form")
        self.parameter("adapt", Adaptation.ONLINE, "TS models: ONLINE estimation or FROZEN initial models")
        self.parameter("method", Estimator.MFRLS, "On-line estimator: GLOBAL_FRLS, LOCAL_FRLS or MFRLS")
        self.parameter("forgetting", 1.0, "Forgetting factor in (0, 1]", unit="1", minimum=0.0, maximum=1.0)
        self.parameter("omega", 0.01, "Initial covariance C(0) = omega I of the estimators", minimum=0.0)
        self.parameter("rules", 3, "Rules per TS model", minimum=1)
        self.parameter("identification_time", 3000.0, "Length of each open-loop identification run", unit="s")
        self.parameter("identification_seed", 0, "Seed s of the identification runs' random firing levels (group g draws with 3 s + g)", minimum=0)
        self.input("r1", 8.75, "Set-point of P_m2", unit="MPa")
        self.input("r2", 8.75, "Set-point of P_m4", unit="MPa")
        self.input("y1", 8.75, "Measured P_m2", unit="MPa")
        self.input("y2", 8.75, "Measured P_m4", unit="MPa")
        for i in (1, 2, 3):
            self.output(f"u{i}", f"Firing demand M_{i} of boiler {i} (p.u.)", lambda i=i: float(self.controller.M[i - 1]), unit="1",
                        variability=Fmi2Variability.discrete)
        self.output("active_group", "Chosen group: 1 = (1,2), 2 = (1,3), 3 = (2,3)", lambda: float(self.controller.group + 1), unit="1",
                    variability=Fmi2Variability.discrete)

    def build(self) -> None:
        models = copy.deepcopy([list(row) for row in initial_models(self.Ts, self.identification_time, self.rules, self.identification_seed)])
        self.controller = OSMMController(
            boiler_groups(3, 2), models, ARXStructure(2, 2), np.full(3, self.M0), self.N1, self.N2, self.Nu,
            self.output_weight, self.move_weight, self.alpha,
            Bounds(self.M_min, self.M_max, -self.dM_max, self.dM_max),
            fixed_group=None if self.group == 0 else self.group - 1, adapt=bool(self.adapt),
            method=Estimator(self.method).rls_method, forgetting=self.forgetting, omega=self.omega,
            efficiency_form="printed" if self.efficiency == EfficiencyForm.PRINTED else "gain",
        )
        self.clock = SampleClock(self.Ts, self.experiment_start)

    def advance(self, t: float, h: float) -> None:
        for _ in self.clock.samples_in(t, h):
            self.controller.step([self.r1, self.r2], [self.y1, self.y2])
