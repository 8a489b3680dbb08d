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

The vibration of the base the wrench excites (residual after the move, or peak) is the
metric object :class:`jaxbal.vibration.BaseVibration` (a base model and sample times).

The shaking wrench is the inertial one of :func:`jaxbal.shaking_wrench` (no gravity);
the moment is the full 3-vector about the base origin (along z for planar robots). The
torque norm mixes N·m and N for robots with both revolute and prismatic actuators.
Every norm is zero-safe (a zero vector gives a zero, not NaN, gradient). The peak
metrics (the torque rate's included) are differentiated at their peak sample
(:mod:`jaxbal._src.peak_sample`): the same derivative as reverse mode through every
sample wherever the peak is unique, at about the cost of one evaluation (``grad``/value
≈ 1 instead of ≈ 3).

References:
    Briot, Arakelian & Le Baron (2012), eq (1) and Tables 1-2 (peak shaking force);
    Arakelian & Briot (2008), eq (7) (inertia about the joint axes).
"""

from __future__ import annotations

from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.actuation import actuator_torque_rate, actuator_torques
from jaxbal._src.along_motion import batched
from jaxbal._src.linalg import matvec, safe_sqrt
from jaxbal._src.merged_guards import merged_guards
from jaxbal._src.momentum import body_com_poses, shaking_wrench
from jaxbal._src.motion_samples import (
    JerkMotion,
    Motion,
    ReducedMotion,
    as_motion,
    motion_samples,
)
from jaxbal._src.peak_sample import peak, peak_abs, unit_scale
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import checked_physics
from jaxbal._src.types import Array, Float, Scalar
from jaxbal._src.validation import guard, is_traced

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
    "torque_samples",
    "wrench_samples",
]


#: a metric: a name of :data:`METRICS` or a callable ``(robot, motion) -> scalar``.
Metric = str | Callable[[Robot, Motion], Scalar]

#: design variables whose sum is the added mass [kg].
ADDED_MASS_VARIABLES = ("counter_mass", "vertical_counterweight")


# --- metrics -----------------------------------------------------------------------------


def wrench_samples(robot: Robot, motion: Motion) -> tuple[Float[Array, "t 3"], ...]:
    """Shaking force ``(t, 3)`` [N] and moment ``(t, 3)`` [N·m] at every sample of the
    motion (:func:`jaxbal.shaking_wrench` under ``vmap``; what the wrench metrics
    reduce). Eagerly the robot, the finite states and a closed chain's loop closures are
    checked first (``ValueError`` naming the samples) and the samples run as one
    compiled program; under ``jit``/``grad`` a plain ``vmap``."""
    return batched(shaking_wrench, robot, motion, "shaking wrench")


def torque_samples(robot: Robot, motion: Motion) -> Float[Array, "t a"]:
    """Actuator torques/forces ``(t, a)`` [N·m, N] at every sample of the motion
    (:func:`jaxbal.actuator_torques`, closed chains included; checked as
    :func:`wrench_samples`)."""
    return batched(actuator_torques, robot, motion, "actuator torques")


_wrench, _torques = wrench_samples, torque_samples


def _rms(vectors: Float[Array, "t k"]) -> Scalar:
    """``sqrt(mean_t ‖v(t)‖²)``, with a zero (not NaN) gradient at ``v ≡ 0``; scaled so
    that a finite wrench above 1e154 N does not overflow to inf."""
    scale = unit_scale(vectors)
    return scale * safe_sqrt(jnp.mean(jnp.sum((vectors / scale) ** 2, axis=-1)))


#: the RMS compiled, for eager calls: run operation by operation, each of its ~10 small
#: operations is a dispatch and, in a fresh process, a compilation of its own (so is
#: :func:`peak_norm` called eagerly)
_rms_compiled = jax.jit(_rms)


def _rms_of(vectors: Float[Array, "t k"]) -> Scalar:
    """:func:`_rms`, as one compiled program when called eagerly."""
    return (_rms if is_traced(vectors) else _rms_compiled)(vectors)


def _force(wrench):
    return wrench[0]


def _moment(wrench):
    return wrench[1]


def _same(vectors):
    return vectors


def peak_force(robot: Robot, motion: Motion) -> Scalar:
    """Peak shaking force ``max_t ‖f_sh(t)‖`` [N] (derivatives: see
    :mod:`~jaxbal._src.peak_sample`)."""
    return peak(shaking_wrench, _force, robot, motion, "shaking wrench")


def _reduced(robot: Robot, motion, part: int, bare=None):
    """The RMS force (``part`` 0) or moment (1), or the added inertia (2, with the
    ``bare`` robot), from the regressor of a :class:`ReducedMotion` (``None`` otherwise)."""
    if not isinstance(motion, ReducedMotion):
        return None
    from jaxbal._src.reduced_motion import reduced_added_inertia, reduced_rms  # circular

    if part == 2:
        return reduced_added_inertia(robot, bare, motion)  # None where the motion lacks it
    return reduced_rms(robot, motion, part)


def rms_force(robot: Robot, motion: Motion) -> Scalar:
    """RMS shaking force ``sqrt(mean_t ‖f_sh(t)‖²)`` [N]."""
    reduced = _reduced(robot, motion, 0)
    return _rms_of(_wrench(robot, motion)[0]) if reduced is None else reduced


def peak_moment(robot: Robot, motion: Motion) -> Scalar:
    """Peak shaking moment about the base origin ``max_t ‖m_sh(t)‖`` [N·m] (derivatives:
    see :mod:`~jaxbal._src.peak_sample`)."""
    return peak(shaking_wrench, _moment, robot, motion, "shaking wrench")


def rms_moment(robot: Robot, motion: Motion) -> Scalar:
    """RMS shaking moment about the base origin ``sqrt(mean_t ‖m_sh(t)‖²)`` [N·m]."""
    reduced = _reduced(robot, motion, 1)
    return _rms_of(_wrench(robot, motion)[1]) if reduced is None else reduced


def peak_torque(robot: Robot, motion: Motion) -> Scalar:
    """Peak norm of the actuator torque/force vector ``max_t ‖τ(t)‖`` [N·m, N]
    (derivatives: see :mod:`~jaxbal._src.peak_sample`)."""
    return peak(actuator_torques, _same, robot, motion, "actuator torques")


def rms_torque(robot: Robot, motion: Motion) -> Scalar:
    """RMS norm of the actuator torque/force vector ``sqrt(mean_t ‖τ(t)‖²)`` [N·m, N]."""
    return _rms_of(_torques(robot, motion))


def torque_rate(robot: Robot, q, qd, qdd, qddd) -> Array:
    """:func:`~jaxbal._src.actuation.actuator_torque_rate` at one state (no gravity)."""
    return actuator_torque_rate(robot, q, qd, qdd, qddd)


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
    return peak_abs(torque_rate, robot, motion, "actuator torque rates")


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
    inertia = jnp.sum(orbital + spin)

    def checks(inertia):
        checked = guard(inertia, ~jnp.isfinite(q), "non-finite coordinates q", q)
        return checked_physics("base inertia", robot, checked)

    return merged_guards(checks, inertia)


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
    reduced = _reduced(robot, motion, 2, bare)
    if reduced is not None:
        return reduced
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


def check_hashable(metric: Metric) -> None:
    """A metric that a compiled program is keyed on (a term of a co-design, a sweep's)
    must be hashable: a name, a module-level function, an ``eqx.Module`` without arrays
    (e.g. :func:`~jaxbal.design.over_payloads` without a motion factory).

    Raises:
        ValueError: naming the metric's type (an ``eqx.Module`` holding arrays).
    """
    try:
        hash(metric)
    except TypeError:
        raise ValueError(
            f"this metric must be hashable (a name, a module-level function, a module "
            f"without arrays such as over_payloads without a motion factory), got "
            f"{type(metric).__name__}"
        ) from None


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


def finite_array(name: str, value, shape: tuple[int, ...] | None = None) -> np.ndarray:
    """``value`` as a float array (broadcast to ``shape``, if given); raise
    ``ValueError`` naming it if not finite or not broadcastable to ``shape``."""
    array = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{name} must be finite, got {array!r}")
    if shape is None:
        return array
    try:
        return np.broadcast_to(array, shape)
    except ValueError:
        raise ValueError(f"{name} has shape {array.shape}, not broadcastable to the "
                         f"variable's shape {tuple(shape)}") from None  # fmt: skip
