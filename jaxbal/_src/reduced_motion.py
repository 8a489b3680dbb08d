"""The RMS shaking force and moment along a fixed motion as one matrix-vector product:
the regressor fast path of :func:`jaxbal.design.codesign`.

Along a fixed joint motion the shaking wrench is linear in the lumped inertial
parameters ``π`` of the bodies (:mod:`jaxbal._src.regressor`), ``w(t) = Y(t) π``, and
``Y`` depends only on the kinematics of the body frames. When the design variables a
co-design optimises leave every body *frame* in place (counter-masses and their
distances along a link, payloads, masses, inertias: they move the bodies' centres of
mass inside their frames, not the frames), ``Y`` is the same for every candidate, so::

    rms_force(robot) = ‖Y_f π(robot)‖ / √t,      Y_f = [Y_f(t_1); …; Y_f(t_t)]

with ``π(robot)`` (:func:`~jaxbal._src.regressor.lumped_parameters`) the only part that
changes. The added inertia (:func:`~jaxbal.design.added_inertia`, the base inertia about
the vertical axis at ``q[0]``) is linear in ``π`` too: ``a · (π(robot) − π(bare))`` with
``a`` the row of :func:`_inertia_row`, computed with ``Y``. :func:`reduce_motion`
evaluates ``Y`` once (one compiled program, with only the parts a loss needs), keeps
its nonzero rows and columns (a planar arm's force uses ``m, h_x, h_y`` of its moving
bodies: ~3 of 10 columns, 2 of 3 rows) and their triangular QR factor ``R``
(``‖Y π‖ = ‖R π‖``); the loss then costs ``columns²`` multiply-adds instead of the
robot's kinematics and dynamics at every sample. No Gram matrix ``YᵀY`` is formed,
which would square the conditioning at a balanced design.

That the frames stay in place is *checked*, never assumed: their tangent along a
random direction of the free design variables must be exactly zero at three samples
(forward mode propagates symbolic zeros, so any dependence shows); otherwise the
co-design evaluates the metrics directly. ``Y π`` equals
:func:`jaxbal.shaking_wrench` on every robot (tests/test_balancing.py), and the reduced
co-design's optimum equals the direct one's (tests/test_reduced_motion.py).
"""

from __future__ import annotations

from collections import OrderedDict
from functools import cache

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.config import compiler_options
from jaxbal._src.motion_samples import Motion, ReducedMotion
from jaxbal._src.planar import PlanarRobot
from jaxbal._src.regressor import _SYMMETRIC, _columns, frame_kinematics, lumped_parameters
from jaxbal._src.robot import Robot
from jaxbal._src.types import Scalar
from jaxbal._src.validation import runtime_checks

__all__ = [
    "PARTS",
    "REDUCE_MIN_VARIABLES",
    "reduce_motion",
    "reduced_added_inertia",
    "reduced_rms",
    "reduces",
    "wanted_parts",
]

#: metric name -> part of the regressor its reduced form needs (0: force, 1: moment,
#: 2: the base inertia's row at the first sample)
PARTS = {"rms_force": 0, "rms_moment": 1, "added_inertia": 2}
#: ``reduce=None`` reduces problems of at least this many scalar design variables: below,
#: compiling the regressor costs more than the evaluations it saves (measured in
#: ``benchmarks/codesign_bench.py``)
REDUCE_MIN_VARIABLES = 10
#: while :func:`wanted_parts` probes a callable metric: the parts it asked for
_WANTED: set | None = None


def reduced_rms(robot: Robot, motion: ReducedMotion, part: int) -> Scalar:
    """RMS of the shaking force (``part`` 0) or moment about the base origin (1) along
    ``motion`` [N or N·m], from its regressor; ``None`` where the motion lacks it."""
    from jaxbal._src.metrics import _rms  # metrics dispatches here: imported late

    if part == 0:
        matrix, columns = motion.force, motion.force_columns
    else:
        matrix, columns = motion.moment, motion.moment_columns
    if matrix is None:
        if _WANTED is not None:  # a probe of the parts a callable metric uses
            _WANTED.add(part)
            return jnp.zeros(())
        return None
    parameters = jnp.ravel(lumped_parameters(robot))[np.asarray(columns, dtype=int)]
    values = matrix @ parameters
    return _rms(values[None, :]) / jnp.sqrt(float(motion.q.shape[0]))


def reduced_added_inertia(robot: Robot, bare: Robot, motion: ReducedMotion) -> Scalar:
    """:func:`~jaxbal.design.added_inertia` [kg·m²] from the base inertia's row ``a`` at
    ``q[0]``: ``a · (π(robot) − π(bare))``; ``None`` where the motion lacks the row."""
    if motion.inertia is None:
        if _WANTED is not None:  # a probe of the parts a callable metric uses
            _WANTED.add(2)
            return jnp.zeros(())
        return None
    added = jnp.ravel(lumped_parameters(robot)) - jnp.ravel(lumped_parameters(bare))
    return motion.inertia @ added


