"""Balancing conditions of any robot: the shaking wrench as a linear map of the
bodies' lumped inertial parameters (mass, first moment, inertia about the frame
origin), evaluated by Newton–Euler independently of :func:`jaxbal.shaking_wrench`, and
the linear conditions on those parameters under which the shaking force or moment
vanishes along a motion.

See :mod:`jaxbal._src.regressor` (formulas, rank decision, references).
"""

from jaxbal._src.regressor import *  # noqa: F403
from jaxbal._src.regressor import __all__  # noqa: F401
