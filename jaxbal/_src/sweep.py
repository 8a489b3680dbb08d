"""``jaxbal.sweep``: a metric over the Cartesian product of named axes, labelled, chunked,
sharded over the devices, resumable, and on a Ray cluster.

The sweep is cut into blocks of points (:class:`~jaxbal._src.sweep_axes.Layout`) sized
from a memory budget; every block is one call of one compiled program
(:func:`~jaxbal._src.sweep_program.run_chunk`: ``vmap`` of the metric, split over the
local devices with ``shard_map``), padded to the same number of points so that nothing
recompiles. Finished blocks stream to a zarr store (:mod:`jaxbal._src.sweep_store`), so
an interrupted sweep resumes where it stopped and ends with the same store.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from pathlib import Path

import numpy as np

from jaxbal._src.sweep_axes import Axis, Layout, grid
from jaxbal._src.sweep_blocks import MAX_CHUNK, MAX_LU_BATCH, chunk_points
from jaxbal._src.sweep_digest import check_resumable, fingerprint, sweep_parts
from jaxbal._src.sweep_inputs import (
    check_bounds,
    check_names,
    check_shapes,
    check_trajectory_domain,
    trajectory_shapes,
)
from jaxbal._src.sweep_loops import check_loops
from jaxbal._src.sweep_program import build, device_mesh, release_programs
from jaxbal._src.sweep_run import connect_backend, run_backend
from jaxbal._src.sweep_store import (
    SweepStore,
    check_labels,
    check_store,
    discard_unfinished,
    open_dataset,
)
from jaxbal._src.writable import check_writable

__all__ = [
    "DEFAULT_MEMORY_BUDGET",
    "MAX_CHUNK",
    "MAX_LU_BATCH",
    "METRIC_UNITS",
    "Chunks",
    "check_bounds",
    "plan_parameters",
    "prepare",
    "sweep",
]

#: bytes one device may use for a block's temporaries, inputs and outputs (default).
DEFAULT_MEMORY_BUDGET = 512 * 2**20
#: units of the named metrics of :data:`jaxbal.design.METRICS`.
METRIC_UNITS = {
    "peak_force": "N",
    "rms_force": "N",
    "peak_moment": "N·m",
    "rms_moment": "N·m",
    "peak_torque": "N·m or N",
    "rms_torque": "N·m or N",
    "peak_torque_rate": "N·m/s or N/s",
    "added_mass": "kg",
    "added_inertia": "kg·m²",
}
#: XLA's CPU backend picks its loop code by array size: measured on the 2R, batches
#: whose arrays hold fewer than ~2,048 elements (points × samples) can differ from larger
#: ones in the last bit at some points. A sweep whose device batches hold at least this
#: many points (the default memory budget gives that for cheap metrics), or that is one
#: block, equals a plain ``jit(vmap)`` of the metric bit for bit; otherwise to rounding.
MIN_DEVICE_BATCH = 2048


def _axes(axes: Mapping) -> dict[str, Axis]:
    if not axes:
        raise ValueError("a sweep needs at least one axis")
    named, seen = {}, set()
    for dim, axis in axes.items():
        if not isinstance(dim, str) or not dim.isidentifier():
            raise ValueError(f"axis names must be identifiers, got {dim!r}")
        axis = (axis if isinstance(axis, Axis) else grid(axis)).named(dim)
        clash = seen & set(axis.values)
        if clash or (dim in seen):
            raise ValueError(f"parameter(s) {sorted(clash or {dim})} set by two axes")
        seen |= set(axis.values)
        named[dim] = axis
    return named


def plan_parameters(axes: dict[str, Axis], robot, motion) -> tuple:
    """How each parameter reaches the point: ``(name, "set" | "design" | "trajectory",
    setter)``, in the order of the axes."""
    design = robot.design() if hasattr(robot, "design") else {}
    plan = []
    for axis in axes.values():
        for name in axis.values:
            setter = axis.setters.get(name)
            if setter is not None:
                plan.append((name, "set", setter))
            elif name in design:
                plan.append((name, "design", None))
            elif callable(motion):
                plan.append((name, "trajectory", None))
            else:
                raise ValueError(
                    f"unknown sweep parameter {name!r}: not a design variable of "
                    f"{type(robot).__name__} ({sorted(design)}), no setter, and the motion "
                    "is not a factory motion(robot, θ)"
                )
    return tuple(plan)


class Chunks:
    """The blocks of a sweep as padded parameter batches.

    Attributes:
        axes, layout: the sweep's axes and blocks.
        batch: points per call (a block padded to a multiple of the device count).
    """

    def __init__(
        self, axes: dict[str, Axis], layout: Layout, devices: int, allow_nonfinite: bool = False
    ):
        self.axes, self.layout, self.allow_nonfinite = axes, layout, allow_nonfinite
        self.batch = math.ceil(layout.points / devices) * devices

    def params(self, k: int) -> tuple[dict, int]:
        """``({parameter: (batch, …)}, m)``: block ``k``'s ``m`` points, the last one
        repeated up to :attr:`batch`."""
        indices = self.layout.indices(k)
        m = len(indices[0])
        params = {}
        for index, axis in zip(indices, self.axes.values(), strict=True):
            padded = np.concatenate([index, np.full(self.batch - m, index[-1])])
            for name, values in axis.values.items():
                params[name] = values[padded]
        return params, m

    def unpad(self, k: int, outputs: dict, m: int) -> dict:
        """Block ``k``'s outputs ``{name: (*extents, …)}`` from a batch's.

        Raises:
            ValueError: an output is not finite at some point (an overflow, a metric
                that divides by zero, …), unless ``allow_nonfinite``; the message names
                the output and the point's parameters.
        """
        extents = tuple(r.stop - r.start for r in self.layout.region(k))
        result = {n: np.asarray(v)[:m].reshape(extents + v.shape[1:]) for n, v in outputs.items()}
        if not self.allow_nonfinite:
            for name, values in result.items():
                flat = values.reshape(m, -1)
                if np.issubdtype(flat.dtype, np.floating) and not np.all(np.isfinite(flat)):
                    i = int(np.argmax(~np.all(np.isfinite(flat), axis=1)))
                    params, _ = self.params(k)
                    at = ", ".join(f"{p} = {np.asarray(v[i]).tolist()}" for p, v in params.items())
                    raise ValueError(
                        f"sweep output {name!r} is not finite at {at} (block {k}); pass "
                        "allow_nonfinite=True to store such values"
                    )
        return result


def _affine(metric, robot, motion, axes, plan, trajectory, linear):
    """``(robot, function, plan, evaluation)`` of the affine fast path
    (:mod:`jaxbal._src.sweep_affine`), or ``None`` to evaluate the metric directly."""
    from jaxbal._src.metrics import as_motion
    from jaxbal._src.sweep_affine import TOLERANCE, WRENCH_METRICS, AffineMetric, affine_model

    if linear not in (True, False, "auto"):
        raise ValueError(f'linear must be True, False or "auto", got {linear!r}')
    eligible = (
        isinstance(metric, str)
        and metric in WRENCH_METRICS
        and not callable(motion)
        and not trajectory
        and all(how != "trajectory" for _, how, _ in plan)
    )
    if not eligible:
        if linear is True:
            raise ValueError(
                f"linear=True needs one of the metrics {sorted(WRENCH_METRICS)} by name, a "
                "fixed motion (not a factory) and no trajectory variables; got metric "
                f"{metric!r}"
            )
        return None
    if linear is False:
        return None
    model, deviation = affine_model(metric, robot, as_motion(motion), axes, plan)
    if deviation <= TOLERANCE:
        model_plan = tuple((name, "design", None) for name, _, _ in plan)
        return model, AffineMetric(metric), model_plan, "affine"
    if linear is True:
        raise ValueError(
            f"the shaking wrench is not affine in the swept parameters {[n for n, _, _ in plan]}"
            f": the affine model deviates by {deviation:.3g} of the wrench's scale (tolerance "
            f"{TOLERANCE:g}); a length or distance enters nonlinearly: use linear=False"
        )
    return None


def prepare(
    metric, robot, motion, axes, *, trajectory=None, devices=None, mesh=True, linear="auto"
):
    """``(axes, program, dynamic, outputs, evaluation)`` of a sweep (see :func:`sweep`);
    ``evaluation`` says whether the affine fast path is used."""
    from jaxbal._src.metrics import check_hashable, resolve_metric
    from jaxbal._src.sweep_inputs import check_payload_axis, trajectory_values

    mesh = device_mesh(devices) if mesh else None  # refused: [], duplicates, not devices
    theta = trajectory_values(motion, trajectory)  # refused: θ of a fixed motion, NaN
    axes = _axes(axes)
    function = resolve_metric(metric) if isinstance(metric, str) else metric
    check_hashable(metric)  # the compiled program is keyed on it
    check_payload_axis(metric, axes)
    plan = plan_parameters(axes, robot, motion)
    check_bounds(axes, robot, plan)
    check_trajectory_domain(axes, motion, theta)
    check_shapes(axes, robot, plan)
    check_loops(axes, robot, motion, plan)
    evaluation = "direct"
    fast = _affine(metric, robot, motion, axes, plan, trajectory, linear)
    if fast is not None:
        robot, function, plan, evaluation = fast
    program, dynamic = build(function, robot, motion, theta, plan, mesh)
    first = {n: v[:1] for a in axes.values() for n, v in a.values.items()}
    outputs = trajectory_shapes(program, dynamic, first, motion, theta)
    check_names(axes, outputs)
    return axes, program, dynamic, outputs, evaluation


def _metadata(metric, robot, axes, outputs, units, output_dims, attrs, evaluation, parts):
    if isinstance(units, str):
        if len(outputs) != 1:
            raise ValueError(f"units as one string needs one output, got {sorted(outputs)}")
        units = {next(iter(outputs)): units}
    name = metric if isinstance(metric, str) else getattr(metric, "__name__", repr(metric))
    unknown = set(units or {}) - set(outputs)
    if unknown:
        raise ValueError(f"units for unknown outputs {sorted(unknown)}; outputs {sorted(outputs)}")
    if not units:  # a named metric's, or a metric object's ``units`` (BaseVibration)
        named = isinstance(metric, str)
        unit = METRIC_UNITS.get(metric, "") if named else getattr(metric, "units", "")
        units = {n: unit for n in outputs} if isinstance(unit, str) and unit else units
    base = {"metric": name, "robot": type(robot).__name__}
    if evaluation != "direct":  # part of the fingerprint: a resume never mixes the two
        base["evaluation"] = "affine"
    return {
        "units": dict(units or {}),
        "output_dims": dict(output_dims or {}),
        "attrs": {**base, **(attrs or {})},
        "fingerprint": fingerprint(parts),
        "parts": parts,
    }


def _check_sizes(chunk_size, memory_budget, store) -> None:
    """Refuse a ``chunk_size`` that is not an integer ≥ 1, a ``memory_budget`` that is
    not > 0 bytes, a ``store`` that is an existing file (a store is a folder), and a new
    ``store`` that cannot be written (:func:`~jaxbal._src.writable.check_writable`)."""
    if chunk_size is not None and not (
        isinstance(chunk_size, int | np.integer) and not isinstance(chunk_size, bool)
        and chunk_size >= 1
    ):  # fmt: skip
        raise ValueError(f"chunk_size must be an integer ≥ 1 (points), got {chunk_size!r}")
    if not (isinstance(memory_budget, int | float | np.number) and memory_budget >= 1):
        raise ValueError(f"memory_budget must be a number of bytes ≥ 1, got {memory_budget!r}")
    if store is not None and Path(store).exists() and not Path(store).is_dir():
        raise ValueError(
            f"{store} is a file, not a jaxbal sweep store (a folder): remove it or choose "
            "another path"
        )
    if store is not None and not Path(store).exists():
        check_writable(store)  # before anything compiles


def sweep(
    metric: Callable | str,
    robot,
    motion,
    axes: Mapping,
    *,
    trajectory: Mapping | None = None,
    units: str | Mapping | None = None,
    output_dims: Mapping | None = None,
    store: str | Path | None = None,
    resume: bool = False,
    memory_budget: int = DEFAULT_MEMORY_BUDGET,
    chunk_size: int | None = None,
    devices=None,
    backend="local",
    progress: bool = True,
    attrs: Mapping | None = None,
    allow_nonfinite: bool = False,
    fold: bool = True,
    linear: bool | str = "auto",
):
    """Evaluate ``metric(robot, motion)`` on the Cartesian product of ``axes``.

    See :mod:`jaxbal.sweep` for the full description; returns an
    :class:`xarray.Dataset` with one variable per output of the metric, dimensions the
    axes then the output's own, coordinates the axes' values, ``units`` attributes.

    ``fold`` (default): the robot, motion and fixed θ are compiled into the program as
    constants, so XLA precomputes what depends only on them (several times faster per
    point for a design sweep along a fixed motion), at one compilation per sweep call;
    ``fold=False`` compiles once for every sweep of the same structure (many small
    sweeps).

    ``linear``: a named wrench metric (``peak_force``, ``rms_force``, ``peak_moment``,
    ``rms_moment``) along a fixed motion is affine in masses and inertias (counter-masses,
    payloads): with ``"auto"`` (default) the sweep verifies that at 8 of its points and
    then evaluates each point from the wrench and its derivatives computed once
    (:mod:`jaxbal._src.sweep_affine`; equal to the direct metric to rounding, far faster);
    a swept length or distance fails the check and is evaluated directly. ``True``
    raises instead of falling back; ``False`` always evaluates directly (bit for bit
    the plain ``vmap`` of the metric). The dataset's ``evaluation`` attribute says
    ``"affine"`` when the fast path ran.

    ``devices``: a non-empty sequence of distinct :class:`jax.Device` that each block
    is split over (``shard_map``; default: ``jax.local_devices()``); a Ray worker uses
    its own local devices.

    Raises:
        ValueError: an unknown parameter, values that are not finite, below a design
            variable's lower bound or of a shape that does not fit it, an axis named
            like an output or ``_jaxbal`` (naming the axis), a trajectory variable
            nobody gives or θ given to a fixed motion (naming it), a closed chain's
            fixed motion off the robot's loops, a store resumed with other inputs, code,
            units or output_dims (naming what changed; it keeps the ``attrs`` it was
            written with), a ``store`` folder that is no sweep store (resumed or not),
            a runtime check failing in a block (``sweep block k (ranges): message``),
            or a non-finite output (naming the point; ``allow_nonfinite=True`` stores
            it instead). The blocks finished before stay in the store.
        ValueError: also a ``chunk_size`` that is not an integer ≥ 1, a
            ``memory_budget`` below 1 byte, a ``store`` that is a file, bad
            ``devices``, or a Ray cluster that cannot be reached (before any store).
        RuntimeError: any other exception raised in a block, as ``sweep block k
            (ranges): message`` (chained to the original).
        FileExistsError: ``store`` exists and ``resume`` is False.
        OSError: a new ``store`` that cannot be written (checked first).
    """
    _check_sizes(chunk_size, memory_budget, store)
    axes, program, dynamic, outputs, evaluation = prepare(
        metric, robot, motion, axes, trajectory=trajectory, devices=devices, linear=linear
    )
    parts = sweep_parts(metric, robot, motion, trajectory, axes, outputs, evaluation)
    meta = _metadata(metric, robot, axes, outputs, units, output_dims, attrs, evaluation, parts)
    count = program.mesh.size
    sizes = tuple(a.size for a in axes.values())
    path = None if store is None else Path(store)
    if path is not None and path.exists() and not discard_unfinished(path, axes, outputs):
        check_store(path)  # a folder of other files: refused, resumed or not
        if not resume:
            raise FileExistsError(f"{path} exists: pass resume=True to continue it, or remove it")
        opened = SweepStore.open(path)  # also removes a killed write's *.partial files
        check_resumable(path, opened.description, parts, axes)
        check_labels(path, opened.group, axes, outputs, meta)
    else:
        if chunk_size is None:
            first, _ = Chunks(axes, Layout.for_chunk(sizes, 1), 1).params(0)
            chunk_size = chunk_points(
                program, dynamic, first, memory_budget, math.prod(sizes), count
            )
        layout = Layout.for_chunk(sizes, chunk_size)
        connect_backend(backend)  # a Ray cluster that is not there: refused, no store left
        opened = SweepStore.create(path, axes, layout, outputs, meta)
    chunks = Chunks(axes, opened.layout, count, allow_nonfinite)
    pending = [k for k, done in enumerate(opened.done()) if not done]
    try:
        run_backend(backend, program, dynamic, chunks, pending, opened, progress, fold)
    finally:  # also after a block's runtime check failed
        release_programs()
    return open_dataset(opened.group)
