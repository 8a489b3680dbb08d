"""Centre-of-mass (COM) motion planning and evaluation along planned motions.

The shaking force of any robot is ``f_sh = −m_tot ẍ_S`` (Briot et al. 2012, eq 1), so
it is smallest when the total COM ``x_S`` moves on the straight line between its
start and end positions with the profile of least peak acceleration -- bang-bang for a
fixed duration (eqs 3-4), or a trapezoidal acceleration when the actuators' torque
rates are bounded (eqs 5-6). The joint motion then follows from the robot's COM
inverse kinematics; for redundant cases (3R) the free coordinates follow their own
law (eqs 19-20).

Every trajectory here is an :class:`equinox.Module` mapping time ``t`` [s] to the
robot's coordinates ``q``; feed it to :func:`jaxbal.trajectory.sample` for exact
``q, q̇, q̈, q⃛`` (or to :func:`jaxbal.joint_motion`, which also checks loop closures).
Every robot takes part through its contract: ``inverse_kinematics(pose, branch=…)``
and ``end_effector(q)``; the COM inverse kinematics is the robot's closed form where it
has one, else Newton on the pose (:func:`com_inverse_kinematics`).

References:
    Briot, Arakelian & Le Baron (2012), sections 2.1-2.3.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.actuation import actuator_torque_rate, actuator_torques
from jaxbal._src.com_components import com_components, planned_com
from jaxbal._src.com_ik import com_inverse_kinematics
from jaxbal._src.momentum import body_com_positions, shaking_wrench
from jaxbal._src.peaks import peak_norm, smooth_peak  # noqa: F401  (re-exported)
from jaxbal._src.profiles import Profile
from jaxbal._src.robot import Robot
from jaxbal._src.solution_guard import guard_solution
from jaxbal._src.trajectory import StraightLine, sample
from jaxbal._src.types import Array, Float, ScalarLike
from jaxbal._src.validation import (
    check_shape,
    checked_call,
    is_traced,
    raise_if_invalid,
)


class EndEffectorLine(eqx.Module):
    """Joint motion that moves the end-effector on a straight line (classical planning).

    ``q(t) = IK(x_E0 + s(t/T)(x_Ef − x_E0))``. For the 3R the pose includes φ, so the
    orientation follows the same profile (case 1 of Briot et al. 2012).
    """

    robot: Robot
    line: StraightLine
    branch: tuple[int, ...] | int | None = eqx.field(static=True, default=None)

    def __call__(self, t: ScalarLike):
        return self.robot.inverse_kinematics(self.line(t), branch=self.branch)


class ComLine(eqx.Module):
    """Joint motion that moves the total COM on a straight line with a given profile.

    Attributes:
        robot: the robot, whose COM inverse kinematics gives ``q(t)``.
        line: the COM path, a :class:`~jaxbal.trajectory.StraightLine` in the plane
            (``(2,)`` endpoints) or in space (``(3,)``). Where the plan has
            ``q_start``/``q_end`` (made by :func:`com_line`), only its profile and
            duration are used: its end points are recomputed from ``robot`` wherever the
            plan is evaluated (:meth:`resolved` gives them).
        free: ``None``, or a callable ``t ↦`` free coordinates (φ for the 3R).
        branch: working mode of the COM inverse kinematics (``+1`` = "+" of eq 10).
        poses: optional straight line of end-effector poses between the same
            configurations: when ``free`` is None, the pose components beyond the COM's
            follow it, and for robots solved numerically it gives Newton's start.
        q_start, q_end: optional ``(dof,)`` configurations the move joins. Given, the
            plan follows its robot: ``eqx.tree_at`` on ``plan.robot`` (a sweep, an
            optimiser) moves the COM line's end points with it (they stayed the old
            robot's: 0.08 rad off ``q_start``, peak moment 24.1 for 22.9 N·m, silently),
            and a plan no longer at ``q_start``/``q_end`` is refused where it is sampled
            at ``t = 0``/``T`` (:meth:`checked_samples`; a direct ``plan(t)`` is not).
    """

    robot: Robot
    line: StraightLine
    free: Callable | None = None
    branch: tuple[int, ...] | int | None = eqx.field(static=True, default=None)
    poses: StraightLine | None = None
    q_start: Float[Array, " dof"] | None = None
    q_end: Float[Array, " dof"] | None = None

    def resolved(self) -> ComLine:
        """The plan with its COM line (and ``poses``, on the line's profile and
        duration) between the end points of its robot at ``q_start`` and ``q_end`` (the
        plan itself where it has none). :func:`jaxbal.trajectory.sample` calls this
        hook once, outside its ``vmap`` over the instants and their nested ``jvp``."""
        if self.q_start is None or self.q_end is None:
            return self
        robot, d = self.robot, self.line.start.shape[0]
        components = com_components(robot, d)  # the plane it moves in (x-y, x-z, …)
        ends = [planned_com(robot, q, components) for q in (self.q_start, self.q_end)]
        line = StraightLine(*ends, self.line.profile, self.line.duration)
        poses = self.poses
        if poses is not None:
            ends = [robot.end_effector(q) for q in (self.q_start, self.q_end)]
            poses = StraightLine(*ends, self.line.profile, self.line.duration)
        return dataclasses.replace(self, line=line, poses=poses, q_start=None, q_end=None)

    def _solve(self, t, return_valid):
        return self.resolved()._solve_line(t, return_valid)

    def _solve_line(self, t, return_valid):
        com = self.line(t)
        free = None if self.free is None else self.free(t)
        guess = None
        if self.poses is not None:
            pose = self.poses(t)
            d = com.shape[0]
            if free is None and pose.shape[0] > d:
                free = pose[d:]  # e.g. φ of the 3R, θ5 of the DUAL-V
            if getattr(self.robot, "com_inverse_kinematics", None) is None:
                guess = pose[:d]  # Newton's start for robots solved numerically
        return com_inverse_kinematics(
            self.robot, com, free, branch=self.branch, return_valid=return_valid, guess=guess
        )

    def __call__(self, t: ScalarLike):
        return self._solve(t, False)

    def checked_samples(self, times, q):
        """``q`` ``(t, dof)`` sampled at ``times``, guarded by the join: where one of
        ``times`` is ``0`` (the line's duration ``T``), the plan must be at ``q_start``
        (``q_end``) there, every body's COM within :data:`JOIN_TOLERANCE` (a runtime
        error, NaN with the checks off): a robot changed after planning can put the COM
        inverse kinematics on the other working mode. ``times`` may be in any order
        (a motion factory appends instants inside the jerk phases after ``T``).
        Checked on the samples: solving the ends again cost the first call of a 2R's
        peak force 2 s of compilation."""
        if self.q_start is None or self.q_end is None:
            return q

        def gap(at_time, q_join):
            at = times == at_time
            return jnp.where(jnp.any(at), body_gap(self.robot, q[jnp.argmax(at)], q_join), 0.0)

        gaps = jnp.stack([gap(0.0, self.q_start), gap(self.line.duration, self.q_end)])
        # NaN also with the checks off: a force-balancing design fixes the COM, and the
        # finite motion of its degenerate COM plan was optimised as the move's
        message = _NOT_JOINED.format(branch=self.branch)
        return guard_solution(q, ~(gaps <= JOIN_TOLERANCE), message, gaps)

    def valid(self, times: Float[Array, " t"]) -> Float[Array, " t"]:
        """Boolean mask: is the COM target reachable at each time (no exception).
        Called eagerly it runs as one compiled program (op by op it took seconds)."""
        return checked_call(_valid_mask, self, jnp.asarray(times, dtype=float), once=True)


def _valid_mask(plan: ComLine, times):
    """:meth:`ComLine.valid` (module level: compiled once per plan structure)."""
    plan = plan.resolved()  # once, outside the vmap
    return jax.vmap(lambda t: plan._solve(t, True)[1])(times)


def com_line(
    robot: Robot,
    q_start,
    q_end,
    profile: Profile,
    duration: ScalarLike,
    free: Callable | None = None,
    branch=None,
    dims: int | None = None,
) -> ComLine:
    """The COM plan between two configurations (eq 3): the COM goes straight from
    ``x_S(q_start)`` to ``x_S(q_end)`` with ``profile`` in ``duration`` seconds.

    ``dims``: 2 (planar COM) or 3; default ``robot.com_dims``. The pose components
    beyond ``dims`` (φ of the 3R, θ5 of the DUAL-V, φ and z of the SCARA) follow the
    straight line between the end-effector poses of ``q_start`` and ``q_end``, unless
    ``free`` is given.

    Raises:
        ValueError: ``q_start``/``q_end`` of the wrong shape or (eagerly) not finite, a
            ``duration`` that is (eagerly) not finite and > 0, or a plan that does not
            start at ``q_start`` and end at ``q_end`` (a COM ``branch`` other than
            theirs: under ``jit``/``vmap``/``grad`` a runtime error where the plan is
            sampled at its ends); the plan is checked again wherever it is sampled.
    """
    plan = com_plan(robot, q_start, q_end, profile, duration, free, branch, dims)
    if not is_traced(plan):  # traced, the plan checks its joins where it is sampled
        _check_joins(plan, plan.q_start, plan.q_end)
    return plan


def com_plan(robot, q_start, q_end, profile, duration, free=None, branch=None, dims=None):
    """:func:`com_line` without its check that the plan joins ``q_start`` and ``q_end``
    (for callers that check the sampled motion themselves); the plan still checks its
    joins where it is sampled (:meth:`ComLine.checked_samples`).

    The COM is planned in the robot's COM components
    (:func:`~jaxbal._src.com_components.com_components`): the leading ``dims`` world
    axes for the built-in robots, the plane it moves in for a mechanism drawn in x-z
    (``(0, 2)``)."""
    components = com_components(robot, dims)
    q_start, q_end = (jnp.asarray(q, dtype=float) for q in (q_start, q_end))
    for name, q in (("q_start", q_start), ("q_end", q_end)):
        check_shape(name, q, (robot.dof,))
        raise_if_invalid(jnp.all(jnp.isfinite(q)), f"{name} must be finite", q)
    if not is_traced(duration):  # NumPy: no eager JAX operations (each one a compile)
        value = np.asarray(duration, float)  # a subnormal is 0 to XLA's CPU (flushed)
        positive = np.isfinite(value) & (value >= np.finfo(float).tiny)
        raise_if_invalid(positive, "duration must be finite and > 0 [s]", duration)
    start, end = (planned_com(robot, q, components) for q in (q_start, q_end))
    poses = StraightLine(*_end_effectors(robot, q_start, q_end), profile, duration)
    line = StraightLine(start, end, profile, duration)
    return ComLine(robot, line, free, branch, poses, q_start, q_end)


#: a COM plan must start and end at its configurations to this tolerance on every
#: body's centre-of-mass position [m] (angles differing by 2π agree).
JOIN_TOLERANCE = 1e-8


def join_gaps(plan: ComLine, q_start, q_end):
    """``(2,)`` largest distance [m] between the bodies' COMs of the plan at ``t = 0``
    (``T``) and of ``q_start`` (``q_end``); ``inf`` where the COM target is not
    reachable."""
    ends = jnp.stack([jnp.zeros(()), plan.line.duration])
    q, valid = jax.vmap(lambda t: plan._solve(t, True))(ends)
    gaps = jnp.stack([body_gap(plan.robot, q[0], q_start), body_gap(plan.robot, q[1], q_end)])
    return jnp.where(valid, gaps, jnp.inf)


def body_gap(robot: Robot, q, target):
    """Largest distance [m] between the bodies' COMs at ``q`` and at ``target`` (angles
    differing by 2π agree): how far a COM plan is from a configuration."""
    return jnp.max(jnp.abs(body_com_positions(robot, q) - body_com_positions(robot, target)))


def _check_joins(plan: ComLine, q_start, q_end) -> None:
    """Raise ``ValueError`` unless the plan starts at ``q_start`` and ends at ``q_end``:
    the COM inverse kinematics on another branch than these configurations' planned the
    move in the other working mode (the 2R's elbow flipped: the same peak force, the
    peak moment 4.2 instead of 22.7 N·m) or jumped between modes. One compiled program
    per plan structure; the branches that would join are named (one sign each)."""
    gaps = np.asarray(checked_call(join_gaps, plan, q_start, q_end, once=True))
    if np.all(gaps <= JOIN_TOLERANCE):
        return
    hint = ""
    if plan.robot.branch_size == 0:  # no branch to give: Newton's start picks the mode
        hint = ("; this robot has no inverse-kinematics branches: its solves start near "
                "the robot's reference, so start them near the move "
                "(robot.with_reference(q_start), or keyframe= when loading it)")  # fmt: skip
    if plan.robot.branch_size == 1:
        signs = [s for s in (1, -1) if _joins_with(plan, s, q_start, q_end)]
        hint = f"; branch={signs[0]} joins them" if signs else "; no branch joins them"
    raise ValueError(f"{_NOT_JOINED.format(branch=plan.branch)}: {gaps.tolist()}{hint}")


_NOT_JOINED = (
    "the COM plan with branch={branch!r} does not start at q_start / end at q_end: give "
    "the branch of the COM inverse kinematics that q_start and q_end are on (its sign is "
    "not the end-effector inverse kinematics'), or the design nearly balances the force "
    "(its COM barely moves, so no COM plan joins them); largest body-COM gap [m] at "
    "start, end"
)


def _joins_with(plan: ComLine, sign: int, q_start, q_end) -> bool:
    """Does the plan with COM branch ``sign`` join ``q_start`` and ``q_end``?"""
    other = dataclasses.replace(plan, branch=sign)
    gaps = checked_call(join_gaps, other, q_start, q_end, once=True)
    return bool(np.all(np.asarray(gaps) <= JOIN_TOLERANCE))


@eqx.filter_jit
def _end_effectors(robot: Robot, q_start, q_end):
    """The end-effector poses of both configurations, compiled (eagerly the robot's
    forward kinematics ran operation by operation, ~10 compilations in a fresh
    process)."""
    return robot.end_effector(q_start), robot.end_effector(q_end)


def wrench_along(
    robot: Robot, path: Callable, times: Float[Array, " t"], gravity=None
) -> tuple[Float[Array, "t 3"], Float[Array, "t 3"]]:
    """Shaking force ``(t, 3)`` [N] and moment ``(t, 3)`` [N·m] along a trajectory.

    A boundary function: compiled once per structure of ``robot``/``path`` (a new
    Python callable inside ``path`` counts as a new structure), not for new parameter
    values, through :func:`~jaxbal.checked_jit` (a failed check, e.g. an unreachable
    pose, raises a ``ValueError`` naming it; the program, free of host callbacks, is
    kept by the persistent compilation cache for the next process).
    """
    return checked_call(_wrench_along, robot, path, times, gravity)


def _wrench_along(robot: Robot, path: Callable, times, gravity):
    q, qd, qdd = sample(path, times, order=2)
    return jax.vmap(lambda a, b, c: shaking_wrench(robot, a, b, c, gravity))(q, qd, qdd)


def torques_along(
    robot: Robot, path: Callable, times: Float[Array, " t"], gravity=None
) -> Float[Array, "t a"]:
    """Actuator torques/forces ``τ`` ``(t, a)`` [N·m, N] along a trajectory
    (:func:`jaxbal.actuator_torques`: any robot, closed chains included, the actuators
    of ``robot.actuated``); compiled as :func:`wrench_along`."""
    return checked_call(_torques_along, robot, path, times, gravity)


def _torques_along(robot: Robot, path: Callable, times, gravity):
    q, qd, qdd = sample(path, times, order=2)
    return jax.vmap(lambda a, b, c: actuator_torques(robot, a, b, c, gravity))(q, qd, qdd)


def torque_rate_along(
    robot: Robot, path: Callable, times: Float[Array, " t"], gravity=None
) -> Float[Array, "t a"]:
    """Actuator torque rates ``dτ/dt`` ``(t, a)`` [N·m/s, N/s] along a trajectory (one
    ``jvp`` of :func:`jaxbal.actuator_torques`: any robot, closed chains included);
    compiled as :func:`wrench_along`.

    Before, both functions returned the generalised forces of *all* coordinates
    (:func:`jaxbal.inverse_dynamics`), the actuator torques of a serial arm whose
    coordinates are all actuated but not of a closed chain, whose rate-limited plan
    (:func:`~jaxbal.planning.plan_rate_limited`) then bounded internal forces."""
    return checked_call(_torque_rate_along, robot, path, times, gravity)


def _torque_rate_along(robot: Robot, path: Callable, times, gravity):
    q, qd, qdd, qddd = sample(path, times, order=3)
    return jax.vmap(lambda a, b, c, d: actuator_torque_rate(robot, a, b, c, d, gravity))(
        q, qd, qdd, qddd
    )


def shaking_peaks(robot: Robot, trajectory, times, reference=None, gravity=None):
    """Peak shaking force and moment of ``robot`` along ``trajectory``, the moment taken
    about any ``reference`` point (e.g. Geng et al. 2021, Tables 1-4).

    Args:
        robot: the robot *as executed* (true masses and payload); the trajectory may
            have been planned with another one (e.g. a payload error).
        trajectory: callable ``t -> q``, e.g. :class:`jaxbal.planning.ComLine`.
        times: ``(t,)`` sampling instants [s].
        reference: ``(3,)`` point about which the moment is taken [m] (default: the
            base origin).
        gravity: optional ``(3,)`` gravity [m/s²] (default none).

    Returns:
        ``(max_t |F_sh| [N], max_t |M_sh| [N·m])``, differentiable (zero-safe norms).
        The moment about ``c`` is ``M_O − c × F``.
    """
    force, moment = wrench_along(robot, trajectory, times, gravity)
    if reference is not None:
        moment = moment - jnp.cross(jnp.asarray(reference, dtype=float), force)
    return peak_norm(force), peak_norm(moment)
