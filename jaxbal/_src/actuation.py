"""Actuator torques/forces of any robot, serial or parallel, from Lagrange's equations.

For a serial robot every coordinate is actuated and ``τ = Q``, the generalised forces
of :func:`jaxbal.inverse_dynamics`. For a parallel robot ``q`` holds all coordinates,
tied by the loop closures ``Φ(q) = 0``; with ``N`` a basis of the velocities that keep
the loops closed (``Φ_q N = 0``, ``N`` = identity on the independent coordinates) the
principle of virtual work gives ``N_aᵀ τ = Nᵀ Q`` (``N_a``: the rows of the actuated
coordinates). With actuation redundancy (the DUAL-V) the minimum-norm solution is
returned; other distributions differ by an internal preload in ``null(N_aᵀ)``.

References:
    van der Wijk et al. (2013), eqs (3)-(11) (pseudo-inverse distribution);
    Corbel et al. (2010).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.dynamics import _inverse_dynamics
from jaxbal._src.motion import has_loops
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import checked_finite
from jaxbal._src.types import Array, Coordinates, Float, Vec3


def velocity_basis(robot: Robot, q: Coordinates) -> Float[Array, "dof m"]:
    """``N (dof, m)``: ``q̇ = N u̇`` for the ``m`` independent coordinates ``u``
    (``Φ_q N = 0``, ``N[independent] = I``). Identity for a serial robot."""
    dof, independent = robot.dof, np.asarray(robot.independent)
    phi_q = jax.jacfwd(robot.constraint)(q)
    if phi_q.shape[0] == 0:
        return jnp.eye(dof)
    dependent = np.setdiff1d(np.arange(dof), independent)
    if phi_q.shape[0] != dependent.size:
        raise ValueError(
            f"{type(robot).__name__}: {phi_q.shape[0]} constraint equations (loop "
            "closures; a ball joint's unit quaternion is one) for the "
            f"{dependent.size} coordinates {dependent.tolist()} that are not independent "
            "(they must match): a joint neither independent (actuated) nor closed by a "
            "loop leaves the mechanism underactuated, so its torques are undefined"
        )
    solved = -jnp.linalg.solve(phi_q[:, dependent], phi_q[:, independent])
    basis = jnp.zeros((dof, independent.size))
    basis = basis.at[independent].set(jnp.eye(independent.size))
    return basis.at[dependent].set(solved)


def actuator_torques(
    robot: Robot, q: Coordinates, qd: Coordinates, qdd: Coordinates, gravity: Vec3 | None = None
) -> Float[Array, " a"]:
    """Actuator torques/forces ``(a,)`` [N·m or N] that drive the state ``(q, q̇, q̈)``:
    at the actuated joints (a motor behind a gear of ratio N supplies them / N; MJCF
    ``<actuator gear>`` is not applied).

    Minimum-norm over the actuators when they are redundant (see the module doc).
    One sample; batch with ``jax.vmap``.

    Raises:
        ValueError: the checks of :func:`jaxbal.inverse_dynamics`, a state off a
            closed chain's loop closures (:func:`jaxbal.state_valid`; e.g. a motion
            held while a length was changed with ``eqx.tree_at``), and torques that are
            not finite (a singular configuration of a parallel robot); eagerly, or at
            run time under ``jit``.
    """
    return _actuator_torques(robot, q, qd, qdd, gravity)


def _actuator_torques(
    robot: Robot, q, qd, qdd, gravity, formulation=None, loops: bool = True
) -> Float[Array, " a"]:
    """:func:`actuator_torques`, the generalised forces by ``formulation`` (see
    :func:`jaxbal._src.dynamics._inverse_dynamics`); ``loops=False`` leaves out the
    loop-closure check (the benchmark's "before", which had none)."""
    forces = _inverse_dynamics(robot, q, qd, qdd, gravity, formulation, loops=loops)
    actuated = np.asarray(robot.actuated)
    if not has_loops(robot):
        return forces[actuated]
    basis = velocity_basis(robot, q)
    a = basis[actuated].T  # (m, a)
    if a.shape[0] == a.shape[1]:
        # Non-redundant: solve a τ = Nᵀ Q directly. The minimum-norm form squares
        # cond(a): 1e-3 rad from a parallel singularity (the Orthoglide with its legs
        # near one plane) a aᵀ was singular to rounding and the torques NaN.
        torques = jnp.linalg.solve(a, basis.T @ forces)
    else:
        torques = a.T @ jnp.linalg.solve(a @ a.T, basis.T @ forces)
    return checked_finite("actuator torques", robot, torques)


def actuator_torque_rate(
    robot: Robot,
    q: Coordinates,
    qd: Coordinates,
    qdd: Coordinates,
    qddd: Coordinates,
    gravity: Vec3 | None = None,
) -> Float[Array, " a"]:
    """Actuator torque rates ``dτ/dt = ∂τ/∂q·q̇ + ∂τ/∂q̇·q̈ + ∂τ/∂q̈·q⃛`` ``(a,)`` [N·m/s,
    N/s] at one state with its jerk ``q⃛`` (one ``jvp`` of :func:`actuator_torques`;
    closed chains included). The torque-rate limit of Briot et al. (2012), eq (6)."""

    def torques(a, b, c):
        return actuator_torques(robot, a, b, c, gravity)

    return jax.jvp(torques, (q, qd, qdd), (qd, qdd, qddd))[1]
