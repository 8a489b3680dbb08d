"""Independent confirmation of jaxbal's shaking wrench by MuJoCo C or MJX.

:func:`confirm` compares :func:`jaxbal.shaking_wrench` with the base reaction that
MuJoCo computes from the robot's own kinematic tree
(:meth:`~jaxbal.Robot.mujoco_tree`), relative to the gross scale of the inertial forces
(so that a balanced robot, whose shaking force is a near-total cancellation, is judged
on the forces that cancel). States that violate a closed chain's loop closures are
refused, not compared. With MuJoCo C and a tree that names ``solved`` joints (the
DUAL-V, the Orthoglide), MuJoCo closes the loops itself from the prescribed joints
(:mod:`jaxbal._src.mujoco.closure`), and :class:`Confirmation` also reports how far its
joint positions are from jaxbal's.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import vee
from jaxbal._src.momentum import shaking_wrench
from jaxbal._src.motion import states_valid
from jaxbal._src.mujoco.inverse import base_reaction_and_closure, mjx_base_reaction, mjx_model
from jaxbal._src.mujoco.tree import Tree
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_robot, checked_finite
from jaxbal._src.trajectory import sample
from jaxbal._src.validation import raise_if_invalid, runtime_checks

#: Largest gap [rad or m] between MuJoCo's own loop closure and the given ``q``.
CLOSURE_GAP = 1e-6

_mjx_along = jax.jit(jax.vmap(mjx_base_reaction, in_axes=(None, None, 0, 0, 0)))


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
        closure_difference: with MuJoCo C and a tree with ``solved`` joints, the
            largest difference between the passive joint positions MuJoCo found by
            closing the loops itself and jaxbal's [rad or m]; 0 otherwise.
        closed_by_mujoco: True when MuJoCo C closed the loops itself (``tree.solved``).
    """

    force_relative: float
    moment_relative: float
    force_error: float
    moment_error: float
    engine: str
    independent: bool
    closure_difference: float = 0.0
    closed_by_mujoco: bool = False

    @property
    def relative(self) -> float:
        return max(self.force_relative, self.moment_relative)


@jax.jit
def _reference_and_scales(robot: Robot, q, qd, qdd, g):
    """jaxbal's shaking wrench ``(T, 3)`` ×2, the gross scales (see :func:`confirm`) and
    the validity of every state (finite, loop closures satisfied). Traced without the
    runtime checks (:func:`confirm` checks the robot, the states and the results on the
    host): a program without host callbacks, which the persistent compilation cache
    keeps for the next process."""
    force, moment = jax.vmap(lambda a, b, c: shaking_wrench(robot, a, b, c, gravity=g))(q, qd, qdd)
    valid = states_valid(robot, q, qd, qdd)
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
        omega = vee(jnp.einsum("nij,nkj->nik", rdot, r))
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

    Raises:
        ValueError: states off the loop closures; with MuJoCo C, joints that MuJoCo's
            own loop closure places more than :data:`CLOSURE_GAP` away from ``q``.
    """
    q, qd, qdd = (jnp.atleast_2d(jnp.asarray(a, dtype=float)) for a in (q, qd, qdd))
    g = jnp.zeros(3) if gravity is None else jnp.asarray(gravity, dtype=float)
    check_robot(robot)
    with runtime_checks(False):
        ref_force, ref_moment, gross_force, gross_moment, valid = _reference_and_scales(
            robot, q, qd, qdd, g
        )
    raise_if_invalid(
        valid,
        f"confirm: states violate the loop closures of {type(robot).__name__} (or are not "
        "finite); first bad q",
        q,
    )
    checked_finite("shaking wrench", robot, (ref_force, ref_moment))
    closure, closed = 0.0, False
    if engine == "mujoco":
        tree = robot.mujoco_tree() if tree is None else tree
        force, moment, closure = base_reaction_and_closure(robot, q, qd, qdd, gravity, tree)
        independent, closed = tree.independent, bool(tree.solved)
        if closure > CLOSURE_GAP:
            raise ValueError(
                f"confirm: MuJoCo closed the loops of {type(robot).__name__} {closure:.3g} rad "
                "or m away from the given q: another assembly mode than the MuJoCo model's "
                "(its tree's guess), e.g. a non-default branch; compare such states with "
                "engine='mjx'"
            )
    elif engine == "mjx":
        compiled = mjx_model(robot, gravity, tree)
        force, moment = _mjx_along(compiled, robot, q, qd, qdd)
        independent = compiled.tree.independent
    else:
        raise ValueError(f"engine must be 'mujoco' or 'mjx', got {engine!r}")
    force_error = float(np.max(np.abs(np.asarray(force) - np.asarray(ref_force))))
    moment_error = float(np.max(np.abs(np.asarray(moment) - np.asarray(ref_moment))))
    force_scale = max(float(np.max(np.abs(ref_force))), float(gross_force), 1e-300)
    moment_scale = max(float(np.max(np.abs(ref_moment))), float(gross_moment), 1e-300)
    numbers = (force_error, moment_error, force_scale, moment_scale)
    if not np.all(np.isfinite(numbers)):  # an overflowed scale made any error "0"
        raise ValueError(
            "confirm: the errors or their scales overflow (force, moment error; force, "
            f"moment scale: {numbers}): the states are too large to compare"
        )
    return Confirmation(
        force_relative=force_error / force_scale,
        moment_relative=moment_error / moment_scale,
        force_error=force_error,
        moment_error=moment_error,
        engine=engine,
        independent=independent,
        closure_difference=closure,
        closed_by_mujoco=closed,
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
