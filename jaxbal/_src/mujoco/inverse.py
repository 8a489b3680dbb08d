"""Base reactions from MuJoCo (C ``mj_inverse``) and MJX (``mjx.inverse``).

The robot is compiled to MJCF by :mod:`jaxbal.mjcf`: the whole robot hangs from one
``base`` body moved by six dofs (slides x, y, z then hinges about x, y, z through the
base origin), held at rest. MuJoCo's inverse dynamics gives the generalised force
``qfrc_inverse`` the world must apply on those dofs to keep the base still, so the
force and moment the robot exerts on its base, about the base origin and in the base
frame, are

    f = -qfrc_inverse[0:3] - m_base g,     m = -qfrc_inverse[3:6]

(``m_base`` = :data:`jaxbal.mjcf.BASE_MASS` sits at the origin), the same quantity
and sign as :func:`jaxbal.shaking_wrench`.

How MuJoCo's coordinates map to jaxbal's: ``qpos = (0_6, c(q))`` where the first six
entries are the base dofs and ``c`` is the robot tree's ``coordinates`` map
(:mod:`jaxbal.mjx_trees`; for the planar arms ``c(q) = q``, the relative joint angles).
``qvel = (0_6, c'(q) q̇)`` and ``qacc = (0_6, c''(q)[q̇, q̇] + c'(q) q̈)``, evaluated
exactly by forward-mode differentiation. The remaining entries of ``qfrc_inverse``
are the joint torques/forces of the tree (the actuator efforts for a serial robot).

For closed chains the ``connect`` constraints act between robot bodies only; when
the state satisfies them (jaxbal's IK) their Jacobian has no base component, so the
base reaction does not depend on how MuJoCo's soft constraint model splits the
internal forces; what remains is the constraint residual times the stiffness.

References:
    Todorov, Erez, Tassa (2012). MuJoCo: A physics engine for model-based control.
    IROS. ``mj_inverse``: https://mujoco.readthedocs.io/en/stable/computation.
"""

from __future__ import annotations

import contextlib
import functools
import io
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import mujoco
import numpy as np

with contextlib.redirect_stdout(io.StringIO()):  # MJX prints "Failed to import warp" (harmless)
    from mujoco import mjx

from jaxbal._src.momentum import shaking_wrench
from jaxbal._src.motion import state_valid
from jaxbal._src.mujoco.mjcf import BASE_MASS, mujoco_inertials, to_mjcf
from jaxbal._src.mujoco.tree import Tree, tree_state
from jaxbal._src.robot import Robot
from jaxbal._src.trajectory import sample
from jaxbal._src.types import Coordinates, Vec3
from jaxbal._src.validation import check_shape, raise_if_invalid


