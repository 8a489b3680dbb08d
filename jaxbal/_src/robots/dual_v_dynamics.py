"""DUAL-V inverse dynamics: the paper's model, an independent check, bearing forces.

Two ways to the actuator torques ``τ`` ``(4,)`` of the redundantly actuated DUAL-V:

* :func:`paper_torques` -- eqs (3)-(29) of van der Wijk et al. (2013) written out as
  in the paper, ``τ = τ_I + τ_II + τ_III``: the platform (with the equivalent masses of
  links i2 at C_i) is driven through the pseudo-inverse ``J^{T*}`` of eq (11); links i1,
  counter-masses, rotors and the equivalent masses at B_i act directly on the
  actuators (eqs 12-20); the inertia of links i2 not captured by the two point masses
  is added by eqs (21)-(29).
* :func:`virtual_work_torques` -- independent: Lagrange's equations over *all* 22 bodies
  and all 11 coordinates by autodiff (:func:`jaxbal.inverse_dynamics`), reduced to the
  platform coordinates with the IK Jacobian ``G = ∂q/∂u`` (autodiff) and distributed
  over the four actuators by the minimum-norm solution of ``Jᵀτ = Gᵀ Q``.

Every ``τ`` with ``Jᵀτ = GᵀQ`` drives the same motion; they differ by an internal preload
along ``null(Jᵀ)`` (1-D). The paper's model distributes only the platform part with the
pseudo-inverse, so it is *not* the minimum-norm solution of the whole robot: its
projection ``J^{T*}Jᵀτ_paper`` on ``range(J)`` is. :func:`torque_split` returns both parts.
The paper's own distribution is also obtained independently, by Lagrange/autodiff on the
exact equivalent model of links i2 in the coordinates ``(θ_i1, u)``
(:class:`SplitModel`, ``virtual_work_torques(..., distribution="paper")``).

Bearing forces (:func:`bearing_forces`) follow from the constraint forces at C_i:
``Q - Bᵀτ = Φ_qᵀ μ`` with the loop closures ``Φ`` of :meth:`DualV.constraint`; then the
base pushes on arm i with ``F_A,i = ṗ_arm,i - μ_i``.

References:
    van der Wijk, Krut, Pierrot & Herder (2013), eqs (3)-(29), Figs 13-14;
    Corbel et al. (2010) for the pseudo-inverse distribution.
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.dynamics import inverse_dynamics, mass_matrix
from jaxbal._src.momentum import body_com_positions, shaking_wrench
from jaxbal._src.motion import pose_motion
from jaxbal._src.robot import Bodies, Robot, concatenate, planar_inertia, rot_z
from jaxbal._src.robots.dual_v import OUTWARD, PLATFORM_END, DualV
from jaxbal._src.types import Array, Float
from jaxbal._src.validation import guard

__all__ = [
    "ARM_BODIES",
    "MotionSample",
    "SplitModel",
    "base_wrench_from_bearings",
    "bearing_forces",
    "evaluate",
    "forward_accelerations",
    "paper_torques",
    "torque_split",
    "virtual_work_torques",
]

# body indices of arm i (link i1, link i2, counter-mass, tuning mass, rotor)
ARM_BODIES = np.array([[i, 4 + i, 10 + i, 14 + i, 18 + i] for i in range(4)])


def _pinv_transpose(jacobian):
    """``J^{T*}`` of eq (11): the pseudo-inverse of ``Jᵀ`` (4×3), ``J (JᵀJ)⁻¹``."""
    return jacobian @ jnp.linalg.inv(jacobian.T @ jacobian)


def paper_torques(robot: DualV, q, pose_d, pose_dd, split: bool = False):
    """Actuator torques [N·m] by the inverse dynamic model, eqs (3)-(29).

    Args:
        robot: the DUAL-V (payload, if any, is added to m5 in eq 10).
        q: ``(11,)`` coordinates from the IK.
        pose_d, pose_dd: ``(3,)`` platform velocity ``u̇`` and acceleration ``ü``.
        split: return ``(τ_I, τ_II, τ_III)`` instead of their sum.

    Eq (10) is exact when the equivalent masses at both platform ends are equal
    (``Σ_{i=1,2} m_eq,i2 = Σ_{i=3,4} m_eq,i2``, true for Table 1).
    """
    q, ud, udd = (jnp.asarray(v, dtype=float) for v in (q, pose_d, pose_dd))
    th1, th2, th5 = q[0:4], q[4:8], q[10]
    l1, l2, p2, b, s = robot.l1, robot.l2, robot.p2, robot.b, PLATFORM_END
    c2, s2 = jnp.cos(th2), jnp.sin(th2)
    # eqs (6)-(9)
    x_n = -l1 * jnp.sin(th1 - th2)  # diagonal
    y_n = jnp.stack([c2, s2, -s * jnp.cos(th2 - th5) * b], -1)
    jac = y_n / x_n[:, None]
    qd1 = jac @ ud
    # eq (17)-(19)
    x_t = l1 * jnp.cos(th1 - th2)
    y_t = jnp.stack([-s2, c2, s * jnp.sin(th2 - th5) * b], -1)
    qd2 = (-x_t * qd1 + y_t @ ud) / l2
    # eqs (10)-(11)
    m_eq2 = robot.m2 * p2 / l2  # at C_i
    m_eq1 = robot.m2 * (1.0 - p2 / l2)  # at B_i
    platform_mass = robot.m5 + robot.payload + jnp.sum(m_eq2)
    m_i = jnp.diag(
        jnp.stack([platform_mass, platform_mass, robot.inertia5 + jnp.sum(m_eq2) * b**2])
    )
    jt_star = _pinv_transpose(jac)
    tau_1 = jt_star @ (m_i @ udd)
    # eqs (12)-(16), (20)
    m_ii = (
        robot.inertia1
        + robot.m1 * robot.p1**2
        + robot.counter_mass_inertia_about_base()
        + robot.inertia_act
        + m_eq1 * l1**2
    )
    dx_n = -l1 * jnp.cos(th1 - th2) * (qd1 - qd2)
    dy_n = jnp.stack([-s2 * qd2, c2 * qd2, s * jnp.sin(th2 - th5) * (qd2 - ud[2]) * b], -1)
    qdd1 = (dy_n @ ud + y_n @ udd - dx_n * qd1) / x_n
    tau_2 = m_ii * qdd1
    # eqs (21)-(29)
    m_iii = robot.inertia2 - m_eq1 * p2**2 - m_eq2 * (l2 - p2) ** 2
    dx_t = -l1 * jnp.sin(th1 - th2) * (qd1 - qd2)
    dy_t = jnp.stack([-c2 * qd2, -s2 * qd2, s * jnp.cos(th2 - th5) * (qd2 - ud[2]) * b], -1)
    qdd2 = (-dx_t * qd1 - x_t * qdd1 + dy_t @ ud + y_t @ udd) / l2
    force_3 = m_iii * qdd2 / l2
    tau_3 = -x_t * force_3 + jt_star @ (y_t.T @ force_3)
    return (tau_1, tau_2, tau_3) if split else tau_1 + tau_2 + tau_3


def _reduced_forces(robot: DualV, pose, pose_d, pose_dd, branch):
    """``(q, q̇, q̈, G, Q)``: motion, IK Jacobian ``∂q/∂u`` and Lagrange forces."""
    q, qd, qdd = pose_motion(robot, pose, pose_d, pose_dd, branch=branch)
    g = jax.jacfwd(lambda u: robot.inverse_kinematics(u, branch=branch))(jnp.asarray(pose, float))
    forces = inverse_dynamics(robot, q, qd, qdd)
    return q, qd, qdd, g, forces


KEPT_BODIES = (0, 1, 2, 3, *range(8, 22))

#: relative residual of the Lagrange equations above which :func:`bearing_forces`
#: refuses its torques (exact torques leave ~1e-15)
BEARING_RTOL = 1e-9  # all bodies but links i2


class SplitModel(Robot):
    """The DUAL-V in the 7 coordinates ``x = (θ_11..θ_41, x5, y5, θ5)`` with each link i2
    replaced by its exact equivalent: point masses ``m_eq,i1`` at B_i (moves with θ_i1),
    ``m_eq,i2`` at C_i (moves with the platform) and a residual inertia
    ``I_i2 - m_i2·p_i2·(l_i2 - p_i2)`` turning with the direction of ``C_i - B_i``
    (a holonomic function of ``x``). Used to compute the paper's torque distribution by
    Lagrange/autodiff, independently of eqs (12)-(29).
    """

    robot: DualV
    #: the residual inertias of the exact split may be negative (checked finite only).
    signed_inertias: ClassVar[bool] = True

    @property
    def dof(self) -> int:
        return 7

    def end_effector(self, x) -> Float[Array, "3"]:
        """The platform pose ``(x5, y5, θ5)``, the last three coordinates."""
        return jnp.asarray(x, dtype=float)[4:7]

    def inverse_kinematics(self, pose, *, branch=None, return_valid: bool = False):
        """``x = (θ_11..θ_41, x5, y5, θ5)`` from the DUAL-V's inverse kinematics."""
        select = np.asarray([0, 1, 2, 3, 8, 9, 10])
        if return_valid:
            q, valid = self.robot.inverse_kinematics(pose, branch=branch, return_valid=True)
            return q[select], valid
        return self.robot.inverse_kinematics(pose, branch=branch)[select]

    def mass_properties(self) -> Bodies:
        r = self.robot
        full = r.mass_properties()
        keep = KEPT_BODIES
        m_eq1 = r.m2 * (1.0 - r.p2 / r.l2)
        m_eq2 = r.m2 * r.p2 / r.l2
        residual = r.inertia2 - r.m2 * r.p2 * (r.l2 - r.p2)
        zeros = jnp.zeros(4)
        extra = Bodies(
            mass=jnp.concatenate([m_eq1, m_eq2, zeros]),
            com=jnp.zeros((12, 3)),
            inertia=planar_inertia(jnp.concatenate([zeros, zeros, residual])),
            names=tuple(f"{kind}{i}" for kind in ("eq_B", "eq_C", "residual") for i in range(1, 5)),
        )
        index = np.asarray(keep)
        kept = Bodies(
            mass=full.mass[index],
            com=full.com[index],
            inertia=full.inertia[index],
            names=tuple(full.names[k] for k in keep),
        )
        return concatenate(kept, extra)

    def body_frames(self, x):
        r = self.robot
        x = jnp.asarray(x, dtype=float)
        theta1, pose = x[:4], x[4:7]
        elbows = r.base_pivots() + r.l1[:, None] * jnp.stack([jnp.cos(theta1), jnp.sin(theta1)], -1)
        ends = r.platform_joints(pose)
        link = ends - elbows
        phi = jnp.arctan2(link[:, 1], link[:, 0])
        origins, rotations = r.body_frames(jnp.concatenate([theta1, phi, pose]))
        keep = np.asarray(KEPT_BODIES)

        def planar(points):
            return jnp.concatenate([points, jnp.zeros((4, 1))], -1)

        extra_origins = jnp.concatenate([planar(elbows), planar(ends), planar(elbows)])
        extra_rotations = jnp.concatenate([rot_z(phi), rot_z(phi), rot_z(phi)])
        return (
            jnp.concatenate([origins[keep], extra_origins]),
            jnp.concatenate([rotations[keep], extra_rotations]),
        )


