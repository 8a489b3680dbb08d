"""Running a sweep's pending blocks on a backend, with a progress bar."""

from __future__ import annotations

import contextlib
import logging
import math

import numpy as np

from jaxbal._src.sweep_program import evaluate, put
from jaxbal._src.sweep_ray import RayBackend, evaluate_ray

__all__ = ["block_error", "evaluate_local", "quiet_checks", "run_backend"]


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
    if backend == "ray":
        backend = RayBackend()
    if not (backend == "local" or isinstance(backend, RayBackend)):
        raise ValueError(f"unknown backend {backend!r}; use 'local', 'ray' or a RayBackend")
    bar = _progress(chunks, pending, progress)
    try:
        if isinstance(backend, RayBackend):
            evaluate_ray(backend, program, dynamic, chunks, pending, store.write, bar.update, fold)
        else:
            with quiet_checks():
                evaluate_local(program, dynamic, chunks, pending, store.write, bar.update, fold)
    finally:
        bar.close()


def evaluate_local(program, dynamic, chunks, pending, write, advance, fold=False) -> None:
    """Evaluate the ``pending`` blocks on the local devices, one call ahead of the
    writes (JAX dispatches asynchronously)."""
    in_flight = None
    for k in pending:
        params, m = chunks.params(k)
        try:
            result = evaluate(program, dynamic, put(program, params), fold)
        except Exception as error:  # noqa: BLE001 - re-raised with the block named
            raise block_error(chunks, k, error) from error
        if in_flight is not None:
            _finish(chunks, *in_flight, write, advance)
        in_flight = (k, result, m)
    if in_flight is not None:
        _finish(chunks, *in_flight, write, advance)


def block_error(chunks, k: int, error: Exception) -> Exception:
    """A runtime check that failed in block ``k`` (e.g. a non-physical robot built by a
    setter) as a ``ValueError`` naming the block's parameter ranges and the check."""
    import re

    text = str(error)
    found = re.findall(r"_EquinoxRuntimeError: ([^\n]+)", text)
    if not found:
        return error
    params, m = chunks.params(k)
    ranges = ", ".join(
        f"{n} in [{np.min(v[:m]):.6g}, {np.max(v[:m]):.6g}]" for n, v in params.items()
    )
    return ValueError(f"sweep block {k} ({ranges}): {found[-1].strip()}")


def _finish(chunks, k, result, m, write, advance):
    try:
        outputs = chunks.unpad(k, result, m)
    except Exception as error:  # noqa: BLE001 - JAX reports runtime checks here
        raise block_error(chunks, k, error) from error
    write(k, outputs)
    advance(m)


def _not_a_check(record: logging.LogRecord) -> bool:
    """False for jax's log of a failed runtime check (an ``_EquinoxRuntimeError`` raised
    in a callback), which :func:`block_error` reports as a ``ValueError``."""
    error = record.exc_info[1] if record.exc_info else None
    return type(error).__name__ != "_EquinoxRuntimeError"


@contextlib.contextmanager
def quiet_checks():
    """Within: jax does not log a traceback for each failed runtime check of a block."""
    logger = logging.getLogger("jax._src.callback")
    logger.addFilter(_not_a_check)
    try:
        yield
    finally:
        logger.removeFilter(_not_a_check)
