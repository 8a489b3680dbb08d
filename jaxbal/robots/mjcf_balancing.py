"""Public face of :mod:`jaxbal._src.robots.mjcf_balance` (balancing a mechanism loaded
with :func:`jaxbal.robots.from_mjcf`: sampled moves, counter-masses, co-design)."""

from jaxbal._src.robots.mjcf_balance import *  # noqa: F403
from jaxbal._src.robots.mjcf_balance import __all__  # noqa: F401
