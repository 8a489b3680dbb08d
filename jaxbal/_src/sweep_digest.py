"""Fingerprints of what a sweep's values depend on, stable from one process to the next.

A resumed store must hold values computed by the same inputs and the same code: the
robot, the motion (or motion factory), the fixed θ, the metric and the axes' setters.
:func:`value_digest` hashes a value by content — arrays by dtype, shape and bytes,
numbers and strings by value, containers and pytrees element by element, a dataclass
instance that is no pytree by its fields and a ``types.SimpleNamespace`` by its
attributes (a config object), a ``functools.partial`` by its function and arguments —
and a Python function by its code: the bytecode, constants and names of its code object
and of the code objects nested in it (lambdas, inner functions), its defaults, the
values its closure captures, and the globals it reads that are numbers, strings,
arrays, containers of them, pytrees (a module-level profile, robot or base model),
config objects (dataclass, namespace, partial), the data attributes it names of a
module it reads (``config.SCALE``), functions of its own module, jitted or not (a
helper whose body changed, a module-level index), or objects whose class gives a
``repr`` of their own (an enum member, a dtype, a path). Line numbers, object addresses
and ``hash()`` (salted per process) never enter, so an unchanged script rerun in a new
process gives the same digest; editing a metric's or a setter's body, or a constant or
config it reads, gives another. Code of other modules (jaxbal's own functions reached
by name, NumPy, …) enters by name only. A global that the user's code reads and that
the digest cannot represent (an instance of a plain class, whose ``repr`` shows no
content) is refused by name rather than skipped: editing it would go unnoticed (a
library's module state — flags, caches — is skipped: it is no config of the user's).
"""

from __future__ import annotations

import dataclasses
import dis
import functools
import hashlib
import json
import re
import sys
import sysconfig
import types
from functools import partial
from pathlib import Path

import jax
import numpy as np

__all__ = ["check_resumable", "fingerprint", "sweep_parts", "value_digest"]

#: what the parts of a sweep's fingerprint are called in a refusal
PART_NAMES = {
    "axes": "axes or their values",
    "outputs": "metric's outputs (names, shapes, dtypes)",
    "evaluation": "evaluation (affine fast path or direct)",
    "metric": "metric (its name or code)",
    "setters": "axes' setters (their code)",
    "robot": "robot",
    "motion": "motion",
    "trajectory": "fixed trajectory variables θ",
}


#: values hashed by their ``repr``
_PLAIN = bool | int | float | complex | str | bytes
#: containers hashed element by element (a global one is read, module doc)
_CONTAINERS = tuple | list | dict | set | frozenset


def _without_addresses(text: str) -> str:
    """``text`` without object addresses (``<function f at 0x7f…>``)."""
    return re.sub(r" at 0x[0-9a-fA-F]+", "", text)


def _update(digest, value, globals_: dict | None, seen: set) -> None:
    """Feed ``value`` into ``digest`` (module doc); ``seen`` stops recursion."""
    put = digest.update
    if value is None or isinstance(value, _PLAIN):
        put(f"{type(value).__name__}:{value!r};".encode())
    elif isinstance(value, jax.Array | np.ndarray | np.generic):
        array = np.ascontiguousarray(np.asarray(value))
        put(f"array:{array.dtype}{array.shape};".encode() + array.tobytes())
    elif isinstance(value, types.CodeType):
        _code(digest, value, globals_, seen)
    elif isinstance(value, types.FunctionType):
        if id(value) in seen:  # a recursive function, or one reached twice
            put(f"function:{value.__qualname__};".encode())
            return
        seen.add(id(value))
        put(f"function:{value.__module__}.{value.__qualname__};".encode())
        _code(digest, value.__code__, value.__globals__, seen)
        for part in (value.__defaults__, value.__kwdefaults__):
            _update(digest, part, None, seen)
        for cell in value.__closure__ or ():
            try:
                _update(digest, cell.cell_contents, None, seen)
            except ValueError:  # an empty cell
                put(b"empty-cell;")
    elif isinstance(value, types.MethodType):
        _update(digest, value.__func__, None, seen)
        _update(digest, value.__self__, None, seen)
    elif isinstance(value, partial):
        _update(digest, (value.func, value.args, value.keywords), None, seen)
    elif isinstance(value, types.SimpleNamespace) or _is_dataclass(value):
        _record(digest, value, seen)
    elif isinstance(value, tuple | list):
        put(f"{type(value).__name__}[{len(value)}];".encode())
        for item in value:
            _update(digest, item, None, seen)
    elif isinstance(value, dict):
        put(f"dict[{len(value)}];".encode())
        for key in sorted(value, key=repr):
            _update(digest, key, None, seen)
            _update(digest, value[key], None, seen)
    elif isinstance(value, set | frozenset):  # element order is salted: sort the digests
        put(f"set[{len(value)}];".encode())
        for item in sorted(value_digest(item) for item in value):
            put(item.encode())
    elif isinstance(value, type):
        put(f"class:{value.__module__}.{value.__qualname__};".encode())
    elif isinstance(value, types.ModuleType):
        put(f"module:{value.__name__};".encode())
    else:
        _object(digest, value, seen)


