"""Sweeps: a metric over named axes of designs, payloads and trajectories, at scale.

``jaxbal.sweep(metric, robot, motion, axes, …)`` (this module is callable; the function
is also :func:`jaxbal.sweep.sweep`) evaluates ``metric(robot, motion)`` on the
Cartesian product of ``axes`` and returns an :class:`xarray.Dataset`::

    ds = jaxbal.sweep("peak_force", robot, motion, {
        "counter_mass": jaxbal.sweep.grid(np.linspace(0, 8, 100), units="kg"),
        "payload": jaxbal.sweep.grid(np.linspace(0, 0.5, 20), units="kg"),
    }, store="sweep.zarr", resume=True)

* **Axes.** :func:`grid` (one parameter's values), :func:`sobol`, :func:`halton`,
  :func:`uniform` (several parameters sampled together in a box) and :func:`points`
  (given samples). A parameter is a design variable of the robot (``robot.design()``:
  ``counter_mass``, ``payload``, …; a scalar is broadcast to the variable's shape),
  any leaf given by ``where=`` (an ``eqx.tree_at`` path) or ``set=`` (``(robot,
  value) -> robot``), or else a trajectory variable: then ``motion`` is a motion
  factory ``motion(robot, θ)`` (e.g. :class:`jaxbal.design.TrapezoidLine`) and ``θ``
  holds the swept variables over the fixed ``trajectory=`` ones.
* **Metric.** A name of :data:`jaxbal.design.METRICS` or any function of ``(robot,
  motion)`` returning an array, a tuple, a NamedTuple or a dict of arrays (one dataset
  variable each, named by ``output_dims`` for their own dimensions; ``units=``).
* **Affine fast path** (``linear="auto"``, default). Along a fixed motion the shaking
  wrench is affine in masses and inertias, so for the named wrench metrics
  (``peak_force``, ``rms_force``, ``peak_moment``, ``rms_moment``) a sweep of
  counter-masses, payloads or inertias computes the wrench and its derivatives in the
  swept parameters once (one ``jacfwd`` along the samples) and each point from them:
  ``t × 3 × p`` multiply-adds instead of the kinematics and dynamics at every sample.
  The sweep first *verifies* affinity at 8 of its points (the direct wrench, to 1e-9 of
  its gross scale); a swept length or distance fails that and is evaluated directly.
  ``linear=True`` raises instead of falling back, ``linear=False`` never uses it (then
  the result is the plain ``vmap`` of the metric bit for bit). The two agree to
  rounding; the dataset's ``evaluation`` attribute says ``"affine"`` when it ran, and a
  store is only resumed by the same evaluation. (:mod:`jaxbal._src.sweep_affine`.)
* **Chunks.** The product is cut into blocks from ``memory_budget`` (bytes one device
  may use, from XLA's memory analysis of the compiled batch) or ``chunk_size``; every
  block is one call of one compiled program (``vmap``), split over all local devices
  with ``shard_map`` (several CPU devices with
  ``XLA_FLAGS=--xla_force_host_platform_device_count=N``). A point's value depends only
  on the per-device batch size (not on the devices or the chunking when that batch is
  the same), so a direct sweep equals the plain ``vmap`` of the metric bit for bit.
* **Store.** With ``store="path.zarr"``, each finished block is written to a zarr
  store (readable with ``xarray.open_zarr(path, consolidated=False)`` or
  :func:`open_sweep`) and marked done; after an interruption ``resume=True``
  recomputes only the missing blocks and the store ends identical to an
  uninterrupted run. The store's fingerprint covers the axes, robot, motion and θ,
  and the metric's and setters' *code* (bytecode, constants, captured values and the
  module constants they read): a resume with any of them changed is refused, naming
  what changed. Progress is shown with tqdm (rate and ETA; ``progress=False``).
* **Cluster.** ``backend="ray"`` (or a :class:`RayBackend`) sends the blocks as Ray
  tasks to the cluster of ``ray.init(address=…)`` (a new local one if none), retries a
  block whose worker died and writes it into the same store (``pip install
  "jaxbal[cluster]"``).

:func:`plot_sweep` draws a line plot (one axis) or a heat map (two) of a variable;
:func:`load_spec` reads the TOML spec of ``jaxbal sweep SPEC.toml`` (format in
:mod:`jaxbal._src.sweep_spec`).
"""

import sys
import types

from jaxbal._src.sweep import DEFAULT_MEMORY_BUDGET, METRIC_UNITS, sweep
from jaxbal._src.sweep_axes import Axis, grid, halton, points, sobol, uniform
from jaxbal._src.sweep_plot import plot_sweep
from jaxbal._src.sweep_ray import RayBackend
from jaxbal._src.sweep_spec import SweepSpec, load_spec
from jaxbal._src.sweep_store import open_dataset as open_sweep

__all__ = [
    "DEFAULT_MEMORY_BUDGET",
    "METRIC_UNITS",
    "Axis",
    "RayBackend",
    "SweepSpec",
    "grid",
    "halton",
    "load_spec",
    "open_sweep",
    "plot_sweep",
    "points",
    "sobol",
    "sweep",
    "uniform",
]


class _CallableModule(types.ModuleType):
    """``jaxbal.sweep(...)`` calls :func:`sweep`; ``jaxbal.sweep.grid`` etc. still work."""

    def __call__(self, *args, **kwargs):
        return sweep(*args, **kwargs)


sys.modules[__name__].__class__ = _CallableModule
