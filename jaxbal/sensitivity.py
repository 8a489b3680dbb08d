"""Design sensitivities for every robot: gradients of a metric with respect to the design
variables, checked against central finite differences on request, and the machining tolerances
and couplings of a design (:func:`tolerance`).

See :mod:`jaxbal._src.sensitivity`; the metrics and :class:`Motion` are those of
:mod:`jaxbal.design`.
"""

from jaxbal._src.metrics import METRICS, Motion, motion_samples
from jaxbal._src.sensitivity import Sensitivity, payload_sensitivity, sensitivity
from jaxbal._src.tolerance import FLAT_RTOL, Tolerance, tolerance

__all__ = [
    "FLAT_RTOL",
    "METRICS",
    "Motion",
    "Sensitivity",
    "Tolerance",
    "motion_samples",
    "payload_sensitivity",
    "sensitivity",
    "tolerance",
]
