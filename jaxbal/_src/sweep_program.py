"""The compiled program of a sweep: one point, ``vmap`` over a chunk, ``shard_map`` over
the devices.

A :class:`Program` is hashable (the metric, how each parameter reaches the robot or the
motion, the static part of the robot/motion pytrees, the device mesh); the arrays of the
robot, the motion and the fixed trajectory variables travel as ``dynamic`` arguments.
:func:`run_chunk` is one module-level ``jit`` with the program static, so a sweep
compiles once per program and chunk shape, whatever its values.

Each device evaluates ``vmap(point)`` on its slice of the chunk, so a point's value does
not depend on how the chunk was cut between devices.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

__all__ = [
    "AXIS",
    "Program",
    "apply_parameters",
    "build",
    "chunk_memory",
    "device_mesh",
    "output_shapes",
    "pytrees",
    "bound_cache",
    "shape_key",
    "evaluate",
    "run_chunk",
]

#: name of the mesh axis the chunk is split along.
AXIS = "points"


def device_mesh(devices=None) -> Mesh:
    """A one-dimensional mesh over ``devices`` (default: all local devices).

    Raises:
        ValueError: ``devices`` is not a non-empty sequence of distinct
            :class:`jax.Device` (``[]`` divided by zero, a duplicate failed inside JAX,
            ``"cpu"`` with an ``AttributeError``).
    """
    if devices is None:
        return Mesh(np.array(jax.local_devices()), (AXIS,))
    try:
        given = [] if isinstance(devices, str | bytes) else list(devices)
    except TypeError:  # not a sequence
        given = []
    if not (given and all(isinstance(d, jax.Device) for d in given)):
        raise ValueError(
            "devices must be a non-empty sequence of distinct jax devices (e.g. "
            f"jax.local_devices()[:2]), got {devices!r}"
        )
    if len(set(given)) != len(given):
        raise ValueError(f"devices lists a device more than once: {given}")
    return Mesh(np.array(given), (AXIS,))


def _split(tree) -> tuple[list, tuple]:
    """Array leaves (dynamic) and the hashable rest ``(treedef, static leaves)``."""
    leaves, treedef = jax.tree.flatten(tree)
    is_array = [isinstance(x, jax.Array | np.ndarray) for x in leaves]
    dynamic = [jnp.asarray(x) for x, a in zip(leaves, is_array, strict=True) if a]
    static = tuple(None if a else x for x, a in zip(leaves, is_array, strict=True))
    return dynamic, (treedef, static)


def _join(dynamic, static):
    treedef, leaves = static
    values = iter(dynamic)
    return jax.tree.unflatten(treedef, [next(values) if x is None else x for x in leaves])


@dataclass(frozen=True)
class Program:
    """What a sweep evaluates at one point (hashable: the static argument of the jit).

    Attributes:
        metric: ``(robot, motion) -> array | dict | NamedTuple``.
        plan: per parameter ``(name, how, setter)``; ``how`` is ``"design"``
            (``robot.with_design``), ``"set"`` (``setter(robot, value)``) or
            ``"trajectory"`` (an entry of ``θ`` given to the motion factory).
        factory: whether the motion is a factory ``motion(robot, θ)``.
        static: static part of ``(robot, motion, θ)``.
        mesh: the devices a chunk is split over (``None``: the default device, no split).
    """

    metric: Callable
    plan: tuple
    factory: bool
    static: tuple
    mesh: Mesh | None = None

    def point(self, dynamic, params: dict):
        """The metric at one point as a dict of arrays (``params``: name ↦ value)."""
        robot, motion, theta = _join(dynamic, self.static)
        robot, theta = apply_parameters(robot, self.plan, params, theta)
        if self.factory:
            motion = motion(robot, theta)
        return as_outputs(self.metric(robot, motion))

    def batch(self, dynamic, params: dict):
        """:meth:`point` mapped over the leading axis of every parameter."""
        return jax.vmap(self.point, in_axes=(None, 0))(dynamic, params)


def apply_parameters(robot, plan: tuple, params: dict, theta=None):
    """``(robot, θ)`` with the point's ``params`` applied as ``plan`` says: a design
    variable by ``robot.with_design`` (a value broadcast to the variable's shape), a
    setter by ``setter(robot, value)``, a trajectory variable into ``θ``."""
    theta = dict(theta or {})
    for name, how, setter in plan:
        value = params[name]
        if how == "set":
            robot = setter(robot, value)
        elif how == "design":
            leaf = robot.design()[name]
            robot = robot.with_design({name: jnp.broadcast_to(value, jnp.shape(leaf))})
        else:
            theta[name] = value
    return robot, theta


def as_outputs(value) -> dict:
    """A metric's value as ``{name: array}``: a dict as it is, a NamedTuple by field,
    a tuple/list as ``value_0, value_1, …``, an array as ``value``."""
    if isinstance(value, dict):
        return {str(k): jnp.asarray(v) for k, v in value.items()}
    if hasattr(value, "_asdict"):
        return {k: jnp.asarray(v) for k, v in value._asdict().items()}
    if isinstance(value, tuple | list):
        return {f"value_{i}": jnp.asarray(v) for i, v in enumerate(value)}
    return {"value": jnp.asarray(value)}


def build(metric, robot, motion, theta, plan, mesh=None) -> tuple[Program, list]:
    """The :class:`Program` and its dynamic arguments."""
    dynamic, static = _split((robot, motion, dict(theta)))
    program = Program(metric, tuple(plan), callable(motion), static, mesh)
    return program, dynamic


def pytrees(program: Program, dynamic) -> tuple:
    """``(robot, motion, θ)`` of a program, its arrays as NumPy arrays (to pickle)."""
    tree = _join(dynamic, program.static)
    return jax.tree.map(lambda x: np.asarray(x) if isinstance(x, jax.Array) else x, tree)


def _local(program: Program, dynamic, params):
    return program.batch(dynamic, params)


def _chunk(program: Program, dynamic, params: dict) -> dict:
    if program.mesh is None:
        return program.batch(dynamic, params)
    spec = PartitionSpec(AXIS)
    mapped = jax.shard_map(
        partial(_local, program),
        mesh=program.mesh,
        in_specs=(PartitionSpec(), spec),
        out_specs=spec,
        check_vma=False,  # the straight-line replay binds primitives itself
    )
    return mapped(dynamic, params)


@partial(jax.jit, static_argnums=0)
def run_chunk(program: Program, dynamic, params: dict) -> dict:
    """``{output: (B, …)}`` at the ``B`` points of ``params`` (``{name: (B, …)}``),
    ``B`` a multiple of the mesh size; every device evaluates its slice. The robot and
    the motion are arguments: one compilation serves every sweep of this structure."""
    return _chunk(program, dynamic, params)


class _Folded:
    """``params -> outputs`` with the robot, motion and θ folded into the program as
    constants (``jit`` of this object's call; the arrays are not arguments)."""

    def __init__(self, program: Program, dynamic):
        self.program, self.dynamic = program, list(dynamic)
        self.run = jax.jit(self.__call__)

    def __call__(self, params: dict) -> dict:
        return _chunk(self.program, self.dynamic, params)


#: the last folded programs, with the very arrays they fold (a repeated or resumed
#: sweep of the same robot and motion in this process compiles nothing).
_FOLDED: list[_Folded] = []


def evaluate(program: Program, dynamic, params: dict, fold: bool = False) -> dict:
    """One chunk: :func:`run_chunk`, or with ``fold`` the program specialised to this
    robot and motion. Folding lets XLA precompute everything that depends only on the
    fixed motion and robot (measured: 4-7× fewer operations per point for a DUAL-V
    counter-mass sweep along a fixed motion) at the price of one compilation per sweep."""
    if not fold:
        return run_chunk(program, dynamic, params)
    for cached in _FOLDED:
        same = len(cached.dynamic) == len(dynamic)
        if (
            same
            and cached.program == program
            and all(a is b for a, b in zip(cached.dynamic, dynamic, strict=True))
        ):
            return cached.run(params)
    folded = _Folded(program, dynamic)
    _FOLDED[:] = [folded, *_FOLDED[:3]]
    return folded.run(params)


@partial(jax.jit, static_argnums=0)
def _single(program: Program, dynamic, params: dict) -> dict:
    return program.batch(dynamic, params)


def put(program: Program, params: dict) -> dict:
    """The chunk's parameters placed on the mesh, split along the points."""
    if program.mesh is None:
        return {k: jnp.asarray(v) for k, v in params.items()}
    sharding = NamedSharding(program.mesh, PartitionSpec(AXIS))
    return {k: jax.device_put(np.asarray(v), sharding) for k, v in params.items()}


def shape_key(program: Program, dynamic, params: dict) -> tuple:
    """What a trace of ``program.point`` depends on: the program and the shapes and
    dtypes of its arguments (not their values)."""

    def spec(x):
        return (np.shape(x), str(np.asarray(x).dtype) if not hasattr(x, "dtype") else str(x.dtype))

    points = tuple((k, spec(v)) for k, v in sorted(params.items()))
    return program, tuple(spec(x) for x in dynamic), points


#: ``output_shapes`` by :func:`shape_key` (a repeated sweep traces nothing twice).
_SHAPES: dict = {}


def output_shapes(program: Program, dynamic, params: dict) -> dict:
    """``{output: ShapeDtypeStruct}`` of one point (nothing is computed; cached by
    :func:`shape_key`)."""
    key = shape_key(program, dynamic, params)
    if key not in _SHAPES:
        one = {k: v[0] for k, v in params.items()}
        _SHAPES[key] = jax.eval_shape(program.point, dynamic, one)
        bound_cache(_SHAPES)
    return _SHAPES[key]


#: the module-level ``jit``s of sweeps whose static argument holds the user's functions
#: (a ``where=`` lambda, a metric): each new one is a program of its own, which XLA keeps
#: with its machine code mapped in memory. Thousands in one process (sweeps in a loop,
#: each with a new lambda) exhausted the kernel's memory-map count and crashed XLA's
#: compiler; :func:`release_programs` bounds them (sweep_affine registers its own).
PROGRAM_JITS: list = [run_chunk, _single]
#: programs kept per ``jit`` of :data:`PROGRAM_JITS` (beyond it, its cache is cleared).
MAX_PROGRAMS = 32


def release_programs() -> None:
    """Clear the cache of each ``jit`` of :data:`PROGRAM_JITS` holding more than
    :data:`MAX_PROGRAMS` programs (called after every sweep)."""
    for function in PROGRAM_JITS:
        if function._cache_size() > MAX_PROGRAMS:
            function.clear_cache()


def bound_cache(cache: dict, size: int = 32) -> None:
    """Drop the oldest entries of ``cache`` beyond ``size`` (they hold programs)."""
    while len(cache) > size:
        cache.pop(next(iter(cache)))


#: ``chunk_memory`` results by program and argument shapes (values do not matter).
_MEMORY: dict = {}


def chunk_memory(program: Program, dynamic, params: dict, probe: int = 64) -> tuple[int, int]:
    """``(bytes per point, fixed bytes)`` of one device evaluating a chunk, from XLA's
    memory analysis of the batch at ``probe`` and ``2·probe`` points (temporaries,
    outputs, the points' parameters, and the robot, motion and θ shared by all points).
    Cached per program and shapes, so a repeated sweep compiles no probe."""
    shapes = tuple((k, np.shape(v)[1:]) for k, v in sorted(params.items()))
    key = (program, shapes, tuple(np.shape(x) for x in dynamic), probe)
    if key not in _MEMORY:
        _MEMORY[key] = _measure(program, dynamic, params, probe)
    return _MEMORY[key]


def _measure(program: Program, dynamic, params: dict, probe: int) -> tuple[int, int]:
    sizes = []
    for batch in (probe, 2 * probe):
        stacked = {k: np.repeat(np.asarray(v)[:1], batch, axis=0) for k, v in params.items()}
        compiled = _single.lower(program, dynamic, stacked).compile()
        stats = compiled.memory_analysis()
        shared = sum(int(np.asarray(x).nbytes) for x in dynamic)  # robot, motion, θ
        inputs = sum(v.nbytes for v in stacked.values()) + shared
        sizes.append(stats.temp_size_in_bytes + stats.output_size_in_bytes + inputs)
    per_point = max((sizes[1] - sizes[0]) / probe, sizes[1] / (2 * probe) / 4, 1.0)
    return int(np.ceil(per_point)), max(int(sizes[0] - per_point * probe), 0)
