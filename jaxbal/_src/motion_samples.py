"""Sampled joint motions: :class:`Motion` ``(q, q̇, q̈)`` and :class:`JerkMotion` (with
``q⃛``), built from trajectories by :func:`motion_samples` (exact derivatives, loop
closures checked) and concatenated by :func:`as_motion`.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.callables import as_pytree
from jaxbal._src.motion import states_valid
from jaxbal._src.robot import Robot
from jaxbal._src.trajectory import sample
from jaxbal._src.types import Array, Float
from jaxbal._src.validation import checked_call, raise_if_invalid

__all__ = [
    "JerkMotion", "Motion", "ReducedMotion", "as_motion", "check_motion_shape", "motion_samples",
]  # fmt: skip


class Motion(NamedTuple):
    """A sampled joint motion: ``q``, ``q̇``, ``q̈``, each ``(t, dof)`` [rad or m, per s, per s²]."""

    q: Float[Array, "t dof"]
    qd: Float[Array, "t dof"]
    qdd: Float[Array, "t dof"]


class JerkMotion(NamedTuple):
    """A sampled joint motion with its jerk: ``q``, ``q̇``, ``q̈``, ``q⃛``, each ``(t, dof)``.

    Every metric takes it (the jerk is ignored where not needed); the torque-rate
    metric :func:`peak_torque_rate` needs it. Built by ``motion_samples(..., order=3)``
    or a motion factory with ``order=3``.
    """

    q: Float[Array, "t dof"]
    qd: Float[Array, "t dof"]
    qdd: Float[Array, "t dof"]
    qddd: Float[Array, "t dof"]


class ReducedMotion(eqx.Module):
    """A :class:`Motion` with its shaking-wrench regressor, for a loss evaluated many
    times along one motion (built by :func:`jaxbal._src.reduced_motion.reduce_motion`).

    ``force`` (``(r_f, c_f)``, or ``None``) holds the nonzero rows and columns of the
    force regressor stacked over the samples (``(3 t, 10 b)``, :func:`~jaxbal._src.
    regressor.linear_wrench`), ``force_columns`` the static indices of those columns in
    the flattened lumped parameters; ``moment`` and ``moment_columns`` likewise.
    ``inertia`` (``(10 b,)``, or ``None``) is the row of the base inertia about the
    vertical axis at ``q[0]`` over the flattened lumped parameters.
    :func:`~jaxbal.design.rms_force`, :func:`~jaxbal.design.rms_moment` and
    :func:`~jaxbal.design.added_inertia` then cost one matrix-vector product; every other
    metric reads ``q``, ``qd``, ``qdd``. It iterates as ``(q, q̇, q̈)``, like a
    :class:`Motion`.
    """

    q: Float[Array, "t dof"]
    qd: Float[Array, "t dof"]
    qdd: Float[Array, "t dof"]
    force: Array | None
    moment: Array | None
    inertia: Array | None
    force_columns: tuple[int, ...] = eqx.field(static=True)
    moment_columns: tuple[int, ...] = eqx.field(static=True)

    def __iter__(self):
        return iter((self.q, self.qd, self.qdd))

    def __len__(self) -> int:
        return 3

    def __getitem__(self, index):
        return (self.q, self.qd, self.qdd)[index]


def _sample(robot, trajectory, times, order):
    """The samples of ``trajectory`` and the validity of each state (loop closures,
    finite): one program, compiled by :func:`~jaxbal._src.validation.checked_call`, whose
    runtime checks (e.g. a trajectory's duration) are functional, so that the
    persistent compilation cache keeps it for the next process."""
    q, qd, qdd, *jerk = sample(trajectory, times, order=order)
    valid = states_valid(robot, q, qd, qdd)
    return (q, qd, qdd, *jerk), valid


def motion_samples(robot: Robot, trajectories, times, order: int = 2) -> Motion | JerkMotion:
    """Exact ``(q, q̇, q̈)`` of one or several trajectories, stacked into one :class:`Motion`.

    Args:
        robot: the robot the trajectories belong to (for the loop-closure check).
        trajectories: a callable ``t ↦ q`` (coordinates of all bodies), or a sequence
            of them.
        times: ``(t,)`` instants [s], shared by every trajectory, or a list with one
            array per trajectory.
        order: 2, or 3 for a :class:`JerkMotion` (the jerk ``q⃛`` too, for the
            torque-rate metric).

    Returns:
        A :class:`Motion` (or :class:`JerkMotion`) with ``Σ t_k`` rows, in the order of
        the trajectories.

    Raises:
        ValueError: eagerly, when a sampled state violates the robot's loop closures
            (or is not finite); the message names the offending instants.
    """
    if callable(trajectories):
        trajectories = [trajectories]
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError("motion_samples needs at least one trajectory")
    if order not in (2, 3):
        raise ValueError(f"order must be 2 (q, q̇, q̈) or 3 (with the jerk), got {order!r}")
    if isinstance(times, list | tuple) and times and np.ndim(times[0]) >= 1:
        times = [jnp.asarray(t, dtype=float) for t in times]
        if len(times) != len(trajectories):
            raise ValueError(f"got {len(times)} time arrays for {len(trajectories)} trajectories")
    else:
        times = [jnp.asarray(times, dtype=float)] * len(trajectories)
    parts = []
    for trajectory, instants in zip(trajectories, times, strict=True):
        if instants.ndim != 1:
            raise ValueError(f"times must have shape (t,), got {instants.shape}")
        # A lambda or closure as a pytree: an equivalent new one reuses the compilation.
        (q, qd, qdd, *jerk), valid = checked_call(
            _sample, robot, as_pytree(trajectory), instants, order, once=True
        )
        raise_if_invalid(
            valid,
            f"trajectory leaves the loop closures of {type(robot).__name__} (or is not "
            "finite) at t [s]",
            instants,
        )
        parts.append(JerkMotion(q, qd, qdd, *jerk) if jerk else Motion(q, qd, qdd))
    if jerk:
        return JerkMotion(*(jnp.concatenate([p[k] for p in parts]) for k in range(4)))
    return as_motion(parts)


def as_motion(motions) -> Motion:
    """One :class:`Motion` from a Motion, a ``(q, q̇, q̈)`` tuple or a sequence of them
    (concatenated along time)."""
    if isinstance(motions, Motion):
        return motions
    if isinstance(motions, JerkMotion | ReducedMotion):
        return Motion(motions.q, motions.qd, motions.qdd)
    if isinstance(motions, tuple) and len(motions) == 3 and not isinstance(motions[0], tuple):
        return Motion(*(jnp.asarray(v, dtype=float) for v in motions))
    parts = [as_motion(m) for m in motions]
    if not parts:
        raise ValueError("need at least one motion")
    return Motion(*(jnp.concatenate([p[k] for p in parts]) for k in range(3)))


def check_motion_shape(robot: Robot, motion) -> None:
    """Raise ``ValueError`` unless every part of ``motion`` (``q``, ``q̇``, ``q̈`` and a
    jerk, if any) has the shape ``(t, robot.dof)`` with ``t ≥ 1`` (static shapes: also
    under ``jit``). Before, parts of different lengths gave NumPy's concatenation error
    and a 1-D motion an ``IndexError``."""
    shapes = [tuple(np.shape(part)) for part in motion]
    names = ("q", "qd", "qdd", "qddd")[: len(shapes)]
    good = len(shapes[0]) == 2 and shapes[0][0] >= 1 and shapes[0][1] == robot.dof
    if not good or any(shape != shapes[0] for shape in shapes):
        listed = ", ".join(f"{n} {s}" for n, s in zip(names, shapes, strict=True))
        raise ValueError(f"a motion's parts must each have shape (t, {robot.dof}) with t >= 1 "
                         f"(samples, {type(robot).__name__}.dof), got {listed}")  # fmt: skip
