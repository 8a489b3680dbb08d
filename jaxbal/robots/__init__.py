"""Robots: the nominal robots of the four papers and their classes.

Every robot satisfies the contract of :class:`jaxbal.Robot`. Robot-specific tools
(closed-form balancing, paper models) live in the submodules
:mod:`jaxbal.robots.planar_arm`, :mod:`jaxbal.robots.scara_balancing`,
:mod:`jaxbal.robots.dual_v_balancing`, :mod:`jaxbal.robots.dual_v_dynamics`,
:mod:`jaxbal.robots.dual_v_plots` and :mod:`jaxbal.robots.orthoglide_planning`; the
studies that reproduce each paper (used by ``experiments/``) in
:mod:`jaxbal.robots.planar_arm_studies`, :mod:`jaxbal.robots.scara_studies`,
:mod:`jaxbal.robots.dual_v_studies` and :mod:`jaxbal.robots.orthoglide_studies`.
"""

from jaxbal._src.robots import ALIASES, ROBOTS, by_name
from jaxbal._src.robots.counter_mass import add_counter_mass
from jaxbal._src.robots.dual_v import CROSSED, OUTWARD, DualV, dual_v
from jaxbal._src.robots.mjcf_export import export_balanced
from jaxbal._src.robots.mjcf_import import from_mjcf, from_urdf
from jaxbal._src.robots.mjcf_robot import MjcfRobot
from jaxbal._src.robots.orthoglide import Orthoglide, orthoglide
from jaxbal._src.robots.planar_arm import PlanarArm, planar_2r, planar_3r
from jaxbal._src.robots.scara import PickAndPlace, Scara, ScaraTrajectory, joint_trajectory, scara

__all__ = [
    "ALIASES",
    "CROSSED",
    "OUTWARD",
    "ROBOTS",
    "DualV",
    "Orthoglide",
    "PickAndPlace",
    "PlanarArm",
    "Scara",
    "ScaraTrajectory",
    "by_name",
    "dual_v",
    "joint_trajectory",
    "orthoglide",
    "planar_2r",
    "planar_3r",
    "scara",
    "MjcfRobot",
    "add_counter_mass",
    "export_balanced",
    "from_mjcf",
    "from_urdf",
]
