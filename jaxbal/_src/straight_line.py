"""Straight-line code: re-evaluate a function's jaxpr one scalar at a time.

The generic physics (nested forward-mode derivatives of body poses, small ``(n, 3)``
arrays of bodies, sums over bodies) is traced once into a jaxpr and then replayed by a
small interpreter that splits every array into its scalar entries. Each primitive
becomes scalar operations, so that under ``vmap`` every operation acts on one ``(N,)``
array: XLA fuses them into a handful of loops, as it does for a hand-written closed
form, instead of materialising ``(N, bodies, 3)`` intermediates and calling reduction
kernels over axes of length 3 or 5. On the way the interpreter folds constants (the
robot's parameters when they are not traced), drops products with an exact zero
(e.g. the zero z-offsets and products of inertia of planar bodies) and emits each
distinct operation once (the same ``cos q_1`` of every body's pose, the same product
in a force and in its derivative: ~40 % fewer operations to trace, transform under
``grad``/``vmap`` and compile; XLA's own CSE made the runtime the same).

The generated code's transcendentals are then computed once per state and read back
by every output (:mod:`jaxbal._src.materialise`: XLA's CPU fusion would copy them into
each output's loop). Under ``vmap`` the program is batched by binding its scalar
operations again on the batched values (:mod:`jaxbal._src.batched_call`), not by JAX's
batching pass; equations no output needs (a ``jvp``'s primal values) are not generated.

Primitives the interpreter does not know (``cond``, callbacks, ``gather``, loops …) are
evaluated on re-assembled arrays, exactly as :func:`jax.core.eval_jaxpr` would, so any
function is accepted; the result is the same function of the same inputs (the same
operations in the same order up to the exact-zero simplifications, which do not change
any finite result).

:func:`straight_line` only rewrites traced calls (under ``jit``, ``vmap``, ``grad``):
eager calls run the original function, whose value checks raise ``ValueError``.
"""

from __future__ import annotations

import functools
from collections import OrderedDict

import jax
import numpy as np
from jax.extend import core

from jaxbal._src.batched_call import batchable, live
from jaxbal._src.materialise import bind, schedule, scheduled
from jaxbal._src.scalar_rules import (
    CALLS,
    CUSTOM,
    ELEMENTWISE,
    TooLarge,
    elementwise,
    join,
    shared_subexpressions,
    split,
    structural,
)


def _fallback(eqn, args):
    """Evaluate ``eqn`` on re-assembled arrays, as :func:`jax.core.eval_jaxpr` does."""
    arrays = [join(a, v.aval.dtype) for a, v in zip(args, eqn.invars, strict=True)]
    return [split(o) for o in bind(eqn, *arrays)]


def _elementwise_only(closed) -> bool:
    """Whether a custom-derivative function is plain elementwise maths (e.g. ``cos_sin``),
    whose own derivative rule equals the one the interpreter's scalar operations have.
    Others (e.g. :func:`equinox.error_if`, whose rule keeps its ``cond`` out of AD) are
    evaluated with their rule, on re-assembled arrays."""
    return all(e.primitive.name in ELEMENTWISE for e in closed.jaxpr.eqns)


