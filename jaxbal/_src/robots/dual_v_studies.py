"""DUAL-V studies: the motions of van der Wijk et al. (2013) and what they measure on them.

* Motions (platform samples ``(u, u̇, ü)``, each ``(t, 3)``): the rest-to-rest moves along
  the orthogonal axes (Figs 9, 11), the smooth triangle of Fig 12 and a move reaching the
  peak accelerations of the Fig 6 validation (§4.2). Every side is a
  :class:`jaxbal.StraightLine` with the quintic profile, whose peak acceleration is
  ``10·S/(√3·T²)`` for a stroke ``S`` in ``T`` seconds (:func:`quintic_duration`).
* Evaluation along a motion (:func:`evaluate_motion`, :func:`motion_peaks`) and the
  balanced/unbalanced ratios of torques, bearing forces and shaking moment
  (:func:`balancing_ratios`, Figs 12-14).
* Checks of the inverse dynamic model eqs (3)-(29): forward dynamics returns the
  prescribed accelerations (:func:`forward_dynamics_error`, the Spacar check of Fig 6)
  and two Lagrange/autodiff computations agree with it (:func:`torque_model_check`).
* Eq (30): the exact gradients of the shaking force with respect to the counter-mass
  moments and the payload (:func:`eq30_sensitivity`).
* The counter-mass co-design over inertia-penalty weights (:func:`codesign_trade`).

References:
    van der Wijk, Krut, Pierrot & Herder (2013), §4.2, §5-§7, eqs (3)-(30), Figs 6, 9,
    11-14.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.metrics import Motion
from jaxbal._src.momentum import shaking_wrench
from jaxbal._src.motion import pose_motion
from jaxbal._src.optimize import Solution, minimize
from jaxbal._src.profiles import Quintic
from jaxbal._src.robots.dual_v import OUTWARD, DualV
from jaxbal._src.robots.dual_v_balancing import codesign_loss, counter_mass_design
from jaxbal._src.robots.dual_v_dynamics import (
    MotionSample,
    evaluate,
    forward_accelerations,
    paper_torques,
    torque_split,
    virtual_work_torques,
)
from jaxbal._src.sensitivity import sensitivity
from jaxbal._src.trajectory import StraightLine, sample, sample_times
from jaxbal._src.types import Array, Float, Scalar

__all__ = [
    "TEST_CIRCLE_RADIUS",
    "BalancingRatios",
    "CodesignPoint",
    "Eq30Sensitivity",
    "Peaks",
    "TorqueCheck",
    "balancing_ratios",
    "codesign_trade",
    "eq30_sensitivity",
    "evaluate_motion",
    "forward_dynamics_error",
    "joint_states",
    "motion_peaks",
    "orthogonal_motion",
    "quintic_duration",
    "torque_model_check",
    "triangle_motion",
    "triangle_vertices",
    "validation_motion",
    "workspace_widths",
]

#: radius of the 0.2 m diameter test circle of §5 [m].
TEST_CIRCLE_RADIUS = 0.1

#: a sampled platform motion ``(u, u̇, ü)``, each ``(t, 3)`` [m, m, rad and per s, s²].
PoseMotion = tuple[Float[Array, "t 3"], Float[Array, "t 3"], Float[Array, "t 3"]]

# --- motions -----------------------------------------------------------------------------


def quintic_duration(stroke, peak_acceleration):
    """Duration ``T = sqrt(10·S/(√3·a))`` [s] of a rest-to-rest quintic move of stroke
    ``S`` [m] whose peak acceleration is ``a`` [m/s²] (``s̈ = 10/√3`` at its peak)."""
    return np.sqrt(10.0 * stroke / (np.sqrt(3.0) * peak_acceleration))


def triangle_vertices(radius: float = TEST_CIRCLE_RADIUS) -> np.ndarray:
    """``(3, 3)`` vertices of the equilateral triangle inscribed in the test circle, apex
    at ``(0, -radius)`` (side ``radius·√3``, platform not rotated) [m, m, rad]."""
    half = radius * np.sqrt(3.0) / 2.0
    return np.array([[0.0, -radius, 0.0], [half, radius / 2, 0.0], [-half, radius / 2, 0.0]])


def triangle_motion(samples: int, side_time: float, radius=TEST_CIRCLE_RADIUS) -> PoseMotion:
    """The smooth triangle of Fig 12: each side a rest-to-rest quintic straight line in
    ``side_time`` [s], ``samples`` per side (``3·samples`` in all). Its peak
    accelerations are ``10·S/(√3·T²)`` along x and ``√3/2`` of that along y."""
    vertices = triangle_vertices(radius)
    pieces = [
        sample(
            StraightLine(vertices[k], vertices[(k + 1) % 3], Quintic(), side_time),
            sample_times(side_time, samples),
        )
        for k in range(3)
    ]
    return tuple(jnp.concatenate([p[i] for p in pieces]) for i in range(3))


def orthogonal_motion(axis: int, peak_acceleration, stroke: float, samples: int) -> PoseMotion:
    """Rest-to-rest quintic move of ``stroke`` [m] centred on the origin along x
    (``axis=0``) or y (``1``), reaching ``peak_acceleration`` [m/s²] (Figs 9, 11)."""
    duration = quintic_duration(stroke, peak_acceleration)
    start = np.zeros(3)
    start[axis] = -stroke / 2
    line = StraightLine(start, -start, Quintic(), duration)
    return sample(line, sample_times(duration, samples))


def validation_motion(samples: int = 101, duration=0.05, peaks=(118.0, 202.0, 1612.0)):
    """One quintic line with rotation reaching the peak accelerations ``(ẍ5, ÿ5, θ̈5)``
    [m/s², m/s², rad/s²] of the Fig 6 validation (§4.2) in ``duration`` [s] (the paper's
    path is not given)."""
    stroke = np.array(peaks) * np.sqrt(3.0) * duration**2 / 10.0
    line = StraightLine(-stroke / 2, stroke / 2, Quintic(), duration)
    return sample(line, sample_times(duration, samples))


# --- evaluation along a motion -----------------------------------------------------------


@eqx.filter_jit
def joint_states(robot: DualV, motion: PoseMotion, branch=OUTWARD) -> tuple:
    """``(q, q̇, q̈)``, each ``(t, 11)``, along a sampled platform motion (exact IK)."""
    return jax.vmap(lambda a, b, c: pose_motion(robot, a, b, c, branch=branch))(*motion)


@eqx.filter_jit
def evaluate_motion(robot: DualV, motion: PoseMotion, branch=OUTWARD) -> MotionSample:
    """:func:`~jaxbal.robots.dual_v_dynamics.evaluate` at every sample: shaking force
    ``(t, 2)`` [N] and moment ``(t,)`` [N·m], torques ``(t, 4)`` [N·m] of eqs (3)-(29)
    and minimum-norm, bearing forces ``(t, 4, 2)`` [N]."""
    return jax.vmap(lambda a, b, c: evaluate(robot, a, b, c, branch))(*motion)


class Peaks(NamedTuple):
    """Peaks over a motion of a :class:`MotionSample` history.

    Attributes:
        force: ``(2,)`` ``max_t |F_x|, max_t |F_y|`` [N].
        force_norm: ``max_t ‖F‖`` [N].
        moment: ``max_t |M|`` [N·m].
        torques, torques_min_norm: ``(4,)`` ``max_t |τ_i|`` [N·m].
        bearing: ``(4,)`` ``max_t ‖F_A,i‖`` [N].
    """

    force: Array
    force_norm: Scalar
    moment: Scalar
    torques: Array
    torques_min_norm: Array
    bearing: Array


def motion_peaks(history: MotionSample) -> Peaks:
    """The :class:`Peaks` of a history from :func:`evaluate_motion`."""
    return Peaks(
        force=jnp.max(jnp.abs(history.shaking_force), axis=0),
        force_norm=jnp.max(jnp.linalg.norm(history.shaking_force, axis=-1)),
        moment=jnp.max(jnp.abs(history.shaking_moment)),
        torques=jnp.max(jnp.abs(history.torques), axis=0),
        torques_min_norm=jnp.max(jnp.abs(history.torques_min_norm), axis=0),
        bearing=jnp.max(jnp.linalg.norm(history.bearing, axis=-1), axis=0),
    )


class BalancingRatios(NamedTuple):
    """What balancing costs and gains on one motion (van der Wijk et al. 2013, §7).

    Attributes:
        torque: ``(4,)`` peak torque balanced / unbalanced (Fig 13: 1.42, 1.42, 1.47, 1.47).
        torque_mean: their mean (paper: 1.4 theoretical, 1.6 measured).
        bearing_reduction: ``(4,)`` ``1 -`` peak bearing force balanced / unbalanced
            (Fig 14: 0.73, 0.73, 0.69, 0.69).
        moment_reduction: ``1 -`` peak shaking moment balanced / unbalanced (0.12).
    """

    torque: Array
    torque_mean: Scalar
    bearing_reduction: Array
    moment_reduction: Scalar


def balancing_ratios(balanced: Peaks, unbalanced: Peaks) -> BalancingRatios:
    """The :class:`BalancingRatios` of two robots' :class:`Peaks` on the same motion."""
    torque = balanced.torques / unbalanced.torques
    return BalancingRatios(
        torque=torque,
        torque_mean=jnp.mean(torque),
        bearing_reduction=1 - balanced.bearing / unbalanced.bearing,
        moment_reduction=1 - balanced.moment / unbalanced.moment,
    )