def _inertia_row(frames) -> jax.Array:
    """``(b, 10)``: the base inertia about the vertical axis, ``J_z = Σ_b a_b · π_b``,
    as a row over the lumped parameters (:data:`~jaxbal._src.regressor.LUMPED`) of bodies
    whose frames have origins ``o`` and rotations ``R``: ``m (o_x² + o_y²)``
    + ``2 (o_x (R h)_x + o_y (R h)_y)`` + ``r_zᵀ J r_z`` (``r_z`` the third row of ``R``;
    :func:`~jaxbal.design.base_inertia` with the COM ``o + R h/m``)."""
    o, rotation = frames.origin, frames.rotation
    r = rotation[:, 2, :]
    first = 2.0 * (o[:, :1] * rotation[:, 0, :] + o[:, 1:2] * rotation[:, 1, :])
    spin = [r[:, i] * r[:, j] * (1.0 if i == j else 2.0) for i, j in _SYMMETRIC]
    return jnp.concatenate(
        [(o[:, 0] ** 2 + o[:, 1] ** 2)[:, None], first, jnp.stack(spin, -1)], axis=-1
    )


def _frames(robot: Robot, q):
    if isinstance(robot, PlanarRobot):
        return robot.planar_frames(q)
    return robot.body_frames(q)


def _frames_tangent(robot: Robot, free, direction, q) -> jax.Array:
    """Largest ``|∂ frames/∂ design · direction|`` at the states ``q (k, dof)``: exactly
    zero where the frames do not depend on the free design variables ``free``."""
    design = {name: jnp.asarray(robot.design()[name], dtype=float) for name in free}

    def frames(d, q_):
        return _frames(robot.with_design(d), q_)

    def largest(q_):
        _, tangent = jax.jvp(lambda d: frames(d, q_), (design,), (direction,))
        return jnp.max(jnp.stack([jnp.max(jnp.abs(t)) for t in jax.tree_util.tree_leaves(tangent)]))

    return jnp.max(jax.vmap(largest)(q))


#: from this many samples on, the regressor's program is compiled with LLVM's
#: optimisations (level 3), below without (level 0). It runs once per reduction, so its
#: compile time is what a user waits for: measured on the 2-core CPU (20-variable arm of
#: ``benchmarks/codesign_bench.py``, with XLA:CPU's elemental emitters), level 0
#: compiled in 0.13–0.14 s and ran in 5.4 ms at 500 samples, 145 ms at 20,000; level 3
#: 0.32–0.35 s, 1.5 ms and 63 ms. The first co-design in a fresh process went from
#: 1.23–1.36 s to 1.04–1.09 s.
OPTIMIZED_SAMPLES = 50_000


@cache
def _regressor_program(level: int):
    """The jitted :func:`_regressor` at LLVM optimisation ``level``, with XLA:CPU's
    elemental emitters (:func:`jaxbal._src.config.compiler_options`; built on first
    use)."""
    return jax.jit(_regressor, static_argnums=(0, 1), compiler_options=compiler_options(level))


def _regressor(parts: tuple[bool, ...], free, robot: Robot, motion: Motion, direction):
    """The regressor's force and moment parts ``(t, 3, 10 b)`` and the base inertia's row
    at ``q[0]`` ``(b, 10)`` wanted by ``parts``, and :func:`_frames_tangent` at three
    samples (one compiled program per structure)."""
    with runtime_checks(False):
        out = [None, None, None]
        if parts[0] or parts[1]:
            force, moment = jax.vmap(lambda *s: _columns(frame_kinematics(robot, *s)))(*motion)
            # the force is independent of the inertia columns (module doc of the regressor)
            out[0] = force.at[..., 4:].set(0.0) if parts[0] else None
            out[1] = moment if parts[1] else None
        if parts[2]:
            out[2] = _inertia_row(frame_kinematics(robot, *(x[0] for x in motion)))
        samples = np.unique(np.linspace(0, motion.q.shape[0] - 1, 3).astype(int))
        tangent = _frames_tangent(robot, free, direction, motion.q[samples])
    return tuple(out), tangent


#: ``(callable metrics, robot structure)`` -> parts they use (:func:`wanted_parts`)
_PROBED: dict = {}


def reduces(reduce: bool | None, variables: int, motion) -> bool:
    """Whether a co-design of ``variables`` scalars with ``reduce`` (``None``: auto)
    evaluates along a :class:`ReducedMotion` (a plain :class:`Motion` only)."""
    if reduce is None:
        reduce = variables >= REDUCE_MIN_VARIABLES
    return bool(reduce) and isinstance(motion, Motion)


