"""Balancing a mechanism read from MJCF: sampled moves and a counter-mass design.

The steps of ``jaxbal balance ROBOT.xml`` (and of notebook 05), each a call into the
generic tools:

1. :func:`pose_samples` / :func:`closure_samples`: the exact joint motion ``(q, q̇,
   q̈)`` of a straight-line move of the end-effector or of the independent joints
   (:meth:`~jaxbal._src.robots.mjcf_robot.MjcfRobot.pose_motion`,
   :meth:`~jaxbal._src.robots.mjcf_robot.MjcfRobot.closure_motion`), solved in time
   order, each Newton solve started from the previous instant's solution (the first
   from the robot's ``reference``), compiled once per robot structure with the checks
   as functional errors (:func:`~jaxbal.checked_jit`), so the persistent compilation
   cache keeps the program for the next process;
2. :func:`with_counter_masses`: a counter-mass on each chosen body, started as the
   mirror image of the body's own mass about its frame origin;
3. :func:`balance`: :func:`jaxbal.design.codesign` of the counter-mass positions (and,
   optionally, masses) for the RMS shaking force, the motion held fixed, with the
   peaks before and after.

References:
    Arakelian & Smith (2005), J. Mech. Design 127(2), §2 (force balancing by
    counterweights); Briot, Arakelian & Le Baron (2012), eq (1) (peak shaking force).
"""

from __future__ import annotations

import itertools
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.design import DesignSolution, codesign
from jaxbal._src.metrics import Motion, peak_force, peak_moment
from jaxbal._src.profiles import Quintic
from jaxbal._src.robots.counter_mass import add_counter_mass
from jaxbal._src.robots.mjcf_robot import MjcfRobot
from jaxbal._src.robots.mjcf_solve import pose_equations
from jaxbal._src.trajectory import StraightLine, sample, sample_times
from jaxbal._src.validation import checked_call, raise_if_invalid

__all__ = [
    "CONFIGURATION_ATOL",
    "Balance",
    "balance",
    "closure_samples",
    "configuration_samples",
    "pose_samples",
    "with_counter_masses",
]


def _continued(solve, start, inputs):
    """``solve(u, u̇, ü, guess)`` at every sample in order (``lax.scan``), each Newton
    solve starting from the previous solution (continuation: the assembly mode is
    followed along the move; one Newton loop to compile, not a batched one)."""

    def step(guess, sample_):
        q, q_d, q_dd, valid = solve(*sample_, guess)
        return jnp.where(valid, q, guess), (q, q_d, q_dd, valid)

    return jax.lax.scan(step, start, inputs)[1]


def _pose_states(robot, line, times):
    def solve(a, b, c, guess):
        return robot.pose_motion(a, b, c, guess, return_valid=True)

    return _continued(solve, robot.reference, sample(line, times, order=2))


def _closure_states(robot, line, times):
    def solve(a, b, c, guess):
        return robot.closure_motion(a, b, c, guess, return_valid=True)

    return _continued(solve, robot.reference, sample(line, times, order=2))


def _samples(states, times, what: str, hint: str = "") -> Motion:
    q, q_d, q_dd, valid = states
    message = f"{what} leaves the mechanism's reach (Newton fails){hint} at t [s]"
    raise_if_invalid(valid, message, times)
    return Motion(q, q_d, q_dd)


#: the pose equations count as singular where σ_min ≤ SINGULAR_RTOL·σ_max of their Jacobian.
SINGULAR_RTOL = 1e-9
#: at most this many ``ik_free`` choices are tried for a regular one (7-joint arm: 35).
MAX_IK_FREE_CHOICES = 2000


def _regular(jacobian: np.ndarray) -> bool:
    singular = np.linalg.svd(jacobian, compute_uv=False)
    return bool(singular[-1] > SINGULAR_RTOL * singular[0])