def workspace_widths(robot: DualV) -> tuple[Scalar, Scalar]:
    """Widths [m] of the workspace of a non-rotated platform along x and y:
    ``2(l_i1 + l_i2 - a)`` and ``2·sqrt((l_i1 + l_i2)² - a²)`` (§2: 0.328 and 0.792 m)."""
    reach = robot.l1[0] + robot.l2[0]
    return 2 * (reach - robot.a), 2 * jnp.sqrt(reach**2 - robot.a**2)


# --- checks of the inverse dynamic model ---------------------------------------------------


@eqx.filter_jit
def forward_dynamics_error(robot: DualV, motion: PoseMotion) -> Scalar:
    """Largest error of the joint accelerations that forward dynamics (all 22 bodies)
    returns for the torques of eqs (3)-(29), relative to the largest prescribed one [-]:
    the check the paper makes with Spacar (Fig 6)."""

    def one(u, ud, udd):
        q, qd, qdd = pose_motion(robot, u, ud, udd)
        recovered, _ = forward_accelerations(robot, q, qd, paper_torques(robot, q, ud, udd))
        return jnp.max(jnp.abs(recovered - qdd)), jnp.max(jnp.abs(qdd))

    error, scale = jax.vmap(one)(*motion)
    return jnp.max(error) / jnp.max(scale)


