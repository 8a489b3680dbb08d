"""Counter-masses attached to the bodies of a mechanism read from MJCF.

:func:`add_counter_mass` fixes a point (or rigid) mass to a moving body of an
:class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot` and registers it as a design
variable: ``robot.design()`` then holds ``counter_mass (k,)`` [kg] and
``counter_position (k, 3)`` [m, in the carrying body's frame] of all ``k`` added
counter-masses, so :func:`jaxbal.design.codesign` and :func:`jaxbal.sensitivity.sensitivity`
work on it unchanged. Its MuJoCo tree welds each counter-mass to its body.

References:
    Arakelian & Smith (2005), "Shaking force and shaking moment balancing of
    mechanisms: a historical review", J. Mech. Design 127(2) (counterweights on links).
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp
import numpy as np

from jaxbal._src.robots.mjcf_robot import MjcfRobot
from jaxbal._src.types import ArrayLike
from jaxbal._src.validation import check_nonnegative, check_shape

__all__ = ["add_counter_mass"]


def add_counter_mass(
    robot: MjcfRobot,
    body: str,
    position: ArrayLike = (0.0, 0.0, 0.0),
    mass: ArrayLike = 0.0,
    inertia: ArrayLike | None = None,
    name: str | None = None,
) -> MjcfRobot:
    """``robot`` with one more counter-mass on the MJCF body ``body``.

    Args:
        robot: an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot`.
        body: name of a moving body of the MJCF.
        position: ``(3,)`` position of the counter-mass's COM in the body frame [m].
        mass: its mass [kg] (≥ 0).
        inertia: ``(3, 3)`` inertia about its COM in the body frame [kg·m²]; default
            zero (a point mass). Not a design variable (kept when the mass changes).
        name: its name in ``mass_properties()`` and the MuJoCo tree (default
            ``"counter_<body>"``, numbered when taken).

    Returns:
        A new robot (the argument is unchanged).

    Raises:
        ValueError: an unknown or fixed body, a counter-mass as body, a wrong shape, a
            negative mass, or a name already taken.
    """
    if not isinstance(robot, MjcfRobot):
        raise ValueError(f"add_counter_mass needs a robot from from_mjcf, got {type(robot)}")
    index = robot.body_index(body)
    if index >= len(robot.moving_bodies):
        raise ValueError(f"{body!r} is a counter-mass; attach counter-masses to MJCF bodies")
    position = jnp.asarray(position, dtype=float)
    check_shape("position", position, (3,))
    mass = jnp.asarray(mass, dtype=float)
    check_shape("mass", mass, ())
    check_nonnegative("counter-mass", mass)
    inertia = jnp.zeros((3, 3)) if inertia is None else jnp.asarray(inertia, dtype=float)
    check_shape("inertia", inertia, (3, 3))
    taken = set(robot.mass_names()) | set(robot.body_names)
    if name is None:
        name, number = f"counter_{body}", 2
        while name in taken:
            name, number = f"counter_{body}_{number}", number + 1
    elif name in taken:
        raise ValueError(f"name {name!r} is already taken by a body or a counter-mass")
    return dataclasses.replace(
        robot,
        counter_mass=jnp.concatenate([robot.counter_mass, mass[None]]),
        counter_position=jnp.concatenate([robot.counter_position, position[None]]),
        counter_inertia=jnp.concatenate([robot.counter_inertia, inertia[None]]),
        counter_bodies=robot.counter_bodies + (index,),
        counter_names=robot.counter_names + (name,),
    )


def counter_masses_on(robot: MjcfRobot, bodies, mass: ArrayLike = 0.0) -> MjcfRobot:
    """``robot`` with a point counter-mass of ``mass`` [kg] at the origin of each of
    ``bodies`` (names): a start for :func:`jaxbal.design.codesign`."""
    for body in bodies:
        robot = add_counter_mass(robot, body, np.zeros(3), mass)
    return robot