def _object(digest, value, seen: set) -> None:
    """A pytree by structure and leaves, anything else by its class and ``repr``
    (without addresses); a callable object also by its class's ``__call__`` code, a
    wrapper (``jax.jit``, ``functools.wraps``) by the function it wraps."""
    wrapped = getattr(value, "__wrapped__", None)
    if wrapped is not None and wrapped is not value:
        _update(digest, wrapped, None, seen)
    leaves, treedef = jax.tree_util.tree_flatten(value)
    if len(leaves) == 1 and leaves[0] is value:  # a leaf: not a container
        digest.update(_without_addresses(repr(value)).encode())
    else:
        digest.update(_without_addresses(str(treedef)).encode())
        for leaf in leaves:
            _update(digest, leaf, None, seen)
    kind = type(value)
    digest.update(f"object:{kind.__module__}.{kind.__qualname__};".encode())
    call = kind.__dict__.get("__call__") if callable(value) else None
    if isinstance(call, types.FunctionType):
        _update(digest, call, None, seen)


def _is_dataclass(value) -> bool:
    """A dataclass instance that is no pytree (an ``equinox.Module`` is one: it is
    hashed by its structure and leaves)."""
    if isinstance(value, type) or not dataclasses.is_dataclass(value):
        return False
    leaves = jax.tree_util.tree_leaves(value)
    return len(leaves) == 1 and leaves[0] is value


def _is_record(value) -> bool:
    """A config object hashed by its content: a dataclass instance, a namespace, a
    ``functools.partial``."""
    return isinstance(value, types.SimpleNamespace | partial) or _is_dataclass(value)


def _record(digest, value, seen: set) -> None:
    """A dataclass instance by its class and fields, a namespace by its attributes (a
    ``repr`` would abbreviate a large array), a callable one also by its ``__call__``."""
    kind = type(value)
    digest.update(f"record:{kind.__module__}.{kind.__qualname__};".encode())
    if id(value) in seen:  # a record that holds itself
        return
    seen.add(id(value))
    if isinstance(value, types.SimpleNamespace):
        fields = vars(value)
    else:
        fields = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
    _update(digest, fields, None, seen)
    call = kind.__dict__.get("__call__")
    if isinstance(call, types.FunctionType):
        _update(digest, call, None, seen)


def _code(digest, code: types.CodeType, globals_: dict | None, seen: set) -> None:
    """A code object: bytecode, constants (nested code objects recursively), names and
    argument counts; the globals it reads (module doc) from ``globals_``."""
    digest.update(f"code:{code.co_name}:{code.co_argcount}:{code.co_kwonlyargcount};".encode())
    digest.update(code.co_code)
    digest.update(repr((code.co_names, code.co_varnames, code.co_freevars)).encode())
    for constant in code.co_consts:
        _update(digest, constant, globals_, seen)
    if globals_ is None:
        return
    module = globals_.get("__name__")
    loaded = {i.argval for i in dis.get_instructions(code) if i.opname == "LOAD_GLOBAL"}
    for name in code.co_names:
        if name not in globals_:
            continue  # an attribute, or a builtin
        found = globals_[name]
        if isinstance(found, types.ModuleType):
            # ``config.SCALE``: the data attributes of an imported module that the code
            # names (every name it reads that the module has: a superset, never fewer)
            for attribute in code.co_names:
                value = getattr(found, attribute, None)
                record = _is_record(value) and not _is_library(found.__name__)
                if attribute != name and (_is_data(value) or record):
                    digest.update(f"global:{name}.{attribute};".encode())
                    _update(digest, value, None, seen)
        elif _is_data(found) or _is_own_function(found, module) or _is_record(found):
            digest.update(f"global:{name};".encode())
            _update(digest, found, None, seen)
        elif name in loaded and not (_by_name(found, module) or _is_library(module)):
            if not _shows_content(found):
                raise _unrepresentable(name, found, code)
            digest.update(f"global:{name};".encode())
            _object(digest, found, seen)


@functools.cache
def _is_library(module: str | None) -> bool:
    """A module of jaxbal, of an installed package or of the standard library: its
    module-level state (flags, caches, registries) is not a user's config; a global of
    its code that the digest cannot represent is skipped, not refused."""
    top = (module or "").partition(".")[0]
    if top == "jaxbal" or top in sys.builtin_module_names:
        return True
    found = getattr(sys.modules.get(top), "__file__", None)
    if found is None:
        return False
    paths = sysconfig.get_paths()
    roots = {Path(paths[k]).resolve() for k in ("stdlib", "platstdlib", "purelib", "platlib")}
    return any(root in Path(found).resolve().parents for root in roots)


def _by_name(value, module) -> bool:
    """A global that enters by its name only: ``None`` (a value replacing it enters), a
    class, or a function or callable of another module (jaxbal's, NumPy's, a jit
    wrapper)."""
    if value is None or isinstance(value, type):
        return True
    return callable(value) and type(value).__module__ != module