class TorqueCheck(NamedTuple):
    """Result of :func:`torque_model_check`, maxima over the motion.

    Attributes:
        split_model: ``max |τ eqs (3-29) - τ Lagrange on the split model|`` [N·m].
        platform_effect: ``max |Jᵀ(τ eqs (3-29) - τ min-norm Lagrange)|`` [N, N·m].
        preload: largest internal preload along ``null(Jᵀ)`` / largest ``|τ|`` [-].
    """

    split_model: Scalar
    platform_effect: Scalar
    preload: Scalar


@eqx.filter_jit
def torque_model_check(robot: DualV, motion: PoseMotion) -> TorqueCheck:
    """Eqs (3)-(29) against two independent Lagrange/autodiff computations (see
    :mod:`jaxbal.robots.dual_v_dynamics`)."""

    def one(u, ud, udd):
        q, _, _ = pose_motion(robot, u, ud, udd)
        tau = paper_torques(robot, q, ud, udd)
        split = virtual_work_torques(robot, u, ud, udd, distribution="paper")
        minimum_norm = virtual_work_torques(robot, u, ud, udd)
        jacobian = robot.jacobian(q)
        preload = tau - torque_split(robot, q, tau)[0]
        return (
            jnp.max(jnp.abs(tau - split)),
            jnp.max(jnp.abs(jacobian.T @ (tau - minimum_norm))),
            jnp.max(jnp.abs(preload)),
            jnp.max(jnp.abs(tau)),
        )

    split, power, preload, peak = jax.vmap(one)(*motion)
    return TorqueCheck(jnp.max(split), jnp.max(power), jnp.max(preload) / jnp.max(peak))


# --- eq (30): sensitivity to the counter-mass moments and the payload ---------------------


class Eq30Sensitivity(NamedTuple):
    """Exact gradients of the shaking force ``F_x`` at the instant of peak ``|ẍ5|``.

    Attributes:
        moment: ``Σ_i ∂F_x/∂(m_cm,i·p_cm,i) / ẍ5`` [1/m] (eq 30: ``2/l_i1``).
        payload: ``-∂F_x/∂payload / ẍ5`` [-] (eq 30: 1).
        tuning_equivalent: payload [kg] with the effect of removing the four tuning
            masses, ``-m_tun·p_tun·Σ_i ∂F_x/∂μ_i / ∂F_x/∂payload`` (paper 0.107 kg).
        acceleration: ``ẍ5`` at that instant [m/s²].
    """

    moment: Scalar
    payload: Scalar
    tuning_equivalent: Scalar
    acceleration: Scalar


