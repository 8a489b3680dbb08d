"""Public face of :mod:`jaxbal._src.robots.dual_v_dynamics`."""

from jaxbal._src.robots.dual_v_dynamics import *  # noqa: F403
from jaxbal._src.robots.dual_v_dynamics import __all__  # noqa: F401
