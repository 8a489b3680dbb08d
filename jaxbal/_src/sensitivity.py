"""Sensitivity of a metric to the design variables of any robot, by automatic
differentiation through :meth:`jaxbal.Robot.with_design`, with an optional check
against central finite differences.

The motion is either held fixed (a :class:`~jaxbal.design.Motion`: the joint motion
does not change with the design) or re-planned with the design (a callable ``robot ->
Motion``, e.g. a COM plan whose joint motion depends on the payload): then the
gradient includes the change of the plan, through the robot's (implicitly
differentiated) inverse kinematics.

**Finite-difference check.** Entry ``i`` of a variable ``x`` is stepped by
``h_i = rel_step · max(|x_i|, 1)`` (SI units: a relative step, floored at one unit
so that a variable at zero moves too) and ``(f(x + h_i) − f(x − h_i)) / 2h_i`` is
compared with the gradient. The error of entry ``i`` is measured relative to
``max(|∂f/∂x_i|, |f| / max(|x_i|, 1))``: relative to the derivative itself, or, for
a derivative much smaller than the metric's natural rate ``f/x``, relative to that
rate (a zero derivative is then checked in absolute terms, not divided by zero).
Evaluations at ``x − h`` may have slightly negative masses; the physics is smooth
there, and they run compiled, where the eager non-negativity checks do not apply.

References:
    Griewank & Walther (2008), *Evaluating Derivatives*, ch. 3 (reverse mode);
    Geng et al. (2021), §3.3 (sensitivity of the shaking force to the payload).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.design_inputs import check_positive_number
from jaxbal._src.metrics import Metric, Motion, as_motion, check_design_names, resolve_metric
from jaxbal._src.robot import Robot
from jaxbal._src.types import Array, Scalar
from jaxbal._src.validation import checked_call, runtime_checks

__all__ = ["Sensitivity", "payload_sensitivity", "sensitivity"]


class Sensitivity(NamedTuple):
    """Result of :func:`sensitivity`.

    Attributes:
        value: the metric at the robot's design [SI units of the metric].
        gradient: design variable name -> ``∂metric/∂variable`` (same shape as the
            variable) [metric units per variable unit, e.g. N/kg].
        finite_difference: the central finite differences of the same shapes
            (``check=True`` only, else ``None``).
        max_relative_error: largest error of the gradient against them, relative as
            in the module doc (``check=True`` only, else ``None``).
    """

    value: Scalar
    gradient: dict[str, Array]
    finite_difference: dict[str, Array] | None = None
    max_relative_error: Scalar | None = None


def _metric_at(design: dict[str, Array], robot: Robot, motion, metric) -> Scalar:
    candidate = robot.with_design(design)
    sampled = motion(candidate) if callable(motion) else motion
    return resolve_metric(metric)(candidate, as_motion(sampled))


def _value_and_grad(design, robot, motion, metric):
    """Value and gradient of the metric; run through :func:`~jaxbal.checked_jit`
    (:func:`~jaxbal._src.validation.checked_call`): a failed runtime check raises a
    ``ValueError`` naming the value, and the program, free of host callbacks, is kept by
    the persistent compilation cache (a second process loads it instead of compiling)."""
    return jax.value_and_grad(_metric_at)(design, robot, motion, metric)


@eqx.filter_jit
def _values_at(designs, robot, motion, metric):
    """The metric at a batch of designs (leading axis of every leaf), compiled."""
    return jax.vmap(lambda d: _metric_at(d, robot, motion, metric))(designs)


def _central_differences(design, robot, motion, metric, rel_step):
    """Central differences of every entry of every variable (one vmapped batch)."""
    names = list(design)
    flat = [np.asarray(design[n], dtype=float).ravel() for n in names]
    sizes = [x.size for x in flat]
    base = np.concatenate(flat)
    steps = rel_step * np.maximum(np.abs(base), 1.0)
    count = base.size
    shifted = np.concatenate([base + np.diag(steps), base - np.diag(steps)])  # (2n, n)
    batch, offset = {}, 0
    for name, size in zip(names, sizes, strict=True):
        shape = np.shape(design[name])
        batch[name] = jnp.asarray(shifted[:, offset : offset + size].reshape((2 * count,) + shape))
        offset += size
    # A variable at its bound (a payload of 0 kg) is probed just outside it: the model
    # is polynomial in the masses there, so the physical-value checks are off here.
    with runtime_checks(False):
        values = np.asarray(_values_at(batch, robot, motion, metric))
    slopes = (values[:count] - values[count:]) / (2.0 * steps)
    result, offset = {}, 0
    for name, size in zip(names, sizes, strict=True):
        result[name] = slopes[offset : offset + size].reshape(np.shape(design[name]))
        offset += size
    return result


def sensitivity(
    robot: Robot,
    motion: Motion | Callable[[Robot], Motion],
    metric: Metric = "peak_force",
    *,
    wrt=None,
    check: bool = False,
    rel_step: float = 1e-6,
    rtol: float = 1e-6,
) -> Sensitivity:
    """Gradient of a metric with respect to the robot's design variables.

    Args:
        robot: any :class:`~jaxbal.Robot`.
        motion: a :class:`~jaxbal.design.Motion` held fixed, or a callable
            ``robot -> Motion`` re-planned with the design (define it once: it is part
            of the compiled structure).
        metric: a metric name (:data:`~jaxbal.design.METRICS`) or a callable
            ``(robot, motion) -> scalar``. Peaks are differentiable almost everywhere
            (the gradient of the instant of the peak); RMS metrics are smooth. Two
            equal peaks make a kink: a symmetric move (a quintic COM line, its peak
            force at two mirrored samples) gives one one-sided derivative there, which
            ``check=True`` reports; prefer an RMS metric for such moves.
        wrt: design variable names (default: all of the robot's).
        check: also compute central finite differences and raise if they disagree.
        rel_step: relative finite-difference step (see the module doc).
        rtol: tolerance of the check on the relative error (see the module doc).

    Returns:
        A :class:`Sensitivity`.

    Raises:
        ValueError: an unknown metric or design-variable name (listing the valid ones),
            an empty ``wrt``, a non-finite gradient, or (``check=True``) a
            ``rel_step`` or ``rtol`` that is not a finite number > 0, a gradient that
            differs from the finite differences by more than ``rtol``, or finite
            differences that are not finite (the model undefined at a probe).
    """
    resolve_metric(metric)
    if check:
        check_positive_number("rel_step", rel_step)
        check_positive_number("rtol", rtol)
    design = robot.design()
    names = tuple(design) if wrt is None else check_design_names(robot, wrt)
    if not names:
        raise ValueError(
            f"wrt names no design variable; {type(robot).__name__} has {sorted(design)}"
        )
    chosen = {name: jnp.asarray(design[name], dtype=float) for name in names}
    value, gradient = checked_call(_value_and_grad, chosen, robot, motion, metric)
    for name, grad in gradient.items():
        if not np.all(np.isfinite(np.asarray(grad))):
            raise ValueError(
                f"gradient of {metric!r} with respect to {name!r} is not finite: {grad!r}"
            )
    if not check:
        return Sensitivity(value, gradient)
    finite = _central_differences(chosen, robot, motion, metric, rel_step)
    worst = 0.0
    for name in names:
        x = np.abs(np.asarray(chosen[name]))
        grad = np.asarray(gradient[name])
        scale = np.maximum(np.abs(grad), abs(float(value)) / np.maximum(x, 1.0))
        scale = np.maximum(scale, np.finfo(float).tiny)
        error = np.abs(grad - finite[name]) / scale
        # a NaN difference (the model not finite at a probe) fails the check: max()
        # would drop it
        worst = np.nan if np.any(np.isnan(error)) else max(worst, float(np.max(error, initial=0.0)))
    if not worst <= rtol:
        raise ValueError(
            f"gradient of {metric!r} differs from central finite differences by "
            f"{worst:.3g} (relative) > rtol = {rtol:.3g}: gradient {gradient!r}, finite "
            f"differences {finite!r}"
        )
    finite = {name: jnp.asarray(v) for name, v in finite.items()}
    return Sensitivity(value, gradient, finite, jnp.asarray(worst))


def payload_sensitivity(
    robot: Robot,
    motion: Motion | Callable[[Robot], Motion],
    metric: Metric = "peak_force",
    **options,
) -> Scalar:
    """``∂metric/∂payload`` [metric units per kg]: :func:`sensitivity` with
    ``wrt=("payload",)`` (``options`` are its keywords, e.g. ``check=True``)."""
    return sensitivity(robot, motion, metric, wrt=("payload",), **options).gradient["payload"]
