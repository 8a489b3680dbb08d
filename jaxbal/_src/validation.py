"""Input validation that works both eagerly and under ``jit``/``vmap``.

Outside a trace, bad values raise :class:`ValueError` naming the offending value.
Inside a trace the concrete value is unknown: callers either return a validity mask
or use :func:`equinox.error_if`, which raises at run time with a static message.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def is_traced(*values) -> bool:
    """True when any leaf of ``values`` is a JAX tracer (inside jit/vmap/grad)."""
    leaves = jax.tree_util.tree_leaves(values)
    return any(isinstance(leaf, jax.core.Tracer) for leaf in leaves)


def check_nonnegative(name: str, value) -> None:
    """Raise ``ValueError`` if a concrete ``value`` has a negative or non-finite entry.

    Traced values are left alone (they are checked where they are used, via masks).
    """
    if is_traced(value):
        return
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr!r}")
    if np.any(arr < 0):
        raise ValueError(f"{name} must be non-negative, got {arr!r}")


def check_shape(name: str, value, shape: tuple[int | None, ...]) -> None:
    """Raise ``ValueError`` at trace time if ``value``'s shape does not match ``shape``.

    ``None`` in ``shape`` matches any size along that axis.
    """
    actual = jnp.shape(value)
    ok = len(actual) == len(shape) and all(
        s is None or s == a for s, a in zip(shape, actual, strict=False)
    )
    if not ok:
        raise ValueError(f"{name} must have shape {shape}, got {actual}")


def raise_if_invalid(valid, message: str, offending) -> None:
    """Eager check: raise ``ValueError(message + offending)`` where ``valid`` is False.

    ``valid`` is a boolean array (a validity mask); ``offending`` is the value to show
    (for a batch, the entries where the mask is False are shown).
    """
    if is_traced(valid, offending):
        return
    valid = np.asarray(valid)
    if not np.all(valid):
        off = np.asarray(offending)
        if off.ndim > valid.ndim:
            off = off[~valid] if valid.ndim else off
        elif valid.ndim:
            off = off[~valid]
        raise ValueError(f"{message}: {off!r}")
