"""Joint motion of any robot, and the loop-closure check of parallel robots.

A trajectory is any callable ``t ↦ q`` returning the coordinates of *all* bodies
(e.g. :class:`~jaxbal.planning.EndEffectorLine`, :class:`~jaxbal.planning.ComLine`, a
robot's inverse kinematics composed with a pose path). :func:`joint_motion` gives its
exact ``q, q̇, q̈`` by nested forward-mode differentiation and checks them against the
robot's loop closures ``Φ(q) = 0`` (:meth:`jaxbal.Robot.constraint`) and their first
two time derivatives, so a state that violates a closed chain is flagged, never
silently evaluated.
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp

from jaxbal._src.robot import Robot
from jaxbal._src.trajectory import time_derivatives
from jaxbal._src.types import Array, Coordinates, Float, Scalar, ScalarLike
from jaxbal._src.validation import check_shape, raise_if_invalid

#: Tolerance of the loop-closure check: ``|Φ| ≤ tol``, ``|Φ̇| ≤ tol (1 + |q̇|)``,
#: ``|Φ̈| ≤ tol (1 + |q̈| + |q̇|²)`` (SI units of the constraints, usually m).
LOOP_TOLERANCE = 1e-8


def loop_closure_residuals(robot: Robot, q: Coordinates, qd: Coordinates, qdd: Coordinates):
    """``(Φ, Φ̇, Φ̈)`` of the robot's loop closures at the state ``(q, q̇, q̈)``, each ``(k,)``."""

    def rate(q_, qd_):
        return jax.jvp(robot.constraint, (q_,), (qd_,))

    (phi, phi_d), (_, phi_dd) = jax.jvp(rate, (q, qd), (qd, qdd))
    return phi, phi_d, phi_dd


def loop_excess(robot: Robot, q, qd, qdd, tol: float = LOOP_TOLERANCE) -> Scalar:
    """Largest loop-closure residual of the state relative to its tolerance ``tol``
    (``≤ 1``: consistent, the test of :func:`state_valid`): ``max(|Φ|/tol, |Φ̇|/(tol (1 +
    |q̇|)), |Φ̈|/(tol (1 + |q̈| + |q̇|²)))`` with max-norms; NaN for a non-finite state."""
    phi, phi_d, phi_dd = loop_closure_residuals(robot, q, qd, qdd)
    speed = jnp.max(jnp.abs(qd))
    bounds = (1.0, 1.0 + speed, 1.0 + jnp.max(jnp.abs(qdd)) + speed**2)
    parts = [jnp.max(jnp.abs(r)) / b for r, b in zip((phi, phi_d, phi_dd), bounds, strict=True)]
    return jnp.maximum(jnp.maximum(parts[0], parts[1]), parts[2]) / tol


def has_loops(robot: Robot) -> bool:
    """Static: does the robot have loop closures (a constraint vector of length > 0)?"""
    q = jax.ShapeDtypeStruct((robot.dof,), jnp.float64)
    return jax.eval_shape(robot.constraint, q).shape[0] > 0


def state_valid(robot: Robot, q, qd, qdd, tol: float = LOOP_TOLERANCE) -> Array:
    """Boolean: the state is finite and satisfies the loop closures to ``tol``
    (always True for a serial robot with a finite state). Works under jit/vmap."""
    q, qd, qdd = (jnp.asarray(v, dtype=float) for v in (q, qd, qdd))
    for name, value in (("q", q), ("qd", qd), ("qdd", qdd)):
        check_shape(name, value, (robot.dof,))
    finite = jnp.all(jnp.isfinite(q)) & jnp.all(jnp.isfinite(qd)) & jnp.all(jnp.isfinite(qdd))
    if not has_loops(robot):
        return finite
    return finite & (loop_excess(robot, q, qd, qdd, tol) <= 1.0)


def states_valid(robot: Robot, q, qd, qdd) -> Array:
    """``(t,)`` :func:`state_valid` of each row of ``(t, dof)`` states (one ``vmap``)."""
    return jax.vmap(lambda a, b, c: state_valid(robot, a, b, c))(q, qd, qdd)


def check_state(robot: Robot, q, qd, qdd) -> None:
    """Eagerly raise ``ValueError`` if ``(q, q̇, q̈)`` is not a consistent state of the
    robot (non-finite, or violating its loop closures); no-op under tracing."""
    raise_if_invalid(
        state_valid(robot, q, qd, qdd),
        f"state violates the loop closures of {type(robot).__name__} (or is not finite); "
        "use the robot's inverse kinematics / jaxbal.joint_motion to build it. q",
        q,
    )


def joint_motion(
    robot: Robot, trajectory: Callable, t: ScalarLike, *, return_valid: bool = False
) -> tuple[Float[Array, " dof"], ...]:
    """Exact ``(q, q̇, q̈)`` ``(dof,)`` each of any robot along ``trajectory`` at time ``t``.

    Args:
        robot: the robot the trajectory belongs to (for the loop-closure check).
        trajectory: ``t ↦ q``, coordinates of all bodies (parallel robots included).
        t: time [s].
        return_valid: return ``(q, q̇, q̈, valid)`` and never raise (batched code).

    Raises:
        ValueError: eagerly, when the state violates the robot's loop closures.
    """
    q, qd, qdd = time_derivatives(trajectory, t, order=2)
    valid = state_valid(robot, q, qd, qdd)
    if return_valid:
        return q, qd, qdd, valid
    raise_if_invalid(
        valid, f"trajectory leaves the loop closures of {type(robot).__name__} at t", t
    )
    return q, qd, qdd


def pose_motion(robot: Robot, pose, pose_d, pose_dd, *, branch=None):
    """``(q, q̇, q̈)`` of all coordinates from an end-effector motion ``(u, u̇, ü)``
    (exact: nested ``jvp`` of the robot's inverse kinematics)."""
    pose, pose_d, pose_dd = (jnp.asarray(v, dtype=float) for v in (pose, pose_d, pose_dd))
    branch = robot.branch(branch)

    def ik(u):
        return robot.inverse_kinematics(u, branch=branch)

    def velocity(u, ud):
        return jax.jvp(ik, (u,), (ud,))

    # one trace of the inverse kinematics (its checks included) for all three
    (q, qd), (_, qdd) = jax.jvp(velocity, (pose, pose_d), (pose_d, pose_dd))
    return checked_rates(q, qd, qdd, pose)


def checked_rates(q, qd, qdd, pose):
    """``(q, q̇, q̈)``, refused where the rates are not finite: an inverse kinematics
    solved implicitly (an MJCF robot's Newton) accepts a pose at a singular
    configuration (an arm stretched), whose rates ``J⁻¹ u̇`` are ``inf``/NaN (they were
    returned as such, eagerly too); eagerly a ``ValueError`` naming the pose."""
    from jaxbal._src.solution_guard import guard_solution

    singular = ~(jnp.all(jnp.isfinite(qd)) & jnp.all(jnp.isfinite(qdd)))
    message = "pose out of reach or at a singular configuration (rates q̇, q̈ not finite)"
    return guard_solution((q, qd, qdd), singular, message, pose)
