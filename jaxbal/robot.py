"""The robot abstraction shared by every robot in jaxbal.

A robot is an immutable :class:`equinox.Module` pytree. Its array fields (masses,
lengths, inertias, payload, counter-masses) are differentiable leaves; names, counts
and joint types are static fields. Every robot exposes the same two methods, and
*nothing else* is needed by the shared physics (:mod:`jaxbal.momentum`,
:mod:`jaxbal.dynamics`):

* :meth:`Robot.mass_properties` -- the rigid bodies it is made of (payload and
  counter-masses included), as a :class:`Bodies` pytree;
* :meth:`Robot.body_frames` -- the pose of every body frame for coordinates ``q``.

Conventions (all robots):

* SI units: m, kg, kg·m², rad, s.
* The base frame is the world frame; every vector is expressed in it.
* ``q`` is the vector of coordinates of all bodies. For serial arms it is the joint
  vector; for parallel robots it is what their inverse kinematics returns.
"""

from __future__ import annotations

import abc

import equinox as eqx
import jax.numpy as jnp

from jaxbal._linalg import cos_sin
from jaxbal.types import Coordinates, Inertias, Masses, Points, Rotations
from jaxbal.validation import check_nonnegative


class Bodies(eqx.Module):
    """Mass properties of ``n`` rigid bodies, each in its own body frame.

    Attributes:
        mass: ``(n,)`` masses [kg].
        com: ``(n, 3)`` centre of mass of each body in its body frame [m].
        inertia: ``(n, 3, 3)`` inertia tensor of each body about its centre of mass,
            in its body frame [kg·m²].
        names: static tuple of ``n`` body names.
    """

    mass: Masses
    com: Points
    inertia: Inertias
    names: tuple[str, ...] = eqx.field(static=True)

    def __check_init__(self):
        n = len(self.names)
        if jnp.shape(self.mass) != (n,):
            raise ValueError(f"mass must have shape ({n},), got {jnp.shape(self.mass)}")
        if jnp.shape(self.com) != (n, 3):
            raise ValueError(f"com must have shape ({n}, 3), got {jnp.shape(self.com)}")
        if jnp.shape(self.inertia) != (n, 3, 3):
            raise ValueError(f"inertia must have shape ({n}, 3, 3), got {jnp.shape(self.inertia)}")
        check_nonnegative("body masses", self.mass)

    @property
    def count(self) -> int:
        return len(self.names)


def planar_inertia(izz) -> Inertias:
    """``(n, 3, 3)`` inertia tensors of planar bodies with only ``I_zz`` (about the COM).

    Planar robots move in the x-y plane; only the axial moment ``I_zz`` matters for
    their shaking moment, the other entries are zero.
    """
    izz = jnp.atleast_1d(jnp.asarray(izz, dtype=float))
    return izz[:, None, None] * jnp.diag(jnp.array([0.0, 0.0, 1.0]))[None]


def point_masses(mass, names: tuple[str, ...]) -> Bodies:
    """Bodies that are point masses at their frame origin (payloads, lumped counter-masses)."""
    mass = jnp.atleast_1d(jnp.asarray(mass, dtype=float))
    n = len(names)
    return Bodies(mass=mass, com=jnp.zeros((n, 3)), inertia=jnp.zeros((n, 3, 3)), names=names)


def concatenate(*groups: Bodies) -> Bodies:
    """Stack several :class:`Bodies` into one (order kept)."""
    return Bodies(
        mass=jnp.concatenate([g.mass for g in groups]),
        com=jnp.concatenate([g.com for g in groups]),
        inertia=jnp.concatenate([g.inertia for g in groups]),
        names=sum((g.names for g in groups), ()),
    )


class Robot(eqx.Module):
    """Abstract base of every jaxbal robot (see the module docstring)."""

    @abc.abstractmethod
    def mass_properties(self) -> Bodies:
        """All moving rigid bodies (links, payload, counter-masses) of the robot."""

    @abc.abstractmethod
    def body_frames(self, q: Coordinates) -> tuple[Points, Rotations]:
        """Origins ``(n, 3)`` [m] and rotation matrices ``(n, 3, 3)`` of the body frames.

        Row ``i`` corresponds to body ``i`` of :meth:`mass_properties`; the rotation
        maps body-frame vectors to the base frame.
        """

    @property
    def dof(self) -> int:
        """Length of the coordinate vector ``q``."""
        raise NotImplementedError


def rot_z(angle) -> jnp.ndarray:
    """``(..., 3, 3)`` rotation matrices about z by ``angle`` [rad]."""
    return rot_z_from(*cos_sin(jnp.asarray(angle)))


def rot_z_from(cos, sin) -> jnp.ndarray:
    """``(..., 3, 3)`` rotations about z from precomputed ``cos`` and ``sin`` of the angle
    (lets a robot share one sine/cosine between its rotations and its positions)."""
    zero, one = jnp.zeros_like(cos), jnp.ones_like(cos)
    return jnp.stack(
        [
            jnp.stack([cos, -sin, zero], -1),
            jnp.stack([sin, cos, zero], -1),
            jnp.stack([zero, zero, one], -1),
        ],
        -2,
    )
