"""MuJoCo and MJX: independent confirmation of jaxbal's base reactions, MJCF export and
open-loop forward simulation. Nothing here is robot-specific: every robot brings its
own kinematic tree (:meth:`jaxbal.Robot.mujoco_tree`)."""

from jaxbal._src.mujoco.confirm import Confirmation, confirm, confirm_path
from jaxbal._src.mujoco.inverse import (
    MjxRobot,
    MujocoRobot,
    mjx_base_reaction,
    mjx_model,
    mujoco_base_reaction,
    mujoco_inverse,
    mujoco_model,
    with_mass_properties,
)
from jaxbal._src.mujoco.mjcf import BASE_MASS, export_mjcf, mujoco_inertials, to_mjcf
from jaxbal._src.mujoco.simulate import Tracking, mujoco_actuator_efforts, simulate_open_loop
from jaxbal._src.mujoco.tree import (
    Connect,
    Joint,
    Tree,
    TreeBody,
    prescribed_tree,
    tree_state,
)
from jaxbal._src.studies import agreement_table, confirm_cases, mujoco_peaks

__all__ = [
    "BASE_MASS",
    "Confirmation",
    "Connect",
    "Joint",
    "MjxRobot",
    "MujocoRobot",
    "Tracking",
    "Tree",
    "TreeBody",
    "confirm",
    "confirm_path",
    "export_mjcf",
    "mjx_base_reaction",
    "mjx_model",
    "mujoco_actuator_efforts",
    "mujoco_base_reaction",
    "mujoco_inertials",
    "mujoco_inverse",
    "mujoco_model",
    "prescribed_tree",
    "simulate_open_loop",
    "to_mjcf",
    "tree_state",
    "agreement_table",
    "confirm_cases",
    "mujoco_peaks",
    "with_mass_properties",
]
