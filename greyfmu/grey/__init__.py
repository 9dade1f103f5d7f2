"""Grey models: AGO/IAGO, GM(1,1) with the moving-window/LDISPI predictor, GM(3/t,1) identification."""

from greyfmu.grey.ago import ago, background, iago
from greyfmu.grey.errors import GreyModelError
from greyfmu.grey.gm3t1 import GM3t1, SecondOrderConstants, StepIdentifier
from greyfmu.grey.gm11 import GM11
from greyfmu.grey.predictor import GreyPredictor, PredictorMode, Threshold

__all__ = [
    "GM11",
    "GM3t1",
    "GreyModelError",
    "GreyPredictor",
    "PredictorMode",
    "Threshold",
    "SecondOrderConstants",
    "StepIdentifier",
    "ago",
    "background",
    "iago",
]
