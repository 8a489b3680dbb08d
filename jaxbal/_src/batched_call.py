"""The call of a generated straight-line program, batched without JAX's batching pass.

A straight-line program (:mod:`jaxbal._src.straight_line`) is a jaxpr of ~500-1,600
scalar operations. Under ``vmap`` JAX's batching interpreter re-traced every one of
them (~80 µs each on the 2-core CPU), then partial evaluation (``grad``) and
``checkify`` (:func:`jaxbal.checked_jit`) each walked the batched copy again: ~0.2 s of
the first Orthoglide peak-force gradient's trace in a fresh process.

:func:`batchable` wraps the program's call so that under ``vmap`` its scalar equations
are bound again on the batched values themselves: an operation of a batched ``(N,)``
value and an unbatched scalar is the same primitive on the ``(N,)`` value (XLA's
elementwise operations broadcast a scalar), one bind each instead of a batching rule.
Equations on arrays (the splitting of the inputs, the stacking of the outputs, a
:mod:`~jaxbal._src.materialise` boundary, a primitive evaluated on arrays) are batched
by ``vmap`` one equation at a time. The batched program is kept as a ``jit`` inside a
``custom_vmap`` that later passes (``checkify``, partial evaluation) do not re-trace.

Differentiation is the program's own: a ``custom_jvp`` whose rule is ``jax.jvp`` of
the unbatched program (only the inputs with a tangent differentiated), so gradients,
Hessians and batched gradients are the ones the program had before.
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_batching import custom_vmap
from jax.custom_derivatives import SymbolicZero
from jax.extend import core

from jaxbal._src.materialise import bind


def _probe_scalar_broadcast() -> bool:
    """Whether this JAX binds a binary primitive on an ``(N,)`` and a ``()`` operand."""
    try:
        jax.make_jaxpr(lambda a, b: jax.lax.mul_p.bind(a, b))(np.ones(2), np.float64(2.0))
    except Exception:  # noqa: BLE001 - older JAX: operands are broadcast explicitly
        return False
    return True


#: Binary primitives whose scalar operand may stay a scalar next to a batched one.
_SCALAR_OPERANDS = frozenset(
    {"add", "sub", "mul", "div", "max", "min", "pow", "atan2", "rem", "nextafter",
     "eq", "ne", "lt", "le", "gt", "ge", "and", "or"}
) if _probe_scalar_broadcast() else frozenset()  # fmt: skip


def live(jaxpr, wanted=None) -> tuple[list[bool], set]:
    """``(keep, used)``: which equations of ``jaxpr`` the outputs marked in ``wanted``
    depend on (or that have effects), and the variables those equations read."""
    wanted = [True] * len(jaxpr.outvars) if wanted is None else wanted
    used = {
        v
        for v, w in zip(jaxpr.outvars, wanted, strict=True)
        if w and not isinstance(v, core.Literal)
    }
    keep = [False] * len(jaxpr.eqns)
    for index in range(len(jaxpr.eqns) - 1, -1, -1):
        eqn = jaxpr.eqns[index]
        if eqn.effects or any(v in used for v in eqn.outvars):
            keep[index] = True
            used.update(v for v in eqn.invars if not isinstance(v, core.Literal))
    return keep, used


def _batched_vars(jaxpr, batched: tuple, keep: list[bool]) -> dict:
    """Whether each variable of ``jaxpr`` has the leading batch axis (``batched[k]``:
    input ``k`` has it): an equation's outputs have it iff one of its inputs has."""
    flag = {v: False for v in jaxpr.constvars}
    flag.update(zip(jaxpr.invars, batched, strict=True))
    for eqn, kept in zip(jaxpr.eqns, keep, strict=True):
        if kept:
            moving = any(flag[v] for v in eqn.invars if not isinstance(v, core.Literal))
            flag.update((v, moving) for v in eqn.outvars)
    return flag


