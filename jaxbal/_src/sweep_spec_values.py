"""Reading one value of a sweep spec (:mod:`jaxbal._src.sweep_spec`): a number, an
integer, a list of numbers or a table, each refused with a :class:`ValueError` that
names the key, ``{key} must be {what}, got {value!r}`` (``[motion] duration must be
> 0 s, got 'fast'``), instead of a ``TypeError`` from ``float()`` or NumPy that names
nothing. A TOML boolean is not a number here: ``duration = true`` is refused, not read
as 1 s.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = [
    "branch_signs",
    "check_options",
    "has_boolean",
    "integer",
    "is_number",
    "number",
    "numbers",
    "refuse",
    "table",
]


def is_number(value) -> bool:
    """A TOML integer or float (not a boolean)."""
    return isinstance(value, int | float) and not isinstance(value, bool)


def refuse(key: str, what: str, value):
    """Raise the spec's one form of error: ``{key} must be {what}, got {value!r}``."""
    raise ValueError(f"{key} must be {what}, got {value!r}")


def number(value, key: str, what: str = "a finite number", valid: Callable = None) -> float:
    """``value`` as a float: a finite number (not a boolean) for which ``valid`` holds."""
    if not (is_number(value) and math.isfinite(value) and (valid is None or valid(value))):
        refuse(key, what, value)
    return float(value)


def integer(value, key: str, what: str = "an integer", valid: Callable = None) -> int:
    """``value`` as an int: a TOML integer (not a float or boolean) for which ``valid``
    holds."""
    if not (is_number(value) and isinstance(value, int) and (valid is None or valid(value))):
        refuse(key, what, value)
    return int(value)


def numbers(value, key: str, what: str = "a list of finite numbers", length=None) -> np.ndarray:
    """``value`` as a ``(n,)`` float64 array: a non-empty list of finite numbers (of
    ``length`` numbers when given; ``what`` then says what they are)."""
    if not (
        isinstance(value, list) and value and all(is_number(v) for v in value)
        and all(math.isfinite(v) for v in value)
        and (length is None or len(value) == length)
    ):  # fmt: skip
        refuse(key, what, value)
    return np.asarray(value, dtype=np.float64)


def has_boolean(value) -> bool:
    """True if a leaf of the nested lists ``value`` is a boolean (the values of a grid
    axis: NumPy would read ``true`` as 1.0)."""
    if isinstance(value, list):
        return any(has_boolean(v) for v in value)
    return isinstance(value, bool)


def table(value, key: str, what: str = "a table") -> dict:
    """``value``, a TOML table (``[key]`` or ``key = {…}``)."""
    if not isinstance(value, dict):
        refuse(key, what, value)
    return value


def branch_signs(value, key: str):
    """An IK branch: ``None`` (the robot's), ``±1`` or a list of ``±1`` signs (a tuple)."""
    signs = value if isinstance(value, list) else [value]
    if value is not None and not all(is_number(s) and s in (-1, 1) for s in signs):
        refuse(key, "±1 or a list of ±1 signs (one per sub-chain)", value)
    return tuple(int(s) for s in value) if isinstance(value, list) else value


def check_options(build, options: dict, where: str = "[robot.options]") -> None:
    """Refuse an option of ``build`` whose default is a boolean (a number) given
    something else (``payload = "heavy"``), naming it; other options are left to
    ``build``."""
    import inspect

    parameters = inspect.signature(build).parameters
    for key, value in options.items():
        default = parameters[key].default if key in parameters else None
        if isinstance(default, bool) and not isinstance(value, bool):
            refuse(f"{where} {key}", "true or false", value)
        if is_number(default):
            number(value, f"{where} {key}", "a finite number")
