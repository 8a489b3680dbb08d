"""The functional checks of :func:`~jaxbal.checked_jit` (:func:`functional_check`), a
batch reduced to its first failing sample in one pass (:func:`first_failure`).

:func:`jax.experimental.checkify.check` of a predicate batched by ``vmap`` reduces the
batch with ``argsort`` (``checkify._reduce_any_error``): a sort of all samples, per
check. Under :func:`~jaxbal.checked_jit` every value check of a vmapped wrench was
such a sort, and the checks cost 5–9× the physics (measured on the 2-core CPU, 10⁵
states, ``checked_jit`` of the vmapped shaking wrench against ``jax.jit`` with the same
checks as callbacks: 2R 3.1e6 against 2.8e7 states/s, Orthoglide 1.5e6 against 7.8e6,
DUAL-V 1.4e6 against 6.6e6). :func:`first_failure` reduces the batch before the check
sees it: ``any`` over the samples and the offending values of the first failing one
(a minimum of indices), so the check itself is not batched: the checked wrench now runs
at 0.75–1.4× the throughput of ``jax.jit`` with callbacks. The state's check also
stopped stacking ``(q, q̇, q̈)`` (:mod:`~jaxbal._src.state_checks`): XLA wrote the
stacked batch to memory for the offending values, ~half of the remaining cost.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from jax.experimental import checkify


@jax.custom_batching.custom_vmap
def first_failure(invalid, offending):
    """``(invalid, offending)`` unchanged for one sample; under ``vmap``, ``invalid`` of
    any sample of the batch and ``offending`` of the first sample with an invalid entry
    (of the first sample when none is), both unbatched.

    Only for checks: the result does not depend on the batch index, which ``vmap`` of
    an identity would. ``offending`` should carry no derivative (``stop_gradient``):
    ``custom_vmap`` has no reverse-mode rule.

    Args:
        invalid: boolean array, any shape.
        offending: pytree of arrays, the values reported with a failed check.

    Returns:
        ``(invalid, offending)``, reduced over every batch axis of ``vmap``.
    """
    return invalid, offending


@first_failure.def_vmap
def _reduce(axis_size, in_batched, invalid, offending):
    invalid_batched, offending_batched = in_batched
    if invalid_batched:
        rows = jnp.any(invalid.reshape(axis_size, -1), axis=1)
        # a minimum, not argmax: XLA:CPU's (value, index) reduction cost 3x more
        first = jnp.min(jnp.where(rows, jnp.arange(axis_size), axis_size)) % axis_size
        invalid = jnp.any(invalid, axis=0)
    else:
        first = 0
    offending = jax.tree_util.tree_map(
        lambda leaf, batched: leaf[first] if batched else leaf, offending, offending_batched
    )
    # nested vmaps: the enclosing one reduces its own axis with the same rule
    return first_failure(invalid, offending), (
        False,
        jax.tree_util.tree_map(lambda _: False, offending),
    )


def functional_check(invalid, offending, *, text: str) -> None:
    """``checkify.check`` that ``invalid`` is all False, formatted with ``offending``,
    inside a ``jit`` of its own.

    ``checkify`` describes each formatting value by its sharding, which a traced value
    does not have; JAX's ``AttributeError`` for that names the operations the value came
    from, and for a value that depends on no argument of the program (e.g. a state of a
    motion captured by the function) it pretty-printed the whole straight-line program:
    30-70 ms per check, ~0.13 s of an Orthoglide gradient's trace. Inside the ``jit``
    the value is an argument and nothing is printed. The ``jit`` is new at each call:
    ``checkify`` reports the failed check of lowest code, codes are numbered as checks
    are traced, and a reused trace would keep an older, lower code (a non-finite
    wrench was then reported instead of the non-finite state that caused it)."""

    def body(invalid, offending):
        # the batch of a vmap reduced here, not by checkify's sort (first_failure)
        invalid, offending = first_failure(invalid, jax.lax.stop_gradient(offending))
        if isinstance(offending, tuple):  # stacked once the batch is reduced (guard)
            offending = jnp.stack(offending)
        checkify.check(~jnp.any(invalid), text + ": {}", offending)

    jax.jit(body)(invalid, offending)
