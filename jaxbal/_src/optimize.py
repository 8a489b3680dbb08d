"""Gradient-based optimisation of design and trajectory parameters with optax.

A small driver for design and trajectory problems (the joint co-design, the Pareto
fronts, a user's own loss): minimise a scalar ``loss(params)`` over any pytree
``params`` with optax's L-BFGS (zoom line search) -- quasi-Newton, so smooth
least-squares design problems converge to ~1e-10 relative in tens of steps -- or with
any optax first-order optimiser (Adam for non-smooth objectives such as a maximum over
time), as one compiled ``lax.while_loop`` (nothing returns to Python between steps).
:func:`jaxbal.design.codesign` uses it when given ``optimizer=``; by default it drives
SciPy's L-BFGS-B from the host around one compiled value-and-gradient
(:mod:`jaxbal._src.lbfgsb`; the joint co-design, a compact L-BFGS, :mod:`jaxbal._src.lbfgs`),
which compiles several times faster.

References:
    Liu & Nocedal (1989), L-BFGS; optax.lbfgs.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

from jaxbal._src.validation import check_stopping, is_traced


class Solution(NamedTuple):
    """Result of :func:`minimize`.

    Attributes:
        params: the optimised pytree.
        value: final loss value.
        grad_norm: final gradient norm (global L2).
        steps: number of iterations done.
        converged: whether ``grad_norm <= gtol`` was reached (the returned iterate is
            the one that met it, not a last update that left the gradient above).
        history: ``(max_steps,)`` loss at every iteration (NaN after stopping).
    """

    params: Any
    value: jax.Array
    grad_norm: jax.Array
    steps: jax.Array
    converged: jax.Array
    history: jax.Array


_DEFAULT_OPTIMIZER = optax.lbfgs()


def minimize(
    loss: Callable[..., jax.Array],
    params: Any,
    optimizer: optax.GradientTransformation | None = None,
    max_steps: int = 200,
    gtol: float = 1e-12,
    args: tuple = (),
) -> Solution:
    """Minimise ``loss(params, *args)`` (jit-compiled ``lax.while_loop``).

    The compiled loop is cached on ``(loss, optimizer, max_steps, gtol)`` and the
    *structure* of ``params`` and ``args``: calling again with new values (another
    path, another robot of the same kind) does not recompile, provided ``loss`` and
    ``optimizer`` are the same Python objects (define them once, at module level).

    Args:
        loss: scalar function of a pytree of float arrays (and of ``args``).
        params: starting point.
        optimizer: an optax transformation; default ``optax.lbfgs()``.
        max_steps: iteration cap.
        gtol: stop when the gradient norm falls below this.
        args: extra pytree arguments of ``loss`` (data; not optimised).

    Raises:
        ValueError: ``max_steps`` not an integer ``>= 1``, ``gtol`` not a finite
            number ``>= 0``, or a (concrete) starting parameter that is not a finite
            float array.
    """
    check_stopping(max_steps, gtol)
    for path, leaf in jax.tree_util.tree_flatten_with_path(params)[0]:
        if is_traced(leaf):
            continue
        value, name = np.asarray(leaf), f"params{jax.tree_util.keystr(path)}"
        if not np.issubdtype(value.dtype, np.floating):
            raise ValueError(f"{name} must be a float array, got dtype {value.dtype}")
        if not np.all(np.isfinite(value)):  # the loop ran, and returned NaN
            raise ValueError(f"{name} must be finite, got {value!r}")
    optimizer = _DEFAULT_OPTIMIZER if optimizer is None else optimizer
    return _run(loss, optimizer, _is_lbfgs(optimizer), max_steps, gtol, params, args)


@eqx.filter_jit
def _run(loss, optimizer, lbfgs: bool, max_steps: int, gtol: float, params, args):
    # one trace of the loss, shared by every call site (the step, the line search's
    # trials, the final value): a nested jit is traced once per argument structure and
    # its derivatives are taken from that jaxpr, not by tracing the Python again
    # (measured: the first co-design of the DUAL-V traced its wrench five times)
    @jax.jit
    def objective(p):
        return loss(p, *args)

    value_and_grad = optax.value_and_grad_from_state(objective) if lbfgs else None
    state = optimizer.init(params)
    history = jnp.full((max_steps,), jnp.nan)

    def cond(carry):
        _, _, step, grad_norm, _, _ = carry
        return (step < max_steps) & (grad_norm > gtol)

    def body(carry):
        params, state, step, _, history, _ = carry
        before = params
        if value_and_grad is not None:
            value, grad = value_and_grad(params, state=state)
            updates, state = optimizer.update(
                grad, state, params, value=value, grad=grad, value_fn=objective
            )
        else:
            value, grad = jax.value_and_grad(objective)(params)
            updates, state = optimizer.update(grad, state, params)
        params = optax.apply_updates(params, updates)
        history = history.at[step].set(value)
        return params, state, step + 1, optax.tree.norm(grad), history, before

    carry = (params, state, jnp.asarray(0), jnp.asarray(jnp.inf), history, params)
    params, state, steps, last_norm, history, before = jax.lax.while_loop(cond, body, carry)
    value, grad = jax.value_and_grad(objective)(params)
    grad_norm = optax.tree.norm(grad)
    # the loop stops on the gradient at the iterate *before* its last update: where the
    # update left a gradient above gtol (1.5e-14 > 1e-14: "not converged" after the
    # test was met), that iterate is returned, converged
    back = (grad_norm > gtol) & (last_norm <= gtol)
    params = jax.tree.map(lambda b, p: jnp.where(back, b, p), before, params)
    value, grad = jax.lax.cond(
        back, lambda: jax.value_and_grad(objective)(params), lambda: (value, grad)
    )
    grad_norm = optax.tree.norm(grad)
    return Solution(params, value, grad_norm, steps, grad_norm <= gtol, history)


def _is_lbfgs(optimizer) -> bool:
    try:
        state = optimizer.init(jnp.zeros(1))
    except Exception:  # pragma: no cover - exotic optimisers
        return False
    return "ScaleByLBFGSState" in repr(state) or "ScaleByZoomLinesearchState" in repr(state)
