"""Straight-line code: re-evaluate a function's jaxpr one scalar at a time.

The generic physics (nested forward-mode derivatives of body poses, small ``(n, 3)``
arrays of bodies, sums over bodies) is traced once into a jaxpr and then replayed by a
small interpreter that splits every array into its scalar entries. Each primitive
becomes scalar operations, so that under ``vmap`` every operation acts on one ``(N,)``
array: XLA fuses them into a handful of loops, as it does for a hand-written closed
form, instead of materialising ``(N, bodies, 3)`` intermediates and calling reduction
kernels over axes of length 3 or 5. On the way the interpreter folds constants (the
robot's parameters when they are not traced) and drops products with an exact zero
(e.g. the zero z-offsets and products of inertia of planar bodies).

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
import jax.numpy as jnp
import numpy as np
from jax.extend import core

_NUMPY = {
    "add": np.add,
    "add_any": np.add,
    "sub": np.subtract,
    "mul": np.multiply,
    "neg": np.negative,
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "asin": np.arcsin,
    "acos": np.arccos,
    "atan": np.arctan,
    "atan2": np.arctan2,
    "sinh": np.sinh,
    "cosh": np.cosh,
    "tanh": np.tanh,
    "exp": np.exp,
    "log": np.log,
    "log1p": np.log1p,
    "expm1": np.expm1,
    "sqrt": np.sqrt,
    "abs": np.abs,
    "sign": np.sign,
    "max": np.maximum,
    "min": np.minimum,
    "pow": np.power,
    "eq": np.equal,
    "ne": np.not_equal,
    "lt": np.less,
    "le": np.less_equal,
    "gt": np.greater,
    "ge": np.greater_equal,
    "and": np.bitwise_and,
    "or": np.bitwise_or,
    "not": np.invert,
    "is_finite": np.isfinite,
    "square": np.square,
    "floor": np.floor,
    "ceil": np.ceil,
}
#: Elementwise primitives without a NumPy twin above (evaluated with ``bind`` only).
_ELEMENTWISE = set(_NUMPY) | {
    "div",
    "integer_pow",
    "convert_element_type",
    "select_n",
    "rsqrt",
    "copy",
    "copy_p",
    "rem",
    "clamp",
    "logistic",
    "erf",
    "round",
    "nextafter",
    "stop_gradient",
}
_REDUCTIONS = {
    "reduce_sum": "add",
    "reduce_max": "max",
    "reduce_min": "min",
    "reduce_prod": "mul",
    "reduce_or": "or",
    "reduce_and": "and",
}
_CUMULATIVE = {"cumsum": "add", "cumprod": "mul", "cummax": "max", "cummin": "min"}
#: The binary operations the interpreter itself introduces (reductions, products).
_LAX = {
    "add": jax.lax.add,
    "mul": jax.lax.mul,
    "max": jax.lax.max,
    "min": jax.lax.min,
    "or": jax.lax.bitwise_or,
    "and": jax.lax.bitwise_and,
}
_CALLS = {"pjit": "jaxpr", "jit": "jaxpr", "closed_call": "call_jaxpr", "core_call": "call_jaxpr"}
_CUSTOM = {"custom_jvp_call": "call_jaxpr", "custom_vjp_call": "call_jaxpr"}


def _concrete(x) -> bool:
    return isinstance(x, np.ndarray | np.generic)


def _entries(shape, values) -> np.ndarray:
    out = np.empty(len(values), dtype=object)
    for k, value in enumerate(values):
        out[k] = value
    return out.reshape(shape)


def split(x) -> np.ndarray:
    """An object array of ``x``'s scalar entries (NumPy scalars where ``x`` is concrete)."""
    shape = np.shape(x)
    if not isinstance(x, jax.core.Tracer):
        flat = np.asarray(x).reshape(-1)
        return _entries(shape, [flat[k] for k in range(flat.size)])
    flat = jnp.reshape(x, (-1,))
    return _entries(shape, [flat[k] for k in range(flat.size)])


