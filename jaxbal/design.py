"""Counter-mass co-design for every robot: sampled motions, the wrench and torques at
their samples, metrics and :func:`codesign`.

See :mod:`jaxbal._src.design` (loss, bounds, compilation) and :mod:`jaxbal._src.metrics`
(the table of metrics and their units).
"""

from jaxbal._src.design import (
    AT_BOUND_RTOL,
    CONSTRAINT_PENALTY,
    FEASIBILITY_RTOL,
    START_OFFSET,
    DesignSolution,
    codesign,
)
from jaxbal._src.joint_codesign import (
    CONSTRAINT_RTOL,
    JointSolution,
    joint_codesign,
    payload_metrics,
)
from jaxbal._src.metrics import (
    METRICS,
    JerkMotion,
    Motion,
    added_inertia,
    added_mass,
    as_motion,
    base_inertia,
    motion_samples,
    peak_force,
    peak_moment,
    peak_torque,
    peak_torque_rate,
    rms_force,
    rms_moment,
    rms_torque,
    torque_samples,
    wrench_samples,
)
from jaxbal._src.motion_factories import ComTrapezoid, TrapezoidLine
from jaxbal._src.multistart import MultiStart, multistart_joint_codesign
from jaxbal._src.pareto import (
    DOMINANCE_RTOL,
    ParetoFront,
    constraint_excess,
    dominance,
    nondominated,
    pareto_front,
    plot_front,
)
from jaxbal._src.payload_metric import OverPayloads, over_payloads

__all__ = [
    "AT_BOUND_RTOL",
    "CONSTRAINT_PENALTY",
    "CONSTRAINT_RTOL",
    "DOMINANCE_RTOL",
    "FEASIBILITY_RTOL",
    "METRICS",
    "ComTrapezoid",
    "JerkMotion",
    "JointSolution",
    "ParetoFront",
    "START_OFFSET",
    "TrapezoidLine",
    "DesignSolution",
    "Motion",
    "MultiStart",
    "OverPayloads",
    "added_inertia",
    "added_mass",
    "as_motion",
    "base_inertia",
    "codesign",
    "constraint_excess",
    "dominance",
    "joint_codesign",
    "motion_samples",
    "multistart_joint_codesign",
    "nondominated",
    "over_payloads",
    "pareto_front",
    "plot_front",
    "payload_metrics",
    "peak_force",
    "peak_moment",
    "peak_torque",
    "peak_torque_rate",
    "rms_force",
    "rms_moment",
    "rms_torque",
    "torque_samples",
    "wrench_samples",
]
