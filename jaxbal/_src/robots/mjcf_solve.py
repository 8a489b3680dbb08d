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
from jaxbal._src.robots.mjcf_kinematics import world_frames
from jaxbal._src.validation import check_shape, guard

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


def closure(robot, q_independent, guess=None, *, return_valid: bool = False):
    """All coordinates ``q (dof,)`` from the independent ones (loop closure).

    Newton's method from ``guess`` (``(dof,)``, default ``robot.reference``), which
    picks the assembly mode; differentiable in ``q_independent`` and in every
    robot parameter (implicit differentiation, any order).

    Args:
        robot: an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot`.
        q_independent: ``(m,)`` values of :attr:`independent` [rad or m].
        guess: ``(dof,)`` starting configuration.
        return_valid: return ``(q, valid)`` and never raise.

    Raises:
        ValueError: at trace time, closure equations that do not match the
            dependent coordinates; eagerly, a closure that does not converge
            (unassemblable input or a singular closure).
    """
    q_independent = jnp.asarray(q_independent, dtype=float)
    check_shape("q_independent", q_independent, (len(robot.independent_coordinates),))
    _check_square(robot, len(robot.dependent), robot.closure_count(), "loop closure")
    start = robot.reference if guess is None else jnp.asarray(guess, dtype=float)
    check_shape("guess", start, (robot.dof,))
    if not robot.dependent:
        q = robot.assemble(q_independent, jnp.zeros(0))
        return (q, jnp.all(jnp.isfinite(q))) if return_valid else q
    solution = newton_solve(
        _closure_residual,
        start[np.asarray(robot.dependent, dtype=int)],
        (robot, q_independent),
        tol=robot.tolerance,
        throw=False,
        what="loop closure",
    )
    q = robot.assemble(q_independent, solution.value)
    valid = solution.converged & jnp.all(jnp.isfinite(q_independent))
    if return_valid:
        return q, valid
    message = "loop closure does not converge (not assemblable, or singular) for q_independent"
    return guard(q, ~valid, message, q_independent)  # under jit too


def closure_motion(robot, u, u_d, u_dd, guess=None, *, return_valid: bool = False):
    """``(q, q̇, q̈)`` ``(dof,)`` each from the independent ``(u, u̇, ü)`` ``(m,)``.

    ``q`` from :func:`closure`; the dependent rates from the differentiated loop
    closures, ``Φ_q q̇ = 0`` and ``Φ_q q̈ = −∂²Φ[q̇, q̇]``, by two linear solves
    (cheaper to compile than nested differentiation through Newton; exact).
    """
    u, u_d, u_dd = (jnp.asarray(v, dtype=float) for v in (u, u_d, u_dd))
    q, valid = robot.closure(u, guess, return_valid=True)
    if not return_valid:  # under jit too
        message = "loop closure does not converge (not assemblable, or singular) for u"
        q = guard(q, ~valid, message, u)
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
    q, valid = inverse_kinematics(robot, pose, guess, return_valid=True)
    if not return_valid:  # under jit too
        message = "end-effector pose not reached by Newton's method"
        q = guard(q, ~valid, message, pose)
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
    return (q, q_d, q_dd, valid) if return_valid else (q, q_d, q_dd)


def inverse_kinematics(robot, pose, guess=None, *, return_valid: bool = False):
    """All coordinates ``q (dof,)`` for an end-effector pose (module doc).

    Newton's method on the loop closures and the pose together, from ``guess``
    (default ``robot.reference``); differentiable in ``pose`` and in every robot
    parameter by implicit differentiation.

    Args:
        robot: an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot` with a site.
        pose: ``(m,)`` as ``robot.end_effector`` returns it [m, then rad or m].
        return_valid: return ``(q, valid)`` (converged, finite) and never raise.
        guess: ``(dof,)`` starting configuration (picks the assembly mode).

    Raises:
        ValueError: eagerly, naming the pose, when Newton does not converge (out of
            reach or singular); at trace time, a wrong shape or a count mismatch.
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
    valid = solution.converged & jnp.all(jnp.isfinite(pose))
    q = jnp.where(jnp.isfinite(solution.value), solution.value, start)
    if return_valid:
        return q, valid
    message = (
        "end-effector pose not reached by Newton's method (out of reach, singular, "
        "or in another assembly mode: try guess=)"
    )
    return guard(q, ~valid, message, pose)  # under jit too
