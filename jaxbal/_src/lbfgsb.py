"""Bound-constrained L-BFGS (SciPy's L-BFGS-B) driven from the host around one compiled
value-and-gradient: the optimiser of :func:`jaxbal.design.codesign` above
:data:`~jaxbal._src.host_bfgs.HOST_MAX_VARIABLES` design variables (below, the dense
BFGS of :mod:`jaxbal._src.host_bfgs`, which needs no SciPy import).

The design variables are optimised directly, their bounds held by L-BFGS-B's projected
search (generalised Cauchy point, then a quasi-Newton step on the free variables), so
a loss that is quadratic in the variables (the RMS force, the added mass and inertia
of counter-masses) stays quadratic: measured on the co-designs of
``benchmarks/codesign_bench.py``, 2–4× fewer evaluations than the L-BFGS of
:mod:`jaxbal._src.lbfgs` on the smooth bound map ``x = lower + r²`` (SCARA 17 → 8,
DUAL-V 43 → 20, a 20-variable arm 144–154 → 37–43, the same optima to 1e-15), and a
variable may start *at* its bound.

It stops when the projected gradient's largest component is at most ``gtol``, or when
an iteration lowers the loss by less than :data:`FTOL` relative (rounding: the point is
then accurate to about ``√FTOL`` relative in a well-conditioned problem). SciPy's test
is relative to ``max(|f|, 1)``, i.e. absolute for a small loss, such as a balancing
loss falling towards zero: each run therefore sees the loss divided by its value at the
run's start, and a run stopped by that test far below it is restarted, rescaled.

``fun`` is called on the host with a NumPy point and returns NumPy values; a point where
the loss or its gradient is not finite (a line-search trial far outside the useful
region) is returned to L-BFGS-B as a large finite value with a zero gradient, so the
line search backtracks, and never becomes the result unless the start itself is not
finite (then the run stops at once).

**One BLAS thread.** L-BFGS-B's matrices are ``n × memory`` (tiny), but SciPy's OpenBLAS
starts a thread pool whose spin-waiting threads fight XLA's own for the cores between
evaluations: measured on the 2-core CPU (20-variable co-design of
``benchmarks/codesign_bench.py``), L-BFGS-B's own time grew from 0.5 ms to 10–62 ms per
co-design. :func:`lbfgsb` therefore limits BLAS to one thread while it runs
(``threadpoolctl``; the limit is restored on return).

References:
    Byrd, Lu, Nocedal & Zhu (1995), SIAM J. Sci. Comput. 16(5), L-BFGS-B;
    Zhu, Byrd, Lu & Nocedal (1997), ACM TOMS 23(4), algorithm 778;
    SciPy's ``scipy.optimize.minimize(method="L-BFGS-B")``.
"""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable
from functools import partial

import numpy as np

from jaxbal._src.lbfgs import MAX_BACKTRACKS, Result

#: Relative reduction of the loss per iteration below which L-BFGS-B stops (a few
#: units of rounding: the loss cannot decrease further); counted as converged.
FTOL = 1e-15
#: A run stopped by :data:`FTOL` with the loss below this fraction of its value at the
#: run's start is restarted with the loss rescaled (L-BFGS-B's test is then absolute).
RESCALE_BELOW = 1e-3
#: Restarts of that kind (each keeps the point, not the correction pairs).
MAX_RESTARTS = 8
#: Evaluations kept to return the final point's auxiliary output without re-evaluating.
_KEPT = 8


def projected_gradient(x, g, lower, upper) -> np.ndarray:
    """``P(x − g) − x``: the gradient with the components that point out of the box at
    an active bound removed (zero exactly at a bound-constrained stationary point)."""
    return np.clip(x - g, lower, upper) - x


def _recorder(history: np.ndarray, steps: int, scale: float):
    """L-BFGS-B's callback (SciPy recognises the parameter name ``intermediate_result``):
    the loss after each iteration, in the caller's units, into ``history`` after the
    ``steps`` iterations of earlier runs."""
    counter = [steps]

    def record(intermediate_result):
        counter[0] += 1
        if counter[0] < history.size:
            history[counter[0]] = intermediate_result.fun * scale

    return record


