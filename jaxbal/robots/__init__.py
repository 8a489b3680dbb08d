"""The robots of the four papers, each in its own module."""

from jaxbal.robots.dual_v import *  # noqa: F403
from jaxbal.robots.orthoglide import *  # noqa: F403
from jaxbal.robots.planar_arm import PlanarArm, planar_2r, planar_3r
from jaxbal.robots.scara import *  # noqa: F403

__all__ = ["PlanarArm", "planar_2r", "planar_3r", "scara", "dual_v", "orthoglide"]  # noqa: F405
