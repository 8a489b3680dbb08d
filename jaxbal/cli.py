"""The ``jaxbal`` command line (typer)."""

from __future__ import annotations

from pathlib import Path

import typer

app = typer.Typer(
    help="jaxbal: dynamic balancing of high-speed robots in JAX.", no_args_is_help=True
)


@app.command()
def reproduce(
    only: str = typer.Option(None, "--only", help="run only experiments whose name contains this"),
    out: Path = typer.Option(Path("results"), "--out", help="output folder"),
    readme: Path = typer.Option(
        Path("README.md"), "--readme", help="README whose results table is refreshed"
    ),
):
    """Reproduce the papers' tables and figures into OUT (CSV, PNG, REPORT.md)."""
    from jaxbal.reproduce import run_all

    results = run_all(out, only=only, update_readme=readme)
    typer.echo(f"{len(results)} experiment(s) written to {out}/ (see {out}/REPORT.md)")


@app.command("list")
def list_experiments():
    """List the experiments that ``reproduce`` runs."""
    from jaxbal.reproduce import discover

    for experiment in discover():
        typer.echo(f"{experiment.name:28s} {experiment.title}")


@app.command("export-mjcf")
def export_mjcf(
    robot: str = typer.Argument(..., help="constructor in jaxbal.robots, e.g. planar_2r, scara"),
    gravity: float = typer.Option(0.0, help="gravity along -z [m/s²] (0: none, as in the papers)"),
):
    """Print the MJCF (MuJoCo XML) of a jaxbal robot with its nominal parameters."""
    import jaxbal
    from jaxbal.mjcf import to_mjcf

    constructor = getattr(jaxbal.robots, robot, None)
    if constructor is None or not callable(constructor):
        raise typer.BadParameter(f"unknown robot {robot!r}; try one of {jaxbal.robots.__all__}")
    typer.echo(to_mjcf(constructor(), gravity=(0.0, 0.0, 0.0 - abs(gravity))))


if __name__ == "__main__":
    app()
