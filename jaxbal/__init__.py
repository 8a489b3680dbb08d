"""jaxbal: vectorised, differentiable dynamic balancing of high-speed robots.

Importing jaxbal enables float64 in JAX (see :mod:`jaxbal._config`).
"""

from jaxbal import (
    _config,  # noqa: F401  (enables float64 once)
    profiles,
    robots,
)
from jaxbal.dynamics import (
    inverse_dynamics,
    inverse_dynamics_rate,
    kinetic_energy,
    mass_matrix,
    potential_energy,
)
from jaxbal.momentum import (
    body_com_positions,
    center_of_mass,
    momentum,
    shaking_wrench,
    total_mass,
)
from jaxbal.robot import Bodies, Robot
from jaxbal.trajectory import StraightLine, sample, sample_times, time_derivatives

__version__ = "0.1.0"

__all__ = [
    "Bodies",
    "Robot",
    "StraightLine",
    "body_com_positions",
    "center_of_mass",
    "inverse_dynamics",
    "inverse_dynamics_rate",
    "kinetic_energy",
    "mass_matrix",
    "momentum",
    "potential_energy",
    "profiles",
    "robots",
    "sample",
    "sample_times",
    "shaking_wrench",
    "time_derivatives",
    "total_mass",
]