def virtual_work_torques(
    robot: DualV, pose, pose_d, pose_dd, branch=OUTWARD, distribution: str = "min_norm"
):
    """Actuator torques [N·m] by virtual work / Lagrange via autodiff (no eq 3-29).

    ``distribution="min_norm"``: ``τ = (Jᵀ)⁺ Gᵀ Q`` with ``Q`` the Lagrange forces of all
    22 bodies on the 11 coordinates, ``G = ∂q/∂u`` and ``J = G[:4]`` (autodiff of the IK):
    the minimum-norm torques of the whole robot.

    ``distribution="paper"``: Lagrange on :class:`SplitModel` (7 coordinates) gives the
    forces ``Q̃_a`` on the actuated angles and ``Q̃_u`` on the platform; the latter are
    distributed with minimum norm, ``τ = Q̃_a + (Jᵀ)⁺ Q̃_u`` -- the distribution of
    eqs (3)-(29).
    """
    if distribution == "min_norm":
        _, _, _, g, forces = _reduced_forces(robot, pose, pose_d, pose_dd, branch)
        return _pinv_transpose(g[:4]) @ (g.T @ forces)
    if distribution != "paper":
        raise ValueError(f"distribution must be 'min_norm' or 'paper', got {distribution!r}")
    q, qd, qdd = pose_motion(robot, pose, pose_d, pose_dd, branch=branch)
    select = jnp.array([0, 1, 2, 3, 8, 9, 10])
    split = inverse_dynamics(SplitModel(robot), q[select], qd[select], qdd[select])
    jacobian = robot.jacobian(q)
    return split[:4] + _pinv_transpose(jacobian) @ split[4:]


