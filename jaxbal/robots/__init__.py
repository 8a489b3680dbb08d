"""The robots of the four papers, each in its own module."""

from jaxbal.robots.planar_arm import PlanarArm, planar_2r, planar_3r

__all__ = ["PlanarArm", "planar_2r", "planar_3r"]