@functools.lru_cache(maxsize=64)
def _compile(xml: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(xml)


@functools.partial(jax.jit, static_argnums=0)
def _batched_state(tree: Tree, q, qd, qdd):
    return jax.vmap(lambda a, b, c: tree_state(tree, a, b, c))(q, qd, qdd)


class MujocoRobot(NamedTuple):
    """A jaxbal robot compiled for MuJoCo C.

    Attributes:
        model: the compiled ``mujoco.MjModel`` (base dofs first).
        tree: the :class:`~jaxbal.mjcf.Tree` it was built from.
        gravity: ``(3,)`` gravity of the model [m/s²].
        xml: the MJCF text.
    """

    model: mujoco.MjModel
    tree: Tree
    gravity: np.ndarray
    xml: str

    def qpos(self, q) -> np.ndarray:
        """Full MuJoCo ``qpos`` (base dofs zero) for jaxbal coordinates ``q``."""
        return self.state(q, jnp.zeros_like(q), jnp.zeros_like(q))[0]

    def state(self, q, qd, qdd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Full MuJoCo ``(qpos, qvel, qacc)`` for jaxbal ``(q, q̇, q̈)``, each ``(nq,)``
        / ``(nv,)``, or ``(T, nq)`` / ``(T, nv)`` for batched ``(T, dof)`` input."""
        q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))
        if q.ndim == 2:
            states = _batched_state(self.tree, q, qd, qdd)
        else:
            states = tree_state(self.tree, q, qd, qdd)
        return tuple(
            np.concatenate([np.zeros(s.shape[:-1] + (6,)), np.asarray(s)], axis=-1) for s in states
        )

    def base_reaction(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """``(force, moment)`` on the base from ``data.qfrc_inverse`` (after ``mj_inverse``)."""
        force = -data.qfrc_inverse[0:3] - BASE_MASS * self.gravity
        return force, -data.qfrc_inverse[3:6].copy()


def mujoco_model(robot: Robot, gravity=None, tree: Tree | None = None) -> MujocoRobot:
    """Compile ``robot`` for MuJoCo C (cached on the MJCF text).

    Args:
        robot: a concrete robot (not traced).
        gravity: ``(3,)`` [m/s²], default zero.
        tree: default ``robot.mujoco_tree()``.

    The ``MjModel`` is cached and shared between calls with the same MJCF: copy it
    (``copy.copy(model)``) before changing its options.
    """
    tree = robot.mujoco_tree() if tree is None else tree
    gravity = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=float)
    xml = to_mjcf(robot, tree, gravity=gravity)
    return MujocoRobot(model=_compile(xml), tree=tree, gravity=gravity, xml=xml)


def mujoco_inverse(robot: Robot, q, qd, qdd, gravity=None, tree=None) -> np.ndarray:
    """``qfrc_inverse`` of MuJoCo C for one state, shape ``(nv,)`` (base dofs first)."""
    compiled = mujoco_model(robot, gravity, tree)
    data = mujoco.MjData(compiled.model)
    data.qpos[:], data.qvel[:], data.qacc[:] = compiled.state(q, qd, qdd)
    mujoco.mj_inverse(compiled.model, data)
    return data.qfrc_inverse.copy()


def mujoco_base_reaction(
    robot: Robot, q, qd, qdd, gravity=None, tree: Tree | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Force [N] and moment [N·m] the robot exerts on its base, from MuJoCo C.

    Same convention as :func:`jaxbal.shaking_wrench` (about the base origin, base
    frame, dynamic part only unless ``gravity`` is given).

    Args:
        robot: a concrete robot.
        q, qd, qdd: ``(dof,)`` jaxbal coordinates and derivatives, or ``(T, dof)``.
        gravity: ``(3,)`` [m/s²] or ``None``.
        tree: optional :class:`~jaxbal.mjcf.Tree` (default: registered, else prescribed).

    Returns:
        ``(force, moment)``, each ``(3,)`` (or ``(T, 3)`` for batched input), numpy.
    """
    compiled = mujoco_model(robot, gravity, tree)
    q, qd, qdd = (np.asarray(a, dtype=float) for a in (q, qd, qdd))
    batched = q.ndim == 2
    check_shape("q", q, (None, robot.dof) if batched else (robot.dof,))
    for name, value in (("qd", qd), ("qdd", qdd)):
        check_shape(name, value, q.shape)
    data = mujoco.MjData(compiled.model)
    forces, moments = [], []
    states = compiled.state(*(np.atleast_2d(a) for a in (q, qd, qdd)))
    for qpos, qvel, qacc in zip(*states, strict=True):
        data.qpos[:], data.qvel[:], data.qacc[:] = qpos, qvel, qacc
        mujoco.mj_inverse(compiled.model, data)
        force, moment = compiled.base_reaction(data)
        forces.append(force)
        moments.append(moment)
    forces, moments = np.array(forces), np.array(moments)
    return (forces, moments) if batched else (forces[0], moments[0])


# --- MJX --------------------------------------------------------------------------------


class MjxRobot(eqx.Module):
    """A robot compiled for MJX, whose mass properties can be swapped in (traced).

    Attributes:
        model: the ``mjx.Model`` (JAX implementation) of the nominal robot.
        data: an ``mjx.Data`` template.
        tree: the :class:`~jaxbal.mjcf.Tree` (static).
        body_ids: MuJoCo body id of each jaxbal body, in ``mass_properties`` order.
        axes: ``(n, 3, 3)`` principal axes of the nominal inertias (MuJoCo's
            ``body_iquat``), kept fixed when the inertias change.
        padding: ``(n, 3)`` principal-moment padding (see
            :func:`jaxbal.mjcf.mujoco_inertials`), kept fixed.
        mass_floor: ``(n,)`` mass added to massless moving bodies [kg], kept fixed.
        subtree: ``(nbody, nbody)`` 0/1 matrix, ``subtree[a, b] = 1`` if body b is in
            the subtree of a (for ``body_subtreemass``).
        gravity: ``(3,)`` [m/s²].
    """

    model: mjx.Model
    data: mjx.Data
    tree: Tree = eqx.field(static=True)
    body_ids: tuple[int, ...] = eqx.field(static=True)
    axes: jax.Array
    padding: jax.Array
    mass_floor: jax.Array
    subtree: jax.Array
    gravity: jax.Array


def mjx_model(robot: Robot, gravity=None, tree: Tree | None = None) -> MjxRobot:
    """Compile a concrete ``robot`` for MJX (see :func:`mujoco_model`)."""
    compiled = mujoco_model(robot, gravity, tree)
    model = compiled.model
    bodies = robot.mass_properties()
    body_ids = tuple(model.body(name).id for name in bodies.names)
    inertials = mujoco_inertials(robot, compiled.tree)
    subtree = np.eye(model.nbody)
    for b in range(model.nbody - 1, 0, -1):
        subtree[model.body_parentid[b]] += subtree[b]
    mjx_m = mjx.put_model(model, impl="jax")
    return MjxRobot(
        model=mjx_m,
        data=mjx.make_data(mjx_m),
        tree=compiled.tree,
        body_ids=body_ids,
        axes=jnp.asarray(inertials.axes),
        padding=jnp.asarray(inertials.padding),
        mass_floor=jnp.asarray(inertials.mass_floor),
        subtree=jnp.asarray(subtree),
        gravity=jnp.asarray(compiled.gravity),
    )


def with_mass_properties(compiled: MjxRobot, robot: Robot) -> mjx.Model:
    """The ``mjx.Model`` with ``robot``'s (possibly traced) masses, COMs and inertias.

    The robot must have the same bodies as the one compiled. Inertias are expressed
    in the compiled principal axes (exact while those axes do not change, e.g. when
    masses, counter-masses or the axial inertias of planar links vary).
    """
    bodies = robot.mass_properties()
    ids = jnp.asarray(compiled.body_ids)
    principal = jnp.einsum("nji,njk,nki->ni", compiled.axes, bodies.inertia, compiled.axes)
    model = compiled.model
    mass = model.body_mass.at[ids].set(bodies.mass + compiled.mass_floor)
    return model.replace(
        body_mass=mass,
        body_ipos=model.body_ipos.at[ids].set(bodies.com),
        body_inertia=model.body_inertia.at[ids].set(principal + compiled.padding),
        body_subtreemass=compiled.subtree @ mass,
    )


def mjx_base_reaction(
    compiled: MjxRobot, robot: Robot, q: Coordinates, qd: Coordinates, qdd: Coordinates
) -> tuple[Vec3, Vec3]:
    """Force [N] and moment [N·m] on the base from ``mjx.inverse`` (one sample).

    Differentiable with respect to ``robot``'s mass properties and the state; batch
    over time or designs with ``jax.vmap``. Gravity is the compiled model's.

    Args:
        compiled: from :func:`mjx_model` (built once from a concrete robot).
        robot: the robot whose mass properties are used (may be traced).
        q, qd, qdd: ``(dof,)`` jaxbal coordinates and derivatives.
    """
    qpos, qvel, qacc = tree_state(compiled.tree, q, qd, qdd)
    base = jnp.zeros(6)
    data = compiled.data.replace(
        qpos=jnp.concatenate([base, qpos]),
        qvel=jnp.concatenate([base, qvel]),
        qacc=jnp.concatenate([base, qacc]),
    )
    data = mjx.inverse(with_mass_properties(compiled, robot), data)
    force = -data.qfrc_inverse[0:3] - BASE_MASS * compiled.gravity
    return force, -data.qfrc_inverse[3:6]


#: ``mjx_base_reaction`` over ``(T, dof)`` states, jitted once per robot structure.
_mjx_along = jax.jit(jax.vmap(mjx_base_reaction, in_axes=(None, None, 0, 0, 0)))


# --- confirmation -----------------------------------------------------------------------


class Confirmation(NamedTuple):
    """How closely jaxbal's shaking wrench and MuJoCo's base reaction agree.

    Attributes:
        force_relative, moment_relative: max over samples of the difference divided by
            the peak reference magnitude (the peak gross inertial force/moment
            ``Σ m_i |a_i|``, ``Σ |dL_i/dt|`` when larger, so a balanced robot's
            round-off is not divided by ~0).
        force_error, moment_error: max absolute differences [N], [N·m].
        relative: ``max(force_relative, moment_relative)``.
        engine: ``"mujoco"`` (C) or ``"mjx"``.
        independent: False when the prescribed fallback tree was used.
    """

    force_relative: float
    moment_relative: float
    force_error: float
    moment_error: float
    engine: str
    independent: bool

    @property
    def relative(self) -> float:
        return max(self.force_relative, self.moment_relative)


@jax.jit
def _reference_and_scales(robot: Robot, q, qd, qdd, g):
    """jaxbal's shaking wrench ``(T, 3)`` ×2, the gross scales (see :func:`confirm`) and
    the validity of every state (finite, loop closures satisfied)."""
    force, moment = jax.vmap(lambda a, b, c: shaking_wrench(robot, a, b, c, gravity=g))(q, qd, qdd)
    valid = jax.vmap(lambda a, b, c: state_valid(robot, a, b, c))(q, qd, qdd)
    return force, moment, *_gross_scales(robot, q, qd, qdd, g), valid


@eqx.filter_jit
def _sample_path(joint_path, times):
    return sample(joint_path, times, 2)[:3]


def _gross_scales(robot: Robot, q, qd, qdd, g):
    """Peak ``Σ_i |m_i a_i - m_i g|`` and ``Σ_i |dL_i/dt - c_i × m_i g|`` [N], [N·m]."""
    bodies = robot.mass_properties()

    def per_body(q_, qd_):
        def poses(x):
            origins, rotations = robot.body_frames(x)
            return origins + jnp.einsum("nij,nj->ni", rotations, bodies.com), rotations

        (c, r), (v, rdot) = jax.jvp(poses, (q_,), (qd_,))
        skew = jnp.einsum("nij,nkj->nik", rdot, r)
        omega = jnp.stack([skew[:, 2, 1], skew[:, 0, 2], skew[:, 1, 0]], -1)
        inertia = jnp.einsum("nij,njk,nlk->nil", r, bodies.inertia, r)
        p = bodies.mass[:, None] * v
        return p, jnp.cross(c, p) + jnp.einsum("nij,nj->ni", inertia, omega), c

    def rates(q_, qd_, qdd_):
        (_, _, c), (dp, dl, _) = jax.jvp(per_body, (q_, qd_), (qd_, qdd_))
        weight = bodies.mass[:, None] * g
        force = jnp.sum(jnp.linalg.norm(dp - weight, axis=-1))
        moment = jnp.sum(jnp.linalg.norm(dl - jnp.cross(c, weight), axis=-1))
        return force, moment

    force, moment = jax.vmap(rates)(q, qd, qdd)
    return jnp.max(force), jnp.max(moment)


def confirm(
    robot: Robot, q, qd, qdd, gravity=None, engine: str = "mujoco", tree: Tree | None = None
) -> Confirmation:
    """Compare :func:`jaxbal.shaking_wrench` with MuJoCo's base reaction.

    Args:
        robot: a concrete robot.
        q, qd, qdd: ``(T, dof)`` states along a trajectory (or one ``(dof,)`` state).
        gravity: ``(3,)`` [m/s²] or ``None``.
        engine: ``"mujoco"`` (C ``mj_inverse``) or ``"mjx"`` (``mjx.inverse``, jitted).
        tree: optional tree (default: registered, else the prescribed fallback).

    Returns:
        A :class:`Confirmation` (max relative and absolute differences).
    """
    q, qd, qdd = (jnp.atleast_2d(jnp.asarray(a, dtype=float)) for a in (q, qd, qdd))
    g = jnp.zeros(3) if gravity is None else jnp.asarray(gravity, dtype=float)
    ref_force, ref_moment, gross_force, gross_moment, valid = _reference_and_scales(
        robot, q, qd, qdd, g
    )
    raise_if_invalid(
        valid,
        f"confirm: states violate the loop closures of {type(robot).__name__} (or are not "
        "finite); first bad q",
        q,
    )
    if engine == "mujoco":
        force, moment = mujoco_base_reaction(robot, q, qd, qdd, gravity=gravity, tree=tree)
        independent = (robot.mujoco_tree() if tree is None else tree).independent
    elif engine == "mjx":
        compiled = mjx_model(robot, gravity, tree)
        force, moment = _mjx_along(compiled, robot, q, qd, qdd)
        independent = compiled.tree.independent
    else:
        raise ValueError(f"engine must be 'mujoco' or 'mjx', got {engine!r}")
    force_error = float(np.max(np.abs(np.asarray(force) - np.asarray(ref_force))))
    moment_error = float(np.max(np.abs(np.asarray(moment) - np.asarray(ref_moment))))
    force_scale = max(float(jnp.max(jnp.abs(ref_force))), float(gross_force), 1e-300)
    moment_scale = max(float(jnp.max(jnp.abs(ref_moment))), float(gross_moment), 1e-300)
    return Confirmation(
        force_relative=force_error / force_scale,
        moment_relative=moment_error / moment_scale,
        force_error=force_error,
        moment_error=moment_error,
        engine=engine,
        independent=independent,
    )


def confirm_path(
    robot: Robot,
    joint_path,
    times,
    gravity=None,
    engine: str = "mujoco",
    tree: Tree | None = None,
) -> Confirmation:
    """:func:`confirm` along a planned joint trajectory ``t -> q`` at ``times`` [s].

    ``q, q̇, q̈`` are sampled exactly (nested ``jvp``, jitted) as in
    :func:`jaxbal.sample`; use this for the MJX column of a shaking-force table.
    """
    q, qd, qdd = _sample_path(joint_path, jnp.asarray(times, dtype=float))
    return confirm(robot, q, qd, qdd, gravity=gravity, engine=engine, tree=tree)
