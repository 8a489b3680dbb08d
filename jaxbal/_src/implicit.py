"""Newton root finding with implicit differentiation, for any robot.

:func:`newton_solve` solves ``residual(x, params) = 0`` for ``x`` by Newton's method
(Jacobian by ``jax.jacfwd``, a dense linear solve per step, a fixed iteration cap in a
``lax.while_loop``), globalised by step halving: a step that does not lower ``‖r‖∞``
enough (Armijo's test) is halved and tried again, so a start far from the root does not
jump to a singularity and diverge. It differentiates the solution *implicitly*:

    dx = -(∂r/∂x)⁻¹ · (∂r/∂params · dparams)

through a :func:`jax.custom_jvp` rule. The Newton iterations themselves are never
differentiated, so the cost of a derivative is one extra linear solve whatever the
number of iterations, and derivatives of every order and in both modes work: the
tangent rule is written in JAX operations that are themselves differentiable
(nested ``jvp`` for velocities/accelerations of a trajectory; ``grad`` through
those by transposition of the linear tangent rule).

Usage::

    sol = newton_solve(lambda x, p: x**2 - p, jnp.array([1.0]), jnp.array([2.0]))
    sol.value, sol.converged           # (√2,), True
    jax.grad(lambda p: newton_solve(f, x0, p).value[0])(p)   # 1 / (2√2)

``throw=True`` (default) raises a :class:`ValueError` eagerly when the solve did not
converge; under ``jit``/``vmap``/``grad`` the concrete outcome is unknown, so use
the returned ``converged`` mask instead.

References:
    Krantz & Parks (2002), *The Implicit Function Theorem*; Blondel et al. (2022),
    "Efficient and modular implicit differentiation", NeurIPS; Yamashita & Fukushima
    (2001), "On the rate of convergence of the Levenberg-Marquardt method",
    Computing Suppl. 15 (the step at a singular Jacobian); Nocedal & Wright (2006),
    *Numerical Optimization*, §3.1 and §11.2 (sufficient decrease, step halving).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.types import Array, Float
from jaxbal._src.validation import is_traced, runtime_checks

__all__ = ["RootSolution", "newton_solve"]

ARMIJO = 1e-4  # sufficient decrease of a (scaled) Newton step, Nocedal & Wright §3.1


class RootSolution(eqx.Module):
    """Outcome of :func:`newton_solve`.

    Attributes:
        value: ``(k,)`` the root ``x`` (differentiable w.r.t. ``params``).
        residual_norm: ``‖residual(value, params)‖∞`` at the returned root.
        converged: boolean, ``residual_norm <= tol`` and everything finite.
    """

    value: Float[Array, " k"]
    residual_norm: Float[Array, ""]
    converged: jax.Array


def _newton_iterations(residual, x0, params, tol, max_steps):
    """Plain Newton iterations (not differentiated: wrapped by the custom_jvp)."""
    unbatched = jax.tree_util.tree_map(lambda _: None, params)
    return _newton_stack(residual, tol, max_steps, unbatched)(x0[None], params)[0]


def _newton_stack(residual, tol, max_steps, axes):
    """Newton iterations on a stack of ``n`` problems, as one ``while_loop``.

    The returned function maps ``xs (n, k)`` and ``params`` (leaves batched along their
    first axis where ``axes`` says ``0``, shared where it says ``None``) to the roots
    ``(n, k)``. The loop runs while *any* problem is unconverged and updates only those
    (a converged or non-finite problem is frozen), which is what ``vmap`` of a
    ``while_loop`` does, written out with a scalar loop predicate: ``checkify`` refuses a
    batched predicate, and with it every checked program that solves inverse kinematics
    along samples. Its batching rule merges a new batch axis into the stack, so a
    ``vmap`` of any depth stays one loop with a scalar predicate. The residual's value
    checks are not traced inside the loop: the caller checks the root it returns.
    """
    res = jax.vmap(residual, in_axes=(0, axes))
    jac = jax.vmap(jax.jacfwd(residual, argnums=0), in_axes=(0, axes))

    @jax.custom_batching.custom_vmap
    def solve(xs, params):
        def norms(x):
            return jnp.max(jnp.abs(res(x, params)), axis=-1)

        def cond(state):
            step, _, norm, _ = state
            return (step < max_steps) & jnp.any(norm > tol)

        def body(state):
            step, x, norm, scale = state
            active = norm > tol  # False for a converged or a non-finite problem
            trial = x - scale[:, None] * _step(jac(x, params), res(x, params))
            trial_norm = norms(trial)
            # a step that does not lower the residual by a fraction of what Newton
            # predicts (Armijo's test on ‖r‖∞), or leaves it non-finite, is refused and
            # halved: a full step from far away can jump to near a singularity and
            # diverge (an arm drawn through its base, to q ~ 1e16)
            accept = active & (trial_norm <= (1.0 - ARMIJO * scale) * norm)
            return (
                step + 1,
                jnp.where(accept[:, None], trial, x),
                jnp.where(accept, trial_norm, norm),
                jnp.where(accept, 1.0, jnp.where(active, scale / 2, scale)),
            )

        start = (jnp.asarray(0), xs, norms(xs), jnp.ones(xs.shape[:1], xs.dtype))
        _, x, _, _ = jax.lax.while_loop(cond, body, start)
        return x

    @solve.def_vmap
    def _batched(axis_size, in_batched, xs, params):
        xs_batched, params_batched = in_batched
        n = xs.shape[-2]
        size = axis_size * n

        def merge(leaf, axis, batched):
            if batched and axis is None:  # (A, ...) -> each repeated for the n problems
                return jnp.repeat(leaf, n, axis=0), 0
            if batched:  # (A, n, ...) -> (A n, ...)
                return leaf.reshape((size, *leaf.shape[2:])), 0
            if axis is None:
                return leaf, None
            return jnp.broadcast_to(leaf, (axis_size, *leaf.shape)).reshape(
                (size, *leaf.shape[1:])
            ), 0

        leaves, tree = jax.tree_util.tree_flatten(params)
        pairs = [
            merge(leaf, axis, batched)
            for leaf, axis, batched in zip(
                leaves,
                tree.flatten_up_to(axes),
                tree.flatten_up_to(params_batched),
                strict=True,
            )
        ]
        flat = tree.unflatten([leaf for leaf, _ in pairs])
        new_axes = tree.unflatten([axis for _, axis in pairs])
        xs = xs if xs_batched else jnp.broadcast_to(xs, (axis_size, *xs.shape))
        roots = _newton_stack(residual, tol, max_steps, new_axes)(
            xs.reshape((size, xs.shape[-1])), flat
        )
        return roots.reshape((axis_size, n, xs.shape[-1])), True

    def checks_off(xs, params):
        # The residual's own value checks (a robot's guards) are traced off: they would
        # be hidden from checkify inside the custom_vmap, and callers check the root.
        with runtime_checks(False):
            return solve(xs, params)

    return checks_off


def _step(jacobian: Float[Array, "n k k"], r: Float[Array, "n k"]) -> Float[Array, "n k"]:
    """Newton's step ``J⁻¹ r`` of each problem, or, where it is not finite (a singular
    Jacobian: e.g. an MJCF arm drawn straight, the usual ``qpos0``, whose inverse
    kinematics starts there), a Levenberg-Marquardt step ``(JᵀJ + μI)⁻¹ Jᵀ r`` with
    ``μ = ‖r‖ (tr(JᵀJ)/k + ‖r‖)`` (Yamashita & Fukushima 2001), which leaves the
    singular configuration. Problems with a finite Newton step are unchanged."""
    newton = jnp.linalg.solve(jacobian, r[..., None])[..., 0]
    finite = jnp.all(jnp.isfinite(newton), axis=-1, keepdims=True)

    def levenberg(_):
        normal = jnp.einsum("nik,nil->nkl", jacobian, jacobian)
        size = r.shape[-1]
        length = jnp.linalg.norm(r, axis=-1)
        mu = length * (jnp.trace(normal, axis1=-2, axis2=-1) / size + length)
        damped = normal + mu[:, None, None] * jnp.eye(size)
        step = jnp.linalg.solve(damped, jnp.einsum("nik,ni->nk", jacobian, r)[..., None])
        return jnp.where(finite, newton, step[..., 0])

    # the predicate is one scalar for the whole stack (the loop's own batching)
    return jax.lax.cond(jnp.all(finite), lambda _: newton, levenberg, None)


@partial(jax.custom_jvp, nondiff_argnums=(0, 3, 4))
def _root(residual, x0, params, tol, max_steps):
    return _newton_iterations(residual, jax.lax.stop_gradient(x0), params, tol, max_steps)


@_root.defjvp
def _root_jvp(residual, tol, max_steps, primals, tangents):
    x0, params = primals
    _, params_dot = tangents
    x = _root_jit(residual, x0, params, tol, max_steps)
    # Implicit function theorem: r(x(θ), θ) = 0  =>  J_x ẋ = -J_θ θ̇.
    _, r_dot = jax.jvp(lambda p: residual(x, p), (params,), (params_dot,))
    jac_x = jax.jacfwd(residual, argnums=0)(x, params)
    x_dot = -jnp.linalg.solve(jac_x, r_dot)
    return x, x_dot


# jit with the residual static: repeated eager solves with the same (module-level)
# residual reuse one compiled Newton loop.
_root_jit = jax.jit(_root, static_argnums=(0, 3, 4))


def newton_solve(
    residual: Callable,
    x0: Float[Array, " k"],
    params,
    *,
    tol: float = 1e-12,
    max_steps: int = 50,
    throw: bool = True,
    what: str = "Newton solve",
) -> RootSolution:
    """Solve ``residual(x, params) = 0`` by Newton's method, differentiable in ``params``.

    Args:
        residual: ``(x (k,), params) -> (k,)``, a pure, hashable function (define it
            at module level so that repeated solves reuse one compilation); any arrays
            it needs to be differentiated with respect to must be passed through
            ``params`` (closed-over arrays are treated as constants).
        x0: ``(k,)`` initial guess (not differentiated).
        params: any pytree of arrays.
        tol: convergence threshold on ``‖residual‖∞`` (units of the residual).
        max_steps: iteration cap (a refused, halved step counts as an iteration).
        throw: raise ``ValueError`` eagerly when not converged (ignored under tracing,
            where the ``converged`` flag must be used).
        what: a short description used in the error message.

    Returns:
        A :class:`RootSolution`. Its ``value`` has the implicit-function derivative
        with respect to ``params`` (forward and reverse mode, any order).

    Raises:
        ValueError: when ``throw`` and the (concrete) solve did not converge.
    """
    x0 = jnp.asarray(x0, dtype=float)
    if x0.ndim != 1:
        raise ValueError(f"x0 must be a vector (k,), got shape {x0.shape}")
    out_shape = jax.eval_shape(residual, x0, params).shape
    if out_shape != x0.shape:
        raise ValueError(f"residual must map (k,) to (k,), got {x0.shape} -> {out_shape}")
    x = _root_jit(residual, x0, params, tol, max_steps)
    norm = jnp.max(jnp.abs(jax.lax.stop_gradient(residual(x, params))))
    converged = jnp.isfinite(norm) & jnp.all(jnp.isfinite(x)) & (norm <= tol)
    if throw and not is_traced(converged):
        if not bool(np.asarray(converged)):
            raise ValueError(
                f"{what} did not converge: residual {float(norm):.3e} "
                f"after at most {max_steps} Newton steps (no solution near the initial guess?)"
            )
    return RootSolution(value=x, residual_norm=norm, converged=converged)