def wanted_parts(robot: Robot, motion: Motion, metrics) -> tuple[bool, bool, bool]:
    """Whether the ``metrics`` (names or callables) use the RMS force / moment / added
    inertia (:data:`PARTS`): names
    are looked up, callables traced abstractly once per robot structure
    (``jax.eval_shape``) with a probe motion whose reduced RMS records the part used."""
    global _WANTED
    from jaxbal._src.metrics import resolve_metric

    wanted = {PARTS[m] for m in metrics if isinstance(m, str) and m in PARTS}
    callables = tuple(m for m in metrics if not isinstance(m, str))
    if callables:
        try:
            key = (callables, jax.tree_util.tree_structure(robot))
            hash(key)
        except TypeError:  # an unhashable callable: probed every time
            key = None
        if key not in _PROBED:
            probe = ReducedMotion(motion.q, motion.qd, motion.qdd, None, None, None, (), ())
            _WANTED = set()
            try:
                with runtime_checks(False):
                    jax.eval_shape(
                        lambda r: [resolve_metric(m)(r, probe) for m in callables], robot
                    )
                found = frozenset(_WANTED)
            finally:
                _WANTED = None
            if key is None:
                wanted |= found
            else:
                _PROBED[key] = found
        if key is not None:
            wanted |= _PROBED[key]
    return 0 in wanted, 1 in wanted, 2 in wanted


def reduce_motion(
    robot: Robot, motion: Motion, free: tuple[str, ...], metrics
) -> ReducedMotion | None:
    """``motion`` with the regressor parts the ``metrics`` need (see the module doc), or
    ``None`` where none is needed or a free variable moves a body frame (e.g. a link
    length)."""
    if isinstance(motion, ReducedMotion):
        return None
    parts = wanted_parts(robot, motion, metrics)
    if not any(parts):
        return None
    key = _fingerprint(robot, motion, tuple(free), parts)
    if key not in _REDUCED:
        _REDUCED[key] = _reduced_parts(robot, motion, tuple(free), parts)
        while len(_REDUCED) > _REDUCED_KEPT:
            _REDUCED.popitem(last=False)
    _REDUCED.move_to_end(key)
    found = _REDUCED[key]
    return None if found is None else ReducedMotion(motion.q, motion.qd, motion.qdd, *found)


#: reduced parts of recent (robot without its free variables, motion) pairs, least
#: recently used first: a multistart co-design, or a study repeating one from several
#: starts, reduces its motion once (the regressor's compiled program runs in ~1 ms, its
#: QR factor and bookkeeping ~2 ms: measured on the 2-core CPU, 10-link arm, 500 samples)
_REDUCED: OrderedDict = OrderedDict()
_REDUCED_KEPT = 8


def _fingerprint(robot: Robot, motion: Motion, free: tuple[str, ...], parts) -> tuple:
    """What the reduced parts depend on: the robot with its free design variables set
    to zero (the regressor does not depend on them: that is what :func:`reduce_motion`
    checks), its static structure, and every value of both (bytes, compared in full on
    a hit, so no collision can return another robot's parts)."""
    design = robot.design()
    bare = robot.with_design({name: np.zeros(np.shape(design[name])) for name in free})
    dynamic, static = eqx.partition(bare, eqx.is_array)
    arrays = [np.asarray(a) for a in jax.tree_util.tree_leaves((dynamic, tuple(motion)))]
    values = tuple((a.dtype.str, a.shape, a.tobytes()) for a in arrays)
    return type(robot), static, free, parts, values


def _reduced_parts(robot: Robot, motion: Motion, free: tuple[str, ...], parts):
    """The fields of :class:`ReducedMotion` after ``q, qd, qdd`` (see
    :func:`reduce_motion`), or ``None`` where a free variable moves a body frame."""
    design = robot.design()
    generator = np.random.default_rng(0)
    direction = {n: generator.standard_normal(np.shape(design[n])) for n in free}
    level = 3 if motion.q.shape[0] >= OPTIMIZED_SAMPLES else 0
    regressors, tangent = _regressor_program(level)(parts, free, robot, motion, direction)
    if float(tangent) != 0.0:
        return None
    t = motion.q.shape[0]
    matrices, columns = [], []
    for regressor in regressors[:2]:
        if regressor is None:
            matrices.append(None)
            columns.append(())
            continue
        stacked = np.asarray(regressor).reshape(3 * t, -1)
        nonzero = stacked != 0.0
        rows, cols = np.any(nonzero, axis=1), np.flatnonzero(np.any(nonzero, axis=0))
        # R of Y = Q R: ‖Y π‖ = ‖R π‖, with min(rows, columns) rows
        matrices.append(jnp.asarray(np.linalg.qr(stacked[rows][:, cols], mode="r")))
        columns.append(tuple(int(c) for c in cols))
    inertia = None if regressors[2] is None else jnp.ravel(regressors[2])
    return (*matrices, inertia, *columns)