def torque_split(robot: DualV, q, tau):
    """``(range part, null part)`` of ``τ``: ``J^{T*}Jᵀτ`` (the minimum-norm torques with
    the same platform effect) and the internal preload ``τ - J^{T*}Jᵀτ``."""
    jac = robot.jacobian(q)
    ranged = _pinv_transpose(jac) @ (jac.T @ tau)
    return ranged, tau - ranged


def bearing_forces(robot: DualV, pose, pose_d, pose_dd, tau, branch=OUTWARD):
    """Forces ``F_A,i`` ``(4, 2)`` [N] that the base bearings exert on the arms at A_i.

    The robot pushes the base with ``-F_A,i``; ``-Σ F_A,i`` is the shaking force and
    ``Σ A_i × (-F_A,i) - Σ τ_i`` the shaking moment about the base origin.

    Args:
        tau: ``(4,)`` actuator torques that produce the motion (the distribution chosen
            fixes the preload), e.g. :func:`virtual_work_torques` plus a null-space part.

    Raises:
        ValueError: ``tau`` does not produce the motion (the Lagrange equations, solved
            for the bearing forces by least squares, leave a residual above
            :data:`BEARING_RTOL` of the forces): eagerly, under ``jit`` a runtime
            error. The paper's torques (eqs 3-29) on a robot whose equivalent masses
            differ at the platform's two ends gave bearing forces 3e-2 N·m off
            Newton–Euler without a word.
    """
    q, qd, qdd, _, forces = _reduced_forces(robot, pose, pose_d, pose_dd, branch)
    constraint_jacobian = jax.jacfwd(robot.constraint)(q)  # (8, 11)
    applied = jnp.zeros(11).at[:4].set(jnp.asarray(tau, dtype=float))
    unbalanced = forces - applied
    mu = jnp.linalg.lstsq(constraint_jacobian.T, unbalanced)[0]
    residual = jnp.max(jnp.abs(constraint_jacobian.T @ mu - unbalanced))
    scale = jnp.maximum(jnp.max(jnp.abs(forces)), jnp.max(jnp.abs(applied)))
    inexact = ~(residual <= BEARING_RTOL * scale)
    message = (
        "bearing_forces: the torques tau do not produce this motion (residual of the "
        "Lagrange equations [N·m or N]); give exact torques, e.g. virtual_work_torques "
        "plus a null-space preload"
    )
    mu = guard(mu, inexact, message, residual).reshape(4, 2)
    bodies = robot.mass_properties()

    def positions(q_):
        return body_com_positions(robot, q_)[:, :2]

    def velocities(q_, qd_):
        return jax.jvp(positions, (q_,), (qd_,))[1]

    accelerations = jax.jvp(velocities, (q, qd), (qd, qdd))[1]
    momentum_rate = bodies.mass[:, None] * accelerations  # (22, 2)
    arm_rate = jnp.sum(momentum_rate[ARM_BODIES], axis=1)  # (4, 2)
    return arm_rate - mu