def lbfgsb(
    fun: Callable[[np.ndarray], tuple[float, np.ndarray, object]],
    x0,
    lower,
    upper,
    *,
    max_steps: int,
    gtol: float,
    memory: int = 10,
) -> Result:
    """Minimise ``f`` over ``lower ≤ x ≤ upper`` (see the module doc).

    Args:
        fun: ``x -> (f, g, aux)``: the loss, its ``(n,)`` gradient (NumPy, float) and
            anything to keep from the evaluation (returned for the final point).
        x0: ``(n,)`` start, inside the bounds.
        lower, upper: ``(n,)`` bounds (``-inf``/``inf`` where there is none).
        max_steps: cap on iterations; evaluations are capped at
            ``(MAX_BACKTRACKS + 2) · max_steps``.
        gtol: stop when the projected gradient (largest component) is at most this.
        memory: stored correction pairs.

    Returns:
        A :class:`~jaxbal._src.lbfgs.Result`; ``grad`` is the gradient at ``x``,
        ``converged`` means the projected gradient fell below ``gtol`` or the loss could
        not be lowered by more than :data:`FTOL` relative (rounding).
    """
    with one_blas_thread():
        return _lbfgsb(fun, x0, lower, upper, max_steps=max_steps, gtol=gtol, memory=memory)


#: the ``threadpoolctl`` controller, created once (it inspects the loaded libraries)
_CONTROLLER = []


def one_blas_thread():
    """A context in which BLAS runs on one thread (module doc). The controller is
    created once, after SciPy's optimisers are loaded (it limits only the BLAS libraries
    loaded when it is created: SciPy may bring its own)."""
    import scipy.optimize  # noqa: F401
    from threadpoolctl import ThreadpoolController

    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0].limit(limits=1, user_api="blas")


def _lbfgsb(fun, x0, lower, upper, *, max_steps: int, gtol: float, memory: int) -> Result:
    # imported here: scipy.optimize takes ~0.3-0.6 s to import, a third of jaxbal's
    # import time when nothing else needs it
    from scipy.optimize import Bounds, minimize

    x0 = np.array(x0, dtype=float)
    lower = np.broadcast_to(np.asarray(lower, dtype=float), x0.shape)
    upper = np.broadcast_to(np.asarray(upper, dtype=float), x0.shape)
    kept: OrderedDict = OrderedDict()
    state = {"evaluations": 0, "penalty": None}
    history = np.full(max_steps, np.nan)

    def evaluate(x):
        key = x.tobytes()
        if key not in kept:
            f, g, aux = fun(x.copy())
            state["evaluations"] += 1
            kept[key] = (float(f), np.asarray(g, dtype=float), aux)
            while len(kept) > _KEPT:
                kept.popitem(last=False)
        return kept[key]

    f0, g0, _ = evaluate(x0)
    if not (np.isfinite(f0) and np.all(np.isfinite(g0))):
        return Result(x0, f0, g0, kept[x0.tobytes()][2], 0, 1, False, history)
    # a non-finite trial is a wall: well above the start, flat (L-BFGS-B backtracks)
    state["penalty"] = abs(f0) * 1e6 + 1e6

    def objective(x, scale):
        f, g, _ = evaluate(x)
        if np.isfinite(f) and np.all(np.isfinite(g)):
            return f / scale, g / scale
        return state["penalty"] / scale, np.zeros_like(g)

    history[0] = f0
    x, f, g, steps, converged = x0, f0, g0, 0, False
    for _ in range(MAX_RESTARTS + 1):
        # L-BFGS-B's FTOL test is relative to max(|f|, 1): the loss is divided by its
        # value at the start of each run, so that the test stays relative as it falls
        scale = abs(f) if f != 0.0 else 1.0
        result = minimize(
            partial(objective, scale=scale),
            x,
            jac=True,
            method="L-BFGS-B",
            bounds=Bounds(lower, upper),
            callback=_recorder(history, steps, scale),
            options={
                "maxiter": max_steps - steps,
                "maxfun": (MAX_BACKTRACKS + 2) * (max_steps - steps),
                "gtol": gtol / scale,
                "ftol": FTOL,
                "maxcor": memory,
            },
        )
        x = np.clip(np.asarray(result.x, dtype=float), lower, upper)
        f, g, aux = evaluate(x)
        steps += int(result.nit)
        stationary = np.max(np.abs(projected_gradient(x, g, lower, upper)), initial=0.0) <= gtol
        # stopped by FTOL: converged, unless the loss fell far below the run's scale
        # (then the test was absolute, not relative): another run, rescaled
        rounding = result.status == 0 and abs(f) >= RESCALE_BELOW * scale
        converged = bool(np.isfinite(f) and (stationary or rounding))
        if converged or result.status != 0 or steps >= max_steps or not np.isfinite(f):
            break
    history[steps:] = np.nan
    return Result(x, f, g, aux, steps, state["evaluations"], converged, history)
