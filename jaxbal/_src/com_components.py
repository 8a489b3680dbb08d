"""Which world components of the total centre of mass (COM) planning steers.

A planar mechanism's COM moves in its plane: planning steers the components in that
plane, and the COM inverse kinematics solves for them. The built-in planar robots move
in the x-y plane, so they steer the first ``com_dims`` world components (``[:2]``); a
mechanism read from MJCF is often drawn in the vertical x-z plane (hinges about y, the
natural way to draw a gravity-loaded arm), and steers ``(0, 2)``. Taking ``[:d]`` there
planned the world ``(x, y)`` of an x-z mechanism: a COM IK with a constant ``y`` (a
singular Newton solve, NaN) or a COM of the wrong shape.

The contract (:class:`jaxbal.Robot`): ``com_components``, the tuple of world axes
(0, 1, 2) that planning steers, ``com_dims`` of them (default
``tuple(range(com_dims))``; a robot moving in another plane overrides it). Every
generic tool projects the COM through :func:`com_components` and :func:`planned_com`,
so that the COM plan
(:func:`jaxbal.planning.com_line`) and the COM inverse kinematics
(:func:`~jaxbal._src.com_ik.numerical_com_inverse_kinematics`) agree. The robots that
steer the leading components (every built-in one) keep the slice ``[:d]``, so their
results are bit-identical to those before this projection existed.

References:
    Briot, Arakelian & Le Baron (2012), §2 (the COM moves in the mechanism's plane).
"""

from __future__ import annotations

import numpy as np

from jaxbal._src.momentum import center_of_mass

__all__ = ["com_components", "is_leading", "planned_com", "world_com_target"]

_AXES = "xyz"


def is_leading(components: tuple[int, ...]) -> bool:
    """True for the leading world axes ``(0, …, d − 1)``: ``[:d]`` takes them."""
    return tuple(components) == tuple(range(len(components)))


def _own(robot) -> tuple[int, ...]:
    return tuple(int(c) for c in robot.com_components)


def com_components(robot, dims: int | None = None) -> tuple[int, ...]:
    """World axes of the COM that planning steers for ``robot``.

    Args:
        robot: any :class:`~jaxbal.Robot`.
        dims: ``None`` (the robot's own choice) or a number of components. A robot
            steering the leading axes takes the first ``dims`` (``dims=3`` plans the
            spatial COM of a planar robot, as before); a robot steering other axes
            (an arm in the x-z plane) accepts only its own count.

    Raises:
        ValueError: a ``dims`` that a robot steering other than the leading axes
            cannot take (names its axes).
    """
    own = _own(robot)
    if dims is None or int(dims) == len(own):
        return own
    if is_leading(own):
        return tuple(range(int(dims)))
    names = ", ".join(_AXES[c] for c in own)
    raise ValueError(
        f"dims={dims}: {type(robot).__name__} plans its COM in the world axes ({names}), "
        f"the plane it moves in (its com_components {own}); leave dims out"
    )


def planned_com(robot, q, components: tuple[int, ...]):
    """The ``components`` of the total COM of ``robot`` at ``q`` [m] (``[:d]`` for the
    leading axes: bit-identical to the slice the tools took before)."""
    com = center_of_mass(robot, q)
    if is_leading(components):
        return com[: len(components)]
    return com[np.asarray(components, dtype=int)]


def world_com_target(robot, com):
    """A COM target in the robot's own components: a ``(3,)`` world COM given to a
    robot that steers fewer, non-leading axes is projected onto them (a user's
    ``center_of_mass(robot, q)`` as the target of an x-z arm); any other target is
    returned as it is (:func:`jaxbal.planning.com_line` plans in the components)."""
    own = _own(robot)
    if com.shape == (3,) and len(own) < 3 and not is_leading(own):
        return com[np.asarray(own, dtype=int)]
    return com
