"""A bound-constrained BFGS method in NumPy, driven from the host: the default optimiser
of :func:`jaxbal.design.codesign` for up to :data:`HOST_MAX_VARIABLES` design variables
(above, and for the reduced co-design's compiled loop, see :mod:`jaxbal._src.lbfgsb`
and :mod:`jaxbal._src.box_bfgs`).

Each iteration calls one compiled value-and-gradient (the co-design's program) on a
NumPy point, as SciPy's L-BFGS-B did, and follows L-BFGS-B's iteration with a dense
BFGS matrix ``B`` (a few design variables):

1. the generalised Cauchy point: the first minimiser of the quadratic model
   ``f + gᵀ(z − x) + ½ (z − x)ᵀ B (z − x)`` along the projected gradient path
   ``P(x − t g)``, crossing its breakpoints in order; the variables it brings to a bound
   are fixed;
2. the subspace step: the model's minimiser over the other variables from that point,
   shortened to stay inside the bounds (the direct primal method);
3. a backtracking line search along ``d = x̄ − x`` (Armijo's condition; quadratic
   interpolation kept in ``[0.1 α, 0.5 α]``; ``α = min(1, 1/‖d‖)`` on the first
   iteration), then the damped BFGS update of :func:`jaxbal._src.box_bfgs._update`,
   self-scaled: ``B`` is first multiplied by ``min(1, sᵀy / sᵀBs)``. A co-design loss
   is often quartic in the variables (a squared objective of squared metrics), whose
   curvature falls as the iterates approach the optimum; without the scaling the
   dense matrix kept the early, larger curvature (DUAL-V counter-masses of
   ``benchmarks/codesign_bench.py``: 28 iterations and 35 evaluations instead of 16 and
   18; L-BFGS-B, which rescales its matrix at every iteration, 17 and 20).

It stops as :func:`~jaxbal._src.box_bfgs.box_bfgs` does: a projected gradient at most
``gtol`` (largest component), a step lowering the loss by at most
:data:`~jaxbal._src.lbfgsb.FTOL` relative (rounding), or ``max_steps``. A trial where
the loss or gradient is not finite is rejected (backtracking).

Why not SciPy's L-BFGS-B here: its optimisers take 0.2–0.4 s to import and its
OpenBLAS must be held to one thread (``threadpoolctl``), which was most of a second
process's first co-design once the compiled program came from the persistent cache
(measured on the 2-core CPU: DUAL-V 0.69–0.72 s with the import, 0.35–0.39 s without;
Orthoglide 0.61–0.79 s and 0.38 s). A projected BFGS without the Cauchy point
(Bertsekas's ε-active set, as in :mod:`~jaxbal._src.box_bfgs`) needed 38 iterations
instead of L-BFGS-B's 17 on the DUAL-V, zig-zagging as three counter-masses reached
zero. On the 20-variable arm (evaluated directly, ``reduce=False``) it takes 24–26
iterations and 26–31 evaluations where L-BFGS-B took 31–36 and 37–43, to the same loss
(1e-16 relative).

References:
    Byrd, Lu, Nocedal & Zhu (1995), SIAM J. Sci. Comput. 16(5): §4 (generalised Cauchy
    point), §5.2 (direct primal subspace minimisation);
    Oren & Luenberger (1974), Management Sci. 20(5), self-scaling variable metric;
    Nocedal & Wright (2006), Numerical Optimization, §16.7, §18.3 (damped BFGS), §3.5.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from jaxbal._src.box_bfgs import ROUNDING, _update
from jaxbal._src.lbfgs import ARMIJO, MAX_BACKTRACKS, Result
from jaxbal._src.lbfgsb import FTOL, projected_gradient

__all__ = ["HOST_MAX_VARIABLES", "host_bfgs"]

#: the host-driven co-design uses this method up to this many scalar design variables
#: (a dense matrix per iteration); above, SciPy's L-BFGS-B.
HOST_MAX_VARIABLES = 64


def _cauchy_point(x, g, lower, upper, hessian) -> np.ndarray:
    """The generalised Cauchy point (module doc, step 1)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        breaks = np.where(g < 0, (x - upper) / g, np.where(g > 0, (x - lower) / g, np.inf))
    breaks = np.where(np.isnan(breaks), np.inf, breaks)
    d = np.where(breaks > 0, -g, 0.0)
    z, t_old = np.zeros_like(x), 0.0
    for i in np.argsort(breaks, kind="stable"):
        if breaks[i] <= 0:
            continue
        bd = hessian @ d
        slope, curvature = g @ d + z @ bd, d @ bd
        if slope >= 0:
            break
        step = -slope / curvature if curvature > 0 else np.inf
        if step < breaks[i] - t_old or not np.isfinite(breaks[i]):
            z = z + (step if np.isfinite(step) else 0.0) * d
            break
        z = z + (breaks[i] - t_old) * d
        z[i] = (upper[i] if d[i] > 0 else lower[i]) - x[i]  # exactly on its bound
        d[i], t_old = 0.0, breaks[i]
    return np.clip(x + z, lower, upper)


