"""Newton solves of a mechanism read from MJCF: loop closure and inverse kinematics.

Both are :func:`jaxbal.newton_solve` calls (Newton's method, differentiated
implicitly): :func:`closure` solves the loop closures ``Φ(q) = 0`` for the dependent
coordinates given the independent ones, :func:`inverse_kinematics` solves the loop
closures and the end-effector pose together for all coordinates. The starting guess
(the robot's ``reference`` configuration, MJCF ``qpos0``, unless given) picks the
assembly mode. :func:`closure_motion` adds velocities and accelerations by the
differentiated loop closures.

References:
    Blondel et al. (2022), "Efficient and modular implicit differentiation", NeurIPS;
    Nikravesh (1988), *Computer-Aided Analysis of Mechanical Systems*, §6
    (coordinate partitioning: ``Φ_q q̇ = 0``, ``Φ_q q̈ = −(Φ_q q̇)_q q̇``).
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.implicit import newton_solve
from jaxbal._src.motion import checked_rates
from jaxbal._src.robots.mjcf_kinematics import world_frames
from jaxbal._src.solution_guard import guard_solution
from jaxbal._src.validation import check_shape

__all__ = ["closure", "closure_motion", "inverse_kinematics", "pose_equations", "pose_motion"]


def _closure_residual(x, params):
    """``Φ(q)`` with ``q`` the independent values ``params[1]`` and the dependent ``x``."""
    robot, independent = params
    return robot.constraint(robot.assemble(independent, x))


def _ik_residual(q, params):
    """``(Φ(q), pose(q) − pose)``: loop closures and the end-effector pose."""
    robot, pose = params
    return pose_equations(robot, q) - jnp.concatenate([jnp.zeros(robot.closure_count()), pose])


def _check_square(robot, unknowns: int, equations: int, what: str) -> None:
    if unknowns != equations:
        raise ValueError(
            f"{what}: {equations} equations for {unknowns} unknowns. The loop closures "
            f"give {robot.closure_count()} equations (connects {list(robot.connect_names)}) "
            f"for the {len(robot.dependent)} dependent coordinates; choose the "
            "independent joints (independent=...) so that they match (a passive freedom "
            "that no joint names, e.g. a bar's spin between two ball joints, cannot be solved)"
        )


#: a joint value within this of its range's end [rad, m] is in range (Newton's rounding
#: of a pose asked for at the limit itself).
RANGE_ATOL = 1e-9


def joint_values(robot, q):
    """``(nj,)`` each joint's value as its range bounds it: a hinge's angle [rad], a
    slide's displacement [m], a ball's rotation angle ``2 atan2(|v|, |w|)`` [rad]."""
    values = []
    for kind, a in zip(robot.joint_types, robot.joint_qpos, strict=True):
        if kind == "ball":
            quat = q[a : a + 4]
            values.append(2.0 * jnp.arctan2(jnp.linalg.norm(quat[1:]), jnp.abs(quat[0])))
        else:
            values.append(q[a])
    return jnp.stack(values) if values else jnp.zeros(0)


def out_of_range(robot, q):
    """``(nj,)`` mask: a limited joint (MJCF ``range``, a URDF ``<limit>``) outside its
    range at ``q``; all False for a robot without ranges."""
    if not robot.joint_range:
        return jnp.zeros(len(robot.joint_types), dtype=bool)
    low, high = np.asarray(robot.joint_range, dtype=float).T
    values = joint_values(robot, q)
    return (values < low - RANGE_ATOL) | (values > high + RANGE_ATOL)


def into_range(robot, q):
    """``q`` with each limited hinge outside its range turned by a multiple of 2π into
    it where one fits (the same configuration: Newton from a singular start wanders
    whole turns away, a URDF shoulder limited to ±3 rad came back at −5.54); other
    coordinates unchanged."""
    ranges = robot.joint_range  # () for a robot built without ranges: nothing to turn
    for kind, a, (lo, hi) in zip(robot.joint_types, robot.joint_qpos, ranges, strict=False):
        if kind == "hinge" and np.isfinite(lo):
            value = q[a]
            inside = (value >= lo - RANGE_ATOL) & (value <= hi + RANGE_ATOL)
            q = q.at[a].set(jnp.where(inside, value, lo + jnp.mod(value - lo, 2.0 * np.pi)))
    return q


def _checked(robot, q, converged, offending, message: str, what: str):
    """``q``, guarded by Newton's convergence (``message``, naming ``offending``), then
    by every limited joint in its range (eagerly a ``ValueError`` naming the joints and
    values, with the ranges; under ``jit`` a runtime error): Newton solves the
    equations, not the ranges, so a pose reached only outside a joint's range came back
    as valid (a slide 26 times past its limit)."""
    q = guard_solution(q, ~converged, message, offending, robot=robot)
    if not robot.joint_range:
        return q
    limited = ", ".join(
        f"{n} [{lo:.6g}, {hi:.6g}]"
        for n, (lo, hi) in zip(robot.joint_names, robot.joint_range, strict=True)
        if np.isfinite(lo) or np.isfinite(hi)
    )
    text = (
        f"{what}: the solution leaves the range of a limited joint (ranges: {limited}; "
        "a pose out of reach within them, or another assembly mode: try guess=)"
    )
    return guard_solution(
        q, out_of_range(robot, q), text, joint_values(robot, q), robot.joint_names
    )


def _valid(robot, q, converged):
    """``return_valid``'s mask: converged, and every limited joint in its range."""
    return converged & ~jnp.any(out_of_range(robot, q))


