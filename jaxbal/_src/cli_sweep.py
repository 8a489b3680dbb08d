"""The ``jaxbal sweep`` and ``jaxbal plot`` commands (registered on the app of
:mod:`jaxbal._src.cli`).

Every error is one line and exit status 2 (:mod:`jaxbal._src.cli_errors`): a bad
spec (naming the key), an ``--out`` that cannot be written (checked before the sweep
compiles), a folder that is not a sweep store, a Ray cluster that cannot be reached
(before any store is created), an exception raised in a block (naming it).
"""

from __future__ import annotations

import warnings
from pathlib import Path

import typer

from jaxbal._src.cli_errors import cannot_write, fail

__all__ = ["plot_command", "sweep_command"]


def sweep_command(
    spec: Path = typer.Argument(..., help="the sweep's TOML spec (robot, motion, metric, axes)"),
    out: Path = typer.Option(..., "--out", help="zarr store written block by block"),
    resume: bool = typer.Option(False, "--resume", help="continue an interrupted store"),
    backend: str = typer.Option("local", "--backend", help="local or ray"),
    address: str = typer.Option(None, "--address", help="Ray cluster address (e.g. auto)"),
    progress: bool = typer.Option(True, "--progress/--no-progress", help="progress bar"),
):
    """Evaluate a metric over the axes of SPEC into the zarr store OUT.

    The spec format is documented in jaxbal/_src/sweep_spec.py (example:
    experiments/sweeps/dual_v_payload.toml). After an interruption, the same command
    with --resume computes only the missing blocks. --backend ray sends the blocks to the
    Ray cluster at --address (default: a new local one).
    """
    from jaxbal._src.sweep import sweep
    from jaxbal._src.sweep_ray import RayBackend
    from jaxbal._src.sweep_spec import load_spec

    if backend not in ("local", "ray"):
        fail(f"unknown backend {backend!r}; choose one of ['local', 'ray']")
    try:
        loaded = load_spec(spec)
        chosen = RayBackend(address=address) if backend == "ray" else "local"
        dataset = sweep(
            loaded.metric, loaded.robot, loaded.motion, loaded.axes, trajectory=loaded.trajectory,
            store=out, resume=resume, backend=chosen, progress=progress,
            attrs=loaded.description, **loaded.options,
        )  # fmt: skip
    except FileExistsError as error:  # the Python call's message names resume=True
        fail(error if resume else f"{out} exists: pass --resume to continue it, or remove it")
    except ConnectionError as error:  # a Ray cluster lost during the sweep
        fail(error)
    except OSError as error:  # the spec was read: the store's folder or its writes
        fail(cannot_write(out, error))
    except (ValueError, RuntimeError) as error:  # RuntimeError: raised in a block
        fail(error)
    sizes = ", ".join(f"{k}={v}" for k, v in dataset.sizes.items())
    typer.echo(f"{out}: {', '.join(sorted(dataset.data_vars))} over {sizes}")


def plot_command(
    store: Path = typer.Argument(..., help="a sweep's zarr store"),
    out: Path = typer.Option(
        None, "--out", help="image to write, its format from the suffix (default: STORE.png)"
    ),
    variable: str = typer.Option(None, "--variable", help="variable (default: the first)"),
    reduce: str = typer.Option("max", "--reduce", help="max, min or mean over other dims"),
):
    """Draw a sweep: a line plot over one axis, a heat map over two (of the blocks done,
    with a warning when some are not)."""
    from jaxbal._src.sweep_plot import IncompleteSweepWarning, plot_sweep
    from jaxbal._src.writable import check_writable

    target = out or store.with_suffix(".png")
    try:
        check_writable(target)
    except OSError as error:
        fail(cannot_write(target, error))
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", IncompleteSweepWarning)
            plot_sweep(store, variable, out=target, reduce=reduce)
    except (ValueError, FileNotFoundError) as error:
        fail(error)
    except OSError as error:
        fail(cannot_write(target, error))
    for warning in caught:
        if issubclass(warning.category, IncompleteSweepWarning):
            typer.echo(f"warning: {warning.message}", err=True)
        else:  # pragma: no cover - another library's warning, shown as Python would
            warnings.showwarning(warning.message, warning.category, warning.filename,
                                 warning.lineno)  # fmt: skip
    typer.echo(f"wrote {target}")
