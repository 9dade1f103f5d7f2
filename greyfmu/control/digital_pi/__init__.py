"""State-space digital PI for MIMO stochastic plants with input delay (Zhou, Shieh, Liu & Wang,
Can. J. Chem. Eng. 84 (2006)): discretisation with a fractional input delay, augmentation,
LQR with poles in a disc (Lee & Lee 1986), static decoupling, Kalman innovation observer, and the
paper's route to the Kalman gain (block companion form, ARMAX by extended least squares)."""

from greyfmu.control.digital_pi.augment import AugmentedPlant, augment_delay, cascade_pi
from greyfmu.control.digital_pi.companion import BlockCompanion, block_companion, companion_matrix
from greyfmu.control.digital_pi.controller import DigitalPI
from greyfmu.control.digital_pi.decoupling import static_decoupling, static_gain
from greyfmu.control.digital_pi.design import (
    DigitalPIDesign,
    closed_loop,
    design_digital_pi,
    reference_dc_gain,
    stationary_variances,
    with_observer_gain,
)
from greyfmu.control.digital_pi.disc_lqr import DiscLQR, dlqr_disc
from greyfmu.control.digital_pi.discretize import ContinuousPlant, DelayTerm, DiscretePlant, c2d, integral_expm, split_delay
from greyfmu.control.digital_pi.errors import DesignError
from greyfmu.control.digital_pi.identification import (
    ARMAX,
    ELSResult,
    armax_observer,
    els_convergence_margin,
    extended_least_squares,
    noise_model_gain,
    one_step_predictions,
)
from greyfmu.control.digital_pi.observer import continuous_noise_gain, innovation_observer, kalman_innovation
from greyfmu.control.digital_pi.parameters import MAX_CHANNELS, MAX_ORDER, design_parameters, stored_design, write_design_ssv

__all__ = [
    "ARMAX",
    "MAX_CHANNELS",
    "MAX_ORDER",
    "AugmentedPlant",
    "BlockCompanion",
    "ContinuousPlant",
    "DelayTerm",
    "DesignError",
    "DigitalPI",
    "DigitalPIDesign",
    "DiscLQR",
    "DiscretePlant",
    "ELSResult",
    "armax_observer",
    "augment_delay",
    "block_companion",
    "c2d",
    "cascade_pi",
    "closed_loop",
    "companion_matrix",
    "continuous_noise_gain",
    "design_digital_pi",
    "design_parameters",
    "dlqr_disc",
    "els_convergence_margin",
    "extended_least_squares",
    "innovation_observer",
    "integral_expm",
    "kalman_innovation",
    "noise_model_gain",
    "one_step_predictions",
    "reference_dc_gain",
    "split_delay",
    "static_decoupling",
    "static_gain",
    "stationary_variances",
    "stored_design",
    "with_observer_gain",
    "write_design_ssv",
]
