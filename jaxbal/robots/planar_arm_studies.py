"""Studies of Briot et al. (2012) on the planar 2R and 3R arms: the three motion laws
between two test points (with the optimal φ law of the 3R) and the input torques of
Fig 11 (public face of :mod:`jaxbal._src.robots.planar_arm_studies`)."""

from jaxbal._src.robots.planar_arm_studies import (
    TEMPERATURES,
    ComPath,
    MotionLaws,
    input_torques,
    moment_objective,
    motion_laws,
    optimal_phi_coefficients,
)

__all__ = [
    "TEMPERATURES",
    "ComPath",
    "MotionLaws",
    "input_torques",
    "moment_objective",
    "motion_laws",
    "optimal_phi_coefficients",
]
