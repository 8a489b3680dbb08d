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


def __getattr__(name):
    # jaxbal.confirm / jaxbal.mjx import MuJoCo lazily (slow to import, optional at use).
    if name in ("confirm", "confirm_path"):
        from jaxbal import mjx

        return getattr(mjx, name)
    if name == "mjx":
        import importlib

        return importlib.import_module("jaxbal.mjx")
    raise AttributeError(f"module 'jaxbal' has no attribute {name!r}")


__all__ = [
    "Bodies",
    "Robot",
    "StraightLine",
    "body_com_positions",
    "center_of_mass",
    "confirm",
    "confirm_path",
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
