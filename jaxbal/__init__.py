"""jaxbal: vectorised, differentiable dynamic balancing of high-speed robots.

This module is the public index: everything a user needs is imported here or in the
public submodules :mod:`jaxbal.robots`, :mod:`jaxbal.profiles`,
:mod:`jaxbal.planning`, :mod:`jaxbal.design`, :mod:`jaxbal.balancing`,
:mod:`jaxbal.sensitivity`, :mod:`jaxbal.vibration`,
:mod:`jaxbal.sweep` (callable: ``jaxbal.sweep(metric, robot, motion, axes)``),
:mod:`jaxbal.mujoco` (imported on first use: MuJoCo is slow to import) and
:mod:`jaxbal.report`. The implementation lives in :mod:`jaxbal._src` (private).

Importing jaxbal enables float64 in JAX (see :mod:`jaxbal._src.config`).
"""

import importlib

from jaxbal import balancing, design, planning, profiles, robots, sensitivity, sweep, vibration  # noqa: E402, I001, E501
from jaxbal._src import config as _config  # noqa: F401  (enables float64 once)
from jaxbal._src.actuation import actuator_torque_rate, actuator_torques, velocity_basis
from jaxbal._src.dynamics import (
    inverse_dynamics,
    inverse_dynamics_rate,
    kinetic_energy,
    mass_matrix,
    potential_energy,
)
from jaxbal._src.implicit import RootSolution, newton_solve
from jaxbal._src.momentum import (
    body_com_positions,
    center_of_mass,
    momentum,
    shaking_wrench,
    total_mass,
)
from jaxbal._src.motion import (
    check_state,
    joint_motion,
    loop_closure_residuals,
    pose_motion,
    state_valid,
)
from jaxbal._src.optimize import Solution, minimize
from jaxbal._src.robot import Bodies, Robot
from jaxbal._src.trajectory import StraightLine, sample, sample_times, time_derivatives
from jaxbal._src.validation import checked_jit, runtime_checks, set_runtime_checks

__version__ = "0.2.0"

_LAZY = {"mujoco", "report"}


def __getattr__(name):
    # jaxbal.mujoco imports MuJoCo lazily (slow to import, needed only for checks).
    if name in _LAZY:
        return importlib.import_module(f"jaxbal.{name}")
    if name in ("confirm", "confirm_path"):
        return getattr(importlib.import_module("jaxbal.mujoco"), name)
    raise AttributeError(f"module 'jaxbal' has no attribute {name!r}")


__all__ = [
    "Bodies",
    "Robot",
    "RootSolution",
    "Solution",
    "StraightLine",
    "actuator_torque_rate",
    "actuator_torques",
    "balancing",
    "body_com_positions",
    "center_of_mass",
    "checked_jit",
    "check_state",
    "confirm",
    "confirm_path",
    "design",
    "inverse_dynamics",
    "inverse_dynamics_rate",
    "joint_motion",
    "kinetic_energy",
    "loop_closure_residuals",
    "mass_matrix",
    "minimize",
    "momentum",
    "mujoco",
    "newton_solve",
    "planning",
    "pose_motion",
    "potential_energy",
    "profiles",
    "report",
    "robots",
    "runtime_checks",
    "sample",
    "sample_times",
    "sensitivity",
    "set_runtime_checks",
    "shaking_wrench",
    "state_valid",
    "sweep",
    "time_derivatives",
    "total_mass",
    "velocity_basis",
    "vibration",
]
