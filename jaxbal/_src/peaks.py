"""Peaks of sampled vectors and values: the exact peak norm of the papers' tables and a
smooth upper bound of it for optimisation (Briot et al. 2012, eq 19).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import safe_sqrt
from jaxbal._src.types import Array, Float, ScalarLike
from jaxbal._src.validation import guard, is_traced

__all__ = ["peak_norm", "smooth_peak"]


def peak_norm(vectors: Float[Array, "t 3"]) -> Float[Array, ""]:
    """``max_t ‖v(t)‖`` (e.g. the maximal shaking force of the papers' tables).

    Differentiable everywhere: the norm uses the double-``where`` trick so that an
    instant with ``v = 0`` (rest at the ends of a move) gives a zero, not NaN, gradient.
    Vectors above 1e150 are scaled first, so that a finite force of 1e200 N does not
    overflow to inf in its square (values below are computed exactly as before).

    Raises:
        ValueError: a non-finite vector (under ``jit`` a runtime error while runtime
            checks are on, see :func:`jaxbal.set_runtime_checks`; with them off the
            peak is NaN).
    """
    if jnp.ndim(vectors) != 2 or jnp.shape(vectors)[0] == 0:
        raise ValueError(f"vectors must have shape (t, k) with t >= 1, got {jnp.shape(vectors)}")
    if not is_traced(vectors):  # one compiled program, not ~10 eager operations
        rows = np.flatnonzero(~np.all(np.isfinite(np.asarray(vectors)), axis=-1))
        if rows.size:  # a NaN row was skipped: the finite peak came back
            raise ValueError(f"peak_norm: vectors must be finite; non-finite rows {rows}")
        return _peak_norm_compiled(jnp.asarray(vectors))
    bad = ~jnp.all(jnp.isfinite(vectors), axis=-1)
    return guard(_peak_norm(vectors), bad, "peak_norm: vectors must be finite", vectors)


def _peak_norm(vectors):
    big = jax.lax.stop_gradient(jnp.max(jnp.abs(vectors)))
    scale = jnp.where(big > 1e150, big, 1.0)
    return scale * jnp.max(safe_sqrt(jnp.sum((vectors / scale) ** 2, axis=-1)))


_peak_norm_compiled = jax.jit(_peak_norm)


def smooth_peak(values: Float[Array, " t"], temperature: ScalarLike) -> Float[Array, ""]:
    """Differentiable upper bound of ``max|values|``: ``τ·logsumexp(|v|/τ)``.

    Tends to the maximum as ``temperature τ → 0`` (error ≤ τ·log t); used to optimise
    trajectory parameters against a peak (e.g. eq 19 of Briot et al. 2012).

    Raises:
        ValueError: ``values`` not of shape ``(t,)`` with ``t ≥ 1``, a temperature that
            is not finite and > 0, or a non-finite value (under ``jit`` a runtime error
            while runtime checks are on).
    """
    if jnp.ndim(values) != 1 or jnp.shape(values)[0] == 0:
        raise ValueError(f"values must have shape (t,) with t >= 1, got {jnp.shape(values)}")
    temperature = jnp.asarray(temperature, dtype=float)
    if jnp.ndim(temperature) != 0:
        raise ValueError(f"temperature must be a scalar, got shape {jnp.shape(temperature)}")
    values = guard(values, ~jnp.isfinite(values), "smooth_peak: values must be finite", values)
    bad = ~(jnp.isfinite(temperature) & (temperature > 0))
    temperature = guard(temperature, bad, "smooth_peak: temperature must be > 0", temperature)
    magnitude = jnp.abs(values)
    return temperature * jax.nn.logsumexp(magnitude / temperature)
