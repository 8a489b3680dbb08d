"""Plain Python functions as pytrees, so that an equivalent function does not recompile.

``jit`` (and :func:`equinox.filter_jit`) treat a function argument as static and hash it
by identity: a trajectory written as ``lambda t: path(t)`` in a notebook cell is a new
object every time the cell runs, and every call compiles again (about a second or more).
:func:`as_pytree` turns such a function into a :class:`PytreeFunction` whose static part
is its code (the code object compares by value), its globals and its name, and whose
leaves are the values it closes over and its defaults: two lambdas with the same code
and the same closed-over structure share one compilation, and new closed-over array
values (a new start pose, a new duration) are ordinary traced inputs.
"""

from __future__ import annotations

import types
from typing import Any

import equinox as eqx

#: The globals of every converted function, by ``id`` (module namespaces: kept alive).
_GLOBALS: dict[int, dict] = {}


class PytreeFunction(eqx.Module):
    """A Python function split into static code and pytree closure values.

    Attributes:
        code: the function's code object (static; compared by value).
        globals_id: ``id`` of its globals dict (static: functions of different modules
            never share a compilation).
        name: its ``__name__`` (static).
        cells: the values of its closure cells (a pytree: arrays are leaves).
        defaults: its default argument values (a pytree).
    """

    code: types.CodeType = eqx.field(static=True)
    globals_id: int = eqx.field(static=True)
    name: str = eqx.field(static=True)
    cells: tuple[Any, ...]
    defaults: tuple[Any, ...] | None

    def function(self) -> types.FunctionType:
        """The equivalent plain function (closure rebuilt from :attr:`cells`)."""
        closure = tuple(types.CellType(value) for value in self.cells) or None
        namespace = _GLOBALS[self.globals_id]
        return types.FunctionType(self.code, namespace, self.name, self.defaults, closure)

    def __call__(self, *args, **kwargs):
        return self.function()(*args, **kwargs)


def as_pytree(fn):
    """``fn`` as a :class:`PytreeFunction` when it is a plain function (lambda, nested
    function, closure); any other callable (an :class:`equinox.Module` path, a bound
    method, a builtin) is returned unchanged. Keyword-only defaults and functions with
    empty cells are returned unchanged too."""
    if not isinstance(fn, types.FunctionType) or fn.__kwdefaults__:
        return fn
    try:
        cells = tuple(cell.cell_contents for cell in fn.__closure__ or ())
    except ValueError:  # a cell not yet filled (a recursive closure)
        return fn
    _GLOBALS.setdefault(id(fn.__globals__), fn.__globals__)
    return PytreeFunction(
        code=fn.__code__,
        globals_id=id(fn.__globals__),
        name=fn.__name__,
        cells=cells,
        defaults=fn.__defaults__,
    )