def _shows_content(value) -> bool:
    """A pytree, or an object whose class gives a ``repr`` of its own (an enum member,
    a dtype, a path): hashed by that (:func:`_object`); not ``object.__repr__``, which
    shows the class and an address only."""
    leaves = jax.tree_util.tree_leaves(value)
    pytree = not (len(leaves) == 1 and leaves[0] is value)
    return pytree or type(value).__repr__ is not object.__repr__


def _unrepresentable(name: str, value, code: types.CodeType) -> ValueError:
    kind = type(value)
    return ValueError(
        f"{code.co_qualname} reads the global {name!r}, a {kind.__module__}.{kind.__qualname__}"
        " that the sweep's fingerprint cannot represent (its repr shows no content), so an "
        "edit of it would go unnoticed when a store is resumed: make it a dataclass, a "
        "types.SimpleNamespace, an equinox.Module or numbers, arrays or containers of "
        "them, or give its class a __repr__ that shows every value the code reads"
    )


def _is_data(value) -> bool:
    """A value a global is read as: a number, string, array, container, or a pytree
    (an ``equinox.Module`` such as a profile or a robot, hashed by its structure and
    leaves); not a function, class, module or an arbitrary object (its ``repr``)."""
    if isinstance(value, _PLAIN | _CONTAINERS | jax.Array | np.ndarray | np.generic):
        return True
    if value is None or callable(value) and not hasattr(value, "__dataclass_fields__"):
        return False  # a function, a class, a jit wrapper (see _is_own_function)
    if isinstance(value, type | types.ModuleType):
        return False
    leaves = jax.tree_util.tree_leaves(value)
    return not (len(leaves) == 1 and leaves[0] is value)  # a pytree, not a leaf


def _is_own_function(value, module) -> bool:
    """A function of the reading code's own module (a helper whose body may change),
    also behind a wrapper (``jax.jit``, ``functools.wraps``)."""
    value = getattr(value, "__wrapped__", value)
    return isinstance(value, types.FunctionType) and value.__module__ == module


def value_digest(value) -> str:
    """SHA-256 (hex) of ``value`` by content and code (module doc)."""
    digest = hashlib.sha256()
    _update(digest, value, None, set())
    return digest.hexdigest()


def sweep_parts(metric, robot, motion, trajectory, axes: dict, outputs: dict, evaluation) -> dict:
    """The parts of a sweep's fingerprint (:data:`PART_NAMES`), each a SHA-256 (hex):
    the axes' names and values, the outputs' shapes and dtypes, the evaluation, and by
    :func:`value_digest` the metric, the axes' setters, the robot, the motion and θ."""
    values = {
        dim: {n: np.asarray(v, dtype=np.float64) for n, v in a.values.items()}
        for dim, a in axes.items()
    }
    shapes = {k: [list(v.shape), str(v.dtype)] for k, v in outputs.items()}
    setters = {dim: dict(a.setters) for dim, a in axes.items()}
    parts = {"axes": (list(axes), values), "outputs": json.dumps(shapes, sort_keys=True)}
    parts |= {"evaluation": evaluation, "metric": metric, "setters": setters, "robot": robot}
    parts |= {"motion": motion, "trajectory": dict(trajectory or {})}
    return {k: value_digest(v) for k, v in parts.items()}


def fingerprint(parts: dict) -> str:
    """SHA-256 (hex) of the parts of :func:`sweep_parts`."""
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def check_resumable(path, description: dict, parts: dict, axes: dict | None = None) -> None:
    """Refuse to resume the store at ``path`` (its ``description``) with a sweep of
    other inputs or code (``parts``; ``axes``, to name an axis whose kind changed).

    Raises:
        ValueError: naming the parts that differ (unknown for a store written before
            they were recorded) and how to start afresh.
    """
    if description.get("fingerprint") == fingerprint(parts):
        return
    stored = description.get("parts")
    if isinstance(stored, dict):
        changed = [f"the {PART_NAMES.get(k, k)}" for k in parts if stored.get(k) != parts[k]]
        kinds = _changed_kinds(description.get("kinds"), axes)
        if kinds:  # a grid has a setter slot that other axes lack: name the kind instead
            setters = f"the {PART_NAMES['setters']}"
            changed = [c for c in changed if c != setters] + [f"the kinds of axes ({kinds})"]
        changed = ", ".join(changed)
    else:  # written before the parts (and the metric's and setters' code) were recorded
        changed = "unknown (the store predates the fingerprint of each part and of code)"
    raise ValueError(
        f"{path} holds a different sweep; changed since it was written: {changed}. A store "
        "resumes only with the same axes, values, outputs, robot, motion, metric, setters "
        f"and θ: pass those, or start afresh (remove {path} or write another store)"
    )


def _changed_kinds(stored, axes: dict | None) -> str:
    """``"'x': grid in the store, points now; …"`` for the axes whose kind (grid,
    points, sobol, …) differs from the store's (``""`` if none, or not recorded)."""
    if not isinstance(stored, dict) or axes is None:
        return ""
    return "; ".join(
        f"{dim!r}: {stored[dim]} in the store, {axis.kind} now"
        for dim, axis in axes.items()
        if dim in stored and stored[dim] != axis.kind
    )
