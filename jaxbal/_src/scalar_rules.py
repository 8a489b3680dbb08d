"""Scalar rules of the straight-line interpreter (:mod:`jaxbal._src.straight_line`).

Arrays are NumPy object arrays of scalars: concrete NumPy scalars (constants, folded
here) or 0-d JAX values. Elementwise primitives apply entry by entry (constants folded,
exact zeros and ones dropped); shape primitives (broadcast, reshape, slice, concatenate,
pad, transpose …) rearrange entries; reductions, cumulative sums and ``dot_general``
become explicit sums in XLA's left-to-right order. :func:`structural` returns ``None``
for a primitive it does not know.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

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
ELEMENTWISE = set(_NUMPY) | {
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
_IDENTITIES = {"add": 0, "mul": 1, "max": -np.inf, "min": np.inf, "or": False, "and": True}
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
CALLS = {"pjit": "jaxpr", "jit": "jaxpr", "closed_call": "call_jaxpr", "core_call": "call_jaxpr"}
CUSTOM = {"custom_jvp_call": "call_jaxpr", "custom_vjp_call": "call_jaxpr"}


def concrete(x) -> bool:
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
    if all(concrete(e) for e in flat):
        return jnp.asarray(np.asarray(flat, dtype=dtype).reshape(entries.shape))
    if not flat:
        return jnp.zeros(entries.shape, dtype)
    return jnp.stack([jnp.asarray(e, dtype) for e in flat]).reshape(entries.shape)


def _is_value(x, value) -> bool:
    return concrete(x) and np.ndim(x) == 0 and x == value and np.isfinite(x)


#: While :func:`shared_subexpressions` is active: ``key -> (result, args)`` of the scalar
#: operations emitted so far, so that an operation repeated on the same inputs (the same
#: ``cos q_1`` of several bodies' poses, the same product in a cross product and in its
#: derivative) is emitted once. The arguments are kept so that their ids stay unique.
_EMITTED: dict | None = None
#: While :func:`shared_subexpressions` has a budget: ``[operations left]``.
_BUDGET: list | None = None


class TooLarge(Exception):
    """More traced scalar operations than the budget of :class:`shared_subexpressions`."""


class shared_subexpressions:
    """A context in which :func:`_scalar_op` emits each distinct operation once
    (common-subexpression elimination: the same primitive with the same parameters on
    the same traced values or constants returns the earlier result, bit for bit).

    With a ``budget``, emitting more than ``budget`` operations on traced values raises
    :class:`TooLarge` (each is one equation of the traced program, so a program cut
    short would have had more than ``budget`` equations)."""

    def __init__(self, budget: int | None = None):
        self.budget = budget

    def __enter__(self):
        global _EMITTED, _BUDGET
        self._outer = (_EMITTED, _BUDGET)
        _EMITTED, _BUDGET = {}, (None if self.budget is None else [self.budget])
        return self

    def __exit__(self, *exc):
        global _EMITTED, _BUDGET
        _EMITTED, _BUDGET = self._outer


#: binary operations whose result does not depend on the order of their operands
_COMMUTATIVE = {"add", "add_any", "mul"}


def _operand_key(x):
    if concrete(x):
        return ("c", str(x.dtype), np.asarray(x).tobytes())
    return ("t", id(x))


def _scalar_op(name, primitive, params, args, dtype):
    """One elementwise primitive on scalar ``args`` (constants folded, exact 0/1 dropped,
    and, within :class:`shared_subexpressions`, repeated operations emitted once)."""
    if _EMITTED is None or all(concrete(a) for a in args):
        return _emit(name, primitive, params, args, dtype)
    try:
        operands = tuple(map(_operand_key, args))
        if name in _COMMUTATIVE:  # a + b and b + a are the same bits (IEEE 754)
            operands = tuple(sorted(operands, key=repr))
        key = (name, tuple(sorted(params.items())), str(dtype), *operands)
        hash(key)
    except TypeError:  # an unhashable parameter: emitted without sharing
        return _emit(name, primitive, params, args, dtype)
    if key not in _EMITTED:
        _EMITTED[key] = (_emit(name, primitive, params, args, dtype), args)
    return _EMITTED[key][0]


def _emit(name, primitive, params, args, dtype):
    if all(concrete(a) for a in args):
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
    if name == "select_n" and concrete(args[0]):
        return args[1 + int(args[0])]
    if _BUDGET is not None:
        _BUDGET[0] -= 1
        if _BUDGET[0] < 0:
            raise TooLarge
    if primitive is None:
        return _LAX[name](*args)
    return primitive.bind(*args, **params)


def elementwise(eqn, args):
    name, dtype = eqn.primitive.name, eqn.outvars[0].aval.dtype
    args = np.broadcast_arrays(*args)
    out = np.empty(args[0].shape, dtype=object)
    for index in np.ndindex(out.shape):
        scalars = [a[index] for a in args]
        out[index] = _scalar_op(name, eqn.primitive, eqn.params, scalars, dtype)
    return out


def _fold(op: str, values, dtype):
    """Left-to-right reduction of a list of scalars with the binary operation ``op`` (the
    order of XLA's own reductions over short axes, so results agree to the last bit).
    An empty list gives the operation's identity (``jnp.all`` of nothing is True)."""
    if not values:
        identity = _IDENTITIES[op]
        if np.issubdtype(dtype, np.integer) and op in ("max", "min"):
            limits = np.iinfo(dtype)
            identity = limits.min if op == "max" else limits.max
        return np.asarray(identity, dtype=dtype)[()]
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


def structural(eqn, args):
    """Shape-only primitives on object arrays (a list of them for the primitives with
    several results, ``split`` and ``unstack``); ``None`` when not handled here."""
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
    if name == "split":  # several results (the transpose of a concatenate)
        bounds = np.cumsum([int(n) for n in p["sizes"]])[:-1]
        return list(np.split(x, bounds, axis=p["axis"]))
    if name == "unstack":  # several results (the transpose of a stack)
        rows = np.moveaxis(x, p["axis"], 0)  # sliced, not indexed: 0-d arrays stay arrays
        return [rows[i : i + 1].reshape(rows.shape[1:]) for i in range(rows.shape[0])]
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