def _regular_ik_free(robot: MjcfRobot, jacobian: np.ndarray) -> tuple[str, ...] | None:
    """Joint names for ``ik_free`` (as many as the robot's) under which the pose
    equations are regular at the reference, ``None`` if none: the rows of the closures
    and of the site's coordinates, ``jacobian`` ``(r, dof)``, with a unit row per free
    joint, tried from the last joints first (the default's order)."""
    count = len(robot.ik_free)
    kept = jacobian[: jacobian.shape[0] - count]
    candidates = [
        i for i in reversed(robot.independent_coordinates) if i in robot.joint_qpos
    ]  # hinge and slide joints only (one coordinate each)
    for k, free in enumerate(itertools.combinations(candidates, count)):
        if k >= MAX_IK_FREE_CHOICES:
            break
        rows = np.zeros((count, jacobian.shape[1]))
        rows[np.arange(count), list(free)] = 1.0
        if _regular(np.vstack([kept, rows])):
            return tuple(robot.joint_names[robot.joint_qpos.index(i)] for i in sorted(free))
    return None


def _singular_start(robot: MjcfRobot) -> str:
    """A hint when the Jacobian of the pose equations (loop closures, then the pose) is
    singular at the robot's ``reference``, where every solve of a move starts: e.g. a
    7-joint arm whose pose is its site's position and its last four joints, drawn with
    its first and third axes aligned. Names a regular ``ik_free`` choice if one exists."""
    jacobian = np.asarray(jax.jacfwd(lambda q: pose_equations(robot, q))(robot.reference))
    if _regular(jacobian):
        return ""
    remedy = "complete the pose with other joints (ik_free=, --ik-free)"
    choice = _regular_ik_free(robot, jacobian) if robot.ik_free else None
    if choice is not None:
        remedy = (
            f"complete the pose with other joints, e.g. ik_free={choice!r} "
            f"(--ik-free {','.join(choice)}), regular there"
        )
    return (
        f" (the start, the reference q = {np.asarray(robot.reference).round(6).tolist()}, "
        f"is a singular configuration of the pose {', '.join(robot.pose_labels())}: start "
        f"from another keyframe (keyframe=, --keyframe) or {remedy})"
    )


def pose_samples(robot: MjcfRobot, start, end, duration, count: int = 101, profile=None):
    """Exact joint motion of a straight end-effector move with a quintic profile.

    Args:
        robot: an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot` with a site.
        start, end: ``(m,)`` end-effector poses [m, rad] (as ``robot.end_effector``).
        duration: move time [s].
        count: samples on ``[0, duration]``, ends included.
        profile: motion profile (default :class:`~jaxbal.profiles.Quintic`).

    Returns:
        A :class:`~jaxbal.design.Motion` ``(count, dof)``.

    Raises:
        ValueError: a pose of the move that Newton cannot reach (naming the instants).
    """
    line = StraightLine(start, end, Quintic() if profile is None else profile, duration)
    times = sample_times(duration, count)
    states = checked_call(_pose_states, robot, line, times, once=True)
    hint = "" if bool(np.all(np.asarray(states[3]))) else _unreached(robot, start, end)
    return _samples(states, times, "end-effector line", hint)


def _unreached(robot: MjcfRobot, start, end) -> str:
    """The hint of a move that fails: its start or end pose not reached on its own (out of
    reach; the singular-start advice alone had pointed the wrong way), and the singular
    start's advice when that applies."""
    ends = {"start": start, "end": end}
    missed = [
        k for k, p in ends.items() if not bool(robot.inverse_kinematics(p, return_valid=True)[1])
    ]
    poses = "; ".join(f"{k} pose {np.asarray(ends[k]).tolist()}" for k in missed)
    return (
        f" (not reached on its own, out of reach?: {poses})" if missed else ""
    ) + _singular_start(robot)


#: a configuration's loop closures count as met within this [m]; a move ends in the
#: configuration asked for within this [rad, m] (else another assembly mode was followed).
CONFIGURATION_ATOL = 1e-9


