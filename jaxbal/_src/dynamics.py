"""Inverse dynamics by Lagrange's equations, through automatic differentiation.

For a robot whose coordinates ``q`` are independent (serial arms), the generalised
forces needed to follow ``(q, q̇, q̈)`` are

    τ = d/dt ∂T/∂q̇ − ∂T/∂q + ∂V/∂q,

with the kinetic energy ``T`` of every body (payload and counter-masses included) and
the potential ``V = −Σ m_i g·c_i``. The total derivative is one ``jax.jvp``; nothing is
robot-specific. Parallel robots reduce these generalised forces to their actuators
with their own constraint Jacobians (see the robot's module).

References:
    Khalil & Dombre (2002), ch. 9 (Lagrange formulation), cited by Briot et al. (2012).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxbal._src.linalg import matvec, rmatvec
from jaxbal._src.momentum import (
    body_com_positions,
    body_velocities,
    checked_bodies,
    checked_finite,
    checked_parameters,
    checked_state,
)
from jaxbal._src.robot import Robot
from jaxbal._src.types import Array, Coordinates, Float, Scalar, Vec3


def kinetic_energy(robot: Robot, q: Coordinates, qd: Coordinates) -> Scalar:
    """Kinetic energy of all moving bodies [J]."""
    bodies = robot.mass_properties()
    _, rotations, velocities, omega_world = body_velocities(robot, q, qd)
    omega_body = rmatvec(rotations, omega_world)
    translational = 0.5 * jnp.sum(bodies.mass * jnp.sum(velocities**2, axis=-1))
    rotational = 0.5 * jnp.sum(omega_body * matvec(bodies.inertia, omega_body))
    return translational + rotational


def potential_energy(robot: Robot, q: Coordinates, gravity: Vec3) -> Scalar:
    """Gravitational potential energy ``−Σ m_i g·c_i`` [J]."""
    bodies = robot.mass_properties()
    positions = body_com_positions(robot, q)
    return -jnp.sum(bodies.mass * (jnp.sum(positions * jnp.asarray(gravity, dtype=float), axis=-1)))


def mass_matrix(robot: Robot, q: Coordinates) -> Float[Array, "dof dof"]:
    """Generalised mass matrix ``M(q) = ∂²T/∂q̇²`` [SI]."""
    zeros = jnp.zeros_like(q)
    return jax.hessian(lambda qd: kinetic_energy(robot, q, qd))(zeros)


def inverse_dynamics(
    robot: Robot,
    q: Coordinates,
    qd: Coordinates,
    qdd: Coordinates,
    gravity: Vec3 | None = None,
) -> Coordinates:
    """Generalised forces ``τ`` (``(dof,)``, N·m for revolute, N for prismatic) that
    drive the robot along ``(q, q̇, q̈)``; valid when ``q`` are independent coordinates.

    Raises:
        ValueError: as :func:`jaxbal.shaking_wrench` (wrong state shapes at trace
            time; eagerly a non-finite state, a negative/non-finite body mass or
            inertia, a non-finite robot parameter or an overflow; under ``jit`` the same
            value checks at run time). Before, such robots gave silent NaN or wrong
            torques under ``jit``.

    References:
        Lagrange's equations of the second kind; Khalil & Dombre (2002).
    """
    q, qd, qdd = checked_state(robot, q, qd, qdd)

    def momentum_gen(q_, qd_):
        return jax.grad(kinetic_energy, argnums=2)(robot, q_, qd_)

    _, dmomentum_dt = jax.jvp(momentum_gen, (q, qd), (qd, qdd))
    tau = dmomentum_dt - jax.grad(kinetic_energy, argnums=1)(robot, q, qd)
    if gravity is not None:
        tau = tau + jax.grad(potential_energy, argnums=1)(robot, q, gravity)
    tau = checked_parameters(robot, checked_bodies(robot, tau))
    return checked_finite("generalised forces", robot, tau)


def inverse_dynamics_rate(
    robot: Robot,
    q: Coordinates,
    qd: Coordinates,
    qdd: Coordinates,
    qddd: Coordinates,
    gravity: Vec3 | None = None,
) -> Coordinates:
    """Time derivative ``dτ/dt`` of :func:`inverse_dynamics` along the motion [N·m/s].

    Needs the jerk ``q⃛``. Used for the actuator torque-rate limit of Briot et al.
    (2012), eq (6).
    """
    q, qd, qdd, qddd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd, qddd))
    _, rate = jax.jvp(
        lambda a, b, c: inverse_dynamics(robot, a, b, c, gravity), (q, qd, qdd), (qd, qdd, qddd)
    )
    return rate
