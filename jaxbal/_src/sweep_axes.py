"""Axes of a sweep: grids, random and quasi-random samples, and the block layout.

An :class:`Axis` is one named dimension of a sweep. It carries one or several
*parameters* (design variables, payload, trajectory variables, or any leaf reached by a
setter), each an array ``(n, *shape)`` of values along the dimension: a grid has one
parameter named after the axis, a sample (:func:`sobol`, :func:`halton`,
:func:`uniform`, :func:`points`) several, drawn together. The sweep is the Cartesian
product of its axes.

The product is cut into rectangular blocks (:class:`Layout`): a block spans whole
trailing axes where it can, so that a block is both one chunk of evaluation (one call
of the compiled program) and one chunk of every array of the zarr store.

References:
    I. M. Sobol' (1967), J. Halton (1960): low-discrepancy sequences, as implemented by
    :mod:`scipy.stats.qmc` (Owen scrambling, Joe & Kuo direction numbers).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

__all__ = ["Axis", "Layout", "grid", "halton", "points", "sobol", "uniform"]

#: a setter ``(robot, value) -> robot`` or ``None`` (design variable or trajectory).
Setter = Callable | None
#: most points of a sample (and of a spec's ``linspace``): more would not fit in memory.
MAX_POINTS = 10**8


@dataclass(frozen=True, eq=False)
class Axis:
    """One dimension of a sweep (build it with :func:`grid`, :func:`sobol`, …).

    Attributes:
        values: parameter name ↦ ``(n, *shape)`` float64 values along the axis.
        units: parameter name ↦ unit string (``""`` when unknown).
        setters: parameter name ↦ ``(robot, value) -> robot``; parameters without one
            are design variables of the robot (``robot.with_design``) or, failing that,
            entries of the trajectory ``θ`` passed to a motion factory.
        coordinate: ``(n,)`` index coordinate of the dimension (the grid values of a
            scalar grid, else ``0 … n-1``).
        kind: ``"grid"``, ``"sobol"``, ``"halton"``, ``"uniform"`` or ``"points"``.
        name: the parameter a grid sets when it is not the axis name (``None``: the
            axis name).
    """

    values: dict[str, np.ndarray]
    units: dict[str, str] = field(default_factory=dict)
    setters: dict[str, Setter] = field(default_factory=dict)
    coordinate: np.ndarray | None = None
    kind: str = "grid"
    name: str | None = None

    @property
    def size(self) -> int:
        return len(next(iter(self.values.values())))

    def named(self, dim: str) -> Axis:
        """This axis as dimension ``dim`` (a grid's single parameter takes that name)."""
        if self.kind != "grid" or self.name is not None:
            return self
        rename = {"values": {dim: self.values[""]}, "units": {dim: self.units.get("", "")}}
        rename["setters"] = {dim: self.setters.get("")}
        return Axis(**rename, coordinate=self.coordinate, kind="grid", name=dim)


def _as_values(values, what: str) -> np.ndarray:
    array = np.asarray(values, dtype=np.float64)
    if array.ndim == 0 or len(array) == 0:
        raise ValueError(f"{what} needs a non-empty sequence of values, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"{what} has non-finite values")
    return array


def _setter(set, where) -> Setter:
    if set is not None and where is not None:
        raise ValueError("give set= or where=, not both")
    if where is None:
        return set
    import equinox as eqx
    import jax.numpy as jnp

    def tree_set(robot, value):
        leaf = where(robot)
        return eqx.tree_at(where, robot, jnp.broadcast_to(value, jnp.shape(leaf)))

    tree_set.where = where  # the leaf's shape is checked before the sweep compiles
    return tree_set


def grid(
    values, *, units: str = "", set: Setter = None, where: Callable | None = None, name=None
) -> Axis:
    """An axis of given values of one parameter.

    Args:
        values: ``(n,)`` scalars or ``(n, *shape)`` arrays (e.g. one counter-mass per
            arm); a scalar value is broadcast to the shape of the leaf it sets.
        units: unit of the values (stored as the coordinate's ``units`` attribute).
        set: ``(robot, value) -> robot`` for a parameter that is not a design variable.
        where: an ``eqx.tree_at`` path ``robot -> leaf``, the leaf replaced by the value.
        name: the parameter set, when it differs from the axis name.
    """
    array = _as_values(values, "grid")
    coordinate = array if array.ndim == 1 else np.arange(len(array), dtype=np.float64)
    key = "" if name is None else name
    setter = _setter(set, where)
    return Axis({key: array}, {key: units}, {key: setter}, coordinate, "grid", name)


def points(values: Mapping, *, units: Mapping | None = None, setters=None) -> Axis:
    """An axis of given samples: ``values`` maps each parameter to ``(n, *shape)``
    values, all with the same ``n`` (the parameters vary together)."""
    arrays = {k: _as_values(v, f"points[{k!r}]") for k, v in values.items()}
    if not arrays:
        raise ValueError("points needs at least one parameter")
    sizes = {len(v) for v in arrays.values()}
    if len(sizes) != 1:
        raise ValueError(f"points: every parameter needs the same number of values, got {sizes}")
    n = sizes.pop()
    return Axis(arrays, dict(units or {}), dict(setters or {}), np.arange(n, dtype=float), "points")


def _bounds(bounds: Mapping) -> tuple[list[str], np.ndarray, np.ndarray]:
    if not bounds:
        raise ValueError("a sample needs bounds {parameter: (low, high)}")
    names = list(bounds)
    pairs = []
    for name in names:
        try:
            low, high = (float(b) for b in bounds[name])
        except (TypeError, ValueError):
            low = high = np.nan  # not a pair of numbers
        if not (np.isfinite(low) and np.isfinite(high) and high > low):
            raise ValueError(
                f"bounds {name!r} must be (low, high), finite with high > low, got {bounds[name]!r}"
            )
        pairs.append((low, high))
    low, high = np.array(pairs).T
    return names, low, high


def _sample(kind: str, unit_cube: np.ndarray, bounds, units, setters) -> Axis:
    names, low, high = _bounds(bounds)
    values = low + unit_cube * (high - low)
    arrays = {name: values[:, i].copy() for i, name in enumerate(names)}
    n = len(values)
    return Axis(arrays, dict(units or {}), dict(setters or {}), np.arange(n, dtype=float), kind)


def sobol(n: int, bounds: Mapping, *, seed: int = 0, scramble=True, units=None, setters=None):
    """``n`` scrambled Sobol' points in the box ``bounds`` ``{parameter: (low, high)}``
    (:class:`scipy.stats.qmc.Sobol`; ``n`` a power of two keeps its balance)."""
    from scipy.stats import qmc

    names, _, _ = _bounds(bounds)
    engine = qmc.Sobol(len(names), scramble=scramble, rng=np.random.default_rng(seed))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # n not a power of two
        cube = engine.random(_count(n))
    return _sample("sobol", cube, bounds, units, setters)


def halton(n: int, bounds: Mapping, *, seed: int = 0, scramble=True, units=None, setters=None):
    """``n`` scrambled Halton points in the box ``bounds`` (:class:`scipy.stats.qmc.Halton`)."""
    from scipy.stats import qmc

    names, _, _ = _bounds(bounds)
    engine = qmc.Halton(len(names), scramble=scramble, rng=np.random.default_rng(seed))
    return _sample("halton", engine.random(_count(n)), bounds, units, setters)


def uniform(n: int, bounds: Mapping, *, seed: int = 0, units=None, setters=None):
    """``n`` independent uniform random points in the box ``bounds`` (NumPy PCG64)."""
    names, _, _ = _bounds(bounds)
    cube = np.random.default_rng(seed).random((_count(n), len(names)))
    return _sample("uniform", cube, bounds, units, setters)


def _count(n) -> int:
    if not (
        isinstance(n, int | float | np.number) and not isinstance(n, bool) and np.isfinite(n)
        and int(n) == n and 1 <= n <= MAX_POINTS
    ):  # fmt: skip
        raise ValueError(f"a sample needs an integer count from 1 to {MAX_POINTS:.0e}, got {n!r}")
    return int(n)


@dataclass(frozen=True)
class Layout:
    """The sweep's axes cut into blocks of at most ``chunk`` points.

    Attributes:
        sizes: length of each axis.
        block: shape of a block (the zarr chunk shape of the axes).
    """

    sizes: tuple[int, ...]
    block: tuple[int, ...]

    @classmethod
    def for_chunk(cls, sizes, chunk: int) -> Layout:
        """Blocks of at most ``chunk`` points, covering whole trailing axes first."""
        sizes = tuple(int(s) for s in sizes)
        block, room = [], max(int(chunk), 1)
        for size in reversed(sizes):
            block.append(max(1, min(size, room)))
            room = max(room // block[-1], 1)
        return cls(sizes, tuple(reversed(block)))

    @property
    def grid(self) -> tuple[int, ...]:
        """Number of blocks along each axis."""
        return tuple(math.ceil(s / b) for s, b in zip(self.sizes, self.block, strict=True))

    @property
    def count(self) -> int:
        """Number of blocks."""
        return math.prod(self.grid)

    @property
    def points(self) -> int:
        """Points of a full block."""
        return math.prod(self.block)

    def region(self, k: int) -> tuple[slice, ...]:
        """Index ranges of block ``k`` (row-major over :attr:`grid`)."""
        index = np.unravel_index(k, self.grid)
        return tuple(
            slice(i * b, min((i + 1) * b, s))
            for i, b, s in zip(index, self.block, self.sizes, strict=True)
        )

    def indices(self, k: int) -> list[np.ndarray]:
        """Per axis, the ``(m,)`` indices of the ``m`` points of block ``k`` (row-major)."""
        ranges = [np.arange(r.start, r.stop) for r in self.region(k)]
        return [g.ravel() for g in np.meshgrid(*ranges, indexing="ij")]
