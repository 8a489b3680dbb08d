"""Kinematic trees: how a robot describes its joints to MuJoCo.

A jaxbal :class:`~jaxbal.Robot` knows its bodies' mass properties and poses, not its
joints. To let MuJoCo compute the dynamics *independently*, every robot describes its
kinematic topology once, in its own :meth:`~jaxbal.Robot.mujoco_tree`: MuJoCo bodies,
each the frame of one jaxbal body (so the mass, COM and inertia of
:meth:`~jaxbal.Robot.mass_properties` apply unchanged), joined by hinge/slide/ball
joints, plus ``connect`` equality constraints that close kinematic loops.

:func:`prescribed_tree` is the generic fallback (the default of
:meth:`~jaxbal.Robot.mujoco_tree`): every jaxbal body hangs from the base on three
slides and a ball joint whose motion is *prescribed* from ``robot.body_frames``. It
checks the mass properties and the momentum bookkeeping (Newton-Euler), not the
kinematics, so it is less independent than a robot's own tree.

This module imports no robot and nothing from MuJoCo: robots import it.

References:
    MuJoCo XML reference, https://mujoco.readthedocs.io/en/stable/XMLreference.html
    (``joint``, ``equality/connect``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import vee

Z = (0.0, 0.0, 1.0)


def vec(*values) -> tuple[float, ...]:
    """Plain Python floats (tree fields are static: no numpy scalars)."""
    return tuple(float(v) for v in np.ravel(np.asarray(values, dtype=float)))


class Joint(NamedTuple):
    """A 1-dof joint of a :class:`TreeBody`.

    Attributes:
        name: unique joint name.
        type: ``"hinge"`` or ``"slide"``.
        axis: ``(3,)`` joint axis in the body frame.
        pos: ``(3,)`` anchor in the body frame [m] (hinges).
    """

    name: str
    type: str
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)


class TreeBody(NamedTuple):
    """One MuJoCo body, whose frame is the frame of a jaxbal body.

    Attributes:
        name: the jaxbal body name (from ``mass_properties().names``); the mass,
            COM and inertia of that body are used. A name that is not a jaxbal body
            gives a massless helper body (only allowed without joints).
        parent: parent body name, ``None`` for the base.
        pos: ``(3,)`` frame origin in the parent frame at ``qpos = 0`` [m].
        rotation: ``(3, 3)`` frame orientation in the parent frame at ``qpos = 0``.
        joints: the joints moving this body relative to its parent.
        visual_to: optional ``(3,)`` end of a visual capsule from the frame origin [m].
    """

    name: str
    parent: str | None
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    joints: tuple[Joint, ...] = ()
    visual_to: tuple[float, float, float] | None = None


class Connect(NamedTuple):
    """A ``connect`` equality (spherical joint) closing a kinematic loop.

    Written with two sites (``site1``/``site2``), so the joint centre is given on both
    bodies and does not depend on MuJoCo's reference configuration ``qpos0``.

    Attributes:
        body1, anchor1: first body and the joint centre in its frame ``(3,)`` [m].
        body2, anchor2: second body and the joint centre in its frame ``(3,)`` [m].
    """

    body1: str
    anchor1: tuple[float, float, float]
    body2: str
    anchor2: tuple[float, float, float]


class Coupling(NamedTuple):
    """A joint ``equality`` (gear, belt, URDF mimic): ``q1 − q1⁰ = Σ_i a_i (q2 − q2⁰)^i``
    (:mod:`jaxbal._src.robots.mjcf_couplings`).

    Attributes:
        joint1: the coupled joint; joint2: the one it follows (``None``: fixed).
        polycoef: ``(a0, a1, a2, a3, a4)``.
    """

    joint1: str
    joint2: str | None
    polycoef: tuple[float, float, float, float, float]


class Tree(NamedTuple):
    """Kinematic description of a robot for MuJoCo.

    Attributes:
        bodies: parents before children.
        coordinates: ``q (dof,) -> qpos (nq_robot,)`` of the tree joints in the order
            they appear in ``bodies``; any smooth JAX function (velocities and
            accelerations follow by forward-mode differentiation).
        connects: loop-closure constraints.
        couplings: joint equalities (closed by MuJoCo C with the ``connects``).
        actuated: names of the actuated joints (motors in the MJCF), if known.
        independent: False for :func:`prescribed_tree`.
        state: optional ``(q, qd, qdd) -> (qpos, qvel, qacc)`` overriding the default
            (derivatives of ``coordinates``), see :func:`tree_state`.
        solved: joints that MuJoCo C places itself by closing the ``connects``
            (:mod:`jaxbal._src.mujoco.closure`); ``coordinates`` then gives only the
            other (prescribed) joints to MuJoCo C. MJX still takes ``coordinates``.
        guess: with ``solved``: ``q (dof,) -> qpos`` (numpy) whose solved entries start
            MuJoCo's Newton; a geometric rule that picks the assembly mode.
    """

    bodies: tuple[TreeBody, ...]
    coordinates: Callable
    connects: tuple[Connect, ...] = ()
    actuated: tuple[str, ...] = ()
    independent: bool = True
    state: Callable | None = None
    solved: tuple[str, ...] = ()
    guess: Callable | None = None
    couplings: tuple[Coupling, ...] = ()

    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for b in self.bodies for j in b.joints)


def _quat_mul(a, b):
    w1, v1 = a[0], a[1:]
    w2, v2 = b[0], b[1:]
    return jnp.concatenate([(w1 * w2 - v1 @ v2)[None], w1 * v2 + w2 * v1 + jnp.cross(v1, v2)])


def tree_state(tree: Tree, q, qd, qdd):
    """``(qpos, qvel, qacc)`` of the tree joints (base dofs excluded) for jaxbal's
    ``(q, q̇, q̈)``, unless ``tree.state`` is given.

    ``qpos = c(q)``; a hinge/slide velocity is ``ċ = c'(q) q̇``; a ball joint's is its
    angular velocity in the child frame, ``ω = 2 vec(Q* ⊗ Q̇)`` (MuJoCo's convention);
    accelerations are their time derivatives. All by nested ``jax.jvp`` (exact).
    """
    if tree.state is not None:
        return tree.state(q, qd, qdd)
    q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))
    types = [j.type for b in tree.bodies for j in b.joints]

    def velocity(q_, qd_):
        qpos, rate = jax.jvp(tree.coordinates, (q_,), (qd_,))
        if "ball" not in types:
            return qpos, rate
        pieces, i = [], 0
        for kind in types:
            if kind == "ball":
                quat, quat_rate = qpos[i : i + 4], rate[i : i + 4]
                conjugate = quat * jnp.array([1.0, -1.0, -1.0, -1.0])
                pieces.append(2.0 * _quat_mul(conjugate, quat_rate)[1:])
                i += 4
            else:
                pieces.append(rate[i : i + 1])
                i += 1
        return qpos, jnp.concatenate(pieces)

    (qpos, qvel), (_, qacc) = jax.jvp(velocity, (q, qd), (qd, qdd))
    return qpos, qvel, qacc


def matrix_to_quat(rotation, xp=jnp):
    """Unit quaternion ``(w, x, y, z)`` of a rotation matrix (Shepperd, branch-free).

    The largest of the four candidate components is chosen with ``argmax`` so the
    division is well conditioned; the result is differentiable almost everywhere.
    ``xp``: the array module, ``jax.numpy`` (traceable) or ``numpy`` (host code such as
    the MJCF writer: eagerly, each of the ~40 small JAX operations is a dispatch, the
    first ones a compilation, ~0.1 s per matrix in a fresh process).
    """
    r = rotation
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    candidates = xp.stack(
        [
            xp.stack([1 + trace, r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]),
            xp.stack(
                [r[2, 1] - r[1, 2], 1 + 2 * r[0, 0] - trace, r[0, 1] + r[1, 0], r[0, 2] + r[2, 0]]
            ),
            xp.stack(
                [r[0, 2] - r[2, 0], r[0, 1] + r[1, 0], 1 + 2 * r[1, 1] - trace, r[1, 2] + r[2, 1]]
            ),
            xp.stack(
                [r[1, 0] - r[0, 1], r[0, 2] + r[2, 0], r[1, 2] + r[2, 1], 1 + 2 * r[2, 2] - trace]
            ),
        ]
    )
    diag = xp.stack([trace, r[0, 0], r[1, 1], r[2, 2]])
    k = xp.argmax(diag)
    row = candidates[k]
    quat = row / (2.0 * xp.sqrt(xp.maximum(row[k], 1e-300)))
    return quat * xp.sign(quat[0] + (quat[0] == 0))


def minimal_rotation_quat(a, d):
    """Unit quaternion of the rotation about ``a × d`` taking unit ``a`` onto ``d``."""
    d = d / jnp.linalg.norm(d)
    quat = jnp.concatenate([(1.0 + a @ d)[None], jnp.cross(a, d)])
    return quat / jnp.linalg.norm(quat)


def prescribed_tree(robot) -> Tree:
    """Generic tree: every jaxbal body on 3 world slides + a ball joint under the base.

    Less independent than a registered tree: the kinematics (poses, velocities,
    accelerations) are jaxbal's own ``body_frames`` and its derivatives; MuJoCo then
    checks the Newton-Euler sum of the bodies' momenta about the base origin. Valid
    for closed chains too. The joints sit on massless helper bodies (mass
    :data:`BASE_MASS`, a relative error ~1e-15) carrying the welded jaxbal bodies.
    Its ``state`` gives slide positions and ball quaternions, the velocities and
    accelerations in MuJoCo's convention (a ball joint's velocity is the angular
    velocity in the body frame, not the derivative of its quaternion).
    """
    bodies = ()
    # the names only: traced abstractly (eagerly the masses and inertias would run
    # operation by operation, each a compilation in a fresh process)
    for name in eqx.filter_eval_shape(lambda r: r.mass_properties(), robot).names:
        slides = tuple(
            Joint(f"{name}_{a}", "slide", tuple(float(x) for x in ax))
            for a, ax in zip("xyz", np.eye(3), strict=True)
        )
        bodies += (
            TreeBody(
                name=f"{name}_frame", parent=None, joints=slides + (Joint(f"{name}_ball", "ball"),)
            ),
            TreeBody(name=name, parent=f"{name}_frame"),
        )

    def coordinates(q):
        origins, rotations = robot.body_frames(q)
        quats = jax.vmap(matrix_to_quat)(rotations)
        return jnp.concatenate([origins, quats], axis=-1).reshape(-1)

    def state(q, qd, qdd):
        q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))

        def frames(q_):
            return robot.body_frames(q_)

        def twist(q_, qd_):
            (origins, rotations), (velocities, rates) = jax.jvp(frames, (q_,), (qd_,))
            omega_local = vee(jnp.einsum("nji,njk->nik", rotations, rates))
            return velocities, omega_local

        (velocities, omega), (accelerations, omega_dot) = jax.jvp(twist, (q, qd), (qd, qdd))
        qvel = jnp.concatenate([velocities, omega], axis=-1).reshape(-1)
        qacc = jnp.concatenate([accelerations, omega_dot], axis=-1).reshape(-1)
        return coordinates(q), qvel, qacc

    return Tree(bodies=bodies, coordinates=coordinates, independent=False, state=state)


def identity(q):
    """The coordinate map ``qpos = q`` (module level: equal trees compare equal)."""
    return q
