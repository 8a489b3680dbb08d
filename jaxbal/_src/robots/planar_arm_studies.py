"""Studies of Briot, Arakelian & Le Baron (2012) on the planar 2R and 3R arms: the three
motion laws between two test points of the square workspace, and the input torques.

Between two end-effector points (and, for the 3R, from φ_0 to φ_f) in a time T:

1. ``case1``: quintic profile on the end-effector straight line (and on φ);
2. ``case2``: bang-bang profile on the straight line of the total centre of mass
   (eqs 3-4), the least peak shaking force for the given T. For the 3R, the free angle
   φ(t) follows a degree-8 polynomial meeting the boundary conditions (20), whose three
   free coefficients minimise the peak shaking moment, eq (19)
   (:func:`optimal_phi_coefficients`: optax L-BFGS on a smoothed maximum with
   continuation in the smoothing, from the quintic and from seeded random starts);
3. ``case3``: trapezoidal acceleration on the same COM line, its switch times chosen
   under ``|dτ_i/dt| ≤ τ̇_max`` (eqs 5-6, :func:`jaxbal.planning.plan_rate_limited`),
   with case 2's φ law.

:func:`motion_laws` builds all three; :func:`input_torques` gives the actuator torques
of §3.3 and Fig 11 (the unbalanced arm, the arm with counterweights, the COM plans).

References:
    Briot, S., Arakelian, V., Le Baron, J.-P. (2012). Shaking force minimization of
    high-speed robots via centre of mass acceleration control. Mech. Mach. Theory 57,
    1-12. Eqs (3)-(6), (19)-(20), §3.1-3.3, Tables 1-3, Figs 5, 9-11.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.momentum import center_of_mass, shaking_wrench
from jaxbal._src.optimize import minimize
from jaxbal._src.planning import (
    ComLine,
    EndEffectorLine,
    com_line,
    smooth_peak,
    torques_along,
    wrench_along,
)
from jaxbal._src.profiles import BangBang, BoundaryPolynomial, Profile, Quintic
from jaxbal._src.rate_limit import RateLimitedPlan, plan_rate_limited
from jaxbal._src.robots.planar_arm import PlanarArm, force_balanced
from jaxbal._src.trajectory import StraightLine, sample, sample_times
from jaxbal._src.types import Array, Float
from jaxbal._src.validation import runtime_checks

__all__ = [
    "TEMPERATURES",
    "ComPath",
    "MotionLaws",
    "input_torques",
    "moment_objective",
    "motion_laws",
    "optimal_phi_coefficients",
]

#: Smoothing continuation of eq (19): temperatures τ [N·m] of ``τ·logsumexp(|m|/τ)``.
TEMPERATURES = (3.0, 1.0, 0.3, 0.1, 0.03)


class ComPath(eqx.Module):
    """``(profile, data) ↦`` the COM straight line with ``profile`` (a
    :class:`~jaxbal.planning.ComLine`), the ``make_path`` of
    :func:`~jaxbal.planning.plan_rate_limited`.

    ``data = (robot, start, end)``, or ``(robot, start, end, coefficients)`` for the 3R
    with φ(t) the degree-8 polynomial from ``phi[0]`` to ``phi[1]`` [rad] with zero
    velocity and acceleration at both ends and free coefficients ``coefficients``
    (eq 20). The fields are static, so equal paths share compiled code.

    Attributes:
        duration: T [s].
        branch: working mode of the COM inverse kinematics (``+1``: "+" of eqs 10, 15).
        phi: ``(φ_0, φ_f)`` [rad] for the 3R, else ``None``.
    """

    duration: float = eqx.field(static=True)
    branch: int = eqx.field(static=True, default=1)
    phi: tuple[float, float] | None = eqx.field(static=True, default=None)

    def phi_law(self, coefficients) -> StraightLine:
        """φ(t) of eq (20) for the free coefficients ``coefficients``."""
        profile = BoundaryPolynomial(coefficients)
        return StraightLine(self.phi[0], self.phi[1], profile, self.duration)

    def __call__(self, profile: Profile, data) -> ComLine:
        robot, start, end, *coefficients = data
        line = StraightLine(start, end, profile, self.duration)
        free = self.phi_law(coefficients[0]) if coefficients else None
        return ComLine(robot, line, free=free, branch=self.branch)


class MotionLaws(NamedTuple):
    """Result of :func:`motion_laws`.

    Attributes:
        trajectories: ``{"case1", "case2", "case3"} ↦`` joint trajectory ``t ↦ q``.
        plan: the rate-limited trapezoid of case 3 (switch times, peak rate).
        coefficients: ``(3,)`` φ-law coefficients of cases 2-3 (3R), else ``None``.
    """

    trajectories: dict
    plan: RateLimitedPlan
    coefficients: Float[Array, "3"] | None


def moment_objective(coefficients, robot: PlanarArm, start, end, temperature, path, samples):
    """Smoothed ``max_t |m_sh,z(t)|`` [N·m] of case 2 for the φ-law ``coefficients``
    (eq 19), on ``samples`` instants; ``path`` a 3R :class:`ComPath`."""
    times = sample_times(path.duration, samples)
    q, qd, qdd = sample(path(BangBang(), (robot, start, end, coefficients)), times, order=2)
    # the wrench traced here, not through the compiled `wrench_along`: a trace of it made
    # with the runtime checks on (any earlier call) would be reused inside the optimiser,
    # which traces with them off (the flag is not part of jit's cache key)
    _, moments = jax.vmap(lambda a, b, c: shaking_wrench(robot, a, b, c))(q, qd, qdd)
    return smooth_peak(moments[:, 2], temperature)


def optimal_phi_coefficients(
    robot: PlanarArm,
    start,
    end,
    path: ComPath,
    starts: int = 3,
    seed: int = 2012,
    temperatures=TEMPERATURES,
    samples: int = 401,
) -> Float[Array, "3"]:
    """The φ-law coefficients that minimise the peak shaking moment of case 2, eq (19).

    For each start (the quintic law, then ``starts − 1`` random laws drawn with
    ``seed``), optax L-BFGS (60 steps) minimises :func:`moment_objective` for each
    temperature of ``temperatures`` in turn; the start whose true maximum ``|m_z|`` on
    ``samples`` instants is least and whose COM targets are all reachable wins.

    Args:
        robot: the 3R arm.
        start, end: ``(2,)`` COM endpoints [m].
        path: the 3R :class:`ComPath` (duration, branch, φ endpoints).
    """
    times = sample_times(path.duration, samples)
    rng = np.random.default_rng(seed)
    best, best_peak = jnp.zeros(3), np.inf
    for index in range(starts):
        coefficients = jnp.asarray(rng.normal(0.0, 30.0, 3) if index else best)
        for temperature in temperatures:
            args = (robot, start, end, jnp.asarray(temperature), path, samples)
            # runtime checks off: a line-search trial may move the COM line out of reach
            # (the COM IK refuses it under jit); a start is kept only if its final plan
            # is reachable at every instant (below)
            with runtime_checks(False):
                solution = minimize(
                    moment_objective, coefficients, max_steps=60, gtol=1e-9, args=args
                )
            if bool(jnp.all(jnp.isfinite(solution.params))):
                coefficients = solution.params
        trajectory = path(BangBang(), (robot, start, end, coefficients))
        peak = float(jnp.max(jnp.abs(wrench_along(robot, trajectory, times)[1][:, 2])))
        if peak < best_peak and bool(jnp.all(trajectory.valid(times))):
            best, best_peak = coefficients, peak
    return best


def motion_laws(
    robot: PlanarArm,
    point_a,
    point_b,
    duration: float,
    rate_limit: float,
    phi: tuple[float, float] | None = None,
    elbow: int = -1,
    com_branch: int = 1,
    check_samples: int = 2001,
) -> MotionLaws:
    """Cases 1-3 of Briot et al. (2012) between two end-effector points.

    Args:
        robot: the 2R or 3R arm.
        point_a, point_b: ``(2,)`` end-effector points [m].
        duration: T [s].
        rate_limit: ``τ̇_max`` of case 3 [N·m/s].
        phi: ``(φ_0, φ_f)`` [rad], required for the 3R.
        elbow: branch of the end-effector inverse kinematics whose COM inverse
            kinematics is the ``com_branch`` mode (−1 with +1 on the test squares).
        com_branch: working mode of eqs (10), (15) (``+1``: the paper's "+").
        check_samples: instants at which the 3R's COM targets must be reachable.

    Raises:
        ValueError: eagerly, when the optimised φ law leaves the reachable COM region
            or no trapezoid meets the rate limit.
    """
    three = robot.n_links == 3
    if three != (phi is not None):
        raise ValueError("phi = (φ_0, φ_f) is required for the 3R and only for it")
    pose_a = jnp.array([*point_a, phi[0]]) if three else jnp.asarray(point_a, dtype=float)
    pose_b = jnp.array([*point_b, phi[1]]) if three else jnp.asarray(point_b, dtype=float)
    q_a = robot.inverse_kinematics(pose_a, branch=elbow)
    q_b = robot.inverse_kinematics(pose_b, branch=elbow)
    path = ComPath(duration, com_branch, phi)
    if three:
        start, end = center_of_mass(robot, q_a)[:2], center_of_mass(robot, q_b)[:2]
        coefficients = optimal_phi_coefficients(robot, start, end, path)
        data, case2 = (robot, start, end, coefficients), None
    else:
        case2 = com_line(robot, q_a, q_b, BangBang(), duration, branch=com_branch)
        data, coefficients = (robot, case2.line.start, case2.line.end), None
    plan = plan_rate_limited(robot, path, data, duration, rate_limit)
    line = StraightLine(pose_a, pose_b, Quintic(), duration)
    trajectories = {
        "case1": EndEffectorLine(robot, line, elbow),
        "case2": path(BangBang(), data) if three else case2,
        "case3": path(plan.profile, data),
    }
    if three and not bool(
        jnp.all(trajectories["case2"].valid(sample_times(duration, check_samples)))
    ):
        raise ValueError("the optimised φ law leaves the reachable COM region")
    return MotionLaws(trajectories, plan, coefficients)


def input_torques(
    robot: PlanarArm, laws: MotionLaws, counter_distances, times, elbow: int = -1
) -> dict:
    """Actuator torques ``(t, n)`` [N·m] along the motion laws of one path (§3.3, Fig 11).

    ``unbalanced``: case 1; ``counterweights``: case 1 on the arm force-balanced by
    counterweights at ``counter_distances`` behind each joint
    (:func:`~jaxbal.robots.planar_arm.force_balanced`); ``com_bang_bang`` and
    ``com_trapezoid``: cases 2 and 3 on the unbalanced arm.
    """
    balanced = force_balanced(robot, counter_distances)
    case1 = laws.trajectories["case1"]
    models = {
        "unbalanced": (robot, case1),
        "counterweights": (balanced, EndEffectorLine(balanced, case1.line, elbow)),
        "com_bang_bang": (robot, laws.trajectories["case2"]),
        "com_trapezoid": (robot, laws.trajectories["case3"]),
    }
    return {name: torques_along(model, path, times) for name, (model, path) in models.items()}
