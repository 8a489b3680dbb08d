"""Inverse dynamics of any robot with independent coordinates, through automatic
differentiation.

The generalised forces needed to follow ``(q, q̇, q̈)`` are those of Lagrange's
equations, ``τ = d/dt ∂T/∂q̇ − ∂T/∂q + ∂V/∂q`` (kinetic energy ``T`` of every body,
payload and counter-masses included; potential ``V = −Σ m_i g·c_i``). They are
evaluated in the equivalent form of Kane's equations (d'Alembert's principle): the
Newton–Euler inertial wrench of every body projected on its partial velocities,

    τ = Σ_i J_v,iᵀ m_i (a_i − g) + J_ω,iᵀ (I_i α_i + ω_i × I_i ω_i),

with ``v_i = J_v,i q̇``, ``ω_i = J_ω,i q̇`` (COM and angular velocities, base frame,
``I_i`` the inertia in the base frame). The accelerations ``(a_i, α_i)`` are one
``jax.jvp`` of the body velocities along ``(q̇, q̈)``, and the projection ``Jᵀ(·)`` one
``jax.vjp`` in ``q̇`` (the velocities are linear in ``q̇``): no second derivative of
``T``, about half the compile time of differentiating ``T`` twice (measured on the
2-core CPU: the 2R 3.6 → 1.8 s, the DUAL-V's 11 coordinates 5.5 → 3.0 s) and
1.1–1.7× faster; traced, it is replayed as straight-line scalar code like the shaking
wrench (``_straight_kane_forces``). Nothing is robot-specific. Parallel robots reduce
these generalised forces to their actuators with their loop-closure Jacobians
(:func:`jaxbal.actuator_torques`). The two forms agree for rigid body frames; a closed
chain whose frames are rotations only on its loops (the Orthoglide's parallelograms,
built from the dependent coordinates) gets generalised forces that differ in the
directions leaving the loops, which the reduction to the actuators removes
(tests/test_kane.py compares them reduced, with ``dynamics.lagrange_forces``).

References:
    Khalil & Dombre (2002), ch. 9 (Lagrange formulation), cited by Briot et al. (2012);
    Kane & Levinson (1985), *Dynamics: Theory and Applications*, ch. 6.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp

from jaxbal._src.linalg import cross, matvec, rmatvec, world_inertia_times
from jaxbal._src.loop_checks import with_closure_excess
from jaxbal._src.merged_guards import merged_guards
from jaxbal._src.momentum import _REPLAY, body_com_positions, body_velocities
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import checked_physics
from jaxbal._src.state_checks import state_check
from jaxbal._src.straight_line import straight_line
from jaxbal._src.types import Array, Coordinates, Float, Scalar, Vec3
from jaxbal._src.validation import check_shape


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
            torques under ``jit``. The loop closures of a closed chain are not
            required: these are the generalised forces of all its coordinates, defined
            for any state (:func:`jaxbal.actuator_torques` requires them).

    References:
        Lagrange's equations of the second kind; Khalil & Dombre (2002); evaluated in
        Kane's form (module doc).
    """
    return _inverse_dynamics(robot, q, qd, qdd, gravity)


def _inverse_dynamics(
    robot: Robot, q, qd, qdd, gravity, formulation=None, loops: bool = False
) -> Coordinates:
    """:func:`inverse_dynamics` with its checks, the forces from ``formulation(robot, q, q̇,
    q̈, gravity)`` (default Kane's form; :func:`lagrange_forces` is the benchmark's
    "before"); with ``loops`` the state must also close a closed chain's loops (the
    actuator torques'; the generalised forces of all coordinates are defined for any
    state, e.g. the bias ``h(q, q̇)`` of a forward dynamics at ``q̈ = 0``)."""
    q, qd, qdd, check = state_check(robot, q, qd, qdd, loops=loops, gravity=gravity)
    if formulation is None:
        straight = _straight_kane_forces_loops if check.traced_loops else _straight_kane_forces
        formulation = straight if _REPLAY.value else straight.as_written
    elif check.traced_loops:  # e.g. Lagrange's form: the loop residuals computed beside
        formulation = with_closure_excess(formulation)
    if not check.traced_loops:
        tau = formulation(robot, q, qd, qdd, gravity)
        return merged_guards(lambda t: check.loops(checked_physics(_FORCES, robot, check(t))), tau)

    # a closed chain's loop residuals written to memory with the forces (momentum's
    # _shaking_wrench)
    def checks(both):
        t, excess = both
        return check.loops(checked_physics(_FORCES, robot, check(t)), excess), excess

    return merged_guards(checks, formulation(robot, q, qd, qdd, gravity))[0]


_FORCES = "generalised forces"


def _kane_forces(robot: Robot, q, qd, qdd, gravity) -> Coordinates:
    """Unchecked generalised forces, Kane's form (module doc)."""
    bodies = robot.mass_properties()

    def velocities(q_, qd_):
        _, rotations, linear, angular = body_velocities(robot, q_, qd_)
        return (linear, angular), rotations

    (_, omega), (accel, alpha), rotations = jax.jvp(velocities, (q, qd), (qd, qdd), has_aux=True)
    if gravity is not None:
        g = jnp.asarray(gravity, dtype=float)
        check_shape("gravity", g, (3,))
        accel = accel - g

    force = bodies.mass[:, None] * accel
    spin_rate = world_inertia_times(rotations, bodies.inertia, alpha)
    moment = spin_rate + cross(omega, world_inertia_times(rotations, bodies.inertia, omega))
    _, project = jax.vjp(lambda qd_: velocities(q, qd_)[0], qd)  # (f, n) -> Jᵀ(f, n)
    return project((force, moment))[0]


# Replayed as straight-line scalar code under jit/vmap/grad, as the shaking wrench
# (momentum.replayed switches both): measured on the 2-core CPU, 20,000 states of the
# 2R 7.2 → 0.12 µs each and the first compile 1.4 → 0.3 s; the DUAL-V's 11
# coordinates 39 → 0.5 µs, 2.5 → 1.6 s.
_straight_kane_forces = straight_line(_kane_forces)
#: with the loop excess of a closed chain's state (:mod:`jaxbal._src.loop_checks`)
_straight_kane_forces_loops = straight_line(with_closure_excess(_kane_forces))


def lagrange_forces(robot: Robot, q, qd, qdd, gravity=None) -> Coordinates:
    """Unchecked generalised forces ``d/dt ∂T/∂q̇ − ∂T/∂q + ∂V/∂q`` by differentiating
    the energies (:func:`kinetic_energy` twice): an independent evaluation of
    :func:`inverse_dynamics`, kept for the tests and as the benchmark's "before"."""

    def momentum_gen(q_, qd_):
        return jax.grad(kinetic_energy, argnums=2)(robot, q_, qd_)

    _, dmomentum_dt = jax.jvp(momentum_gen, (q, qd), (qd, qdd))
    tau = dmomentum_dt - jax.grad(kinetic_energy, argnums=1)(robot, q, qd)
    if gravity is not None:
        tau = tau + jax.grad(potential_energy, argnums=1)(robot, q, gravity)
    return tau


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
