"""Public face of :mod:`jaxbal._src.robots.dual_v_balancing`."""

from jaxbal._src.robots.dual_v_balancing import *  # noqa: F403
from jaxbal._src.robots.dual_v_balancing import __all__  # noqa: F401
