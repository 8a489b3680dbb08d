"""Several runtime checks of one value traced as one :func:`equinox.error_if`.

A physics function guards its output with up to six checks (a finite state, body
masses and inertias, finite and non-negative parameters, a finite result:
:mod:`jaxbal._src.momentum`), each a :func:`~jaxbal._src.validation.guard`. Under ``jit``
each was an :func:`equinox.error_if`, which walks the Python stack to describe where
the check was made, and JAX's test of each frame (``traceback_util.include_frame``,
against ~40 excluded paths, with file-system calls) cost 20–40 ms per check: ~0.14–0.24
s of the ~0.8 s trace of a peak-force gradient (measured on the 2-core CPU, Orthoglide,
DUAL-V, 2R). :func:`merged_guards` traces the checks of one value as one
:func:`equinox.branched_error_if`, with the same messages and the same data dependency
(every check guarded that value before too), the value written to memory before the
checks read it (as the chained checks' conditionals did).

Which message is raised when several checks fail: the first check in program order
that fails for any sample of a batch (as the chained checks did, the first of the
chain firing first), e.g. a non-finite state rather than the non-finite wrench it
causes. Eager checks (concrete values) raise at once as before, and the functional
checks of :func:`~jaxbal.checked_jit` stay one ``checkify`` check each.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxbal._src.materialise import materialise

T = TypeVar("T")

#: the checks collected by the open :func:`merged_guards` calls (innermost last), as
#: ``(failed, message)`` pairs with ``failed`` a traced scalar bool
OPEN: list[list] = []


def merged_guards(checks: Callable[[T], T], value: T) -> T:
    """``checks(value)``, whose traced guards (called directly by it, at the trace level
    of ``value``) are applied to its result as one runtime check (module doc).

    Where checks are traced, ``value`` is first written to memory
    (:func:`~jaxbal._src.materialise.materialise`): a check reads the value (is it
    finite?) and the result passes it on, and XLA's CPU backend compiled the whole
    computation of ``value`` into both (the Orthoglide's vmapped wrench ran 3.4× slower
    with the merged check; the functional checks of :func:`~jaxbal.checked_jit`, which
    pass nothing on, had the same copy); the chained checks had been such boundaries
    themselves."""
    # imported here: validation imports OPEN from this module
    from jaxbal._src.validation import is_traced, runtime_checks_enabled

    if is_traced(value) and runtime_checks_enabled():
        leaves = jax.tree_util.tree_leaves(value)
        value = materialise(value, leaves[0])
    collected: list = []
    OPEN.append(collected)
    try:
        value = checks(value)
    finally:
        OPEN.pop()
    if not collected:
        return value
    failed = jnp.stack([f for f, _ in collected])
    if len(collected) == 1:
        return eqx.error_if(value, failed[0], collected[0][1])
    # equinox keeps the largest index over a batch: the first check gets the largest
    priority = jnp.arange(len(collected) - 1, -1, -1)
    index = jnp.max(jnp.where(failed, priority, 0))
    messages = [message for _, message in reversed(collected)]
    return eqx.branched_error_if(value, jnp.any(failed), index, messages)