def base_wrench_from_bearings(robot: DualV, bearing, tau) -> tuple[Float[Array, "2"], Array]:
    """Shaking force ``(2,)`` [N] and moment [N·m] on the base from the bearing forces
    and the stator reactions (check of :func:`bearing_forces`)."""
    on_base = -bearing
    pivots = robot.base_pivots()
    moment = jnp.sum(pivots[:, 0] * on_base[:, 1] - pivots[:, 1] * on_base[:, 0]) - jnp.sum(tau)
    return jnp.sum(on_base, axis=0), moment


def forward_accelerations(robot: DualV, q, qd, tau):
    """Forward dynamics: ``(q̈ (11,), μ (4, 2))`` for actuator torques ``τ`` at ``(q, q̇)``.

    Solves ``M q̈ + h = Bᵀτ + Φ_qᵀμ`` with ``Φ_q q̈ = -(dΦ_q/dt) q̇`` (loop closures of
    :meth:`DualV.constraint`); ``M`` and ``h`` from Lagrange over all bodies (autodiff).
    Used to validate the inverse model as the paper does with Spacar (Fig 6).
    """
    q, qd, tau = (jnp.asarray(v, dtype=float) for v in (q, qd, tau))
    mass = mass_matrix(robot, q)
    bias = inverse_dynamics(robot, q, qd, jnp.zeros_like(q))
    phi_q = jax.jacfwd(robot.constraint)(q)

    def constraint_rate(q_):
        return jax.jvp(robot.constraint, (q_,), (qd,))[1]

    gamma = jax.jvp(constraint_rate, (q,), (qd,))[1]
    kkt = jnp.block([[mass, -phi_q.T], [phi_q, jnp.zeros((8, 8))]])
    rhs = jnp.concatenate([jnp.zeros(11).at[:4].set(tau) - bias, -gamma])
    solution = jnp.linalg.solve(kkt, rhs)
    return solution[:11], solution[11:].reshape(4, 2)


