"""Running a sweep's pending blocks on a backend, with a progress bar."""

from __future__ import annotations

import math

from jaxbal._src.sweep_program import put, run_chunk
from jaxbal._src.sweep_ray import RayBackend, evaluate_ray

__all__ = ["evaluate_local", "run_backend"]


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


def run_backend(backend, program, dynamic, chunks, pending, store, progress: bool) -> None:
    """Evaluate the ``pending`` blocks on ``backend`` (``"local"``, ``"ray"`` or a
    :class:`~jaxbal._src.sweep_ray.RayBackend`) and write them to ``store``."""
    if backend == "ray":
        backend = RayBackend()
    if not (backend == "local" or isinstance(backend, RayBackend)):
        raise ValueError(f"unknown backend {backend!r}; use 'local', 'ray' or a RayBackend")
    bar = _progress(chunks, pending, progress)
    try:
        if isinstance(backend, RayBackend):
            evaluate_ray(backend, program, dynamic, chunks, pending, store.write, bar.update)
        else:
            evaluate_local(program, dynamic, chunks, pending, store.write, bar.update)
    finally:
        bar.close()


def evaluate_local(program, dynamic, chunks, pending, write, advance) -> None:
    """Evaluate the ``pending`` blocks on the local devices, one call ahead of the
    writes (JAX dispatches asynchronously)."""
    in_flight = None
    for k in pending:
        params, m = chunks.params(k)
        result = run_chunk(program, dynamic, put(program, params))
        if in_flight is not None:
            _finish(chunks, *in_flight, write, advance)
        in_flight = (k, result, m)
    if in_flight is not None:
        _finish(chunks, *in_flight, write, advance)


def _finish(chunks, k, result, m, write, advance):
    write(k, chunks.unpad(k, result, m))
    advance(m)
