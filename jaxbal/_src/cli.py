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
    from jaxbal._src.reproduce import run_all, select

    try:
        select(only)
    except (ValueError, FileNotFoundError) as error:
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(code=2) from None
    results = run_all(out, only=only, update_readme=readme)
    typer.echo(f"{len(results)} experiment(s) written to {out}/ (see {out}/REPORT.md)")


@app.command("list")
def list_experiments():
    """List the experiments that ``reproduce`` runs."""
    from jaxbal._src.reproduce import discover

    for experiment in discover():
        typer.echo(f"{experiment.name:28s} {experiment.title}")


@app.command("export-mjcf")
def export_mjcf(
    robot: str = typer.Argument(
        ..., help="planar_2r, planar_3r, scara, dual_v or orthoglide (aliases: 2r, 3r, dual-v)"
    ),
    gravity: bool = typer.Option(False, help="include gravity (0, 0, -9.81) m/s²"),
    base_joints: bool = typer.Option(False, help="mount the robot on the 6 base dofs"),
):
    """Print the MJCF (MuJoCo XML) of a robot with its nominal parameters.

    View it with ``python -m mujoco.viewer --mjcf robot.xml``.
    """
    from jaxbal._src.mujoco.mjcf import export_mjcf as to_xml
    from jaxbal._src.robots import by_name

    try:
        nominal = by_name(robot)
    except ValueError as error:
        typer.echo(f"error: {error}", err=True)
        raise typer.Exit(code=2) from None
    xml = to_xml(nominal, gravity=(0.0, 0.0, -9.81) if gravity else None, base_joints=base_joints)
    typer.echo(xml)


if __name__ == "__main__":
    app()
