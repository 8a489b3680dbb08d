"""Design sensitivities for every robot: gradients of a metric with respect to the design
variables, checked against central finite differences on request.

See :mod:`jaxbal._src.sensitivity`; the metrics and :class:`Motion` are those of
:mod:`jaxbal.design`.
"""

from jaxbal._src.metrics import METRICS, Motion, motion_samples
from jaxbal._src.sensitivity import Sensitivity, payload_sensitivity, sensitivity

__all__ = [
    "METRICS",
    "Motion",
    "Sensitivity",
    "motion_samples",
    "payload_sensitivity",
    "sensitivity",
]
