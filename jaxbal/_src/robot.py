"""The robot contract shared by every robot in jaxbal (:class:`Robot`).

A robot is an immutable :class:`equinox.Module` pytree. Its array fields (masses,
lengths, inertias, payload, counter-masses) are differentiable leaves; names, counts
and joint types are static. The shared physics (:mod:`jaxbal._src.momentum`,
:mod:`jaxbal._src.dynamics`) needs only :meth:`Robot.mass_properties` and
:meth:`Robot.body_frames`; planning, co-design, sensitivity, sweeps and the MuJoCo
checks use the rest of the contract, documented on :class:`Robot` -- and nothing else.

Conventions (all robots):

* SI units: m, kg, kg·m², rad, s.
* The base frame is the world frame; every vector is expressed in it.
* ``q`` is the vector of coordinates of all bodies. For serial arms it is the joint
  vector; for parallel robots it is what their inverse kinematics returns.
* Validation: shapes and names are checked at trace time (``ValueError``); values
  (negative masses, unreachable poses) eagerly with a ``ValueError`` naming the value,
  or through ``return_valid`` masks in batched code.
"""

from __future__ import annotations

import abc
from collections.abc import Mapping
from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import cos_sin
from jaxbal._src.mujoco.tree import prescribed_tree
from jaxbal._src.types import (
    Array,
    ArrayLike,
    Coordinates,
    Float,
    Inertias,
    Masses,
    Points,
    Rotations,
)
from jaxbal._src.validation import check_nonnegative, check_shape


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
    """Abstract base of every jaxbal robot: **the robot contract**.

    Everything generic in jaxbal (shaking wrench, planning, co-design, sensitivity,
    sweeps, MuJoCo checks) talks to a robot only through these members, so a new robot
    is one file that subclasses :class:`Robot` and provides them.

    Required:

    * :meth:`mass_properties` -- the rigid bodies (links, payload, counter-masses);
    * :meth:`body_frames` -- pose of every body frame for the coordinates ``q``;
    * :attr:`dof` -- length of ``q``;
    * :meth:`inverse_kinematics` -- ``pose -> q`` with the keyword-only ``branch`` and
      ``return_valid`` (see its docstring: with ``return_valid=True`` it never raises);
    * :meth:`end_effector` -- ``q -> pose`` (the inverse of the above).

    Provided with defaults (override where the robot knows better):

    * :meth:`mujoco_tree` -- the robot's kinematic tree for MuJoCo (default: the
      generic, less independent :func:`~jaxbal._src.mujoco.tree.prescribed_tree`);
    * :meth:`design` / :meth:`with_design` -- the named design variables
      (counter-masses, their positions, payload) from :attr:`design_fields`;
    * :meth:`design_lower_bounds` -- lower bound of each design variable (default 0);
    * :meth:`constraint`, :attr:`independent`, :attr:`actuated` -- loop closures of
      parallel robots (default: none; every coordinate independent and actuated);

    Optional: ``com_inverse_kinematics(com, free, *, branch, return_valid, guess)``, a
    closed-form COM inverse kinematics (the 2R/3R, the Orthoglide); without it,
    :func:`jaxbal.planning.com_inverse_kinematics` solves numerically.

    The branch of the inverse kinematics is always a tuple of ``±1`` signs, one per
    sub-chain with two assembly modes (:attr:`branch_size` of them); ``None`` is the
    robot's :attr:`default_branch`, and an ``int`` ``s`` means ``(s,) * branch_size``.
    """

    #: design variable name -> attribute name (override per robot class).
    design_fields: ClassVar[dict[str, str]] = {}
    #: number of ±1 signs of the inverse-kinematics branch.
    branch_size: ClassVar[int] = 1
    #: dimension of the COM that planning steers (2: x, y of a planar motion; 3: x, y, z).
    com_dims: ClassVar[int] = 3
    #: fields whose entries are physically >= 0 (lengths, masses, inertias). The shared
    #: physics checks them on the robot as it is evaluated, so a value set with
    #: ``eqx.tree_at`` or by an optimiser is refused too (not only by the constructor).
    nonnegative_parameters: ClassVar[tuple[str, ...]] = ()

    @property
    def com_components(self) -> tuple[int, ...]:
        """World axes (0, 1, 2) of the COM that planning steers, ``com_dims`` of them:
        the leading ones by default (``(0, 1)`` for a planar robot in x-y); a mechanism
        moving in another plane overrides it (an MJCF arm in x-z: ``(0, 2)``; see
        :mod:`jaxbal._src.com_components`)."""
        return tuple(range(self.com_dims))

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

    # --- inverse kinematics ------------------------------------------------------------

    @property
    def default_branch(self) -> tuple[int, ...]:
        """The working mode used when ``branch=None`` (all ``+1`` unless overridden)."""
        return (1,) * self.branch_size

    def branch(self, branch=None) -> tuple[int, ...]:
        """Normalise a ``branch`` argument to a tuple of :attr:`branch_size` signs ±1.

        Raises:
            ValueError: a sign other than ±1 (strings and booleans included, also inside
                a tuple) or a tuple of the wrong length.
        """
        if branch is None:
            return self.default_branch
        if isinstance(branch, int | float | np.integer | np.floating) and not isinstance(
            branch, bool
        ):  # one sign for every entry; 1.0 is +1 as inside a tuple, 1.5 is refused below
            branch = (branch,) * self.branch_size
        try:
            signs = tuple(int(s) for s in branch)
            exact = all(float(s) == int(s) for s in branch) and not isinstance(branch, str)
            # ("1",) or (True,) are not signs (int() would accept them silently).
            exact = exact and not any(isinstance(s, str | bool | np.bool_) for s in branch)
        except (TypeError, ValueError) as error:
            raise ValueError(f"branch must be ±1 or a tuple of ±1 signs, got {branch!r}") from error
        if not exact or len(signs) != self.branch_size or any(s not in (1, -1) for s in signs):
            raise ValueError(
                f"branch of {type(self).__name__} must be ±1 or a tuple of "
                f"{self.branch_size} signs ±1, got {branch!r}"
            )
        return signs

    def inverse_kinematics(self, pose, *, branch=None, return_valid: bool = False):
        """Coordinates ``q (dof,)`` of all bodies for an end-effector ``pose``.

        Args:
            pose: the end-effector pose (its shape is the robot's, see
                :meth:`end_effector`).
            branch: working mode, see :meth:`branch`.
            return_valid: return ``(q, valid)`` and never raise (for batched code);
                where ``valid`` is False, ``q`` is finite but meaningless.

        Raises:
            ValueError: eagerly (``return_valid=False``), naming the pose, when it is
                out of reach; under ``jit`` the same check raises at run time
                (:func:`jaxbal._src.validation.guard`), never a clipped ``q``.
        """
        raise NotImplementedError(f"{type(self).__name__} has no inverse kinematics")

    def end_effector(self, q: Coordinates):
        """The end-effector pose for the coordinates ``q`` (what IK takes)."""
        raise NotImplementedError(f"{type(self).__name__} has no end-effector pose")

    # --- closed chains --------------------------------------------------------------

    def constraint(self, q: Coordinates) -> Float[Array, " k"]:
        """Loop-closure residuals ``Φ(q)`` (zero for consistent ``q``); none by default."""
        return jnp.zeros((0,))

    @property
    def independent(self) -> tuple[int, ...]:
        """Indices of the independent coordinates (all, for a serial robot)."""
        return tuple(range(self.dof))

    @property
    def actuated(self) -> tuple[int, ...]:
        """Indices of the actuated coordinates (all, for a serial robot)."""
        return tuple(range(self.dof))

    # --- MuJoCo -----------------------------------------------------------------------

    def mujoco_tree(self):
        """The robot's kinematic tree for MuJoCo (a
        :class:`~jaxbal._src.mujoco.tree.Tree`). Default: the generic prescribed tree,
        which checks the mass bookkeeping but not the kinematics."""
        return prescribed_tree(self)

    # --- design variables -----------------------------------------------------------

    def design(self) -> dict[str, Array]:
        """The named design variables (counter-masses, their positions, payload)."""
        return {name: getattr(self, field) for name, field in self.design_fields.items()}

    def with_design(self, design: Mapping[str, ArrayLike]) -> Robot:
        """The robot with the given design variables replaced (others kept).

        Raises:
            ValueError: an unknown name or a wrong shape (checked at trace time);
                negative masses are caught where the physics runs.
        """
        current = self.design()
        unknown = set(design) - set(current)
        if unknown:
            raise ValueError(
                f"unknown design variable(s) {sorted(unknown)} of {type(self).__name__}; "
                f"it has {sorted(current)}"
            )
        if not design:
            return self
        names = list(design)
        values = []
        for name in names:
            value = jnp.asarray(design[name], dtype=float)
            check_shape(f"design[{name!r}]", value, jnp.shape(current[name]))
            values.append(value)
        fields = [self.design_fields[name] for name in names]
        return eqx.tree_at(lambda r: tuple(getattr(r, f) for f in fields), self, tuple(values))

    def design_lower_bounds(self) -> dict[str, float]:
        """Lower bound of each design variable (masses and distances: 0)."""
        return {name: 0.0 for name in self.design()}


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
