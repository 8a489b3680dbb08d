"""The zarr store of a sweep: labelled arrays written block by block, and which blocks
are done.

Layout (zarr format 3, readable by ``xarray.open_zarr(path, consolidated=False)``):

* one array per axis, the axis's index coordinate (``units``, ``kind`` attributes), and
  one per parameter that is not the coordinate itself (e.g. the points of a Sobol'
  sample), ``(n, *shape)``;
* one array per output of the metric, ``(*axis sizes, *output shape)``, chunked like
  the sweep's blocks: a finished block is one chunk of each output, written whole (zarr
  writes every chunk to a temporary file and renames it);
* the group ``_jaxbal`` with ``done``, one byte per block, set after the block's
  outputs are written: a block is done when its byte is, so a run killed at any moment
  leaves a store whose done blocks are complete; ``resume=True`` recomputes the others.

A new store is built under a hidden sibling name (``.NAME.PID-….new``) and renamed
into place once its description is written: a run killed while creating it leaves no
store at ``path`` (a later run deletes the orphaned sibling). A half-made store of an
older jaxbal (no description, no block done, only this sweep's arrays) is re-created
(:func:`discard_unfinished`) instead of being refused on every resume.

The group attribute ``jaxbal_sweep`` records the axes, the block shape and a fingerprint
of every value and every piece of code the sweep depends on — the axes, the outputs'
shapes, the robot, the motion, the fixed θ, and the metric and the axes' setters by
their code (:mod:`jaxbal._src.sweep_digest`), with the digest of each part; a resumed
sweep must match it, so a store resumed with another robot, motion, metric body or
setter is refused, naming what changed, instead of mixing the two; so is one resumed
with other labels, the units of an output, axis or parameter or the names of an
output's own dimensions (:func:`check_labels`). The group's other attributes
(``attrs=``) are those of the first call: a resume keeps them.
"""

from __future__ import annotations

import os
import secrets
import shutil
from pathlib import Path

import numpy as np

from jaxbal._src.sweep_axes import Axis, Layout

__all__ = ["MANIFEST", "SweepStore", "check_labels", "check_store", "open_dataset"]

#: the group of the store's own records (``done``)
MANIFEST = "_jaxbal"
_FORMAT = 1


def _output_dims(name: str, shape: tuple, given) -> list[str]:
    if given is not None:
        given = [given] if isinstance(given, str) else list(given)
        if len(given) != len(shape):
            raise ValueError(f"output {name!r} has shape {shape}; got dims {given}")
        return given
    return [f"{name}_dim{i}" for i in range(len(shape))]


def check_output_dims(axes: dict, outputs: dict, given: dict) -> None:
    """Refuse ``output_dims`` (``given``) that names an output the metric does not have
    (it was ignored), gives an output's dimension an axis's name, or gives one name to
    dimensions of different sizes (xarray refused the finished sweep, after every point
    was computed and stored).

    Raises:
        ValueError: naming the output and the dimension.
    """
    unknown = sorted(set(given) - set(outputs))
    if unknown:
        raise ValueError(f"output_dims for unknown outputs {unknown}; outputs {sorted(outputs)}")
    sizes = {}
    for name, spec in outputs.items():
        shape = tuple(spec.shape)
        for dim, size in zip(_output_dims(name, shape, given.get(name)), shape, strict=True):
            if dim in axes:
                raise ValueError(
                    f"output_dims of {name!r}: {dim!r} is a sweep axis ({sorted(axes)}); "
                    "name the output's own dimension otherwise"
                )
            if sizes.setdefault(dim, size) != size:
                raise ValueError(
                    f"output_dims of {name!r}: dimension {dim!r} has size {size} here and "
                    f"{sizes[dim]} in another output; give them different names"
                )


class SweepStore:
    """A sweep's zarr group (local path, or in memory when ``path`` is ``None``)."""

    def __init__(self, group, layout: Layout):
        self.group = group
        self.layout = layout
        self.done_array = group[MANIFEST]["done"]

    @classmethod
    def create(cls, path, axes: dict[str, Axis], layout: Layout, outputs: dict, meta: dict):
        """A new store (``outputs``: name ↦ ShapeDtypeStruct of one point; ``meta``:
        ``units``, ``output_dims``, ``attrs``, ``fingerprint``, ``parts``)."""
        import zarr

        check_output_dims(axes, outputs, meta.get("output_dims", {}))
        if path is None:
            group = zarr.open_group(zarr.storage.MemoryStore(), mode="w", zarr_format=3)
            return cls(_fill(group, axes, layout, outputs, meta), layout)
        # built under a hidden sibling and renamed into place: a run killed meanwhile
        # leaves no half-made store at ``path`` (one without its description)
        path = Path(path)
        _remove_abandoned(path)
        building = path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.new")
        try:
            _fill(zarr.open_group(str(building), mode="w", zarr_format=3), axes, layout,
                  outputs, meta)  # fmt: skip
            building.rename(path)
        except BaseException:
            shutil.rmtree(building, ignore_errors=True)
            raise
        return cls(_open_group(path, "r+"), layout)

    @classmethod
    def open(cls, path) -> SweepStore:
        """An existing store (to resume it), without the temporary files of a write
        that was killed (:func:`remove_partial_files`)."""
        remove_partial_files(path)
        group = _open_group(path, "r+")
        description = describe(group)
        layout = Layout(tuple(description["sizes"]), tuple(description["block"]))
        return cls(group, layout)

    @property
    def description(self) -> dict:
        return describe(self.group)

    def done(self) -> np.ndarray:
        """``(blocks,)`` True where a block is done."""
        return np.asarray(self.done_array[:]).astype(bool)

    def write(self, k: int, outputs: dict) -> None:
        """Write block ``k`` (``outputs``: name ↦ ``(*block extents, *shape)``) and then
        mark it done."""
        region = self.layout.region(k)
        for name, values in outputs.items():
            self.group[name][region] = values
        self.done_array[k] = 1