def closure(robot, q_independent, guess=None, *, return_valid: bool = False):
    """All coordinates ``q (dof,)`` from the independent ones (loop closure).

    Newton's method from ``guess`` (``(dof,)``, default ``robot.reference``), which
    picks the assembly mode; differentiable in ``q_independent`` and in every
    robot parameter (implicit differentiation, any order).

    Args:
        robot: an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot`.
        q_independent: ``(m,)`` values of :attr:`independent` [rad or m].
        guess: ``(dof,)`` starting configuration.
        return_valid: return ``(q, valid)`` (converged, every limited joint in its
            range) and never raise.

    Raises:
        ValueError: at trace time, closure equations that do not match the
            dependent coordinates; eagerly, a closure that does not converge
            (unassemblable input or a singular closure) or leaves a limited joint's
            range (the joints, values and ranges named).
    """
    q_independent = jnp.asarray(q_independent, dtype=float)
    check_shape("q_independent", q_independent, (len(robot.independent_coordinates),))
    _check_square(robot, len(robot.dependent), robot.closure_count(), "loop closure")
    start = robot.reference if guess is None else jnp.asarray(guess, dtype=float)
    check_shape("guess", start, (robot.dof,))
    q, converged = _closure(robot, q_independent, start)
    if return_valid:
        return q, _valid(robot, q, converged)
    message = "loop closure does not converge (not assemblable, or singular) for q_independent"
    return _checked(robot, q, converged, q_independent, message, "loop closure")  # jit too


def _closure(robot, q_independent, start):
    """``(q, converged)`` of :func:`closure` from ``start`` (no range check)."""
    if not robot.dependent:
        q = robot.assemble(q_independent, jnp.zeros(0))
        return q, jnp.all(jnp.isfinite(q))
    solution = newton_solve(
        _closure_residual,
        start[np.asarray(robot.dependent, dtype=int)],
        (robot, q_independent),
        tol=robot.tolerance,
        throw=False,
        what="loop closure",
    )
    q = into_range(robot, robot.assemble(q_independent, solution.value))
    return q, solution.converged & jnp.all(jnp.isfinite(q_independent))


def closure_motion(robot, u, u_d, u_dd, guess=None, *, return_valid: bool = False):
    """``(q, q̇, q̈)`` ``(dof,)`` each from the independent ``(u, u̇, ü)`` ``(m,)``.

    ``q`` from :func:`closure`; the dependent rates from the differentiated loop
    closures, ``Φ_q q̇ = 0`` and ``Φ_q q̈ = −∂²Φ[q̇, q̇]``, by two linear solves
    (cheaper to compile than nested differentiation through Newton; exact).
    """
    u, u_d, u_dd = (jnp.asarray(v, dtype=float) for v in (u, u_d, u_dd))
    if return_valid:
        q, valid = robot.closure(u, guess, return_valid=True)
    else:  # under jit too: the message of what failed
        q = robot.closure(u, guess)
    if not robot.dependent:
        q_d, q_dd = robot.assemble(u_d, jnp.zeros(0)), robot.assemble(u_dd, jnp.zeros(0))
        return (q, q_d, q_dd, valid) if return_valid else (q, q_d, q_dd)
    dependent = np.asarray(robot.dependent, dtype=int)
    independent = np.asarray(robot.independent_coordinates, dtype=int)
    jacobian = jax.jacfwd(robot.constraint)(q)
    solve = functools.partial(jnp.linalg.solve, jacobian[:, dependent])
    q_d = robot.assemble(u_d, -solve(jacobian[:, independent] @ u_d))

    def rate(x):
        return jax.jvp(robot.constraint, (x,), (q_d,))[1]

    curvature = jax.jvp(rate, (q,), (q_d,))[1]
    q_dd = robot.assemble(u_dd, -solve(jacobian[:, independent] @ u_dd + curvature))
    return (q, q_d, q_dd, valid) if return_valid else (q, q_d, q_dd)


