"""Compute each transcendental of a straight-line program once per state.

XLA's CPU backend has no multi-output loop fusion: every output array of a compiled
``vmap`` (the force ``(N, 3)``, the moment ``(N, 3)``) is its own loop, into which XLA
copies every operation the output depends on. The DUAL-V's 8 sines and 8 cosines were
compiled into both the force's and the moment's loop (and the loop of an ``(N, 3)``
output computes each of its entries separately). ``jax.lax.optimization_barrier``
does not stop this on the CPU (its pipeline removes the barrier before fusion).

:func:`schedule` evaluates a scalar program (the straight-line code of
:mod:`jaxbal._src.straight_line`) in levels: a level's transcendentals (those whose
inputs are ready) that several output entries share (:data:`MIN_OUTPUTS`) pass
together through :func:`materialise`, which writes them to memory; the operations that
use them read them back. On the CPU :func:`materialise` is
a ``lax.cond`` whose branches both return their operand unchanged (XLA keeps a
conditional as a boundary no fusion crosses; the predicate is read from the bits of an
input value the level depends on, so that XLA cannot fold it unless that input is a
constant of the compiled program, e.g. a motion captured by ``jit``, whose
transcendentals and their users then fold as before; either branch gives the same
values);
elsewhere it is an optimisation barrier, which GPU fusion respects. Under ``vmap`` the
conditional acts on the whole batch (:func:`custom_vmap`: a batched predicate would
turn it into a ``select``, which fuses); under differentiation it is the identity (its
tangent passes through unchanged).

Measured on the 2-core CPU, one device, ``jit(vmap)`` of the shaking wrench in chunks of
1,024 states (million states/s, before → after): 2R 9.9 → 14.7, 3R 7.7 → 10.7, SCARA
7.0 → 11.7, DUAL-V 3.35 → 5.8; the Orthoglide has no transcendental (unchanged). The
first ``grad`` of a peak force compiles 0.03–0.08 s longer.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.custom_batching import custom_vmap
from jax.extend import core

#: Primitives worth computing once and reading back (XLA counts them as expensive).
EXPENSIVE = frozenset(
    {
        "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh",
        "asinh", "acosh", "atanh", "exp", "exp2", "expm1", "log", "log1p", "pow",
        "logistic", "erf", "erf_inv",
    }
)  # fmt: skip


def _predicate(anchor):
    """A boolean XLA cannot fold (from the bits of the first entry of ``anchor``);
    either value gives the same result."""
    first = jnp.reshape(anchor, (-1,))[0].astype(jnp.float32)
    return jax.lax.bitcast_convert_type(first, jnp.int32) != np.int32(0x7FC0_0BAD)


def _times_one(v):
    # the same values as ``v`` (x · 1 is exact, NaN and −0 included); a branch XLA
    # does not merge with the identity
    return jax.tree.map(lambda t: t * jnp.ones((), t.dtype), v)


def _cpu(x, anchor):
    return jax.lax.cond(_predicate(anchor), lambda v: v, _times_one, x)


def _other(x, anchor):
    del anchor
    return jax.lax.optimization_barrier(x)


@custom_vmap
def _boundary(x, anchor):
    # the default backend, read while tracing (``lax.platform_dependent`` costs ~80 ms
    # of lowering per program); either boundary gives the same values anywhere
    return (_cpu if jax.default_backend() == "cpu" else _other)(x, anchor)


@_boundary.def_vmap
def _boundary_batched(axis_size, in_batched, x, anchor):
    del axis_size
    # one boundary on the whole batch, at the innermost level: nested vmaps each
    # come back here, and the predicate is never batched
    return _boundary(x, anchor), in_batched[0]


@jax.custom_jvp
def materialise(x, anchor):
    """``x``, computed once and read back by its users (see the module doc).

    Args:
        x: the array to materialise.
        anchor: any array that is an input of the program (its first entry is the
            conditional's predicate on the CPU); not differentiated.
    """
    return _boundary(x, anchor)


@materialise.defjvp
def _materialise_jvp(primals, tangents):
    x, anchor = primals
    return materialise(x, anchor), tangents[0]


def _read(env, v):
    return v.val if isinstance(v, core.Literal) else env[v]


def _floating(v) -> bool:
    return jnp.issubdtype(v.aval.dtype, jnp.floating)


#: A transcendental is materialised when at least this many output entries depend on
#: it (below, its copies cost less than the boundary's write and read: measured on the
#: 2-core CPU, the 2R's torques, 2 outputs of sin q2 and cos q2, 27 → 17 million
#: states/s with it; its wrench, 6 outputs, 9.9 → 14.7).
MIN_OUTPUTS = 3


def _shared(jaxpr) -> set:
    """Indices of the expensive scalar equations that at least :data:`MIN_OUTPUTS`
    output entries of ``jaxpr`` depend on."""
    sizes = [int(np.prod(v.aval.shape, dtype=int)) for v in jaxpr.outvars]
    reach: dict = {}
    for k, v in enumerate(jaxpr.outvars):
        if not isinstance(v, core.Literal):
            reach[v] = reach.get(v, frozenset()) | {k}
    shared = set()
    for index in range(len(jaxpr.eqns) - 1, -1, -1):
        eqn = jaxpr.eqns[index]
        outputs = frozenset().union(*(reach.get(v, frozenset()) for v in eqn.outvars))
        if _grouped(eqn) and sum(sizes[k] for k in outputs) >= MIN_OUTPUTS:
            shared.add(index)
        for v in eqn.invars:
            if not isinstance(v, core.Literal):
                reach[v] = reach.get(v, frozenset()) | outputs
    return shared


def _levels(jaxpr, shared: set) -> tuple[list[int], list]:
    """For each equation: the number of ``shared`` equations on its longest input path,
    and the position of one program input it depends on (``None``: none)."""
    depth, source = {}, {v: k for k, v in enumerate(jaxpr.invars)}
    levels, sources = [], []
    for index, eqn in enumerate(jaxpr.eqns):
        inputs = [v for v in eqn.invars if not isinstance(v, core.Literal)]
        level = max((depth.get(v, 0) for v in inputs), default=0)
        found = [source[v] for v in inputs if source.get(v) is not None]
        levels.append(level)
        sources.append(min(found, default=None))
        for v in eqn.outvars:
            depth[v] = level + (index in shared)
            source[v] = sources[-1]
    return levels, sources


def bind(eqn, *args) -> list:
    """The outputs of ``eqn`` evaluated on ``args`` (as :func:`jax.core.eval_jaxpr` does)."""
    params = eqn.primitive.get_bind_params(eqn.params)
    with eqn.ctx.manager:
        out = eqn.primitive.bind(*args, **params)
    return out if eqn.primitive.multiple_results else [out]


def _batched(level: list, env: dict, anchor) -> None:
    """Evaluate the expensive scalar equations of one level into ``env``, their results
    materialised together."""
    outs = [bind(e, *(_read(env, v) for v in e.invars))[0] for e in level]
    if not outs:
        return
    outs = materialise(outs, anchor)
    for e, out in zip(level, outs, strict=True):
        env[e.outvars[0]] = out


def _grouped(eqn) -> bool:
    """An expensive floating-point operation on scalars."""
    scalar = all(v.aval.shape == () for v in eqn.invars + eqn.outvars)
    single = len(eqn.outvars) == 1 and _floating(eqn.outvars[0])
    return eqn.primitive.name in EXPENSIVE and single and scalar


def scheduled(closed) -> bool:
    """Whether :func:`schedule` changes how ``closed`` is evaluated: some expensive
    scalar operations are shared by several outputs (:data:`MIN_OUTPUTS`)."""
    return bool(_shared(closed.jaxpr))


def schedule(closed, *args):
    """Evaluate the scalar program ``closed`` (a closed jaxpr whose equations act on
    scalars) on ``args``, the expensive operations of each level materialised together.

    Level by level: the other equations in their order, then the level's expensive ones
    that several outputs share (:data:`MIN_OUTPUTS`), whose results pass together
    through :func:`materialise`.
    Programs without such operations are evaluated as they are.
    """
    jaxpr = closed.jaxpr
    anchor = next((a for a in args if np.size(a) > 0), None)
    shared = _shared(jaxpr)
    if not shared or anchor is None:
        return core.jaxpr_as_fun(closed)(*args)
    env = dict(zip(jaxpr.constvars, closed.consts, strict=True))
    env.update(zip(jaxpr.invars, args, strict=True))
    levels, sources = _levels(jaxpr, shared)
    for level in sorted(set(levels)):
        delayed, inputs = [], []
        for index, (eqn, at, source) in enumerate(zip(jaxpr.eqns, levels, sources, strict=True)):
            if at != level:
                continue
            if index in shared:
                delayed.append(eqn)
                inputs.append(source)
                continue
            env.update(zip(eqn.outvars, bind(eqn, *(_read(env, v) for v in eqn.invars)),
                           strict=True))  # fmt: skip
        # the predicate is read from an input these operations depend on: where it is a
        # constant of the compiled program (a motion captured by ``jit``), XLA folds the
        # boundary away and with it the transcendentals of constants
        found = [k for k in inputs if k is not None and np.size(args[k]) > 0]
        _batched(delayed, env, args[min(found)] if found else anchor)
    return [_read(env, v) for v in jaxpr.outvars]
