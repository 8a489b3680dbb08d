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
import gc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import checkify

from jaxbal._src.config import compiler_options
from jaxbal._src.first_failure import functional_check
from jaxbal._src.merged_guards import OPEN


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


def check_stopping(max_steps, gtol) -> None:
    """Raise ``ValueError`` unless ``max_steps`` is an integer ``>= 1`` and ``gtol`` a
    finite number ``>= 0`` (an optimiser's stopping rule: a NaN ``gtol`` silently ran to
    ``max_steps`` and reported no convergence, a negative ``max_steps`` failed deep in
    the loop's set-up). A traced ``gtol`` is left alone."""
    integral = isinstance(max_steps, int | np.integer) and not isinstance(max_steps, bool)
    if not (integral and max_steps >= 1):
        raise ValueError(f"max_steps must be an integer >= 1, got {max_steps!r}")
    if is_traced(gtol):
        return
    try:
        value = float(gtol)
    except (TypeError, ValueError):
        raise ValueError(f"gtol must be a finite number >= 0, got {gtol!r}") from None
    if not (np.isfinite(value) and value >= 0):
        raise ValueError(f"gtol must be a finite number >= 0, got {gtol!r}")


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


class _TraceFlag:
    """A switch read while tracing, part of JAX's trace and ``jit`` cache keys.

    jaxbal's nested compiled functions (a Newton solve's ``jax.jit``, an
    ``eqx.filter_jit`` called under another trace) are traced once per cache key, and
    their jaxprs are reused by later traces. A plain Python switch is not in that key:
    a solve first traced with the checks off (inside an optimiser) would then be reused,
    unchecked, by a checked program. Backed by :func:`jax.make_user_context`, the switch
    is in the key, so each setting traces (and compiles) its own program.
    """

    def __init__(self, default: bool):
        make = getattr(jax, "make_user_context", None)
        self._context = None if make is None else make(default_value=bool(default))
        self._value = [bool(default)]  # without user contexts (older JAX)

    @property
    def value(self) -> bool:
        return bool(self._context.value) if self._context is not None else self._value[0]

    def set_global(self, enabled: bool) -> None:
        if self._context is not None:
            self._context.set_global(bool(enabled))
        self._value[0] = bool(enabled)

    @contextlib.contextmanager
    def __call__(self, enabled: bool):
        if self._context is not None:
            with self._context(bool(enabled)):
                yield
            return
        with switched(self._value, enabled):
            yield


_RUNTIME_CHECKS = _TraceFlag(True)


def set_runtime_checks(enabled: bool) -> None:
    """Turn the value checks that run inside compiled code on (default) or off.

    The checks (finite, non-negative body masses and inertias, finite states) cost a
    few comparisons per evaluation; they are read when a function is traced, so call
    this *before* compiling. Eager calls always check.
    """
    _RUNTIME_CHECKS.set_global(enabled)


def runtime_checks_enabled() -> bool:
    """Whether compiled code checks values (see :func:`set_runtime_checks`)."""
    return _RUNTIME_CHECKS.value


def guard(value, invalid, message: str, offending, names=None):
    """Return ``value``, checked: where ``invalid`` (a boolean array) is True, raise.

    Eagerly a ``ValueError`` naming the offending entries (and their ``names``, if given);
    under ``jit``/``vmap`` an :func:`equinox.error_if` runtime error carrying ``message``
    (the data dependency on ``value`` keeps the check in the compiled graph).
    ``offending`` is an array or a tuple of equally shaped arrays, reported stacked (a
    tuple spares :func:`checked_jit`'s batched check a stacked copy of a whole batch).
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
    if _FUNCTIONAL.value:
        # braces of the message escaped: checkify formats it with the offending values
        functional_check(invalid, offending, text=message.replace("{", "{{").replace("}", "}}"))
        return value
    if OPEN:  # inside merged_guards: one runtime check for all (merged_guards module doc)
        OPEN[-1].append((jnp.any(invalid), message))
        return value
    return eqx.error_if(value, jnp.any(invalid), message)


#: whether traced guards are functional checkify checks (:func:`checked_jit`).
_FUNCTIONAL = _TraceFlag(False)


def checked_jit(fn, *, compiler_options: dict | None = None):
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
    a trace (inside ``jit``/``vmap``/``grad``, even with concrete arguments), it is
    ``fn`` itself, checked by the enclosing program.

    ``checkify`` refuses a ``vmap`` of a plain ``lax.while_loop`` (jaxbal's own Newton
    solves are written so that it accepts them, :mod:`jaxbal._src.implicit`). For
    arguments of such a structure the call falls back, once per structure, to the
    program with the checks as callbacks (``eqx.filter_jit`` with
    :func:`equinox.error_if`): the same checks, a failed one raised as a ``ValueError``
    with its message (the offending values are not known to the callback), compiled
    once per process instead of kept in the persistent cache.

    Example::

        grad = jaxbal.checked_jit(jax.grad(lambda d: peak_force(robot.with_design(d), motion)))
        grad(robot.design())   # the next process loads the compiled program from the cache

    Args:
        fn: a function of positional arguments (arrays, pytrees such as robots and
            motions; other values are static, as for ``eqx.filter_jit``).
        compiler_options: optional XLA options of its programs (``jax.jit``'s).

    Returns:
        The checked, compiled function.
    """
    programs = {}
    # structures of arguments for which checkify refused the program (batched while)
    refused: set = set()

    def compiled(mode: str):
        if mode not in programs:
            if mode == "functional":
                body = checkify.checkify(fn, errors=checkify.user_checks)
            elif mode == "callback":
                # a function of its own: equinox keys its compiled programs by function
                body = functools.wraps(fn)(lambda *args: fn(*args))
            else:
                body = fn
            options = {"compiler_options": compiler_options} if compiler_options else {}
            programs[mode] = eqx.filter_jit(body, **options)
        return programs[mode]

    @functools.wraps(fn)
    def call(*args):
        if is_traced(args) or _under_trace():
            # inside another trace (even with concrete arguments: jit stages every
            # operation) the checks are the enclosing program's
            return fn(*args)
        with collection_paused():
            return checked(*args)

    def checked(*args):
        if not runtime_checks_enabled():
            return compiled("unchecked")(*args)
        key = _structure(args)
        if key not in refused:
            try:
                with _FUNCTIONAL(True):
                    error, out = compiled("functional")(*args)
            except ValueError as refusal:
                if _BATCHED_WHILE not in str(refusal):
                    raise
                refused.add(key)
            else:
                message = error.get()
                if message is not None:
                    # checkify appends " (`check` failed)" (the offending values of a
                    # multi-row array, e.g. the state's q, qd, qdd, span several lines)
                    head, failed, _ = message.rpartition(" (`check` failed)")
                    raise ValueError((head if failed else message).strip())
                return out
        try:
            return compiled("callback")(*args)
        except RuntimeError as failure:
            message = _equinox_message(failure)
            if message is None:
                raise
            raise ValueError(message) from failure

    call.compiled = compiled  # the programs, for inspection (tests)
    call.compiler_options = compiler_options
    call.refused = refused
    call.programs = programs  # mode -> compiled program, those built so far (tests)
    return call


