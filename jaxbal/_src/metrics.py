"""Motion samples and the scalar metrics of a design, shared by co-design and sensitivity.

A :class:`Motion` is the joint motion ``(q, q̇, q̈)`` sampled at ``t`` instants; it is
*held fixed* while the design changes (sequential design: counter-masses do not
change the inverse kinematics). A metric is any function ``metric(robot, motion) ->
scalar``; the named ones are in :data:`METRICS`:

==================  =============================================================  ======
name                definition                                                     unit
==================  =============================================================  ======
``peak_force``      ``max_t ‖f_sh(t)‖``, shaking force                             N
``rms_force``       ``sqrt(mean_t ‖f_sh(t)‖²)``                                    N
``peak_moment``     ``max_t ‖m_sh(t)‖``, shaking moment about the base origin      N·m
``rms_moment``      ``sqrt(mean_t ‖m_sh(t)‖²)``                                    N·m
``peak_torque``     ``max_t ‖τ(t)‖``, actuator torques/forces                      N·m, N
``rms_torque``      ``sqrt(mean_t ‖τ(t)‖²)``                                       N·m, N
``peak_torque_rate``  ``max_t max_i |dτ_i/dt|``, per actuator (Briot 2012 eq 6);   N·m/s,
                    needs a :class:`JerkMotion`                                    N/s
``added_mass``      sum of the design variables ``counter_mass`` and               kg
                    ``vertical_counterweight``
``added_inertia``   ``J_z(robot) − J_z(robot without counter-masses)`` at the      kg·m²
                    motion's first sample (see :func:`base_inertia`)
==================  =============================================================  ======

The shaking wrench is the inertial one of :func:`jaxbal.shaking_wrench` (no gravity);
the moment is the full 3-vector about the base origin (along z for planar robots). The
torque norm mixes N·m and N for robots with both revolute and prismatic actuators.
Every norm is zero-safe (a zero vector gives a zero, not NaN, gradient).

References:
    Briot, Arakelian & Le Baron (2012), eq (1) and Tables 1-2 (peak shaking force);
    Arakelian & Briot (2008), eq (7) (inertia about the joint axes).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.actuation import actuator_torques
from jaxbal._src.callables import as_pytree
from jaxbal._src.linalg import matvec
from jaxbal._src.momentum import (
    body_com_poses,
    checked_bodies,
    checked_finite,
    checked_parameters,
    shaking_wrench,
)
from jaxbal._src.motion import state_valid
from jaxbal._src.planning import peak_norm
from jaxbal._src.robot import Robot
from jaxbal._src.trajectory import sample
from jaxbal._src.types import Array, Float, Scalar
from jaxbal._src.validation import guard, is_traced, raise_if_invalid, runtime_checks

__all__ = [
    "ADDED_MASS_VARIABLES",
    "METRICS",
    "Metric",
    "Motion",
    "added_inertia",
    "added_mass",
    "JerkMotion",
    "as_motion",
    "base_inertia",
    "check_design_names",
    "finite_array",
    "metric_name",
    "motion_samples",
    "peak_force",
    "peak_moment",
    "peak_torque",
    "peak_torque_rate",
    "resolve_metric",
    "rms_force",
    "rms_moment",
    "rms_torque",
]


class Motion(NamedTuple):
    """A sampled joint motion: ``q``, ``q̇``, ``q̈``, each ``(t, dof)`` [rad or m, per s, per s²]."""

    q: Float[Array, "t dof"]
    qd: Float[Array, "t dof"]
    qdd: Float[Array, "t dof"]


class JerkMotion(NamedTuple):
    """A sampled joint motion with its jerk: ``q``, ``q̇``, ``q̈``, ``q⃛``, each ``(t, dof)``.

    Every metric takes it (the jerk is ignored where not needed); the torque-rate
    metric :func:`peak_torque_rate` needs it. Built by ``motion_samples(..., order=3)``
    or a motion factory with ``order=3``.
    """

    q: Float[Array, "t dof"]
    qd: Float[Array, "t dof"]
    qdd: Float[Array, "t dof"]
    qddd: Float[Array, "t dof"]


#: a metric: a name of :data:`METRICS` or a callable ``(robot, motion) -> scalar``.
Metric = str | Callable[[Robot, Motion], Scalar]

#: design variables whose sum is the added mass [kg].
ADDED_MASS_VARIABLES = ("counter_mass", "vertical_counterweight")


# --- motion samples --------------------------------------------------------------------


@eqx.filter_jit
def _sample(trajectory, times, order=2):
    return sample(trajectory, times, order=order)


@eqx.filter_jit
def _valid(robot, q, qd, qdd):
    return jax.vmap(lambda a, b, c: state_valid(robot, a, b, c))(q, qd, qdd)


def motion_samples(robot: Robot, trajectories, times, order: int = 2) -> Motion | JerkMotion:
    """Exact ``(q, q̇, q̈)`` of one or several trajectories, stacked into one :class:`Motion`.

    Args:
        robot: the robot the trajectories belong to (for the loop-closure check).
        trajectories: a callable ``t ↦ q`` (coordinates of all bodies), or a sequence
            of them.
        times: ``(t,)`` instants [s], shared by every trajectory, or a list with one
            array per trajectory.
        order: 2, or 3 for a :class:`JerkMotion` (the jerk ``q⃛`` too, for the
            torque-rate metric).

    Returns:
        A :class:`Motion` (or :class:`JerkMotion`) with ``Σ t_k`` rows, in the order of
        the trajectories.

    Raises:
        ValueError: eagerly, when a sampled state violates the robot's loop closures
            (or is not finite); the message names the offending instants.
    """
    if callable(trajectories):
        trajectories = [trajectories]
    trajectories = list(trajectories)
    if not trajectories:
        raise ValueError("motion_samples needs at least one trajectory")
    if order not in (2, 3):
        raise ValueError(f"order must be 2 (q, q̇, q̈) or 3 (with the jerk), got {order!r}")
    if isinstance(times, list | tuple) and times and np.ndim(times[0]) >= 1:
        times = [jnp.asarray(t, dtype=float) for t in times]
        if len(times) != len(trajectories):
            raise ValueError(f"got {len(times)} time arrays for {len(trajectories)} trajectories")
    else:
        times = [jnp.asarray(times, dtype=float)] * len(trajectories)
    parts = []
    for trajectory, instants in zip(trajectories, times, strict=True):
        if instants.ndim != 1:
            raise ValueError(f"times must have shape (t,), got {instants.shape}")
        # A lambda or closure as a pytree: an equivalent new one reuses the compilation.
        q, qd, qdd, *jerk = _sample(as_pytree(trajectory), instants, order)
        raise_if_invalid(
            _valid(robot, q, qd, qdd),
            f"trajectory leaves the loop closures of {type(robot).__name__} (or is not "
            "finite) at t [s]",
            instants,
        )
        parts.append(JerkMotion(q, qd, qdd, *jerk) if jerk else Motion(q, qd, qdd))
    if jerk:
        return JerkMotion(*(jnp.concatenate([p[k] for p in parts]) for k in range(4)))
    return as_motion(parts)


def as_motion(motions) -> Motion:
    """One :class:`Motion` from a Motion, a ``(q, q̇, q̈)`` tuple or a sequence of them
    (concatenated along time)."""
    if isinstance(motions, Motion):
        return motions
    if isinstance(motions, JerkMotion):
        return Motion(motions.q, motions.qd, motions.qdd)
    if isinstance(motions, tuple) and len(motions) == 3 and not isinstance(motions[0], tuple):
        return Motion(*(jnp.asarray(v, dtype=float) for v in motions))
    parts = [as_motion(m) for m in motions]
    if not parts:
        raise ValueError("need at least one motion")
    return Motion(*(jnp.concatenate([p[k] for p in parts]) for k in range(3)))


# --- metrics -----------------------------------------------------------------------------


def _batched(evaluate, robot: Robot, motion: Motion, what: str, jerk: bool = False):
    """``evaluate(robot, q, qd, qdd)`` at every sample of the motion (``vmap``);
    ``evaluate(robot, q, qd, qdd, qddd)`` with ``jerk`` (``motion`` a JerkMotion).

    An eager call checks the values first and raises ``ValueError``: inside ``vmap`` the
    runtime checks would surface as a JAX-internal callback error (``INTERNAL:
    CpuCallback error``) instead of naming the offending value.
    """
    motion = motion if jerk else as_motion(motion)
    if is_traced(robot, motion):
        return jax.vmap(lambda *state: evaluate(robot, *state))(*motion)
    checked_parameters(robot, checked_bodies(robot, None))
    finite = jnp.all(jnp.isfinite(jnp.concatenate(motion, axis=-1)), axis=-1)
    raise_if_invalid(finite, "non-finite state (q, qd, qdd) in the motion at samples",
                     jnp.arange(finite.shape[0]))  # fmt: skip
    with runtime_checks(False):  # checked above and below, eagerly
        out = jax.vmap(lambda *state: evaluate(robot, *state))(*motion)
    return checked_finite(what, robot, out)


def _wrench(robot: Robot, motion: Motion):
    return _batched(shaking_wrench, robot, motion, "shaking wrench")


def _torques(robot: Robot, motion: Motion):
    return _batched(actuator_torques, robot, motion, "actuator torques")


def _unit_scale(vectors):
    """``max |v|`` when the squares of ``vectors`` would overflow (> 1e150), else 1 (exact:
    the usual values are unchanged); no gradient."""
    big = jax.lax.stop_gradient(jnp.max(jnp.abs(vectors), initial=0.0))
    return jnp.where(big > 1e150, big, 1.0)


def _rms(vectors: Float[Array, "t k"]) -> Scalar:
    """``sqrt(mean_t ‖v(t)‖²)``, with a zero (not NaN) gradient at ``v ≡ 0``; scaled so
    that a finite wrench above 1e154 N does not overflow to inf."""
    scale = _unit_scale(vectors)
    mean_square = jnp.mean(jnp.sum((vectors / scale) ** 2, axis=-1))
    positive = mean_square > 0.0
    return scale * jnp.where(positive, jnp.sqrt(jnp.where(positive, mean_square, 1.0)), 0.0)


def peak_force(robot: Robot, motion: Motion) -> Scalar:
    """Peak shaking force ``max_t ‖f_sh(t)‖`` [N]."""
    return peak_norm(_wrench(robot, motion)[0])


def rms_force(robot: Robot, motion: Motion) -> Scalar:
    """RMS shaking force ``sqrt(mean_t ‖f_sh(t)‖²)`` [N]."""
    return _rms(_wrench(robot, motion)[0])


def peak_moment(robot: Robot, motion: Motion) -> Scalar:
    """Peak shaking moment about the base origin ``max_t ‖m_sh(t)‖`` [N·m]."""
    return peak_norm(_wrench(robot, motion)[1])


def rms_moment(robot: Robot, motion: Motion) -> Scalar:
    """RMS shaking moment about the base origin ``sqrt(mean_t ‖m_sh(t)‖²)`` [N·m]."""
    return _rms(_wrench(robot, motion)[1])


def peak_torque(robot: Robot, motion: Motion) -> Scalar:
    """Peak norm of the actuator torque/force vector ``max_t ‖τ(t)‖`` [N·m, N]."""
    return peak_norm(_torques(robot, motion))


def rms_torque(robot: Robot, motion: Motion) -> Scalar:
    """RMS norm of the actuator torque/force vector ``sqrt(mean_t ‖τ(t)‖²)`` [N·m, N]."""
    return _rms(_torques(robot, motion))


def torque_rate(robot: Robot, q, qd, qdd, qddd) -> Array:
    """Actuator torque rates ``dτ/dt = ∂τ/∂q·q̇ + ∂τ/∂q̇·q̈ + ∂τ/∂q̈·q⃛`` [N·m/s, N/s]
    at one state (one ``jvp`` of :func:`jaxbal.actuator_torques`; closed chains
    included)."""

    def torques(a, b, c):
        return actuator_torques(robot, a, b, c)

    return jax.jvp(torques, (q, qd, qdd), (qd, qdd, qddd))[1]


def peak_torque_rate(robot: Robot, motion: JerkMotion) -> Scalar:
    """Peak actuator torque rate ``max_t max_i |dτ_i/dt|`` [N·m/s, N/s], the quantity
    limited for every actuator in Briot et al. (2012), eqs (5)-(6).

    The peak is over the motion's samples: the rate jumps where the jerk does (at a
    trapezoid's switch times), so sample densely enough to catch a short ramp.

    Raises:
        ValueError: ``motion`` is not a :class:`JerkMotion` (no jerk to differentiate
            the torques along).
    """
    if not isinstance(motion, JerkMotion):
        raise ValueError(
            "peak_torque_rate needs the jerk: give a JerkMotion (motion_samples(..., "
            f"order=3) or a motion factory with order=3), got {type(motion).__name__}"
        )
    rates = _batched(torque_rate, robot, motion, "actuator torque rates", jerk=True)
    return jnp.max(jnp.abs(rates))


def added_mass(robot: Robot, motion: Motion | None = None) -> Scalar:
    """Mass added by balancing [kg]: the sum of the design variables ``counter_mass``
    and ``vertical_counterweight`` (those the robot has; zero if none). ``motion`` is
    ignored (kept for the metric signature)."""
    design = robot.design()
    names = [name for name in ADDED_MASS_VARIABLES if name in design]
    terms = [jnp.sum(design[name]) for name in names]
    total = sum(terms, jnp.zeros(()))
    if not names:
        return total
    # A NaN or negative counter-mass set with eqx.tree_at gave a NaN / negative
    # added mass silently: refused (eagerly ValueError naming it, at run time under jit).
    invalid = jnp.stack([~jnp.all(jnp.isfinite(design[n]) & (design[n] >= 0)) for n in names])
    message = "added-mass design variables must be finite and >= 0 [kg]"
    offending = jnp.stack([jnp.min(jnp.asarray(design[n])) for n in names])
    return guard(total, invalid, message, offending, names=names)


def base_inertia(robot: Robot, q: Float[Array, " dof"]) -> Scalar:
    """Moment of inertia of all moving bodies about the base z axis at ``q`` [kg·m²]:
    ``J_z = Σ_i m_i (x_i² + y_i²) + (R_i I_i R_iᵀ)_zz`` (``(x_i, y_i)``: COM of body i).

    Raises ``ValueError`` (at run time under ``jit``) as :func:`jaxbal.center_of_mass`."""
    q = jnp.asarray(q, dtype=float)
    bodies = robot.mass_properties()
    positions, rotations = body_com_poses(robot, q)
    # (R I Rᵀ)_zz = e_zᵀ R I Rᵀ e_z = rᵀ I r with r = Rᵀ e_z, the third row of R.
    row_z = rotations[:, 2, :]
    spin = jnp.sum(row_z * matvec(bodies.inertia, row_z), axis=-1)
    orbital = bodies.mass * jnp.sum(positions[:, :2] ** 2, axis=-1)
    # Checked like the shaking wrench (a NaN length or mass gave a NaN added inertia).
    inertia = guard(jnp.sum(orbital + spin), ~jnp.isfinite(q), "non-finite coordinates q", q)
    inertia = checked_parameters(robot, checked_bodies(robot, inertia))
    return checked_finite("base inertia", robot, inertia)


def added_inertia(robot: Robot, motion: Motion) -> Scalar:
    """Inertia added by balancing [kg·m²]: :func:`base_inertia` of the robot minus that
    of the same robot with ``counter_mass`` and ``vertical_counterweight`` set to zero,
    both in the configuration of the motion's first sample ``q[0]``.

    For the planar robots and the SCARA this is the increase of the inertia the base
    sees about its vertical axis (what raises the shaking moment and the torques).
    """
    design = robot.design()
    zeroed = {n: jnp.zeros_like(design[n]) for n in ADDED_MASS_VARIABLES if n in design}
    bare = robot.with_design(zeroed)
    q0 = motion.q[0]
    return base_inertia(robot, q0) - base_inertia(bare, q0)


#: name -> metric ``(robot, motion) -> scalar`` (SI units, see the module table).
METRICS: dict[str, Callable[[Robot, Motion], Scalar]] = {
    "peak_force": peak_force,
    "rms_force": rms_force,
    "peak_moment": peak_moment,
    "rms_moment": rms_moment,
    "peak_torque": peak_torque,
    "rms_torque": rms_torque,
    "peak_torque_rate": peak_torque_rate,
    "added_mass": added_mass,
    "added_inertia": added_inertia,
}


def resolve_metric(metric: Metric) -> Callable[[Robot, Motion], Scalar]:
    """The metric function of a name of :data:`METRICS` or of a callable.

    Raises:
        ValueError: an unknown name (the message lists the valid ones) or neither a
            string nor a callable.
    """
    if isinstance(metric, str):
        if metric not in METRICS:
            raise ValueError(f"unknown metric {metric!r}; choose one of {sorted(METRICS)}")
        return METRICS[metric]
    if callable(metric):
        return metric
    raise ValueError(
        f"a metric must be one of {sorted(METRICS)} or a callable (robot, motion) -> "
        f"scalar, got {metric!r}"
    )


def metric_name(metric: Metric) -> str:
    """Display name of a metric: its name, or the callable's ``__name__``."""
    if isinstance(metric, str):
        return metric
    return getattr(metric, "__name__", repr(metric))


def _check_names(kind: str, names, valid) -> None:
    unknown = [n for n in names if n not in valid]
    if unknown:
        raise ValueError(f"unknown {kind}(s) {unknown}; valid: {sorted(valid)}")


def check_design_names(robot: Robot, names) -> tuple[str, ...]:
    """``names`` as a tuple, checked against the robot's design variables.

    Raises:
        ValueError: an unknown name (the message lists the robot's variables).
    """
    names = (names,) if isinstance(names, str) else tuple(names)
    _check_names(f"design variable of {type(robot).__name__}", names, robot.design())
    return names


def finite_array(name: str, value) -> np.ndarray:
    """``value`` as a float array; raise ``ValueError`` naming it if not finite."""
    array = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {array!r}")
    return array
