"""Planar nR arms of Briot et al. (2012): the class, the counterweight closed form and
the test points P1…P16 of the paper's Fig 3."""

from jaxbal._src.robots.planar_arm import PlanarArm, force_balanced, planar_2r, planar_3r
from jaxbal._src.square_paths import BRIOT2012_PATHS, path_name, square_points

__all__ = [
    "BRIOT2012_PATHS",
    "PlanarArm",
    "force_balanced",
    "path_name",
    "planar_2r",
    "planar_3r",
    "square_points",
]