def _configuration(robot: MjcfRobot, q, what: str) -> jnp.ndarray:
    """All coordinates ``(dof,)`` from ``q``: every coordinate, or (closed chain) the
    independent ones, closed by Newton from the robot's reference (the caller sets it)."""
    q = np.asarray(q, dtype=float)
    independent = len(robot.independent_coordinates)
    if q.ndim != 1 or q.size not in (robot.dof, independent) or not np.all(np.isfinite(q)):
        names = [
            robot.joint_names[robot.joint_qpos.index(i)] for i in robot.independent_coordinates
        ]
        raise ValueError(
            f"{what} must be {robot.dof} finite coordinates (or the {independent} independent "
            f"ones, {names}), got {q.tolist()}"
        )
    if q.size != robot.dof:
        q = np.asarray(robot.closure(jnp.asarray(q)))
    residual = float(np.max(np.abs(np.asarray(robot.constraint(jnp.asarray(q)))), initial=0.0))
    if residual > CONFIGURATION_ATOL:
        raise ValueError(f"{what} does not close the loops: |Φ| = {residual:.3g} m at q = {q}")
    return jnp.asarray(q)


def configuration_samples(
    robot: MjcfRobot, start, end, duration, count: int = 101, profile=None
) -> Motion:
    """Exact joint motion of the straight end-effector move between two configurations.

    The poses are those of ``start`` and ``end`` (:meth:`~MjcfRobot.end_effector`,
    ``ik_free`` joints included), the Newton solves start from ``start`` (so no
    reference or keyframe is needed), and the move must arrive in ``end`` itself.

    Args:
        robot: an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot` with a site.
        start, end: ``(dof,)`` configurations, or for a closed chain the independent
            coordinates [rad, m] (``start`` closed from the robot's reference, ``end``
            from ``start``'s configuration: the assembly mode the move starts in).
        duration, count, profile: as :func:`pose_samples`.

    Raises:
        ValueError: a configuration of the wrong length, non-finite or off its loop
            closures; a move that leaves the reach; or one that arrives in another
            assembly mode than ``end`` (the difference named).
    """
    first = _configuration(robot, start, "start")
    # a closed chain's end closed by Newton from the start, not the model's reference:
    # a slider-crank's crank from 120 to 175 degrees landed in the other assembly mode
    robot = robot.with_reference(first)
    last = _configuration(robot, end, "end")
    motion = pose_samples(
        robot, robot.end_effector(first), robot.end_effector(last), duration, count, profile
    )
    gap = np.abs(np.asarray(motion.q[-1]) - np.asarray(last))
    if float(gap.max(initial=0.0)) > CONFIGURATION_ATOL:
        raise ValueError(
            f"the straight move from start's pose to end's arrives at q = "
            f"{np.asarray(motion.q[-1]).round(6).tolist()}, not in end's assembly mode "
            f"({np.asarray(last).round(6).tolist()}; largest difference {gap.max():.3g}): "
            "choose end in the mode start leads to, or other ik_free joints"
        )
    return motion


def closure_samples(robot: MjcfRobot, start, end, duration, count: int = 101, profile=None):
    """As :func:`pose_samples`, for a straight move of the independent joints
    ``(m,)`` [rad, m] (loop closures solved at every instant)."""
    line = StraightLine(start, end, Quintic() if profile is None else profile, duration)
    times = sample_times(duration, count)
    states = checked_call(_closure_states, robot, line, times, once=True)
    return _samples(states, times, "joint line")


def with_counter_masses(robot: MjcfRobot, bodies=None, scale: float = 1.0) -> MjcfRobot:
    """``robot`` with one point counter-mass per body of ``bodies`` (default: every
    moving body with mass but the payload body), of ``scale`` times the body's mass, at
    the mirror image of the body's COM about its frame origin (the classical
    counterweight's start)."""
    names = robot.mass_names()[: len(robot.moving_bodies)]
    mass = np.asarray(robot.mass)
    if bodies is None:
        bodies = [
            name
            for i, (name, m) in enumerate(zip(names, mass, strict=True))
            if m > 0 and i != robot.payload_body
        ]
    for body in bodies:
        i = robot.body_index(body)
        position = -np.asarray(robot.com[i]) if i < len(names) else np.zeros(3)
        robot = add_counter_mass(robot, body, position, scale * float(mass[i]))
    return robot


