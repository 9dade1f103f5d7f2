"""Controllers as plain classes following `greyfmu.contract.Controller`: one ``step`` per sample, ``reset()`` to start over."""

from greyfmu.control.pid import PID, DerivativeOn, IntegralMode, PIForm, integral_step

__all__ = ["PID", "DerivativeOn", "IntegralMode", "PIForm", "integral_step"]

from greyfmu.control.sopdt_predictive import (
    ControlLaw,
    HorizonWarning,
    SOPDTDesign,
    SOPDTPredictive,
    dominant_time_constant,
    free_response,
    horizon_length,
    law_weights,
    sampling_time_range,
    sopdt_design,
)

__all__ += [
    "ControlLaw",
    "HorizonWarning",
    "SOPDTDesign",
    "SOPDTPredictive",
    "dominant_time_constant",
    "free_response",
    "horizon_length",
    "law_weights",
    "sampling_time_range",
    "sopdt_design",
]

from greyfmu.control.scheduled_pid import GainScheduledPID
from greyfmu.control.scheduling import ITAE, GainSchedule, Gains, Interpolation, OperatingPoint, ScheduleError

__all__ += ["GainScheduledPID", "GainSchedule", "Gains", "ITAE", "Interpolation", "OperatingPoint", "ScheduleError"]

from greyfmu.control.grey_pi import GrayPredictivePI  # noqa: E402

__all__ += ["GrayPredictivePI"]

from greyfmu.control.digital_pi import DigitalPI, DigitalPIDesign, design_digital_pi  # noqa: E402

__all__ += ["DigitalPI", "DigitalPIDesign", "design_digital_pi"]

from greyfmu.control.gpc import CARIMA, GPC, Bounds, diophantine, prediction, smoothed_reference, solve_moves
from greyfmu.control.osmm import (
    OSMMGPC,
    ARXStructure,
    boiler_groups,
    choose_group,
    identify_group_models,
    regulating_efficiency,
)
from greyfmu.control.ts_fuzzy import (
    Antecedent,
    FuzzyRLS,
    TSModel,
    antecedent_from_partition,
    batch_wls,
    fuzzy_c_means,
    gustafson_kessel,
)

__all__ += [
    "CARIMA",
    "GPC",
    "Bounds",
    "diophantine",
    "prediction",
    "smoothed_reference",
    "solve_moves",
    "OSMMGPC",
    "ARXStructure",
    "boiler_groups",
    "choose_group",
    "identify_group_models",
    "regulating_efficiency",
    "Antecedent",
    "FuzzyRLS",
    "TSModel",
    "antecedent_from_partition",
    "batch_wls",
    "fuzzy_c_means",
    "gustafson_kessel",
]
