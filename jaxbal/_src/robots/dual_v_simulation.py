"""DUAL-V in MuJoCo: open-loop forward simulation of jaxbal's torques, the check of van
der Wijk et al. (2013), Fig 6, with MuJoCo in place of Spacar.

:func:`confirm_motions` compares jaxbal's shaking force and moment with MuJoCo's (or MJX's)
base reaction along sampled platform motions (:func:`jaxbal.mujoco.confirm`).

The platform follows a path of rest-to-rest quintic moves (:class:`QuinticMoves`);
the torques of eqs (3)-(29) or the minimum-norm Lagrange torques along it
(:func:`torque_law`) drive MuJoCo's DUAL-V open-loop (:func:`open_loop_tracking`,
through :func:`jaxbal.mujoco.simulate_open_loop`). The tracking error is time
discretisation when it falls as ``dt^p`` with the step: :func:`open_loop_convergence`
runs several steps and extrapolates to ``dt → 0`` (Richardson) from the two finest.

MuJoCo is imported on first use (slow to import).

References:
    van der Wijk, Krut, Pierrot & Herder (2013), §3.3 and Fig 6;
    Richardson & Gaunt (1927), extrapolation to the limit.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.profiles import Quintic
from jaxbal._src.robots.dual_v import DualV
from jaxbal._src.robots.dual_v_dynamics import paper_torques, virtual_work_torques
from jaxbal._src.robots.dual_v_studies import joint_states
from jaxbal._src.trajectory import time_derivatives
from jaxbal._src.types import Array, Float, ScalarLike

if TYPE_CHECKING:
    from jaxbal.mujoco import Confirmation, Tracking

__all__ = [
    "PLATFORM_JOINTS",
    "TORQUE_MODELS",
    "OpenLoopConvergence",
    "QuinticMoves",
    "confirm_motions",
    "open_loop_convergence",
    "open_loop_tracking",
    "torque_law",
]

#: MuJoCo joint names of the platform pose ``(x5, y5, θ5)``.
PLATFORM_JOINTS = ("x5", "y5", "theta5")
#: the torque distributions :func:`torque_law` knows.
TORQUE_MODELS = ("paper", "min_norm")


class QuinticMoves(eqx.Module):
    """Platform pose ``t ↦ u(t)`` [m, m, rad] through ``waypoints`` ``(k + 1, 3)``: move
    ``j`` goes from waypoint ``j`` to ``j + 1`` with the quintic profile in
    ``durations[j]`` seconds, at rest at every waypoint (then held at the last one)."""

    waypoints: Float[Array, "k 3"]
    durations: tuple[float, ...] = eqx.field(static=True)

    def __init__(self, waypoints, durations):
        self.waypoints = jnp.asarray(waypoints, dtype=float)
        self.durations = tuple(float(d) for d in durations)
        if self.waypoints.ndim != 2 or self.waypoints.shape[0] != len(self.durations) + 1:
            raise ValueError(
                f"need len(durations) + 1 waypoints (k + 1, 3), got {self.waypoints.shape} "
                f"for {len(self.durations)} durations"
            )

    @property
    def duration(self) -> float:
        """Total duration [s]."""
        return sum(self.durations)

    def __call__(self, t: ScalarLike) -> Float[Array, "3"]:
        profile = Quintic()
        pose, begin = self.waypoints[0], 0.0
        for j, duration in enumerate(self.durations):
            elapsed = t if j == 0 else t - begin
            progress = profile(jnp.clip(elapsed / duration, 0.0, 1.0))
            pose = pose + progress * (self.waypoints[j + 1] - self.waypoints[j])
            begin += duration
        return pose


def torque_law(robot: DualV, pose_path: Callable, model: str = "paper") -> Callable:
    """``t ↦ τ (4,)`` [N·m] along the pose path (exact time derivatives by ``jvp``):
    ``"paper"``, eqs (3)-(29); ``"min_norm"``, the minimum-norm Lagrange torques of all
    22 bodies (:func:`~jaxbal.robots.dual_v_dynamics.virtual_work_torques`). Both give
    the same platform motion; they differ by an internal preload along ``null(Jᵀ)``."""
    if model == "paper":

        def paper(t):
            u, ud, udd = time_derivatives(pose_path, t, 2)[:3]
            return paper_torques(robot, robot.inverse_kinematics(u), ud, udd)

        return paper
    if model == "min_norm":

        def minimum_norm(t):
            return virtual_work_torques(robot, *time_derivatives(pose_path, t, 2)[:3])

        return minimum_norm
    raise ValueError(f"model must be one of {TORQUE_MODELS}, got {model!r}")


def open_loop_tracking(
    robot: DualV,
    pose_path: Callable,
    duration: float,
    model: str = "paper",
    timestep: float = 1e-4,
    record_every: int = 10,
    effort_scale: float = 1.0,
) -> Tracking:
    """MuJoCo's DUAL-V driven open-loop by :func:`torque_law` along ``pose_path`` for
    ``duration`` [s], its platform pose compared with the plan (a
    :class:`jaxbal.mujoco.Tracking` of :data:`PLATFORM_JOINTS`; settings there)."""
    laws = (_joint_path(robot, pose_path), torque_law(robot, pose_path, model))
    return _simulate(robot, *laws, duration, timestep, record_every, effort_scale)


def _joint_path(robot: DualV, pose_path: Callable) -> Callable:
    """``t ↦ q (11,)``: the inverse kinematics along the pose path."""

    def path(t):
        return robot.inverse_kinematics(pose_path(t))

    return path


def _simulate(robot, path, efforts, duration, timestep, record_every, effort_scale=1.0):
    from jaxbal.mujoco import simulate_open_loop

    return simulate_open_loop(
        robot,
        path,
        efforts,
        duration,
        PLATFORM_JOINTS,
        timestep=timestep,
        record_every=record_every,
        effort_scale=effort_scale,
    )


class OpenLoopConvergence(NamedTuple):
    """Result of :func:`open_loop_convergence`.

    Attributes:
        runs: time step [s] ↦ :class:`jaxbal.mujoco.Tracking`.
        extrapolated: ``(3,)`` tracking error of the Richardson ``dt → 0`` motion of the
            two finest steps [m, m, rad].
        order: ``(3,)`` observed order ``log(e_coarse/e_fine)/log(dt_coarse/dt_fine)``.
    """

    runs: dict
    extrapolated: np.ndarray
    order: np.ndarray

    def passed(self, order_range: tuple[float, float], bound) -> bool:
        """Every observed order inside ``order_range`` and every extrapolated error
        below ``bound`` ``(3,)``."""
        inside = (self.order > order_range[0]) & (self.order < order_range[1])
        return bool(np.all(inside) and np.all(self.extrapolated < np.asarray(bound)))


def open_loop_convergence(
    robot: DualV,
    pose_path: Callable,
    duration: float,
    model: str = "paper",
    timesteps=(1e-4, 5e-5, 2.5e-5),
    record_interval: float = 1e-4,
    expected_order: int = 2,
    progress: Callable[[str], None] | None = None,
) -> OpenLoopConvergence:
    """:func:`open_loop_tracking` at each time step [s] (coarse to fine), recorded every
    ``record_interval`` [s] (the same instants for every step), then Richardson
    extrapolation of the two finest with ``expected_order`` (RK4 with a mid-step
    control held over the step converges as ``dt²``)."""
    laws = (_joint_path(robot, pose_path), torque_law(robot, pose_path, model))  # jit once
    runs = {}
    for dt in timesteps:
        if progress is not None:
            progress(f"MuJoCo {model}, dt = {dt:g} s")
        every = max(1, int(round(record_interval / dt)))
        runs[dt] = _simulate(robot, *laws, duration, dt, every)
    coarse, fine = runs[timesteps[-2]], runs[timesteps[-1]]
    factor = (timesteps[-2] / timesteps[-1]) ** expected_order
    limit = (factor * fine.simulated - coarse.simulated) / (factor - 1.0)
    extrapolated = np.max(np.abs(limit - fine.planned), axis=0)
    order = np.log2(coarse.error / fine.error) / np.log2(timesteps[-2] / timesteps[-1])
    return OpenLoopConvergence(runs, extrapolated, order)


def confirm_motions(
    robots: Mapping[str, DualV], cases: Mapping[str, tuple], engine: str = "mjx"
) -> dict[str, Confirmation]:
    """:func:`jaxbal.mujoco.confirm` of every robot along every platform motion.

    Args:
        robots: label ↦ robot.
        cases: name ↦ ``(motion, branch)``, ``motion = (u, u̇, ü)`` each ``(t, 3)``.
        engine: ``"mjx"`` (``mjx.inverse``) or ``"mujoco"`` (C ``mj_inverse``).

    Returns:
        ``"{case} {label}"`` ↦ :class:`jaxbal.mujoco.Confirmation`, cases outermost.
    """
    from jaxbal.mujoco import confirm

    return {
        f"{case} {label}": confirm(robot, *joint_states(robot, motion, branch), engine=engine)
        for case, (motion, branch) in cases.items()
        for label, robot in robots.items()
    }
