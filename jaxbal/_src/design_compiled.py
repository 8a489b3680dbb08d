"""The reduced co-design as one compiled program: scales, projected BFGS iterations
and final metric values in a single dispatch (:mod:`jaxbal._src.box_bfgs`).

Along a :class:`~jaxbal._src.motion_samples.ReducedMotion` the loss costs a few hundred
multiply-adds (:mod:`jaxbal._src.reduced_motion`), so the host-driven L-BFGS-B of the
default co-design (:mod:`jaxbal._src.lbfgsb`) spent its time waiting: ~0.1 ms of
dispatch and synchronisation per evaluation plus SciPy's own ~50 µs, 40–45 times on a
20-variable arm. :func:`compiled_function` instead compiles, once per structure, the
whole co-design: the starting robot's metric values (which set the scales, as in
:mod:`jaxbal._src.design`), the bound-constrained BFGS loop (one value-and-gradient
site), and the loss's metric values at the optimum. Used by
:func:`jaxbal.design.codesign` on a reduced motion with at most
:data:`COMPILED_MAX_VARIABLES` scalar design variables.

The program has no runtime-error callbacks (as the L-BFGS-B's, so that it is kept by
the persistent compilation cache): the caller checks the robot before and the
starting values after.
"""

from __future__ import annotations

from functools import cache

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxbal._src.box_bfgs import BoxResult, box_bfgs
from jaxbal._src.config import compiler_options
from jaxbal._src.design_loss import (
    _everything,
    _floor,
    _loss_of,
    _Problem,
    _structure,
    _to_design,
    _unflatten,
)
from jaxbal._src.momentum import replayed
from jaxbal._src.robot import Robot
from jaxbal._src.validation import runtime_checks

__all__ = ["COMPILED_MAX_VARIABLES", "compiled_function"]

#: the reduced co-design uses the compiled BFGS loop up to this many scalar design
#: variables (a dense ``n × n`` Hessian approximation and its Cholesky factor per
#: iteration); above, the host-driven L-BFGS-B.
COMPILED_MAX_VARIABLES = 64
#: LLVM optimisation level of the program (with XLA:CPU's elemental emitters,
#: :func:`jaxbal._src.config.compiler_options`). Its loop evaluates the loss and
#: gradient ~50 times in one dispatch, so unlike the host-driven co-design's program
#: (level 0) the generated code's speed shows: measured on the 2-core CPU (20-variable
#: arm of ``benchmarks/codesign_bench.py``), level 0 compiled in 0.29 s and ran in
#: 5.7 ms, level 1 0.46 s and 1.3 ms, level 3 0.52 s and 1.0 ms.
OPTIMIZATION_LEVEL = 1


@cache
def compiled_program():
    """The jitted :func:`_compiled_flat` (built on first use: its compiler options
    probe the backend, which importing jaxbal must not start)."""
    options = compiler_options(OPTIMIZATION_LEVEL)
    return jax.jit(_compiled_flat, static_argnums=(0, 1, 2), compiler_options=options)


def _compiled_flat(layout, structure, max_steps, x, given, leaves, lower, upper, gtol):
    treedef, static = structure
    robot, motion, problem = eqx.combine(jax.tree_util.tree_unflatten(treedef, leaves), static)
    everything = _everything(problem)
    n = len(problem.terms)
    where = jnp.asarray([everything.index(m) for m in problem.constrained], dtype=int)
    # runtime checks off: line-search trials may be non-finite (see validation)
    with runtime_checks(False), replayed(False):
        floors = jnp.stack([_floor(robot, motion, m) for m in everything])

        def prepare(values):
            """The scales set by the starting design's metric values (as
            :func:`jaxbal._src.design._codesign_compact` sets them on the host)."""
            scales = jnp.maximum(jnp.abs(values[:n]), floors[:n])
            bound_scales = jnp.maximum(jnp.abs(problem.bounds), floors[where])
            return values, scales, bound_scales

        def loss(y, scaled):
            designed = robot.with_design(_to_design(_unflatten(y, layout), scaled))
            return _loss_of(designed, motion, scaled)

        def fun(y, context):
            _, scales, bound_scales = context
            scaled = eqx.tree_at(
                lambda p: (p.scales, p.bound_scales), problem, (scales, bound_scales)
            )
            (value, values), grad = jax.value_and_grad(loss, has_aux=True)(y, scaled)
            return value, grad, values

        values = jnp.zeros(len(everything), dtype=x.dtype)
        context = (values, problem.scales, problem.bound_scales)
        return box_bfgs(
            fun, x, lower, upper, max_steps=max_steps, gtol=gtol, aux=values,
            context=context, prelude=(given, prepare),
        )  # fmt: skip


def compiled_function(robot: Robot, motion, problem: _Problem, layout, max_steps: int):
    """``(x, given, lower, upper, gtol) -> BoxResult``: the compiled reduced co-design
    (module doc) from the flat start ``x``, with the scales set by the metric values of
    the design ``given`` (the robot's own, before ``x`` was moved inside the bounds);
    ``result.context`` holds those values and scales, ``result.aux`` the values at the
    optimum. Compiled once per structure and ``max_steps``."""
    dynamic, static = eqx.partition((robot, motion, problem), eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    structure = _structure((treedef, static))
    program = compiled_program()

    def call(x, given, lower, upper, gtol) -> BoxResult:
        return program(layout, structure, max_steps, x, given, leaves, lower, upper, gtol)

    return call
