"""Input validation that works both eagerly and under ``jit``/``vmap``.

Outside a trace, bad values raise :class:`ValueError` naming the offending value.
Inside a trace the concrete value is unknown: callers either return a validity mask
or use :func:`equinox.error_if`, which raises at run time with a static message.

Programs that jaxbal compiles itself and calls eagerly (e.g. the sampling of
:func:`~jaxbal.design.motion_samples`) trace the same checks as functional errors
instead (:func:`checked_jit`, ``jax.experimental.checkify``): the compiled program then
has no host callback, so JAX's persistent compilation cache keeps it for the next
process (it refuses programs with callbacks), and the error is raised on the host as a
``ValueError`` with the same message.
"""

from __future__ import annotations

import contextlib
import functools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import checkify


def is_traced(*values) -> bool:
    """True when any leaf of ``values`` is a JAX tracer (inside jit/vmap/grad)."""
    leaves = jax.tree_util.tree_leaves(values)
    return any(isinstance(leaf, jax.core.Tracer) for leaf in leaves)


#: Tolerance of every sign check [kg, m, kg·m²]: values that are zero up to rounding (a
#: derived ``I + m p² − m p²``, a subnormal ``−1e-309`` that compiled code flushes to
#: zero) are accepted, alike in constructors, eagerly and under ``jit``.
ROUNDING = 1e-12


def check_nonnegative(name: str, value) -> None:
    """Raise ``ValueError`` if a concrete ``value`` has a non-finite entry or one below
    ``−ROUNDING`` (the tolerance of the physics' own checks, so that a constructor and
    the physics judge a tiny negative alike).

    Traced values are left alone (they are checked where they are used, via masks).
    """
    if is_traced(value):
        return
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got {arr!r}")
    if np.any(arr < -ROUNDING):
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


# --- runtime value checks (eager and under jit) ---------------------------------------

_RUNTIME_CHECKS = [True]


def set_runtime_checks(enabled: bool) -> None:
    """Turn the value checks that run inside compiled code on (default) or off.

    The checks (finite, non-negative body masses and inertias, finite states) cost a
    few comparisons per evaluation; they are read when a function is traced, so call
    this *before* compiling. Eager calls always check.
    """
    _RUNTIME_CHECKS[0] = bool(enabled)


def runtime_checks_enabled() -> bool:
    """Whether compiled code checks values (see :func:`set_runtime_checks`)."""
    return _RUNTIME_CHECKS[0]


def guard(value, invalid, message: str, offending, names=None):
    """Return ``value``, checked: where ``invalid`` (a boolean array) is True, raise.

    Eagerly a ``ValueError`` naming the offending entries (and their ``names``, if given);
    under ``jit``/``vmap`` an :func:`equinox.error_if` runtime error carrying ``message``
    (the data dependency on ``value`` keeps the check in the compiled graph).
    """
    if not is_traced(invalid, offending):
        bad = np.asarray(invalid)
        if np.any(bad):
            off = np.asarray(offending)
            if names is not None and bad.ndim == 1 and len(names) == bad.size:
                listed = {n: off[i].tolist() for i, n in enumerate(names) if bad[i]}
                raise ValueError(f"{message}: {listed}")
            raise ValueError(f"{message}: {off[bad] if off.shape == bad.shape else off!r}")
        return value
    if not runtime_checks_enabled():
        return value
    if _FUNCTIONAL[0]:
        # braces of the message escaped: checkify formats it with the offending values
        text = message.replace("{", "{{").replace("}", "}}")
        checkify.check(~jnp.any(invalid), text + ": {}", offending)
        return value
    return eqx.error_if(value, jnp.any(invalid), message)


#: whether traced guards are functional checkify checks (:func:`checked_jit`).
_FUNCTIONAL = [False]


def checked_jit(fn):
    """``jit`` of ``fn`` whose runtime checks raise ``ValueError`` on the host and whose
    compiled program the persistent compilation cache keeps.

    Under ``jax.jit`` jaxbal's value checks (:func:`guard`: finite states, non-negative
    masses, reachable poses …) are host callbacks (:func:`equinox.error_if`), and JAX
    does not store programs with callbacks in its persistent cache, so a second Python
    process compiles them again. ``checked_jit(fn)`` traces the same checks as
    functional errors (:func:`jax.experimental.checkify.checkify`, user checks): the
    program has no callback, returns the error with the values, and the call raises a
    ``ValueError`` with the check's message and the offending values. With the runtime
    checks off (:func:`set_runtime_checks`) it is ``eqx.filter_jit(fn)``; called under
    a trace (traced arguments), it is ``fn`` itself.

    Example::

        grad = jaxbal.checked_jit(jax.grad(lambda d: peak_force(robot.with_design(d), motion)))
        grad(robot.design())   # the next process loads the compiled program from the cache

    Args:
        fn: a function of positional arguments (arrays, pytrees such as robots and
            motions; other values are static, as for ``eqx.filter_jit``).

    Returns:
        The checked, compiled function.
    """
    programs = {}

    def compiled(functional: bool):
        if functional not in programs:
            body = checkify.checkify(fn, errors=checkify.user_checks) if functional else fn
            programs[functional] = eqx.filter_jit(body)
        return programs[functional]

    @functools.wraps(fn)
    def call(*args):
        if is_traced(args):
            return fn(*args)
        if not runtime_checks_enabled():
            return compiled(False)(*args)
        with switched(_FUNCTIONAL, True):
            error, out = compiled(True)(*args)
        message = error.get()
        if message is not None:
            # checkify appends " (`check` failed)" and the location on further lines
            raise ValueError(message.split("\n")[0].strip().removesuffix(" (`check` failed)"))
        return out

    call.compiled = compiled  # the two programs, for inspection (tests)
    return call


_LIBRARY: dict = {}


def checked_call(fn, *args):
    """``checked_jit(fn)(*args)`` for a module-level function of jaxbal, compiled once
    per process (e.g. the sampling of :func:`~jaxbal.design.motion_samples`)."""
    if fn not in _LIBRARY:
        _LIBRARY[fn] = checked_jit(fn)
    return _LIBRARY[fn](*args)


@contextlib.contextmanager
def runtime_checks(enabled: bool):
    """Context manager: runtime value checks on/off while tracing inside the block.

    Optimisers use ``runtime_checks(False)``: their line searches may try non-finite
    points on purpose (and reject them), while the reparametrised design variables
    cannot become negative; the starting design is checked before.
    """
    with switched(_RUNTIME_CHECKS, enabled):
        yield


@contextlib.contextmanager
def switched(flag: list, enabled: bool):
    """Context manager: the one-element list ``flag`` (a switch read while tracing) set
    to ``enabled`` inside the block, restored after it."""
    previous = flag[0]
    flag[0] = bool(enabled)
    try:
        yield
    finally:
        flag[0] = previous