class Balance(NamedTuple):
    """Result of :func:`balance`.

    Attributes:
        robot: the balanced robot (counter-masses at their optimum).
        solution: the :class:`~jaxbal.design.DesignSolution` of the co-design.
        peak_force: ``(before, after)`` peak shaking force [N].
        peak_moment: ``(before, after)`` peak shaking moment about the base origin [N·m].
        unbalanced_peak_force, unbalanced_peak_moment: without counter-masses [N], [N·m].
    """

    robot: MjcfRobot
    solution: DesignSolution
    peak_force: tuple[float, float]
    peak_moment: tuple[float, float]
    unbalanced_peak_force: float
    unbalanced_peak_moment: float


def _peaks(robot, motion):
    return peak_force(robot, motion), peak_moment(robot, motion)


def _clipped(robot: MjcfRobot, free, lower, upper) -> MjcfRobot:
    """``robot`` with its free design variables moved into the bounds (``lower`` over
    the robot's own lower bounds, ``upper`` if given): the start of :func:`balance`."""
    design, bounds = robot.design(), {**robot.design_lower_bounds(), **(lower or {})}
    moved = {}
    for name in free:
        if name in design:
            high = (upper or {}).get(name, np.inf)
            moved[name] = np.clip(np.asarray(design[name]), bounds.get(name, -np.inf), high)
    return robot.with_design(moved)


def balance(
    robot: MjcfRobot,
    motion: Motion,
    *,
    free=("counter_position",),
    lower=None,
    upper=None,
    objective="rms_force",
    max_steps: int = 200,
    gtol: float = 1e-14,
) -> Balance:
    """Co-design the counter-masses of ``robot`` for the RMS shaking force of ``motion``.

    Args:
        robot: a robot with counter-masses (e.g. from :func:`with_counter_masses`).
        motion: the joint motion, held fixed (counter-masses do not change it).
        free: design variables to optimise (default: the positions only, masses kept;
            the force is then linear in the positions, so a force-balanceable
            mechanism converges to a residual near round-off).
        lower, upper: bounds by name, as in :func:`~jaxbal.design.codesign` (default:
            masses ≥ 0, positions ≥ −:meth:`~MjcfRobot.position_bound` per
            coordinate); ``solution.at_bound`` tells which the optimum reached. The
            robot's counter-masses are only the start: one outside these bounds is
            moved onto them.
        objective: as :func:`~jaxbal.design.codesign`'s (default the RMS shaking
            force); e.g. ``{"rms_force": 1.0, "rms_moment": w}`` trades the force for
            the moment, each relative to its value at the start.
        max_steps, gtol: L-BFGS iteration cap and gradient tolerance.

    Returns:
        A :class:`Balance`.
    """
    if not robot.counter_names:
        raise ValueError("the robot has no counter-masses: use with_counter_masses first")
    bare = robot.with_design({"counter_mass": jnp.zeros_like(robot.counter_mass)})
    # peaks: evaluated three times per balance, a compile-bound program (``once``)
    unbalanced = [float(v) for v in checked_call(_peaks, bare, motion, once=True)]
    before = [float(v) for v in checked_call(_peaks, robot, motion, once=True)]
    robot = _clipped(robot, free, lower, upper)
    solution = codesign(
        robot, motion, objective, free=free, lower=lower, upper=upper,
        max_steps=max_steps, gtol=gtol,
    )  # fmt: skip
    after = [float(v) for v in checked_call(_peaks, solution.robot, motion, once=True)]
    return Balance(
        robot=solution.robot,
        solution=solution,
        peak_force=(before[0], after[0]),
        peak_moment=(before[1], after[1]),
        unbalanced_peak_force=unbalanced[0],
        unbalanced_peak_moment=unbalanced[1],
    )