def join(entries: np.ndarray, dtype) -> jax.Array:
    """The array whose scalar entries are ``entries`` (inverse of :func:`split`)."""
    flat = list(entries.reshape(-1))
    if all(_concrete(e) for e in flat):
        return jnp.asarray(np.asarray(flat, dtype=dtype).reshape(entries.shape))
    if not flat:
        return jnp.zeros(entries.shape, dtype)
    return jnp.stack([jnp.asarray(e, dtype) for e in flat]).reshape(entries.shape)


def _is_value(x, value) -> bool:
    return _concrete(x) and np.ndim(x) == 0 and x == value and np.isfinite(x)


def _scalar_op(name, primitive, params, args, dtype):
    """One elementwise primitive on scalar ``args`` (constants folded, exact 0/1 dropped)."""
    if all(_concrete(a) for a in args):
        if name in _NUMPY:
            with np.errstate(all="ignore"):
                return np.asarray(_NUMPY[name](*args), dtype=dtype)[()]
        if name == "select_n":
            return args[1 + int(args[0])]
        with jax.ensure_compile_time_eval():
            out = primitive.bind(*(np.asarray(a) for a in args), **params)
        return np.asarray(out, dtype=dtype)[()]
    if name in ("add", "add_any") and _is_value(args[0], 0):
        return args[1]
    if name in ("add", "add_any", "sub") and _is_value(args[1], 0):
        return args[0]
    if name == "mul":
        for k in (0, 1):
            if _is_value(args[k], 0):
                return np.zeros((), dtype)[()]
            if _is_value(args[k], 1):
                return args[1 - k]
    if name == "select_n" and _concrete(args[0]):
        return args[1 + int(args[0])]
    if primitive is None:
        return _LAX[name](*args)
    return primitive.bind(*args, **params)


def _elementwise(eqn, args):
    name, dtype = eqn.primitive.name, eqn.outvars[0].aval.dtype
    args = np.broadcast_arrays(*args)
    out = np.empty(args[0].shape, dtype=object)
    for index in np.ndindex(out.shape):
        scalars = [a[index] for a in args]
        out[index] = _scalar_op(name, eqn.primitive, eqn.params, scalars, dtype)
    return out


def _fold(op: str, values, dtype):
    """Left-to-right reduction of a list of scalars with the binary operation ``op`` (the
    order of XLA's own reductions over short axes, so results agree to the last bit)."""
    out = values[0]
    for value in values[1:]:
        out = _scalar_op(op, None, {}, [out, value], dtype)
    return out


def _reduce(eqn, operand):
    op, dtype = _REDUCTIONS[eqn.primitive.name], eqn.outvars[0].aval.dtype
    axes = tuple(eqn.params["axes"])
    kept = [d for d in range(operand.ndim) if d not in axes]
    moved = np.transpose(operand, kept + list(axes))
    moved = moved.reshape(moved.shape[: len(kept)] + (-1,))
    out = np.empty(moved.shape[:-1], dtype=object)
    for index in np.ndindex(out.shape):
        out[index] = _fold(op, list(moved[index]), dtype)
    return out


def _cumulative(eqn, operand):
    op, dtype = _CUMULATIVE[eqn.primitive.name], eqn.outvars[0].aval.dtype
    axis, reverse = eqn.params["axis"], eqn.params["reverse"]
    moved = np.moveaxis(operand, axis, -1)
    out = np.empty(moved.shape, dtype=object)
    order = range(moved.shape[-1] - 1, -1, -1) if reverse else range(moved.shape[-1])
    for index in np.ndindex(moved.shape[:-1]):
        running = None
        for k in order:
            value = moved[index + (k,)]
            running = (
                value if running is None else _scalar_op(op, None, {}, [running, value], dtype)
            )
            out[index + (k,)] = running
    return np.moveaxis(out, -1, axis)


