"""Running a sweep's pending blocks on a backend, with a progress bar.

An exception raised in a block (a runtime check, a host callback, a Ray task) is
re-raised as ``sweep block k (ranges): message`` (:func:`block_error`) after the
blocks finished before it are written (the local backend keeps one call in flight).
"""

from __future__ import annotations

import contextlib
import logging
import math
import re

import numpy as np

from jaxbal._src.sweep_program import evaluate, put
from jaxbal._src.sweep_ray import RayBackend, connect, evaluate_ray

__all__ = ["block_error", "connect_backend", "evaluate_local", "quiet_checks", "run_backend"]


def _progress(chunks, pending, enabled: bool):
    from tqdm.auto import tqdm

    total = math.prod(chunks.layout.sizes)
    remaining = sum(math.prod(r.stop - r.start for r in chunks.layout.region(k)) for k in pending)
    return tqdm(
        total=total,
        initial=total - remaining,
        unit="pt",
        unit_scale=True,
        desc="sweep",
        disable=not enabled,
        smoothing=0.05,
        dynamic_ncols=True,
    )


def run_backend(
    backend, program, dynamic, chunks, pending, store, progress: bool, fold: bool = False
) -> None:
    """Evaluate the ``pending`` blocks on ``backend`` (``"local"``, ``"ray"`` or a
    :class:`~jaxbal._src.sweep_ray.RayBackend`) and write them to ``store``."""
    backend = _backend(backend)
    bar = _progress(chunks, pending, progress)
    try:
        if isinstance(backend, RayBackend):
            evaluate_ray(backend, program, dynamic, chunks, pending, store.write, bar.update, fold)
        else:
            with quiet_checks():
                evaluate_local(program, dynamic, chunks, pending, store.write, bar.update, fold)
    finally:
        bar.close()


def _backend(backend):
    """``"local"`` or a :class:`~jaxbal._src.sweep_ray.RayBackend` (for ``"ray"``)."""
    if isinstance(backend, str) and backend == "ray":
        return RayBackend()
    if not (isinstance(backend, RayBackend) or (isinstance(backend, str) and backend == "local")):
        raise ValueError(f"unknown backend {backend!r}; use 'local', 'ray' or a RayBackend")
    return backend


def connect_backend(backend) -> None:
    """Refuse an unknown backend and connect to a Ray backend's cluster, before the
    sweep creates its store (a cluster that is not there left an empty store behind,
    which the next run refused: "exists: pass --resume").

    Raises:
        ValueError: an unknown backend, or a cluster that cannot be reached (one line).
    """
    backend = _backend(backend)
    if isinstance(backend, RayBackend):
        connect(backend)


def evaluate_local(program, dynamic, chunks, pending, write, advance, fold=False) -> None:
    """Evaluate the ``pending`` blocks on the local devices, one call ahead of the
    writes (JAX dispatches asynchronously)."""
    in_flight = None
    for k in pending:
        params, m = chunks.params(k)
        try:
            result = evaluate(program, dynamic, put(program, params), fold)
        except Exception as error:  # noqa: BLE001 - re-raised with the block named
            if in_flight is not None:  # the block before is done: write it first
                _finish(chunks, *in_flight, write, advance)
            raise block_error(chunks, k, error) from error
        if in_flight is not None:
            _finish(chunks, *in_flight, write, advance)
        in_flight = (k, result, m)
    if in_flight is not None:
        _finish(chunks, *in_flight, write, advance)


#: ANSI colour codes (a Ray task's error is coloured for a terminal).
_ANSI = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")
#: a Python error line of a traceback in an error's text: ``RuntimeError: message``.
_ERROR_LINE = re.compile(r"^([A-Za-z_][\w.]*(?:Error|Exception)): (.+)$")


def block_error(chunks, k: int, error: Exception) -> Exception:
    """Any exception raised in block ``k`` as ``sweep block k (ranges): message``: a
    runtime check (e.g. a non-physical robot built by a setter) or a ``ValueError``
    raised in a host callback as a ``ValueError``, anything else as a
    ``RuntimeError``; the message is the innermost error's line of the text (a
    ``JaxRuntimeError`` or a Ray task's error carries the callback's whole traceback),
    without colour codes."""
    text = _ANSI.sub("", str(error))
    found = re.findall(r"_EquinoxRuntimeError: ([^\n]+)", text)
    if found:
        kind, message = ValueError, found[-1].strip()
    else:
        lines = [line.strip() for line in text.splitlines() if line.strip()]
        inner = [_ERROR_LINE.match(line) for line in lines]
        inner = [match for match in inner if match]
        name = inner[-1].group(1) if inner else type(error).__name__
        message = inner[-1].group(2) if inner else (lines[0] if lines else repr(error))
        name = name.rpartition(".")[2]
        kind = ValueError if name == "ValueError" else RuntimeError
        message = message if name in ("ValueError", "RuntimeError") else f"{name}: {message}"
    params, m = chunks.params(k)
    ranges = ", ".join(
        f"{n} in [{np.min(v[:m]):.6g}, {np.max(v[:m]):.6g}]" for n, v in params.items()
    )
    return kind(f"sweep block {k} ({ranges}): {message}")


def _finish(chunks, k, result, m, write, advance):
    try:  # JAX reports a block's runtime checks and callbacks' errors here
        result = {name: np.asarray(value) for name, value in result.items()}
    except Exception as error:  # noqa: BLE001 - re-raised with the block named
        raise block_error(chunks, k, error) from error
    write(k, chunks.unpad(k, result, m))
    advance(m)


def _not_a_check(record: logging.LogRecord) -> bool:
    """False for jax's log of an exception raised in a callback (a failed runtime
    check, ``_EquinoxRuntimeError``, or the metric's own host callback), which
    :func:`block_error` reports, naming the block."""
    return not record.exc_info


@contextlib.contextmanager
def quiet_checks():
    """Within: jax does not log a traceback for each exception raised in a callback of
    a block (the block's error reports it)."""
    logger = logging.getLogger("jax._src.callback")
    logger.addFilter(_not_a_check)
    try:
        yield
    finally:
        logger.removeFilter(_not_a_check)
