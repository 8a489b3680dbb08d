"""DUAL-V studies of van der Wijk et al. (2013): the paper's motions (Figs 6, 9, 11, 12),
evaluation and balancing ratios along them, checks of the inverse dynamic model
(forward dynamics, Lagrange, MuJoCo open-loop simulation), eq (30) sensitivities and
the counter-mass co-design trade-off.

See :mod:`jaxbal._src.robots.dual_v_studies` and
:mod:`jaxbal._src.robots.dual_v_simulation` (MuJoCo, imported on first use).
"""

from jaxbal._src.robots.dual_v_simulation import (
    PLATFORM_JOINTS,
    TORQUE_MODELS,
    OpenLoopConvergence,
    QuinticMoves,
    confirm_motions,
    open_loop_convergence,
    open_loop_tracking,
    torque_law,
)
from jaxbal._src.robots.dual_v_studies import (
    TEST_CIRCLE_RADIUS,
    BalancingRatios,
    CodesignPoint,
    Eq30Sensitivity,
    Peaks,
    TorqueCheck,
    balancing_ratios,
    codesign_trade,
    eq30_sensitivity,
    evaluate_motion,
    forward_dynamics_error,
    joint_states,
    motion_peaks,
    orthogonal_motion,
    quintic_duration,
    torque_model_check,
    triangle_motion,
    triangle_vertices,
    validation_motion,
    workspace_widths,
)

__all__ = [
    "PLATFORM_JOINTS",
    "TEST_CIRCLE_RADIUS",
    "TORQUE_MODELS",
    "BalancingRatios",
    "CodesignPoint",
    "Eq30Sensitivity",
    "OpenLoopConvergence",
    "Peaks",
    "QuinticMoves",
    "TorqueCheck",
    "balancing_ratios",
    "codesign_trade",
    "confirm_motions",
    "eq30_sensitivity",
    "evaluate_motion",
    "forward_dynamics_error",
    "joint_states",
    "motion_peaks",
    "open_loop_convergence",
    "open_loop_tracking",
    "orthogonal_motion",
    "quintic_duration",
    "torque_law",
    "torque_model_check",
    "triangle_motion",
    "triangle_vertices",
    "validation_motion",
    "workspace_widths",
]