def _force_x(robot: DualV, motion: Motion) -> Scalar:
    """``F_x`` [N] at the first sample of ``motion`` (a metric of jaxbal.sensitivity)."""
    return shaking_wrench(robot, motion.q[0], motion.qd[0], motion.qdd[0])[0][0]


def eq30_sensitivity(robot: DualV, motion: PoseMotion, check: bool = False) -> Eq30Sensitivity:
    """Eq (30) by automatic differentiation (:func:`jaxbal.sensitivity.sensitivity` with
    respect to ``counter_distance`` and ``payload``; ``check``: against central finite
    differences). ``F_x`` is linear in both, so the gradients hold for any change.

    ``∂F_x/∂μ_i = (∂F_x/∂p_cm,i)/m_cm,i`` with ``μ_i = m_cm,i·p_cm,i`` (mounted mass kept).
    """
    index = int(jnp.argmax(jnp.abs(motion[2][:, 0])))
    u, ud, udd = (m[index] for m in motion)
    states = Motion(*(x[None] for x in pose_motion(robot, u, ud, udd)))
    result = sensitivity(robot, states, _force_x, wrt=("counter_distance", "payload"), check=check)
    per_moment = result.gradient["counter_distance"] / robot.design()["counter_mass"]
    d_payload = result.gradient["payload"]
    acceleration = udd[0]
    tuning = robot.m_tun * robot.p_tun
    return Eq30Sensitivity(
        moment=jnp.sum(per_moment) / acceleration,
        payload=-d_payload / acceleration,
        tuning_equivalent=-jnp.sum(tuning * per_moment) / d_payload,
        acceleration=acceleration,
    )


# --- counter-mass co-design ------------------------------------------------------------------


class CodesignPoint(NamedTuple):
    """One point of :func:`codesign_trade`.

    Attributes:
        weight: inertia-penalty weight ``w`` [-].
        peak_force: ``max_t ‖F‖`` on the evaluation motion [N].
        peak_torque: ``max_{t,i} |τ_i|`` of eqs (3)-(29) on it [N·m].
        mean_moment: mean ``m_cm,i·p_cm,i`` of the design [kg·m].
        robot: the designed robot.
        solution: the L-BFGS :class:`jaxbal.Solution`.
    """

    weight: float
    peak_force: Scalar
    peak_torque: Scalar
    mean_moment: Scalar
    robot: DualV
    solution: Solution


def codesign_trade(
    robot: DualV,
    weights,
    design_motion: PoseMotion,
    evaluation_motion: PoseMotion,
    start=None,
    max_steps: int = 400,
    gtol: float = 1e-13,
) -> list[CodesignPoint]:
    """Counter-mass co-design for each inertia-penalty weight: L-BFGS on
    :func:`~jaxbal.robots.dual_v_balancing.codesign_loss` over ``(log m_cm, log p_cm)``
    (mean squared shaking force on ``design_motion`` + ``w·Σ(I_cm,i + m_cm,i·p_cm,i²)``),
    each design then evaluated on ``evaluation_motion``. Default start: 4 kg at 0.05 m
    on every arm. With ``w = 0`` it lands on the balance line of eq (1) (see
    :func:`~jaxbal.robots.dual_v_balancing.balance_line_offsets`)."""
    if start is None:
        start = (jnp.log(jnp.full(4, 4.0)), jnp.log(jnp.full(4, 0.05)))
    states = jax.vmap(lambda a, b, c: pose_motion(robot, a, b, c))(*design_motion)
    points = []
    for weight in weights:
        args = (robot, states, jnp.asarray(weight))
        solution = minimize(codesign_loss, start, max_steps=max_steps, gtol=gtol, args=args)
        design = counter_mass_design(robot, solution.params)
        force, torque = _force_and_torque_peaks(design, evaluation_motion)
        moment = jnp.mean(design.m_cm * design.p_cm)
        points.append(CodesignPoint(weight, force, torque, moment, design, solution))
    return points


@eqx.filter_jit
def _force_and_torque_peaks(robot: DualV, motion: PoseMotion) -> tuple[Scalar, Scalar]:
    """``(max_t ‖F‖ [N], max_{t,i} |τ_i| [N·m])``, torques of eqs (3)-(29)."""

    def one(u, ud, udd):
        q, qd, qdd = pose_motion(robot, u, ud, udd)
        return shaking_wrench(robot, q, qd, qdd)[0][:2], paper_torques(robot, q, ud, udd)

    force, tau = jax.vmap(one)(*motion)
    return jnp.max(jnp.linalg.norm(force, axis=-1)), jnp.max(jnp.abs(tau))