def _emit(closed, batched: tuple, size: int):
    """``(run, out_flags)``: ``run`` computes the program's outputs batched from its
    inputs (``batched[k]``: input ``k`` has a leading axis of length ``size``);
    ``out_flags[k]``: whether output ``k`` has that axis."""
    jaxpr = closed.jaxpr
    keep, _ = live(jaxpr)
    flag = _batched_vars(jaxpr, batched, keep)

    def run(*args):
        env = dict(zip(jaxpr.constvars, closed.consts, strict=True))
        env.update(zip(jaxpr.invars, args, strict=True))

        def read(v):
            return v.val if isinstance(v, core.Literal) else env[v]

        for eqn, kept in zip(jaxpr.eqns, keep, strict=True):
            if not kept:  # no output depends on it (a pjit's would be removed by JAX)
                continue
            values = [read(v) for v in eqn.invars]
            flags = [not isinstance(v, core.Literal) and flag[v] for v in eqn.invars]
            if not any(flags):
                outs = bind(eqn, *values)
            elif all(v.aval.shape == () for v in eqn.invars + eqn.outvars) and not list(
                core.jaxprs_in_params(eqn.params)
            ):
                # a scalar operation: the same primitive on the (N,) values
                if eqn.primitive.name not in _SCALAR_OPERANDS:
                    values = [
                        x if b else jnp.broadcast_to(x, (size,))
                        for x, b in zip(values, flags, strict=True)
                    ]
                outs = bind(eqn, *values)
            else:
                axes = [0 if b else None for b in flags]
                outs = jax.vmap(functools.partial(bind, eqn), in_axes=axes)(*values)
            env.update(zip(eqn.outvars, outs, strict=True))
        return [read(v) for v in jaxpr.outvars]

    out_flags = [not isinstance(v, core.Literal) and flag[v] for v in jaxpr.outvars]
    return run, out_flags


def _front(x):
    """``x`` unchanged; under ``vmap`` with its batch axis first. A ``custom_jvp`` must
    batch its rule as it batches its function (JAX does not reconcile them), and the
    function's batched outputs have the axis first (``custom_vmap``), while JAX's
    batching of the rule may leave it elsewhere. A reshape to its own shape is that
    move: its batching rule puts the axis first, and it is linear (transposable)."""
    if x.dtype == jax.dtypes.float0:
        return x
    return jax.lax.reshape_p.bind(x, new_sizes=tuple(x.shape), dimensions=None, sharding=None)


#: Batched programs kept per program (batched inputs and batch size), oldest dropped.
CACHE_SIZE = 16


def batchable(program, closed):
    """``program`` (a ``jit`` of the scalar jaxpr ``closed``, called on flat arrays and
    returning a list), batched by :func:`_emit` under ``vmap`` and differentiated as
    ``program`` (module doc)."""
    cache: dict = {}

    def batched_program(in_batched: tuple, size: int):
        key = (in_batched, size)
        if key not in cache:
            emitted, flags = _emit(closed, in_batched, size)
            compiled = jax.jit(emitted)
            # opaque to checkify and partial evaluation; a nested vmap batches it
            opaque = custom_vmap(lambda *args: compiled(*args))

            @opaque.def_vmap
            def _nested(axis_size, nested_batched, *args):
                axes = [0 if b else None for b in nested_batched]
                outs = jax.vmap(compiled, in_axes=axes, out_axes=0, axis_size=axis_size)(*args)
                return outs, [True] * len(outs)

            cache[key] = (opaque, flags)
            if len(cache) > CACHE_SIZE:
                cache.pop(next(iter(cache)))
        return cache[key]

    @custom_vmap
    def run(*args):
        return program(*args)

    @run.def_vmap
    def _batched(axis_size, in_batched, *args):
        opaque, flags = batched_program(tuple(in_batched), axis_size)
        return opaque(*args), list(flags)

    @jax.custom_jvp
    def call(*args):
        return run(*args)

    def _jvp(primals, tangents):
        active = [not isinstance(t, SymbolicZero) for t in tangents]

        def moving(*values):
            it = iter(values)
            return program(*(next(it) if a else p for p, a in zip(primals, active, strict=True)))

        chosen = [p for p, a in zip(primals, active, strict=True) if a]
        directions = [t for t, a in zip(tangents, active, strict=True) if a]
        outs, tangents_out = jax.jvp(moving, chosen, directions)
        return [_front(x) for x in outs], [_front(t) for t in tangents_out]

    call.defjvp(_jvp, symbolic_zeros=True)
    call.program = program  # the unbatched program (tests)
    return call