def _fill(group, axes: dict[str, Axis], layout: Layout, outputs: dict, meta: dict):
    """Write a new store's arrays, manifest and, last, its description into ``group``."""
    dims = list(axes)
    coordinates = []
    for dim, axis in axes.items():
        coord = group.create_array(
            dim, shape=(axis.size,), chunks=(axis.size,), dtype="f8", dimension_names=[dim]
        )
        coord[:] = axis.coordinate
        coord.attrs.update({"kind": axis.kind, "units": _coordinate_units(dim, axis)})
        for name, values in axis.values.items():
            if axis.kind == "grid" and values.ndim == 1:
                continue  # the values are the coordinate itself
            key = parameter_key(dim, name)
            names = [dim] + [f"{name}_dim{i}" for i in range(values.ndim - 1)]
            array = group.create_array(
                key, shape=values.shape, chunks=values.shape, dtype="f8", dimension_names=names
            )
            array[...] = values
            array.attrs["units"] = axis.units.get(name, "")
            array.attrs["parameter"] = name
            coordinates.append(key)
    units, given_dims = meta.get("units", {}), meta.get("output_dims", {})
    for name, spec in outputs.items():
        extra = tuple(spec.shape)
        dtype = np.dtype(spec.dtype)
        fill = np.nan if np.issubdtype(dtype, np.floating) else 0
        array = group.create_array(
            name,
            shape=layout.sizes + extra,
            chunks=layout.block + extra,
            dtype=dtype,
            fill_value=fill,
            dimension_names=dims + _output_dims(name, extra, given_dims.get(name)),
        )
        array.attrs["units"] = units.get(name, "")
        if coordinates:
            array.attrs["coordinates"] = " ".join(coordinates)
    manifest = group.create_group(MANIFEST)
    manifest.create_array("done", shape=(layout.count,), chunks=(1,), dtype="u1", fill_value=0)
    description = {
        "format": _FORMAT,
        "dims": dims,
        "sizes": list(layout.sizes),
        "block": list(layout.block),
        "outputs": sorted(outputs),
        "kinds": {dim: axis.kind for dim, axis in axes.items()},
        "fingerprint": meta["fingerprint"],
        "parts": meta["parts"],
    }
    group.attrs.update({**meta.get("attrs", {}), "jaxbal_sweep": description})
    return group


def _remove_abandoned(path: Path) -> None:
    """Delete the hidden siblings ``.NAME.PID-….new`` that a run killed while creating
    the store at ``path`` left (their process is gone)."""
    for leftover in path.parent.glob(f".{path.name}.*.new"):
        pid = leftover.name[len(path.name) + 2 :].partition("-")[0]
        try:
            os.kill(int(pid), 0)  # signal 0: is the process alive?
        except ProcessLookupError:
            shutil.rmtree(leftover, ignore_errors=True)
        except (ValueError, OSError):
            continue  # not ours, or alive under another user


def discard_unfinished(path, axes: dict[str, Axis], outputs: dict) -> bool:
    """Delete the store at ``path`` if its creation was interrupted (by a jaxbal whose
    creation was not atomic) and it could never be resumed: a zarr group without
    attributes (the description is written last) holding only arrays of this sweep
    (``axes``' coordinates and parameters, the ``outputs``) and the ``_jaxbal``
    manifest, no block done. True if it was deleted (the sweep then creates it anew)."""
    import zarr

    names = {MANIFEST, *outputs}
    for dim, axis in axes.items():
        names |= {dim} | {parameter_key(dim, name) for name in axis.values}
    try:
        group = zarr.open_group(str(path), mode="r", zarr_format=3)
        members = set(group.keys())
        done = group[MANIFEST]["done"][:] if MANIFEST in members else ()
    except Exception:  # noqa: BLE001 - not zarr, or not ours: left to open()
        return False
    if len(group.attrs) or not members <= names or np.any(done):
        return False
    shutil.rmtree(path)
    return True


def describe(group) -> dict:
    """The ``jaxbal_sweep`` attribute of a store's group."""
    description = group.attrs.get("jaxbal_sweep")
    if not isinstance(description, dict) or description.get("format") != _FORMAT:
        raise ValueError(
            "not a jaxbal sweep store (no jaxbal_sweep attribute: not written by "
            "jaxbal.sweep, or by another version of it)"
        )
    return description


