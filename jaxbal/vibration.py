"""The base's vibration excited by the shaking wrench: a linear modal model of the
frame the robot stands on, its exact response to a sampled wrench, and the residual
and peak vibration as metrics of co-design, sensitivity and sweeps.

See :mod:`jaxbal._src.base_vibration` (model, discretisation, references) and
:mod:`jaxbal._src.base_vibration_metric` (the metric).
"""

from jaxbal._src.base_vibration import *  # noqa: F403
from jaxbal._src.base_vibration import __all__ as _model
from jaxbal._src.base_vibration_metric import BaseVibration

__all__ = [*_model, "BaseVibration"]