def evaluate(jaxpr, consts, args, wanted=None) -> list[np.ndarray]:
    """Evaluate ``jaxpr`` on object arrays of scalars; returns object arrays (``None``
    for the outputs not ``wanted``). Equations no wanted output depends on are skipped:
    a ``jvp``'s primal values, for one (the momentum of the wrench's ``dp/dt``), were a
    third of the DUAL-V's and Orthoglide's generated operations, traced by every
    transformation of the program before JAX or XLA removed them."""
    wanted = [True] * len(jaxpr.outvars) if wanted is None else wanted
    keep, used = live(jaxpr, wanted)
    env = {}

    def read(v):
        if isinstance(v, core.Literal):
            return split(np.asarray(v.val, dtype=v.aval.dtype))
        return env[v]

    for var, value in zip(jaxpr.constvars, consts, strict=True):
        env[var] = split(value)
    for var, value in zip(jaxpr.invars, args, strict=True):
        env[var] = value
    for eqn, kept in zip(jaxpr.eqns, keep, strict=True):
        if not kept:
            continue
        args_ = [read(v) for v in eqn.invars]
        name = eqn.primitive.name
        outs = None
        if name in ELEMENTWISE:
            outs = [elementwise(eqn, args_)]
        elif name in CALLS or (name in CUSTOM and _elementwise_only(eqn.params[CUSTOM[name]])):
            closed = eqn.params[CALLS.get(name) or CUSTOM[name]]
            outs = evaluate(closed.jaxpr, closed.consts, args_, [v in used for v in eqn.outvars])
        else:
            result = structural(eqn, args_)
            several = eqn.primitive.multiple_results
            outs = None if result is None else (result if several else [result])
        if outs is None:
            outs = _fallback(eqn, args_)
        for var, value in zip(eqn.outvars, outs, strict=True):
            if not isinstance(var, core.DropVar):
                env[var] = value
    return [read(v) if w else None for v, w in zip(jaxpr.outvars, wanted, strict=True)]


#: Above this many scalar results (summed over the jaxpr's equations) the replay would
#: trace and compile too long: ``fn`` runs as is. XLA's compile time of the replay grows
#: faster than linearly (measured on the 2-core CPU: the DUAL-V's Kane forces, 21,696
#: scalars, 2.3 s; the 22-body split model of its torque distribution, 39,563 scalars,
#: 19.7 s for a single state against 3.6 s without the replay).
MAX_SCALARS = 30_000
#: Above this many scalar operations in the *generated* code (after constant folding,
#: dropped zeros and shared subexpressions) ``fn`` runs as is: the replay's compile time
#: outgrows its gain. Measured on the 2-core CPU, vmapped shaking wrench with the robot
#: traced: the built-in robots generate 176–1,582 operations (compile 0.2–0.9 s, 4–27×
#: faster than without the replay; their Kane forces 257–1,617), an MJCF RUSR loop
#: 3,607 (compile 3.7 s against 1.0 s, only 1.6× faster) and an MJCF 3-RRR 7,779 (8 s
#: against 1.3 s, 1.3× faster; its first ``wrench_along`` took 17 s). (Before the
#: subexpressions were shared: 294–3,006, 4,280 and 9,148, with a limit of 4,000.)
MAX_GENERATED = 3_000
#: Generated programs kept per wrapped function (least recently used dropped).
CACHE_SIZE = 64


def scalar_count(jaxpr) -> int:
    """Scalar results of all equations of ``jaxpr``, nested calls included."""
    total = 0
    for eqn in jaxpr.eqns:
        total += sum(int(np.prod(v.aval.shape, dtype=int)) for v in eqn.outvars)
        for sub in core.jaxprs_in_params(eqn.params):
            total += scalar_count(sub)
    return total


def _leaf_key(leaf):
    """Cache key of one argument leaf: the abstract value of a traced leaf, the value
    of a concrete one (it is folded into the generated code)."""
    if isinstance(leaf, jax.core.Tracer):
        aval = leaf.aval
        return ("traced", aval.shape, str(aval.dtype), bool(getattr(aval, "weak_type", False)))
    value = np.asarray(leaf)
    return ("const", type(leaf).__name__, value.shape, str(value.dtype), value.tobytes())


