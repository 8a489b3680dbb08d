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
the state satisfies them (jaxbal's IK for MJX; MuJoCo C's own loop closure for the
joints a tree lists as ``solved``, see :mod:`jaxbal._src.mujoco.closure`) their
Jacobian has no base component, so the
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
from typing import TYPE_CHECKING, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import mujoco
import numpy as np

if TYPE_CHECKING:
    from mujoco import mjx

from jaxbal._src.mujoco.closure import close_loops, closure_index, position_gap
from jaxbal._src.mujoco.mjcf import BASE_MASS, host_bodies, mujoco_inertials, to_mjcf
from jaxbal._src.mujoco.tree import Tree, tree_state
from jaxbal._src.robot import Robot
from jaxbal._src.types import Coordinates, Vec3
from jaxbal._src.validation import check_shape


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
        / ``(nv,)``, or ``(T, nq)`` / ``(T, nv)`` for batched ``(T, dof)`` input.

        The joints of ``tree.solved`` are MuJoCo's own loop-closure solution
        (:func:`~jaxbal._src.mujoco.closure.close_loops`), the others the tree's
        ``coordinates``."""
        return self.closed_state(q, qd, qdd)[:3]

    def closed_state(self, q, qd, qdd):
        """:meth:`state` and the largest difference between MuJoCo's solved hinge/slide
        positions and the tree's ``coordinates`` (jaxbal's) [rad or m]; 0 without
        ``tree.solved``."""
        q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))
        if q.ndim == 2:
            states = _batched_state(self.tree, q, qd, qdd)
        else:
            states = tree_state(self.tree, q, qd, qdd)
        states = tuple(
            np.concatenate([np.zeros(s.shape[:-1] + (6,)), np.asarray(s)], axis=-1) for s in states
        )
        if not self.tree.solved:
            return (*states, 0.0)
        index = closure_index(self.model, self.tree.solved)
        data = mujoco.MjData(self.model)
        batch = [np.atleast_2d(s) for s in states]
        closed, difference = [], 0.0
        for x, qpos, qvel, qacc in zip(np.atleast_2d(np.asarray(q)), *batch, strict=True):
            start = qpos.copy()
            start[index.qpos] = np.asarray(self.tree.guess(x), dtype=float)[index.qpos - 6]
            closed.append(close_loops(self.model, data, index, start, qvel, qacc))
            difference = max(difference, position_gap(index, closed[-1][0], qpos))
        closed = tuple(np.array(s) for s in zip(*closed, strict=True))
        if q.ndim == 1:
            closed = tuple(s[0] for s in closed)
        return (*closed, difference)

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
    forces, moments, _ = base_reaction_and_closure(robot, q, qd, qdd, gravity, tree)
    return forces, moments


def base_reaction_and_closure(robot: Robot, q, qd, qdd, gravity=None, tree: Tree | None = None):
    """:func:`mujoco_base_reaction` and the largest difference between the joints that
    MuJoCo solved (``tree.solved``) and jaxbal's (see :meth:`MujocoRobot.closed_state`)."""
    compiled = mujoco_model(robot, gravity, tree)
    q, qd, qdd = (np.asarray(a, dtype=float) for a in (q, qd, qdd))
    batched = q.ndim == 2
    check_shape("q", q, (None, robot.dof) if batched else (robot.dof,))
    for name, value in (("qd", qd), ("qdd", qdd)):
        check_shape(name, value, q.shape)
    data = mujoco.MjData(compiled.model)
    forces, moments = [], []
    *states, difference = compiled.closed_state(*(np.atleast_2d(a) for a in (q, qd, qdd)))
    for qpos, qvel, qacc in zip(*states, strict=True):
        data.qpos[:], data.qvel[:], data.qacc[:] = qpos, qvel, qacc
        mujoco.mj_inverse(compiled.model, data)
        force, moment = compiled.base_reaction(data)
        forces.append(force)
        moments.append(moment)
    forces, moments = np.array(forces), np.array(moments)
    return (forces, moments, difference) if batched else (forces[0], moments[0], difference)


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


@functools.cache
def _mjx():
    """``mujoco.mjx``, imported on first use: it takes ~0.5 s to import, which a check
    with MuJoCo C (the default engine) does not need."""
    with contextlib.redirect_stdout(io.StringIO()):  # prints "Failed to import warp"
        from mujoco import mjx
    return mjx


def mjx_model(robot: Robot, gravity=None, tree: Tree | None = None) -> MjxRobot:
    """Compile a concrete ``robot`` for MJX (see :func:`mujoco_model`)."""
    compiled = mujoco_model(robot, gravity, tree)
    model = compiled.model
    bodies = host_bodies(robot)
    body_ids = tuple(model.body(name).id for name in bodies.names)
    inertials = mujoco_inertials(robot, compiled.tree)
    subtree = np.eye(model.nbody)
    for b in range(model.nbody - 1, 0, -1):
        subtree[model.body_parentid[b]] += subtree[b]
    mjx = _mjx()
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
    data = _mjx().inverse(with_mass_properties(compiled, robot), data)
    force = -data.qfrc_inverse[0:3] - BASE_MASS * compiled.gravity
    return force, -data.qfrc_inverse[3:6]


#: ``mjx_base_reaction`` over ``(T, dof)`` states, jitted once per robot structure.
