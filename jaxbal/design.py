"""Counter-mass co-design for every robot: sampled motions, metrics and :func:`codesign`.

See :mod:`jaxbal._src.design` (loss, bounds, compilation) and :mod:`jaxbal._src.metrics`
(the table of metrics and their units).
"""

from jaxbal._src.design import (
    CONSTRAINT_PENALTY,
    FEASIBILITY_RTOL,
    START_OFFSET,
    DesignSolution,
    codesign,
)
from jaxbal._src.metrics import (
    METRICS,
    Motion,
    added_inertia,
    added_mass,
    as_motion,
    base_inertia,
    motion_samples,
    peak_force,
    peak_moment,
    peak_torque,
    rms_force,
    rms_moment,
    rms_torque,
)

__all__ = [
    "CONSTRAINT_PENALTY",
    "FEASIBILITY_RTOL",
    "METRICS",
    "START_OFFSET",
    "DesignSolution",
    "Motion",
    "added_inertia",
    "added_mass",
    "as_motion",
    "base_inertia",
    "codesign",
    "motion_samples",
    "peak_force",
    "peak_moment",
    "peak_torque",
    "rms_force",
    "rms_moment",
    "rms_torque",
]