def _generate(fn, leaves, treedef, traced):
    """``(jitted straight-line program, output treedef, fn's own jaxpr)`` of ``fn`` for
    these argument leaves; the program is ``None`` when ``fn`` is larger than
    :data:`MAX_SCALARS` or the code generated larger than :data:`MAX_GENERATED`."""
    specs = [
        jax.ShapeDtypeStruct(leaf.aval.shape, leaf.aval.dtype)
        for leaf, t in zip(leaves, traced, strict=True)
        if t
    ]

    def inner(*values):
        it = iter(values)
        full = [next(it) if t else leaf for leaf, t in zip(leaves, traced, strict=True)]
        return fn(*jax.tree_util.tree_unflatten(treedef, full))

    closed, shapes = jax.make_jaxpr(inner, return_shape=True)(*specs)
    flat_shapes, out_tree = jax.tree_util.tree_flatten(shapes)
    if scalar_count(closed.jaxpr) > MAX_SCALARS:
        return None, out_tree, closed

    def program(*values):
        # stopped as soon as it emits more operations than the limit (TooLarge): the
        # MJCF UR5e's, 3-RRR's and RUSR's (about 3,000-6,500) took 0.4-1.2 s in full
        with shared_subexpressions(budget=MAX_GENERATED):
            outs = evaluate(closed.jaxpr, closed.consts, [split(v) for v in values])
        return [join(o, s.dtype) for o, s in zip(outs, flat_shapes, strict=True)]

    # The generated program is traced once and kept as one jaxpr: later traces (under
    # other jit/vmap/grad contexts) reuse it and JAX's caches of its transformations.
    try:
        generated = jax.make_jaxpr(program)(*specs)
    except TooLarge:
        return None, out_tree, closed
    if len(generated.jaxpr.eqns) > MAX_GENERATED:
        return None, out_tree, closed
    if scheduled(generated):
        # the transcendentals computed once per state and read back (materialise.py)
        generated = jax.make_jaxpr(functools.partial(schedule, generated))(*specs)
    program = jax.jit(core.jaxpr_as_fun(generated))
    if not generated.effects:  # a check inside stays visible to checkify, batched by vmap
        program = batchable(program, generated)
    return program, out_tree, closed


def straight_line(fn, context=lambda: ()):
    """``fn``, evaluated as straight-line scalar code whenever it is traced.

    The arguments' traced leaves become the inputs of the generated code; concrete
    leaves (e.g. a robot closed over by ``vmap``) are folded into it as constants.
    Functions larger than :data:`MAX_SCALARS`, or whose generated code is larger than
    :data:`MAX_GENERATED`, are evaluated as they are. The generated
    code is cached on the argument structure, the traced leaves' shapes and dtypes, the
    concrete leaves' values and ``context()`` (global switches read while tracing).
    """
    cache: OrderedDict = OrderedDict()

    def entry(args, generate: bool):
        """``(cache entry or None, traced leaves)`` of a call with ``args``."""
        leaves, treedef = jax.tree_util.tree_flatten(args)
        traced = [isinstance(leaf, jax.core.Tracer) for leaf in leaves]
        dynamic = [leaf for leaf, t in zip(leaves, traced, strict=True) if t]
        if not dynamic:
            return None, dynamic
        key = (treedef, tuple(_leaf_key(leaf) for leaf in leaves), context())
        try:
            found = cache.get(key)
        except TypeError:  # an unhashable static field: generate without caching
            key, found = None, None
        if found is not None:
            cache.move_to_end(key)
        elif generate:
            found = _generate(fn, leaves, treedef, traced)
            if key is not None:
                cache[key] = found
                if len(cache) > CACHE_SIZE:
                    cache.popitem(last=False)
        return found, dynamic

    @functools.wraps(fn)
    def wrapped(*args):
        found, dynamic = entry(args, generate=True)
        if found is None or found[0] is None:
            return fn(*args)
        program, out_tree, _ = found
        return jax.tree_util.tree_unflatten(out_tree, program(*dynamic))

    def as_written(*args):
        """``fn(*args)`` as written (not replayed): the jaxpr traced for the replay of
        the same call, when there is one, is evaluated instead of tracing ``fn`` again
        (the same operations, in a fraction of the trace time: e.g. the peak metrics'
        re-evaluation of their peak sample after the replay of every sample)."""
        found, dynamic = entry(args, generate=False)
        if found is None:
            return fn(*args)
        _, out_tree, closed = found
        outs = core.jaxpr_as_fun(closed)(*dynamic)
        return jax.tree_util.tree_unflatten(out_tree, outs)

    wrapped.as_written = as_written
    return wrapped
