"""Public face of :mod:`jaxbal._src.robots.scara_balancing`."""

from jaxbal._src.robots.scara_balancing import *  # noqa: F403
from jaxbal._src.robots.scara_balancing import __all__  # noqa: F401