def check_store(path) -> None:
    """Refuse the existing folder ``path`` as a sweep's store unless it is one: said
    before ``resume`` is advised (a folder of other files, or an empty one, was told
    "exists: pass resume", then "not a jaxbal sweep store"). Nothing in it is touched.

    Raises:
        ValueError: naming the path and what it holds instead.
    """
    group = _open_group(path, "r", advice=": choose another path")
    try:
        describe(group)
    except ValueError as error:
        raise ValueError(f"{path} is {error}: remove it or choose another path") from None


def _open_group(path, mode: str, advice: str = ""):
    """The zarr group at ``path``; a folder without one (empty, or not zarr) is refused.

    Raises:
        ValueError: naming the path (zarr's own message says "No group found in store"),
            followed by ``advice``.
    """
    import zarr

    try:
        return zarr.open_group(str(path), mode=mode, zarr_format=3)
    except zarr.errors.NodeNotFoundError:
        held = sum(1 for _ in Path(path).iterdir()) if Path(path).is_dir() else 0
        what = f"a folder of {held} other item(s)" if held else "an empty folder"
        raise ValueError(f"{path} is not a jaxbal sweep store (no zarr group in it), {what}"
                         f"{advice}") from None  # fmt: skip


def check_labels(path, group, axes: dict, outputs: dict, meta: dict) -> None:
    """Refuse to resume the store at ``path`` (its ``group``) with other units (of an
    output, an axis or a parameter) or other names of an output's own dimensions
    (``output_dims``) than it was written with: the store would keep the old ones.

    Raises:
        ValueError: naming each label that differs, stored and given.
    """
    units, given = meta.get("units", {}), meta.get("output_dims", {})
    check_output_dims(axes, outputs, given)
    labels = []  # (what, stored, given)
    for name, spec in outputs.items():
        array = group[name]
        labels.append((f"units of {name!r}", array.attrs.get("units", ""), units.get(name, "")))
        stored = list(array.metadata.dimension_names or ())[len(axes) :]
        dims = _output_dims(name, tuple(spec.shape), given.get(name))
        labels.append((f"output_dims of {name!r}", stored, dims))
    for dim, axis in axes.items():
        coordinate = _coordinate_units(dim, axis)
        labels.append((f"units of axis {dim!r}", group[dim].attrs.get("units", ""), coordinate))
        for name, values in axis.values.items():
            if not (axis.kind == "grid" and values.ndim == 1):  # stored apart (create)
                stored = group[parameter_key(dim, name)].attrs.get("units", "")
                labels.append((f"units of {name!r}", stored, axis.units.get(name, "")))
    changed = [
        f"{what} {old!r} in the store, {new!r} now" for what, old, new in labels if old != new
    ]
    if changed:
        raise ValueError(
            f"{path} was written with other labels: {'; '.join(changed)}. Resume with the "
            f"same units and output_dims, or start afresh (remove {path} or write another "
            "store)"
        )


def parameter_key(dim: str, name: str) -> str:
    """Store name of a parameter's values: the parameter's name, or ``NAME_values`` when
    it is the axis's own name (an array-valued grid: the coordinate is then ``0 … n-1``)."""
    return f"{name}_values" if name == dim else name


def _coordinate_units(dim: str, axis: Axis) -> str:
    """The coordinate's unit: a scalar grid's values are the coordinate."""
    (name, values), *others = axis.values.items()
    if axis.kind == "grid" and not others and values.ndim == 1:
        return axis.units.get(name, "")
    return ""


def remove_partial_files(path) -> int:
    """Delete the temporary ``*.partial`` files a killed zarr write leaves behind."""
    removed = 0
    for leftover in Path(path).rglob("*.partial"):
        leftover.unlink(missing_ok=True)
        removed += 1
    return removed


def open_dataset(source, *, complete: bool = True):
    """The sweep in ``source`` (a path or a zarr group) as an :class:`xarray.Dataset`,
    loaded into memory; ``complete``: raise if some blocks are not done."""
    import xarray as xr

    group = source
    if isinstance(source, str | Path):
        if not Path(source).exists():
            raise FileNotFoundError(f"no sweep store at {source}")
        group = _open_group(source, "r")
    try:
        description = describe(group)
    except ValueError as error:
        if group is source:
            raise
        raise ValueError(f"{source} is {error}") from None
    done = np.asarray(group[MANIFEST]["done"][:]).astype(bool)
    if complete and not done.all():
        missing = int((~done).sum())
        raise ValueError(f"{missing} of {done.size} blocks of the sweep are not done (resume it)")
    dataset = xr.open_zarr(group.store, consolidated=False, mask_and_scale=False).load()
    dataset.attrs.pop("jaxbal_sweep", None)
    dataset.attrs["blocks_done"] = f"{int(done.sum())}/{done.size}"
    dims = description["dims"]
    return dataset.transpose(*dims, ...)
