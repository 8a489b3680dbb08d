"""Motion on every robot: COM and end-effector straight lines, evaluation along a
motion (shaking wrench, torques, peaks) and the torque-rate-limited planner."""

from jaxbal._src.planning import (
    ComLine,
    EndEffectorLine,
    com_line,
    peak_norm,
    shaking_peaks,
    smooth_peak,
    torque_rate_along,
    torques_along,
    wrench_along,
)
from jaxbal._src.rate_limit import RateLimitedPlan, peak_torque_rate, plan_rate_limited

__all__ = [
    "ComLine",
    "EndEffectorLine",
    "RateLimitedPlan",
    "com_line",
    "peak_norm",
    "peak_torque_rate",
    "plan_rate_limited",
    "shaking_peaks",
    "smooth_peak",
    "torque_rate_along",
    "torques_along",
    "wrench_along",
]