class MotionSample(NamedTuple):
    """Everything the paper plots for one instant of a platform motion.

    Attributes:
        shaking_force: ``(2,)`` force on the base [N].
        shaking_moment: moment on the base about its origin [N·m].
        torques: ``(4,)`` actuator torques of eqs (3)-(29) [N·m] (exact where eq 10
            is: equal equivalent masses at the platform's two ends, Table 1).
        torques_min_norm: ``(4,)`` minimum-norm actuator torques [N·m] (exact).
        bearing: ``(4, 2)`` bearing forces at A_i with the paper's torques made exact
            (:func:`evaluate`) [N].
    """

    shaking_force: Array
    shaking_moment: Array
    torques: Array
    torques_min_norm: Array
    bearing: Array


def evaluate(robot: DualV, pose, pose_d, pose_dd, branch=OUTWARD) -> MotionSample:
    """Shaking wrench, actuator torques and bearing forces at one instant (vmap it).

    The bearing forces are those of the paper's torques made exact: their preload (null
    part) kept, their platform part the exact minimum-norm torques'. Where eq (10) is
    exact (equal equivalent masses at the platform's two ends, Table 1) these are the
    paper's torques themselves; where it is not, the paper's torques do not produce the
    motion and would give bearing forces off Newton–Euler."""
    q, qd, qdd = pose_motion(robot, pose, pose_d, pose_dd, branch=branch)
    force, moment = shaking_wrench(robot, q, qd, qdd)
    tau = paper_torques(robot, q, pose_d, pose_dd)
    min_norm = virtual_work_torques(robot, pose, pose_d, pose_dd, branch)
    _, preload = torque_split(robot, q, tau)
    bearing = bearing_forces(robot, pose, pose_d, pose_dd, min_norm + preload, branch)
    return MotionSample(force[:2], moment[2], tau, min_norm, bearing)