def _dot_general(eqn, lhs, rhs):
    (lc, rc), (lb, rb) = eqn.params["dimension_numbers"]
    dtype = eqn.outvars[0].aval.dtype
    lf = [d for d in range(lhs.ndim) if d not in lc and d not in lb]
    rf = [d for d in range(rhs.ndim) if d not in rc and d not in rb]
    lhs = np.transpose(lhs, list(lb) + lf + list(lc))
    rhs = np.transpose(rhs, list(rb) + rf + list(rc))
    nb, nlf, nrf = len(lb), len(lf), len(rf)
    shape = lhs.shape[: nb + nlf] + rhs.shape[nb : nb + nrf]
    contracted = int(np.prod(lhs.shape[nb + nlf :], dtype=int))
    lhs = lhs.reshape(lhs.shape[: nb + nlf] + (contracted,))
    rhs = rhs.reshape(rhs.shape[: nb + nrf] + (contracted,))
    out = np.empty(shape, dtype=object)
    for index in np.ndindex(shape):
        batch, left, right = index[:nb], index[nb : nb + nlf], index[nb + nlf :]
        terms = [
            _scalar_op("mul", None, {}, [lhs[batch + left][k], rhs[batch + right][k]], dtype)
            for k in range(contracted)
        ]
        out[index] = _fold("add", terms, dtype) if terms else np.zeros((), dtype)[()]
    return out


def _pad(eqn, operand, value):
    config = eqn.params["padding_config"]
    if any(lo < 0 or hi < 0 for lo, hi, _ in config):
        return None
    shape = tuple(
        lo + hi + n + max(n - 1, 0) * interior
        for n, (lo, hi, interior) in zip(operand.shape, config, strict=True)
    )
    out = np.empty(shape, dtype=object)
    out.fill(value[()])
    target = tuple(
        slice(lo, lo + max(n - 1, 0) * (interior + 1) + 1, interior + 1)
        for n, (lo, _, interior) in zip(operand.shape, config, strict=True)
    )
    if operand.size:
        out[target] = operand
    return out


def _broadcast(eqn, operand):
    shape, dims = eqn.params["shape"], eqn.params["broadcast_dimensions"]
    expanded = [1] * len(shape)
    for source, target in enumerate(dims):
        expanded[target] = operand.shape[source]
    return np.broadcast_to(operand.reshape(expanded), shape)


def _structural(eqn, args):
    """Shape-only primitives on object arrays; ``None`` when not handled here."""
    name, p = eqn.primitive.name, eqn.params
    x = args[0] if args else None
    if name == "broadcast_in_dim":
        return _broadcast(eqn, x)
    if name == "reshape" and p.get("dimensions") is None:
        return x.reshape(p["new_sizes"])
    if name == "squeeze":
        return x.reshape(eqn.outvars[0].aval.shape)
    if name == "transpose":
        return np.transpose(x, p["permutation"])
    if name == "slice":
        strides = p["strides"] or (1,) * x.ndim
        index = tuple(
            slice(a, b, s)
            for a, b, s in zip(p["start_indices"], p["limit_indices"], strides, strict=True)
        )
        return x[index]
    if name == "concatenate":
        return np.concatenate(args, axis=p["dimension"])
    if name == "stack":
        return np.stack(args, axis=p["axis"])
    if name == "rev":
        return np.flip(x, axis=tuple(p["dimensions"])) if p["dimensions"] else x
    if name == "pad":
        return _pad(eqn, x, args[1])
    if name == "iota":
        aval = eqn.outvars[0].aval
        values = np.arange(aval.shape[p["dimension"]], dtype=aval.dtype)
        shape = [1] * len(aval.shape)
        shape[p["dimension"]] = -1
        return split(np.broadcast_to(values.reshape(shape), aval.shape))
    if name in _REDUCTIONS:
        return _reduce(eqn, x)
    if name in _CUMULATIVE:
        return _cumulative(eqn, x)
    if name == "dot_general":
        return _dot_general(eqn, *args)
    return None


def _fallback(eqn, args):
    """Evaluate ``eqn`` on re-assembled arrays, as :func:`jax.core.eval_jaxpr` does."""
    arrays = [join(a, v.aval.dtype) for a, v in zip(args, eqn.invars, strict=True)]
    params = eqn.primitive.get_bind_params(eqn.params)
    with eqn.ctx.manager:
        outs = eqn.primitive.bind(*arrays, **params)
    outs = outs if eqn.primitive.multiple_results else [outs]
    return [split(o) for o in outs]


