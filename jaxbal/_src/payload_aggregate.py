"""Aggregation of a metric over a payload grid, and the kink the mean of a norm has.

:func:`jaxbal.design.joint_codesign` evaluates each objective metric at every payload
``p`` of its grid and aggregates the ``n`` values ``v_p`` (``robust=``):

- ``"mean"``: ``(1/n) Σ_p v_p``, the expected value over a uniform grid;
- ``"rms"``: the quadratic mean ``sqrt((1/n) Σ_p v_p²)`` (metrics ``≥ 0``); for an RMS
  metric, the RMS over every payload and every instant together;
- ``"max"``: the smooth maximum ``s/k · log (1/n) Σ_p exp(k v_p / s)``.

The loss squares each aggregate. The RMS force (or moment) at one payload is a norm of
a function of the design that a counter-mass design can make exactly zero: the robot
then balances that payload perfectly (a force balanced for payload ``p*`` is
``(p − p*)·a_E(t)`` at payload ``p``). The mean of such norms is not differentiable
where one of them is zero, like ``|x|`` at 0, and its minimum lies on such a kink (for
the 2R's RMS force: balanced at the *median* payload). There L-BFGS stalls with a
gradient norm that does not shrink and cannot report convergence, although the design
is (nearly) optimal; :func:`kinks` names the payloads so the co-design can say so. The
quadratic mean squared is the mean of ``v_p²``, smooth wherever the squared metrics are
(a balanced payload included): its minimum balances the *mean* payload.

References:
    Briot, Arakelian & Le Baron (2012), eq (3) (the shaking force is the total mass
    times the COM acceleration); Geng et al. (2021) (payload variation spoils the
    balance); Clarke (1983), Optimization and Nonsmooth Analysis (a gradient method's
    stationarity test fails at a kink of a norm).
"""

from __future__ import annotations

import warnings

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import safe_sqrt
from jaxbal._src.types import Array

__all__ = [
    "KINK_RTOL",
    "ROBUST",
    "aggregate",
    "aggregate_numpy",
    "check_aggregable",
    "kinks",
    "warn_at_kink",
]

#: the aggregations over the payload grid (``robust=``)
ROBUST = ("mean", "rms", "max")
#: a payload's metric at most this fraction of its scale counts as zero (a kink)
KINK_RTOL = 1e-6


def aggregate(values: Array, scales: Array, robust: str, sharpness) -> Array:
    """``(n_payloads, k)`` metric values -> ``(k,)`` aggregates (module doc); the
    quadratic mean has a zero (not NaN) gradient where every payload's value is zero."""
    if robust == "mean":
        return jnp.mean(values, axis=0)
    if robust == "rms":
        return scales * safe_sqrt(jnp.mean((values / scales) ** 2, axis=0))
    scaled = sharpness * values / scales
    log_mean = jax.scipy.special.logsumexp(scaled, axis=0) - np.log(values.shape[0])
    return scales / sharpness * log_mean


def aggregate_numpy(values: np.ndarray, robust: str) -> np.ndarray:
    """``(n_payloads, k)`` -> ``(k,)``: the mean, the quadratic mean or the (hard)
    maximum over the payloads (the scales of a Pareto front)."""
    values = np.asarray(values, dtype=float)
    if robust == "max":
        return values.max(axis=0)
    if robust == "rms":
        return np.sqrt(np.mean(values**2, axis=0))
    return values.mean(axis=0)


def check_aggregable(robust: str, values: np.ndarray) -> None:
    """The quadratic mean aggregates metrics ``≥ 0`` (of ``v < 0`` it is ``|v|``)."""
    negative = np.asarray(values, dtype=float)[np.asarray(values) < 0]
    if robust == "rms" and negative.size:
        raise ValueError(f"robust='rms' needs objective metrics >= 0, got {negative.tolist()}")


def kinks(values: np.ndarray, scales, names, payloads) -> list[str]:
    """Where the mean over payloads has a kink: ``"name = v at payload p kg"`` for each
    objective metric (column of ``(n_payloads, k)`` ``values``) whose value is at most
    :data:`KINK_RTOL` of its scale at some payload while another payload's is not."""
    values, payloads = np.asarray(values, dtype=float), np.asarray(payloads, dtype=float)
    found = []
    for column, scale, name in zip(values.T, np.asarray(scales, float), names, strict=True):
        zero = np.abs(column) <= KINK_RTOL * scale
        if zero.any() and not zero.all():
            found += [f"{name} = {column[i]:.3g} at payload {payloads[i]:g} kg"
                      for i in np.flatnonzero(zero)]  # fmt: skip
    return found


def warn_at_kink(values: np.ndarray, scales, names, payloads, grad_norm) -> None:
    """A ``RuntimeWarning`` naming the :func:`kinks` of an unconverged mean, if any."""
    zeros = kinks(values, scales, names, payloads)
    if zeros:
        warnings.warn(f"joint_codesign stopped unconverged (gradient norm {grad_norm:.2g}) "
                      f"at a kink of its loss: {', '.join(zeros)}. The mean over payloads of "
                      "a norm is not differentiable where one payload is balanced exactly; "
                      "its minimum lies on such a kink, so the design may well be optimal, "
                      "but no gradient test can confirm it. robust='rms' is smooth there.",
                      RuntimeWarning, stacklevel=3)  # fmt: skip
