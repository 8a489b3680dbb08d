"""The Ray backend of :func:`jaxbal.sweep`: blocks as Ray tasks, written by the driver.

The driver puts the program (metric, robot, motion; without its device mesh) in Ray's
object store once, then submits one task per pending block with the block's parameters
and writes each result to the zarr store as it arrives, so the store is the same
whichever worker computed a block and in whatever order. A worker that dies (killed,
out of memory, node lost) fails its task with a system error, which Ray retries up to
``max_retries`` times on another worker; an exception raised by the metric itself is
not retried and stops the sweep (the blocks written so far stay done).

Each worker compiles the program once (it keeps it by the sweep's token) and splits a
block over its own local devices.

Requires the ``cluster`` extra (``pip install "jaxbal[cluster]"``).

References:
    Moritz et al. (2018), Ray: a distributed framework for emerging AI applications,
    OSDI; https://docs.ray.io/en/latest/ray-core/fault_tolerance/tasks.html (retries).
"""

from __future__ import annotations

import math
import uuid
from dataclasses import dataclass, field

import numpy as np

__all__ = ["CONNECT_TIMEOUT", "RayBackend", "connect", "evaluate_ray"]

#: seconds to wait for a TCP connection to an explicit ``host:port`` address before
#: ``ray.init``, which retries for minutes where nothing listens.
CONNECT_TIMEOUT = 10.0

#: programs a worker has compiled, by sweep token (so a block never recompiles).
_PROGRAMS: dict[str, tuple] = {}


@dataclass(frozen=True)
class RayBackend:
    """Where and how :func:`jaxbal.sweep` sends its blocks as Ray tasks.

    Attributes:
        address: the cluster (``"auto"``, ``"ray://head:10001"``, …); ``None``: the
            cluster this process is connected to, or a new local one.
        max_retries: retries of a block whose worker died.
        num_cpus, num_gpus: resources of one task (``num_gpus=0.5``: two workers per
            GPU; then start the workers with ``XLA_PYTHON_CLIENT_PREALLOCATE=false``).
        max_in_flight: blocks submitted ahead of the results (default: twice the
            cluster's CPUs).
        init: more keyword arguments of ``ray.init`` (e.g. ``num_cpus`` locally).
    """

    address: str | None = None
    max_retries: int = 3
    num_cpus: float = 1.0
    num_gpus: float = 0.0
    max_in_flight: int | None = None
    init: dict = field(default_factory=dict)


def connect(backend: RayBackend):
    """The ``ray`` module, connected to the backend's cluster (a new local one when
    ``address`` is ``None`` and this process is not connected yet).

    Raises:
        ValueError: nothing listens at an explicit ``host:port`` address (checked with
            a TCP connection within :data:`CONNECT_TIMEOUT`), or ``ray.init`` fails
            (``address="auto"`` with no cluster running), in one line naming the address.
    """
    try:
        import ray
    except ImportError:  # pragma: no cover - depends on the installed extras
        raise ImportError('the Ray backend needs Ray: pip install "jaxbal[cluster]"') from None
    if ray.is_initialized():
        return ray
    address = backend.address
    try:
        _probe(address)
        ray.init(address=address, **backend.init)
    except (ConnectionError, OSError, RuntimeError) as error:  # ray's, and the probe's
        reason = str(error).strip().splitlines()[0] if str(error).strip() else repr(error)
        raise ValueError(f"cannot connect to the Ray cluster at {address!r}: {reason}") from None
    return ray


def _probe(address) -> None:
    """Raise ``ConnectionError`` if nothing accepts a TCP connection at an explicit
    ``[ray://]host:port`` address (``None`` and ``"auto"`` are left to Ray)."""
    import socket

    if not isinstance(address, str) or address in ("auto", "local"):
        return
    host, _, port = address.removeprefix("ray://").rpartition(":")
    if not (host and port.isdigit()):
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), CONNECT_TIMEOUT).close()
    except OSError as error:
        raise ConnectionError(f"nothing listens at {host}:{port} ({error})") from None


def _worker_program(token: str, payload):
    """The program with this worker's device mesh, built once per worker from the
    pickled ``(metric, plan, (robot, motion, θ))`` (pytree definitions of equinox
    modules do not pickle; the modules themselves do)."""
    if token not in _PROGRAMS:
        from jaxbal._src.sweep_program import build, device_mesh

        metric, plan, (robot, motion, theta), _ = payload
        _PROGRAMS.clear()  # one sweep at a time per worker
        _PROGRAMS[token] = build(metric, robot, motion, theta, plan, device_mesh())
    return _PROGRAMS[token]


def evaluate_block(token: str, payload, params: dict) -> dict:
    """One block on this process's devices: ``{output: (B, …)}`` as NumPy arrays."""
    from jaxbal._src.sweep_program import evaluate, put
    from jaxbal._src.sweep_run import quiet_checks

    program, dynamic = _worker_program(token, payload)
    batch = len(next(iter(params.values())))
    padded = math.ceil(batch / program.mesh.size) * program.mesh.size
    if padded != batch:
        params = {k: np.concatenate([v, np.repeat(v[-1:], padded - batch, 0)]) for k, v in
                  params.items()}  # fmt: skip
    with quiet_checks():
        result = evaluate(program, dynamic, put(program, params), payload[3])
        return {k: np.asarray(v)[:batch] for k, v in result.items()}


def evaluate_ray(
    backend: RayBackend, program, dynamic, chunks, pending, write, advance, fold=False
) -> None:
    """Evaluate the ``pending`` blocks as Ray tasks; ``write(k, outputs)`` each result.
    A runtime check failing in a block raises the ``ValueError`` of the local backend."""
    from jaxbal._src.sweep_run import block_error

    ray = connect(backend)
    remote = ray.remote(evaluate_block).options(
        max_retries=backend.max_retries,
        retry_exceptions=False,
        num_cpus=backend.num_cpus,
        num_gpus=backend.num_gpus,
    )
    from jaxbal._src.sweep_program import pytrees

    token = uuid.uuid4().hex
    payload = ray.put((program.metric, program.plan, pytrees(program, dynamic), fold))
    limit = backend.max_in_flight or max(2 * int(ray.cluster_resources().get("CPU", 1)), 1)
    queue, running = list(pending), {}
    try:
        while queue or running:
            while queue and len(running) < limit:
                k = queue.pop(0)
                params, m = chunks.params(k)
                running[remote.remote(token, payload, params)] = (k, m)
            ready, _ = ray.wait(list(running), num_returns=1)
            for ref in ready:
                k, m = running.pop(ref)
                try:
                    outputs = ray.get(ref)
                except Exception as error:  # noqa: BLE001 - re-raised with the block named
                    _write_finished(ray, running, chunks, write, advance)
                    raise block_error(chunks, k, error) from error
                write(k, chunks.unpad(k, outputs, m))
                advance(m)
    finally:
        for ref in running:
            ray.cancel(ref, force=True)


def _write_finished(ray, running: dict, chunks, write, advance) -> None:
    """Write the blocks of ``running`` whose tasks have finished without error (a block
    failed: these would be lost with the cancelled ones)."""
    if not running:
        return
    ready, _ = ray.wait(list(running), num_returns=len(running), timeout=0)
    for ref in ready:
        k, m = running.pop(ref)
        try:
            outputs = chunks.unpad(k, ray.get(ref), m)
        except Exception:  # noqa: BLE001 - failed too: the first failure is reported
            continue
        write(k, outputs)
        advance(m)
