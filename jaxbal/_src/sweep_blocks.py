"""How many points a sweep's block holds: from XLA's memory analysis of the compiled
batch and a memory budget (:func:`chunk_points`), capped so that the progress bar and
the store's chunks keep moving and a batch of LU factorisations stays small enough for
jaxlib's CPU solver (:data:`MAX_LU_BATCH`). The numbers a sweep produces do not depend
on it except through the per-device batch size (see ``MIN_DEVICE_BATCH`` in
:mod:`jaxbal._src.sweep`).
"""

from __future__ import annotations

import numpy as np

from jaxbal._src.sweep_program import bound_cache, chunk_memory, shape_key

__all__ = ["MAX_CHUNK", "MAX_LU_BATCH", "chunk_points"]

#: largest block [points] (keeps the progress bar and the store's chunks moving).
MAX_CHUNK = 2**18

#: most LU factorisations one device batch may hold. jaxlib's CPU LU (``jnp.linalg.solve``)
#: splits a large batch over XLA's thread pool and, with two such calls at once on a
#: 2-core machine, can wait forever (measured: a hang from ~8,000 3×3 systems); below this
#: it runs inline.
MAX_LU_BATCH = 4096


def _lu_batch(jaxpr) -> int:
    """Matrices factorised by ``lu`` primitives in ``jaxpr`` and its sub-programs."""
    total = 0
    for eqn in jaxpr.eqns:
        if eqn.primitive.name == "lu":
            shape = eqn.invars[0].aval.shape
            total += int(np.prod(shape[:-2], dtype=np.int64))
        for value in eqn.params.values():
            for sub in value if isinstance(value, tuple | list) else (value,):
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    total += _lu_batch(inner)
    return total


#: LU factorisations per point by :func:`~jaxbal._src.sweep_program.shape_key`.
_LU: dict = {}


def chunk_points(program, dynamic, params, budget, total, devices) -> int:
    """Points of a block: as many as ``budget`` bytes per device hold (``params``: one
    point's), times the ``devices``, at most ``total`` and :data:`MAX_CHUNK`."""
    per_point, fixed = chunk_memory(program, dynamic, params)
    per_device = max((budget - fixed) // per_point, 1)
    import jax

    key = shape_key(program, dynamic, params)
    if key not in _LU:
        one = {k: v[0] for k, v in params.items()}
        _LU[key] = _lu_batch(jax.make_jaxpr(program.point)(dynamic, one).jaxpr)
        bound_cache(_LU)
    lu = _LU[key]
    if lu:
        per_device = min(per_device, max(MAX_LU_BATCH // lu, 1))
    return int(min(per_device * devices, total, MAX_CHUNK))
