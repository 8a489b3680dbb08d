"""A bound-constrained (projected) BFGS method that runs as one compiled loop: the
reduced co-design's optimiser (:mod:`jaxbal._src.design_compiled`).

Along a reduced motion (:mod:`jaxbal._src.reduced_motion`) the co-design loss costs a
few hundred multiply-adds, so the host-driven L-BFGS-B (:mod:`jaxbal._src.lbfgsb`)
spends its time in latency: ~0.1 ms to dispatch and wait for each evaluation plus
~50 µs of SciPy per iteration. Here the whole run is one ``lax.while_loop`` inside the
caller's compiled program (one dispatch), and each pass of the loop evaluates the
value and gradient exactly once (a single call site, so the loss is compiled once):

- the first pass evaluates the start;
- after an accepted point ``x`` (loss ``f``, gradient ``g``): stop when the projected
  gradient ``P(x − g) − x`` is at most ``gtol`` (largest component), when the step
  lowered ``f`` by at most :data:`~jaxbal._src.lbfgsb.FTOL` relative (rounding), or
  after ``max_steps`` steps. Otherwise the next trial is ``x(α) = P(x + α d)``, with
  ``d`` the quasi-Newton direction on the free variables: the ε-active set of Bertsekas
  (1982) (within ``ε = min(ε₀, ‖P(x − g) − x‖)`` of a bound, gradient pointing out)
  is decoupled from the dense BFGS approximation ``B`` of the Hessian and moves along
  ``−g_i / B_ii``; ``α = 1``, except ``min(1, 1/‖g‖)`` on the first step (``B = I``);
- a trial is accepted when its loss is finite and satisfies Armijo's condition along
  the projection arc, ``f(α) ≤ f + c₁ g·(x(α) − x)``; otherwise ``α`` shrinks to the
  minimiser of the interpolating quadratic, kept in ``[0.1 α, 0.5 α]``. After
  :data:`~jaxbal._src.lbfgs.MAX_BACKTRACKS` trials the run stops: converged when every
  trial's loss lay within rounding of ``f``.
- an accepted step updates ``B`` with ``s = Δx``, ``y = Δg`` (Powell's damping keeps it
  positive definite; before the first update ``B = (y·y / s·y) I``).

A dense ``B`` (``n × n``) suits the few tens of variables this is used for; the
direction is a Cholesky solve of that size.

References:
    Bertsekas (1982), SIAM J. Control Optim. 20(2), projected (quasi-)Newton methods;
    Nocedal & Wright (2006), Numerical Optimization, eqs (6.19) BFGS update, (6.20)
    initial scaling, (18.14) Powell's damping, §3.5 interpolating backtracking.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jax import lax

from jaxbal._src.lbfgs import ARMIJO, MAX_BACKTRACKS
from jaxbal._src.lbfgsb import FTOL
from jaxbal._src.types import Array, Scalar

__all__ = ["BoxResult", "box_bfgs"]

#: largest ε of the ε-active set (in the variables' units; Bertsekas's ε₀).
ACTIVE_EPS = 1e-8
#: a failed line search whose trials all lay within this relative distance of ``f``
#: stopped at rounding: converged.
ROUNDING = 1e-13
#: Powell's damping: ``y`` is mixed with ``B s`` when ``s·y < DAMPING · s·B s``.
DAMPING = 0.2


class BoxResult(NamedTuple):
    """Result of :func:`box_bfgs` (arrays: it runs under ``jit``).

    Attributes:
        x: ``(n,)`` final point.
        value: loss at ``x``.
        grad: ``(n,)`` gradient at ``x``.
        aux: auxiliary output of ``fun`` at ``x``.
        steps: accepted iterations.
        evaluations: value-and-gradient evaluations.
        converged: the projected gradient reached ``gtol``, or the loss could not be
            lowered by more than :data:`~jaxbal._src.lbfgsb.FTOL` relative (rounding).
        history: ``(max_steps,)`` loss before each accepted iteration (NaN after).
        context: the context of the run (see :func:`box_bfgs`'s ``prelude``).
    """

    x: Array
    value: Scalar
    grad: Array
    aux: Any
    steps: Array
    evaluations: Array
    converged: Array
    history: Array
    context: Any


def _update(hessian, s, y, first, xp=jnp):
    """Damped BFGS update of the Hessian approximation (``first``: scaled identity
    before it), in the array namespace ``xp`` (``jax.numpy``, or ``numpy`` for the
    host-driven :mod:`jaxbal._src.host_bfgs`)."""
    with np.errstate(divide="ignore", invalid="ignore"):  # masked below
        sy = xp.dot(s, y)
        scale = xp.dot(y, y) / sy
        usable = first & (sy > 0) & xp.isfinite(scale)
        hessian = xp.where(usable, scale * xp.eye(s.size, dtype=s.dtype), hessian)
        hs = hessian @ s
        shs = xp.dot(s, hs)
        theta = xp.where(sy >= DAMPING * shs, 1.0, (1.0 - DAMPING) * shs / (shs - sy))
        r = theta * y + (1.0 - theta) * hs
        updated = hessian - xp.outer(hs, hs) / shs + xp.outer(r, r) / xp.dot(s, r)
        good = (shs > 0) & xp.all(xp.isfinite(updated))
    return xp.where(good, 0.5 * (updated + updated.T), hessian)


def _solve(matrix, rhs):
    """``matrix⁻¹ rhs`` for a symmetric positive definite ``matrix`` by Gauss–Jordan
    elimination without pivoting (stable for such matrices) in a ``fori_loop``: a few
    operations to compile, where LAPACK's Cholesky factor and triangular solves cost
    ~0.3 s of tracing and compiling for ``n`` of a few tens."""
    n = rhs.size
    augmented = jnp.concatenate([matrix, rhs[:, None]], axis=1)

    def eliminate(k, augmented):
        row = augmented[k] / augmented[k, k]
        factors = augmented[:, k].at[k].set(0.0)
        return (augmented - factors[:, None] * row[None, :]).at[k].set(row)

    return lax.fori_loop(0, n, eliminate, augmented)[:, n]


def _direction(hessian, grad, active):
    """``−B̃⁻¹ g`` with the active variables decoupled (diagonal only)."""
    free = ~active
    diagonal = jnp.diagonal(hessian)
    kept = jnp.where(free[:, None] & free[None, :], hessian, 0.0)
    kept = kept + jnp.diag(jnp.where(active, diagonal, 0.0))
    step = _solve(kept, grad)
    # B stays positive definite (damped updates); a failed elimination (rounding)
    # falls back to the scaled gradient
    return jnp.where(jnp.all(jnp.isfinite(step)), -step, -grad / diagonal)


def box_bfgs(
    fun: Callable[[Array, Any], tuple[Scalar, Array, Any]],
    x0: Array,
    lower: Array,
    upper: Array,
    *,
    max_steps: int,
    gtol: Scalar,
    aux: Any,
    context: Any = None,
    prelude: tuple[Array, Callable[[Any], Any]] | None = None,
) -> BoxResult:
    """Minimise ``f`` over ``lower ≤ x ≤ upper`` (module doc); pure JAX, to be called
    under ``jit``.

    Args:
        fun: ``(x, context) -> (f, g, aux)``: loss, ``(n,)`` gradient and anything to
            keep for the final point; called at one site.
        x0: ``(n,)`` start inside the bounds.
        lower, upper: ``(n,)`` bounds (``-inf``/``inf`` where there is none).
        max_steps: cap on accepted steps (static: the history's length); evaluations
            are capped at ``(MAX_BACKTRACKS + 2) · max_steps``.
        gtol: stop when the projected gradient's largest component is at most this.
        aux: a pytree shaped as ``fun``'s ``aux`` (its values are not used).
        context: the second argument of ``fun`` (a pytree of arrays).
        prelude: ``(x, prepare)``: evaluate ``fun`` first at this ``x`` and replace
            ``context`` with ``prepare(aux)`` before the run (e.g. scales set by the
            starting design's metric values), with the same call site.

    Returns:
        A :class:`BoxResult`. A start where ``f`` or ``g`` is not finite returns at
        once, not converged.
    """
    x0 = jnp.clip(jnp.asarray(x0, dtype=float), lower, upper)
    n = x0.size
    zero, false = jnp.asarray(0.0, dtype=x0.dtype), jnp.asarray(False)
    offset = 0 if prelude is None else 1
    state = {
        "x": x0, "f": zero, "g": jnp.zeros_like(x0), "aux": aux,
        "hessian": jnp.eye(n, dtype=x0.dtype),
        "trial": x0 if prelude is None else jnp.asarray(prelude[0], dtype=x0.dtype),
        "direction": jnp.zeros_like(x0), "alpha": zero, "steps": jnp.asarray(0),
        "evaluations": jnp.asarray(0), "tries": jnp.asarray(0), "close": false,
        "stop": false, "converged": false, "context": context,
        "history": jnp.full(max_steps, jnp.nan, dtype=x0.dtype),
    }  # fmt: skip
    cap = (MAX_BACKTRACKS + 2) * max_steps + offset

    def cond(state):
        return ~state["stop"]

    def body(state):
        x, f, g, trial = state["x"], state["f"], state["g"], state["trial"]
        first = state["evaluations"] == offset
        value, grad, aux = fun(trial, state["context"])
        finite = jnp.isfinite(value) & jnp.all(jnp.isfinite(grad))
        moved = jnp.dot(g, trial - x)
        accepted = first | (finite & (value <= f + ARMIJO * moved))
        evaluations = state["evaluations"] + 1
        # -- accepted: the trial is the new point
        tiny = ~first & (f - value <= FTOL * jnp.abs(f))
        updated = _update(state["hessian"], trial - x, grad - g, state["steps"] == 0)
        hessian = jnp.where(first, state["hessian"], updated)
        steps = state["steps"] + jnp.where(first, 0, 1)
        history = jnp.where(first, state["history"], state["history"].at[state["steps"]].set(f))
        projected = jnp.clip(trial - grad, lower, upper) - trial
        stationary = jnp.max(jnp.abs(projected), initial=0.0) <= gtol
        done = ~finite | stationary | tiny | (steps >= max_steps) | (evaluations >= cap)
        eps = jnp.minimum(ACTIVE_EPS, jnp.linalg.norm(projected))
        active = ((trial - lower <= eps) & (grad > 0)) | ((upper - trial <= eps) & (grad < 0))
        direction = _direction(hessian, grad, active)
        alpha = jnp.where(steps == 0, jnp.minimum(1.0, 1.0 / jnp.linalg.norm(grad)), 1.0)
        new = {
            "x": trial, "f": value, "g": grad, "aux": aux, "hessian": hessian,
            "trial": jnp.clip(trial + alpha * direction, lower, upper), "direction": direction,
            "alpha": alpha, "steps": steps, "evaluations": evaluations,
            "tries": jnp.asarray(0), "close": jnp.asarray(True), "stop": done,
            "converged": finite & (stationary | tiny), "history": history,
            "context": state["context"],
        }  # fmt: skip
        # -- rejected: backtrack along the projection arc
        a = state["alpha"]
        curvature = value - f - moved
        shrunk = jnp.where(
            finite & (curvature > 0), -moved * a / (2.0 * curvature), 0.5 * a
        )  # moved = α g·d' along the arc: the quadratic through f, slope and value
        shrunk = jnp.clip(shrunk, 0.1 * a, 0.5 * a)
        close = state["close"] & finite & (jnp.abs(value - f) <= ROUNDING * jnp.abs(f))
        tries = state["tries"] + 1
        failed = (tries >= MAX_BACKTRACKS) | (evaluations >= cap)
        back = dict(state)
        back.update(
            trial=jnp.clip(x + shrunk * state["direction"], lower, upper), alpha=shrunk,
            evaluations=evaluations, tries=tries, close=close, stop=failed,
            converged=failed & close,
        )  # fmt: skip
        chosen = jax.tree_util.tree_map(lambda a, b: jnp.where(accepted, a, b), new, back)
        if prelude is None:
            return chosen
        # the prelude's evaluation: only the context and the first trial change
        ready = dict(state)
        ready.update(context=prelude[1](aux), trial=x0, evaluations=evaluations)
        return jax.tree_util.tree_map(
            lambda a, b: jnp.where(state["evaluations"] == 0, a, b), ready, chosen
        )

    out = lax.while_loop(cond, body, state)
    return BoxResult(
        out["x"], out["f"], out["g"], out["aux"], out["steps"], out["evaluations"] - offset,
        out["converged"], out["history"], out["context"],
    )  # fmt: skip