def pose_equations(robot, q):
    """``(Φ(q), pose(q))``: the loop closures and the end-effector pose."""
    frames = world_frames(robot, q)
    return jnp.concatenate([robot.closures_at(q, frames), robot.pose_at(q, frames)])


def pose_motion(robot, pose, pose_d, pose_dd, guess=None, *, return_valid: bool = False):
    """``(q, q̇, q̈)`` ``(dof,)`` each from an end-effector motion ``(u, u̇, ü)`` ``(m,)``.

    ``q`` from :func:`inverse_kinematics`; the rates from the differentiated equations
    ``G(q) = (Φ(q), pose(q)) = (0, u)``: ``G_q q̇ = (0, u̇)`` and ``G_q q̈ = (0, ü) −
    ∂²G[q̇, q̇]`` (exact; the same as :func:`jaxbal.pose_motion`, which differentiates
    through Newton, but several times cheaper to compile).
    """
    pose_d, pose_dd = (jnp.asarray(v, dtype=float) for v in (pose_d, pose_dd))
    if return_valid:
        q, valid = inverse_kinematics(robot, pose, guess, return_valid=True)
    else:  # under jit too: the message of what failed
        q = inverse_kinematics(robot, pose, guess)
    closures = robot.closure_count()

    def equations(x):
        return pose_equations(robot, x)

    jacobian = jax.jacfwd(equations)(q)
    zeros = jnp.zeros(closures)
    q_d = jnp.linalg.solve(jacobian, jnp.concatenate([zeros, pose_d]))

    def rate(x):
        return jax.jvp(equations, (x,), (q_d,))[1]

    curvature = jax.jvp(rate, (q,), (q_d,))[1]
    q_dd = jnp.linalg.solve(jacobian, jnp.concatenate([zeros, pose_dd]) - curvature)
    if return_valid:
        return q, q_d, q_dd, valid & jnp.all(jnp.isfinite(q_d)) & jnp.all(jnp.isfinite(q_dd))
    return checked_rates(q, q_d, q_dd, pose)  # a singular configuration: inf, NaN


def inverse_kinematics(robot, pose, guess=None, *, return_valid: bool = False):
    """All coordinates ``q (dof,)`` for an end-effector pose (module doc).

    Newton's method on the loop closures and the pose together, from ``guess``
    (default ``robot.reference``); differentiable in ``pose`` and in every robot
    parameter by implicit differentiation.

    Args:
        robot: an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot` with a site.
        pose: ``(m,)`` as ``robot.end_effector`` returns it [m, then rad or m].
        return_valid: return ``(q, valid)`` (converged, finite, every limited joint in
            its range) and never raise.
        guess: ``(dof,)`` starting configuration (picks the assembly mode).

    Raises:
        ValueError: eagerly, naming the pose, when Newton does not converge (out of
            reach or singular), or naming the joints when the solution leaves a
            limited joint's range; at trace time, a wrong shape or a count mismatch.
    """
    robot.require_site()
    pose = jnp.asarray(pose, dtype=float)
    labels = robot.pose_labels()
    if pose.shape != (len(labels),):
        raise ValueError(
            f"pose must have shape ({len(labels)},), got {pose.shape}: the components are "
            f"{', '.join(labels)} [m for the site's axes, rad or m for the joints]"
        )
    _check_square(robot, robot.dof, robot.closure_count() + len(labels), "inverse kinematics")
    start = robot.reference if guess is None else jnp.asarray(guess, dtype=float)
    check_shape("guess", start, (robot.dof,))
    solution = newton_solve(
        _ik_residual, start, (robot, pose), tol=robot.tolerance, throw=False, what="IK"
    )
    converged = solution.converged & jnp.all(jnp.isfinite(pose))
    q = into_range(robot, jnp.where(jnp.isfinite(solution.value), solution.value, start))
    if return_valid:
        return q, _valid(robot, q, converged)
    message = (
        "end-effector pose not reached by Newton's method (out of reach, singular, "
        "or in another assembly mode: try guess=)"
    )
    return _checked(robot, q, converged, pose, message, "inverse kinematics")  # jit too
