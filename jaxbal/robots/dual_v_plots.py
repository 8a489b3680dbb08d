"""Public face of :mod:`jaxbal._src.robots.dual_v_plots`."""

from jaxbal._src.robots.dual_v_plots import *  # noqa: F403
from jaxbal._src.robots.dual_v_plots import __all__  # noqa: F401
