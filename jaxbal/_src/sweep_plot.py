"""Plots of a sweep: a line plot over one axis, a heat map over two, drawn in the order
of the axes' values (a grid may list them in any order). A sweep whose blocks are not
all done is drawn with what is done, its title saying how many are, and an
:class:`IncompleteSweepWarning`; the image's format is its file's suffix."""

from __future__ import annotations

import io
import warnings
from pathlib import Path

import numpy as np

__all__ = ["IncompleteSweepWarning", "plot_sweep"]


class IncompleteSweepWarning(UserWarning):
    """A sweep plotted before all its blocks are done (the others are blank)."""


_REDUCERS = {"max": np.nanmax, "min": np.nanmin, "mean": np.nanmean}


def _label(dataset, name: str) -> str:
    units = dataset[name].attrs.get("units", "")
    return f"{name} [{units}]" if units else name


def _reduce(data, keep: int, how: str):
    """``data`` with every dimension after the first ``keep`` reduced by ``how``."""
    if how not in _REDUCERS:  # also when nothing is reduced: a typo is a typo
        raise ValueError(f"unknown reduction {how!r}; choose one of {sorted(_REDUCERS)}")
    extra = list(data.dims[keep:])
    if not extra:
        return data, ""
    reduced = data.reduce(_REDUCERS[how], dim=extra)
    return reduced, f" ({how} over {', '.join(extra)})"


def plot_sweep(source, variable: str | None = None, *, out=None, reduce: str = "max"):
    """Line plot (one sweep axis) or heat map (the first two) of a sweep variable.

    Args:
        source: a sweep :class:`xarray.Dataset` or the path of its zarr store.
        variable: the variable (default: the first one).
        out: write the figure there (atomically) in the format of its suffix (``.png``,
            ``.pdf``, ``.svg``, …; none: PNG) and close it.
        reduce: ``"max"``, ``"min"`` or ``"mean"`` over the dimensions not drawn.

    Returns:
        The matplotlib figure (``None`` when written to ``out``).

    Raises:
        ValueError: an unknown variable or reduction, or a suffix of ``out`` that
            matplotlib cannot write (checked first).
    """
    import matplotlib

    if out is not None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    image = None if out is None else _format(out)

    from jaxbal._src.sweep_store import open_dataset

    dataset = source if hasattr(source, "data_vars") else open_dataset(source, complete=False)
    names = list(dataset.data_vars)
    variable = names[0] if variable is None else variable
    if variable not in dataset.data_vars:
        raise ValueError(f"unknown sweep variable {variable!r}; the store has {names}")
    data = dataset[variable]
    axes = [d for d in data.dims if d in dataset.coords and data.sizes[d] > 1] or [data.dims[0]]
    keep = min(len(axes), 2)
    data = data.transpose(*axes[:keep], ...)
    data, note = _reduce(data, keep, reduce)
    # a grid's values in the order given (grid([4, 0, 2])): a line and a mesh need them
    # ascending; the dataset keeps its order
    data = data.sortby([d for d in data.dims if d in data.coords])
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    x = data.dims[0]
    if keep == 1:
        ax.plot(data[x].values, data.values, marker="." if data.size < 60 else None)
        ax.set_ylabel(_label(dataset, variable))
    else:
        y = data.dims[1]
        mesh = ax.pcolormesh(
            data[y].values, data[x].values, data.values, shading="nearest", cmap="viridis"
        )
        fig.colorbar(mesh, ax=ax, label=_label(dataset, variable))
        ax.set_xlabel(_label(dataset, y))
        ax.set_ylabel(_label(dataset, x))
    if keep == 1:
        ax.set_xlabel(_label(dataset, x))
        ax.grid(alpha=0.3)
    done, _, count = str(dataset.attrs.get("blocks_done", "")).partition("/")
    if count and done != count:
        note += f"\n{done} of {count} blocks done"
        warnings.warn(
            f"{done} of {count} blocks of the sweep are done: the plot shows those only "
            "(resume the sweep for the others)",
            IncompleteSweepWarning,
            stacklevel=2,
        )
    ax.set_title(f"{variable}{note}", fontsize=10)
    if out is None:
        return fig
    from jaxbal._src.report import atomic_write_bytes

    buffer = io.BytesIO()
    fig.savefig(buffer, format=image, dpi=130, bbox_inches="tight")
    plt.close(fig)
    atomic_write_bytes(Path(out), buffer.getvalue())
    return None


def _format(out) -> str:
    """The image format of the file ``out``: its suffix (PNG without one).

    Raises:
        ValueError: a suffix matplotlib cannot write, naming those it can.
    """
    from matplotlib.backend_bases import FigureCanvasBase

    suffix = Path(out).suffix.lstrip(".").lower() or "png"
    known = FigureCanvasBase.get_supported_filetypes()
    if suffix not in known:
        raise ValueError(
            f"cannot write {out}: matplotlib writes no {suffix!r} images; use one of the "
            f"suffixes {sorted(known)}"
        )
    return suffix