def _elementwise_only(closed) -> bool:
    """Whether a custom-derivative function is plain elementwise maths (e.g. ``cos_sin``),
    whose own derivative rule equals the one the interpreter's scalar operations have.
    Others (e.g. :func:`equinox.error_if`, whose rule keeps its ``cond`` out of AD) are
    evaluated with their rule, on re-assembled arrays."""
    return all(e.primitive.name in _ELEMENTWISE for e in closed.jaxpr.eqns)


def evaluate(jaxpr, consts, args) -> list[np.ndarray]:
    """Evaluate ``jaxpr`` on object arrays of scalars; returns object arrays."""
    env = {}

    def read(v):
        if isinstance(v, core.Literal):
            return split(np.asarray(v.val, dtype=v.aval.dtype))
        return env[v]

    for var, value in zip(jaxpr.constvars, consts, strict=True):
        env[var] = split(value)
    for var, value in zip(jaxpr.invars, args, strict=True):
        env[var] = value
    for eqn in jaxpr.eqns:
        args_ = [read(v) for v in eqn.invars]
        name = eqn.primitive.name
        outs = None
        if name in _ELEMENTWISE:
            outs = [_elementwise(eqn, args_)]
        elif name in _CALLS or (name in _CUSTOM and _elementwise_only(eqn.params[_CUSTOM[name]])):
            closed = eqn.params[_CALLS.get(name) or _CUSTOM[name]]
            outs = evaluate(closed.jaxpr, closed.consts, args_)
        else:
            result = _structural(eqn, args_)
            outs = None if result is None else [result]
        if outs is None:
            outs = _fallback(eqn, args_)
        for var, value in zip(eqn.outvars, outs, strict=True):
            if not isinstance(var, core.DropVar):
                env[var] = value
    return [read(v) for v in jaxpr.outvars]


#: Above this many scalar results (summed over the jaxpr's equations) the replay would
#: trace and compile too long (a mechanism with hundreds of bodies): ``fn`` runs as is.
MAX_SCALARS = 40_000
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
    """``(jitted straight-line program, output treedef)`` of ``fn`` for these argument
    leaves, or ``None`` when ``fn`` is larger than :data:`MAX_SCALARS`."""
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
    if scalar_count(closed.jaxpr) > MAX_SCALARS:
        return None
    flat_shapes, out_tree = jax.tree_util.tree_flatten(shapes)

    def program(*values):
        outs = evaluate(closed.jaxpr, closed.consts, [split(v) for v in values])
        return [join(o, s.dtype) for o, s in zip(outs, flat_shapes, strict=True)]

    # The generated program is traced once and kept as one jaxpr: later traces (under
    # other jit/vmap/grad contexts) reuse it and JAX's caches of its transformations.
    generated = jax.make_jaxpr(program)(*specs)
    return jax.jit(core.jaxpr_as_fun(generated)), out_tree


def straight_line(fn, context=lambda: ()):
    """``fn``, evaluated as straight-line scalar code whenever it is traced.

    The arguments' traced leaves become the inputs of the generated code; concrete
    leaves (e.g. a robot closed over by ``vmap``) are folded into it as constants.
    Functions larger than :data:`MAX_SCALARS` are evaluated as they are. The generated
    code is cached on the argument structure, the traced leaves' shapes and dtypes, the
    concrete leaves' values and ``context()`` (global switches read while tracing).
    """
    cache: OrderedDict = OrderedDict()

    @functools.wraps(fn)
    def wrapped(*args):
        leaves, treedef = jax.tree_util.tree_flatten(args)
        traced = [isinstance(leaf, jax.core.Tracer) for leaf in leaves]
        if not any(traced):
            return fn(*args)
        key = (treedef, tuple(_leaf_key(leaf) for leaf in leaves), context())
        try:
            generated = cache.get(key)
        except TypeError:  # an unhashable static field: generate without caching
            key, generated = None, None
        if generated is None:
            generated = _generate(fn, leaves, treedef, traced) or (None, None)
            if key is not None:
                cache[key] = generated
                if len(cache) > CACHE_SIZE:
                    cache.popitem(last=False)
        else:
            cache.move_to_end(key)
        program, out_tree = generated
        if program is None:
            return fn(*args)
        dynamic = [leaf for leaf, t in zip(leaves, traced, strict=True) if t]
        return jax.tree_util.tree_unflatten(out_tree, program(*dynamic))

    return wrapped