@contextlib.contextmanager
def collection_paused():
    """Python's cyclic garbage collector paused inside the block (restored on exit,
    left off if it was off).

    Tracing a program allocates objects by the hundred thousand, and each of Python's
    full collections then walks every object of the process (JAX's and NumPy's modules
    included): measured on the 2-core CPU, 0.08-0.18 s of a 0.7-1.1 s first call of a
    checked gradient (SCARA, DUAL-V, Orthoglide). The garbage of the trace is collected
    after the block, as it would have been. Used around the calls of
    :func:`checked_jit`, whose first call traces and compiles."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


#: the start of the error ``checkify`` raises for a ``vmap`` of a ``while_loop``
_BATCHED_WHILE = "Checkify does not support batched while-loops"


def _under_trace() -> bool:
    """True inside a ``jit``/``vmap``/``grad`` trace, whatever the arguments."""
    try:
        from jax._src.core import trace_state_clean
    except ImportError:  # pragma: no cover - a JAX without it: probe with an operation
        return isinstance(jnp.zeros(()) + 0.0, jax.core.Tracer)
    return not trace_state_clean()


def _equinox_message(failure: RuntimeError) -> str | None:
    """The message of a failed :func:`equinox.error_if` check, if ``failure`` is one."""
    marker = "EquinoxRuntimeError: "
    text = str(failure)
    if type(failure).__name__ != "EquinoxRuntimeError" or marker not in text:
        return None
    return text.split(marker, 1)[1].split("\n", 1)[0].strip()


def _structure(args):
    """Hashable structure of ``args`` as ``eqx.filter_jit`` sees it: tree, array
    shapes and dtypes, other leaves by value (identity when unhashable)."""
    leaves, tree = jax.tree_util.tree_flatten(args)

    def key(leaf):
        if eqx.is_array(leaf):
            return ("array", np.shape(leaf), str(leaf.dtype))
        try:
            hash(leaf)
        except TypeError:
            return ("object", id(leaf))
        return leaf

    return tree, tuple(key(leaf) for leaf in leaves)


_LIBRARY: dict = {}


def checked_call(fn, *args, once: bool = False):
    """``checked_jit(fn)(*args)`` for a module-level function of jaxbal, compiled once
    per process (e.g. the sampling of :func:`~jaxbal.design.motion_samples`).

    ``once``: a program that typically runs once per compilation (sampling a motion, an
    eager motion factory, a validity mask): compiled with XLA's fast-compile options
    (:func:`~jaxbal._src.config.compiler_options` level 0; same arithmetic, no
    fast-math). DUAL-V ``motion_samples`` (1,000 samples, 2-core CPU, fresh processes)
    2.6 -> 1.25 s, the program ~1.5x slower to run: throughput programs keep defaults.
    """
    if fn not in _LIBRARY:
        options = compiler_options(ONCE_OPTIMIZATION_LEVEL) if once else None
        _LIBRARY[fn] = checked_jit(fn, compiler_options=options)
    return _LIBRARY[fn](*args)


#: LLVM optimisation level of the programs :func:`checked_call` runs ``once``.
ONCE_OPTIMIZATION_LEVEL = 0


@contextlib.contextmanager
def runtime_checks(enabled: bool):
    """Context manager: runtime value checks on/off while tracing inside the block.

    Optimisers use ``runtime_checks(False)``: their line searches may try non-finite
    points on purpose (and reject them), while the reparametrised design variables
    cannot become negative; the starting design is checked before.
    """
    with _RUNTIME_CHECKS(enabled):
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