def _direction(x, g, lower, upper, hessian) -> np.ndarray:
    """``x̄ − x`` (module doc, steps 1–2)."""
    cauchy = _cauchy_point(x, g, lower, upper, hessian)
    free = (cauchy > lower) & (cauchy < upper)
    target = cauchy.copy()
    if np.any(free):
        reduced = g + hessian @ (cauchy - x)
        try:
            step = -np.linalg.solve(hessian[np.ix_(free, free)], reduced[free])
        except np.linalg.LinAlgError:
            step = np.zeros(int(np.sum(free)))
        room = np.where(step > 0, upper[free] - cauchy[free], lower[free] - cauchy[free])
        with np.errstate(divide="ignore", invalid="ignore"):
            limits = np.where(step != 0, room / step, np.inf)
        alpha = min(1.0, float(np.min(limits, initial=np.inf)))
        if np.all(np.isfinite(step)):
            target[free] += max(alpha, 0.0) * step
    return target - x


def _finite(value, grad) -> bool:
    return bool(np.isfinite(value) and np.all(np.isfinite(grad)))


def host_bfgs(
    fun: Callable[[np.ndarray], tuple], x0, lower, upper, *, max_steps: int, gtol: float
) -> Result:
    """Minimise ``f`` over ``lower ≤ x ≤ upper`` (module doc).

    Args:
        fun: ``x -> (f, g, aux)`` on the host (NumPy in, float and NumPy out).
        x0: ``(n,)`` start (clipped into the bounds).
        lower, upper: ``(n,)`` bounds (``-inf``/``inf`` where there is none).
        max_steps: cap on accepted steps; evaluations are capped at
            ``(MAX_BACKTRACKS + 2) · max_steps``.
        gtol: stop when the projected gradient's largest component is at most this.

    Returns:
        A :class:`~jaxbal._src.lbfgs.Result`. A start where ``f`` or ``g`` is not finite
        returns at once, not converged.
    """
    lower = np.broadcast_to(np.asarray(lower, dtype=float), np.shape(x0))
    upper = np.broadcast_to(np.asarray(upper, dtype=float), np.shape(x0))
    x = np.clip(np.asarray(x0, dtype=float), lower, upper)
    history = np.full(max_steps, np.nan)
    f, g, aux = fun(x)
    f, g, evaluations = float(f), np.asarray(g, dtype=float), 1
    if not _finite(f, g):
        return Result(x, f, g, aux, 0, evaluations, False, history)
    hessian, steps, converged = np.eye(x.size), 0, False
    cap = (MAX_BACKTRACKS + 2) * max_steps
    while True:
        if np.max(np.abs(projected_gradient(x, g, lower, upper)), initial=0.0) <= gtol:
            converged = True
            break
        if steps >= max_steps or evaluations >= cap:
            break
        direction = _direction(x, g, lower, upper, hessian)
        slope = float(g @ direction)
        if not (np.isfinite(slope) and slope < 0):  # not a descent direction: restart
            hessian = np.eye(x.size)
            direction = np.clip(x - g, lower, upper) - x
            slope = float(g @ direction)
        alpha = min(1.0, 1.0 / float(np.linalg.norm(direction))) if steps == 0 else 1.0
        close, accepted = True, False
        for _ in range(MAX_BACKTRACKS):
            trial = np.clip(x + alpha * direction, lower, upper)
            value, grad, trial_aux = fun(trial)
            value, grad = float(value), np.asarray(grad, dtype=float)
            evaluations += 1
            if _finite(value, grad) and value <= f + ARMIJO * alpha * slope:
                accepted = True
                break
            finite = _finite(value, grad)
            close = close and finite and abs(value - f) <= ROUNDING * abs(f)
            curvature = value - f - alpha * slope
            # the minimiser of the quadratic through f, the slope and the trial's value
            shrunk = -slope * alpha**2 / (2.0 * curvature) if finite and curvature > 0 else alpha
            alpha = float(np.clip(shrunk, 0.1 * alpha, 0.5 * alpha))
            if evaluations >= cap:
                break
        if not accepted:  # every trial failed: converged when all lay within rounding
            converged = close
            break
        history[steps] = f
        tiny = f - value <= FTOL * abs(f)
        s_, y_ = trial - x, grad - g
        shs, sy = float(s_ @ hessian @ s_), float(s_ @ y_)
        if steps > 0 and shs > 0 and sy > 0:  # self-scaling (Oren & Luenberger 1974)
            hessian = hessian * min(1.0, sy / shs)
        hessian = _update(hessian, s_, y_, steps == 0, xp=np)
        x, f, g, aux, steps = trial, value, grad, trial_aux, steps + 1
        if tiny:
            converged = True
            break
    return Result(x, f, g, aux, steps, evaluations, converged, history)
