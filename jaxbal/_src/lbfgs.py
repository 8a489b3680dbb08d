"""A compact L-BFGS driven from the host around one compiled value-and-gradient (the
joint co-design's solver, on its smooth bound map; the counter-mass co-design uses
SciPy's L-BFGS-B, :mod:`jaxbal._src.lbfgsb`, which holds the bounds itself).

:func:`jaxbal.minimize` compiles optax's L-BFGS and its zoom line search into one
``lax.while_loop``: the objective is inlined at every call site of that program (the
step, the line search's trials, the final value) and the loop's own bookkeeping
compiles to ~80 small XLA kernels. On the first co-design of a process that compile
dominated (measured on the 2-core CPU: 1.4 s for the DUAL-V's loop against 0.5 s for
one value-and-gradient of its objective; ~0.4 s for the bookkeeping of a compiled
loop even on a quadratic). Here the only compiled program is the caller's
value-and-gradient; the iteration runs in NumPy on the host (tens of microseconds per
step for the problems of a co-design: a few to a few hundred variables).

Each iteration evaluates value and gradient once, at a trial point:

- the start: first direction ``−g`` (at most a unit step);
- a trial ``x + α d`` of the line search, from ``α = 1``: sufficient decrease when
  finite and either the Armijo condition ``f(α) ≤ f + c₁ α g·d`` holds or, where
  differences of ``f`` are at rounding level, the approximate Wolfe condition of Hager
  & Zhang (``f(α) ≤ f + ε|f|`` and ``g(α)·d ≤ (2δ − 1) g·d``). A step with sufficient
  decrease whose slope is still steep (``g(α)·d < c₂ g·d``) is doubled while the
  decrease holds (a start where the bound map's gradient is tiny is left in a few
  steps); one without shrinks to the minimiser of the interpolating quadratic, kept in
  ``[0.1 α, 0.5 α]``. An accepted
  step stores the pair ``(s, y)`` when ``s·y > 0`` (curvature), and the next direction
  is the two-loop recursion with ``H₀ = (s·y / y·y) I``. A line search that fails with
  a memory restarts once from steepest descent; without one the run stops.

References:
    Nocedal & Wright (2006), Numerical Optimization, Algorithm 7.4 (two-loop
    recursion), eq (7.20) (initial scaling), §3.5 (interpolating backtracking);
    Hager & Zhang (2005), SIAM J. Optim. 16(1), approximate Wolfe conditions (eq 4.1).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np

#: Armijo constant ``c₁`` (sufficient decrease).
ARMIJO = 1e-4
#: Hager–Zhang ``δ`` of the approximate Wolfe slope condition.
APPROXIMATE_WOLFE = 0.1
#: Relative increase of ``f`` accepted with the approximate Wolfe condition (rounding).
ROUNDING_RTOL = 1e-12
#: Backtracking trials of one line search before it fails.
MAX_BACKTRACKS = 40
#: Curvature constant ``c₂``: a step whose slope is still below ``c₂ g·d`` is doubled.
CURVATURE = 0.9
#: Doublings of a too-short step in one line search.
MAX_EXPANSIONS = 30


class Result(NamedTuple):
    """Result of :func:`lbfgs`.

    Attributes:
        x: ``(n,)`` final point.
        value: loss at ``x``.
        grad: ``(n,)`` gradient at ``x``.
        aux: auxiliary output of ``fun`` at ``x``.
        steps: accepted iterations.
        evaluations: value-and-gradient evaluations.
        converged: ``‖grad‖ ≤ gtol`` was reached.
        history: ``(max_steps,)`` loss before each accepted iteration (NaN after).
    """

    x: np.ndarray
    value: float
    grad: np.ndarray
    aux: Any
    steps: int
    evaluations: int
    converged: bool
    history: np.ndarray


def _steepest(g: np.ndarray) -> np.ndarray:
    """Steepest descent, at most a unit step (the first direction, and a restart)."""
    return -g * min(1.0, 1.0 / max(float(np.linalg.norm(g)), 1e-300))


def _direction(g: np.ndarray, pairs: deque, gamma: float) -> np.ndarray:
    """``−H g`` by the two-loop recursion over the stored ``(s, y, 1/s·y)`` pairs."""
    q = g.copy()
    alphas = []
    for s, y, rho in reversed(pairs):
        a = rho * float(s @ q)
        q -= a * y
        alphas.append(a)
    r = gamma * q
    for (s, y, rho), a in zip(pairs, reversed(alphas), strict=True):
        r += (a - rho * float(y @ r)) * s
    return -r


def _finite(f: float, g: np.ndarray) -> bool:
    return bool(np.isfinite(f) and np.all(np.isfinite(g)))


def _line_search(fun, x, f, g, d, budget):
    """``((x + α d, f, g, aux) or None, evaluations)``: the first ``α = 1`` trial that
    decreases ``f`` enough (Armijo, or approximate Wolfe at rounding level) and is not
    too short (``g(α)·d ≥ c₂ g·d``, the curvature condition); a short step is doubled
    while it keeps decreasing ``f`` (so a start near a stationary point of the bound
    map, where the gradient is tiny, is left in a few steps); a failed trial shrinks
    ``α`` by the interpolating quadratic, or returns the last good expanded step."""
    slope = float(g @ d)
    alpha, used, expansions, best = 1.0, 0, 0, None
    scale = float(np.linalg.norm(d))
    while used < min(budget, MAX_BACKTRACKS + MAX_EXPANSIONS):
        trial = x + alpha * d
        ft, gt, aux = fun(trial)
        used += 1
        finite = _finite(ft, gt)
        armijo = finite and ft <= f + ARMIJO * alpha * slope
        approximate = (
            finite
            and ft <= f + ROUNDING_RTOL * abs(f)
            and float(gt @ d) <= (2.0 * APPROXIMATE_WOLFE - 1.0) * slope
        )
        if armijo or approximate:
            if float(gt @ d) < CURVATURE * slope and expansions < MAX_EXPANSIONS:
                best, alpha, expansions = (trial, ft, gt, aux), 2.0 * alpha, expansions + 1
                continue
            return (trial, ft, gt, aux), used
        if best is not None:  # an expansion went too far: keep the last good step
            return best, used
        if alpha * scale <= 1e-16 * (1.0 + float(np.linalg.norm(x))):
            break
        quadratic = -slope * alpha**2 / (2.0 * (ft - f - slope * alpha)) if finite else np.nan
        shrunk = 0.5 * alpha
        alpha = float(np.clip(quadratic, 0.1 * alpha, shrunk)) if np.isfinite(quadratic) else shrunk
    return best, used


def lbfgs(
    fun: Callable[[np.ndarray], tuple[float, np.ndarray, Any]],
    x0,
    *,
    max_steps: int,
    gtol: float,
    memory: int = 10,
) -> Result:
    """Minimise ``f`` over a ``(n,)`` float vector (see the module doc).

    Args:
        fun: ``x -> (f, g, aux)``: the loss, its ``(n,)`` gradient (NumPy, float) and
            anything to keep from the evaluation (returned for the final point).
        x0: ``(n,)`` start.
        max_steps: cap on accepted iterations; evaluations are capped at
            ``(MAX_BACKTRACKS + 2) · max_steps``.
        gtol: stop when the gradient norm is at most this.
        memory: stored ``(s, y)`` pairs.
    """
    x = np.array(x0, dtype=float)
    f, g, aux = fun(x)
    evaluations, steps = 1, 0
    history = np.full(max_steps, np.nan)
    pairs: deque = deque(maxlen=memory)
    gamma = 1.0
    converged = bool(np.linalg.norm(g) <= gtol)
    d = _steepest(g)
    while not converged and steps < max_steps and _finite(f, g):
        budget = (MAX_BACKTRACKS + 2) * max_steps - evaluations
        found, used = _line_search(fun, x, f, g, d, budget)
        evaluations += used
        if found is None:
            if pairs and evaluations < (MAX_BACKTRACKS + 2) * max_steps:  # restart
                pairs.clear()
                d = _steepest(g)
                continue
            break
        trial, ft, gt, aux_t = found
        s, y = trial - x, gt - g
        sy = float(s @ y)
        if sy > 1e-12 * float(np.linalg.norm(s)) * float(np.linalg.norm(y)):
            pairs.append((s, y, 1.0 / sy))
            gamma = sy / float(y @ y)
        history[steps] = f
        steps += 1
        x, f, g, aux = trial, ft, gt, aux_t
        converged = bool(np.linalg.norm(g) <= gtol)
        d = _direction(g, pairs, gamma) if pairs else _steepest(g)
        if not (float(g @ d) < 0.0 and np.all(np.isfinite(d))):
            pairs.clear()
            d = _steepest(g)
    return Result(x, f, g, aux, steps, evaluations, converged, history)
