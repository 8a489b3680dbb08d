"""The ``jaxbal`` command line (typer)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import typer

from jaxbal._src.cli_errors import cannot_write, fail, shorten_arrays
from jaxbal._src.cli_sweep import plot_command, sweep_command

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
        fail(error)
    results = run_all(out, only=only, update_readme=readme)
    typer.echo(f"{len(results)} experiment(s) written to {out}/ (see {out}/REPORT.md)")


@app.command("list")
def list_experiments():
    """List the experiments that ``reproduce`` runs."""
    from jaxbal._src.reproduce import discover

    try:
        experiments = discover()
    except FileNotFoundError as error:  # an install without the repository's experiments/
        fail(error)
    for experiment in experiments:
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
        fail(error)
    xml = to_xml(nominal, gravity=(0.0, 0.0, -9.81) if gravity else None, base_joints=base_joints)
    typer.echo(xml)


def _floats(text: str, option: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        raise ValueError(f"{option} must be comma-separated numbers, got {text!r}") from None


_BALANCE_HELP = (
    "Shaking-force peaks of a move of ROBOT and a force-balancing counter-mass design.\n\n"
    "ROBOT is loaded with MuJoCo's compiler (hinge, slide and ball joints, connect loop "
    "closures; see jaxbal.robots.from_mjcf). The end-effector SITE moves on a straight line "
    "from START to END in DURATION seconds with a quintic profile; a pose lists the site's "
    "coordinates along the axes it can move in (x,y for a mechanism in the x-y plane), in m, "
    "then, for an arm with more joints than those axes (a 6-joint arm), the values of its "
    "last joints in rad (a pose of the wrong length is refused with its components named). "
    "The command prints the peak shaking force (N) and moment about the base origin (N·m), "
    "then puts a point counter-mass on each counter body (the mirror image of the body's "
    "mass about its frame origin), co-designs their positions in the body frames for the "
    "least RMS shaking force (jaxbal.design.codesign, the motion held fixed) and prints the "
    "design and the peaks after. With --conditions it also prints the linear conditions on "
    "the bodies' lumped inertial parameters under which the shaking force vanishes along "
    "the move (jaxbal.balancing.balancing_conditions) and how far the design is from them. "
    "A URDF has no sites: name the end-effector link with --body (and --offset); a file "
    "whose mesh files are not at hand loads with --ignore-meshes. With --joints, START and "
    "END are joint configurations (every coordinate, or a closed chain's independent ones): "
    "the tool moves on the straight line between their poses, starting from START."
    "\n\n"
    "Example: jaxbal balance five_bar.xml --actuated a,b --site tip "
    "--start -0.05,0.35 --end 0.05,0.4 --duration 0.3"
)


@app.command(help=_BALANCE_HELP)
def balance(
    robot: Path = typer.Argument(..., help="MJCF (.xml) or URDF (.urdf) file of the mechanism"),
    start: str = typer.Option(..., "--start", help="start pose, e.g. -0.05,0.35 (m)"),
    end: str = typer.Option(..., "--end", help="end pose, e.g. 0.05,0.40 (m)"),
    duration: float = typer.Option(0.5, "--duration", help="move time T (s)"),
    actuated: str = typer.Option(
        None, "--actuated", help="actuated joints, e.g. j1,j2 (default: joints with actuators)"
    ),
    independent: str = typer.Option(
        None, "--independent", help="independent joints (default: the actuated ones)"
    ),
    site: str = typer.Option(None, "--site", help="end-effector site (default: the only site)"),
    body: str = typer.Option(
        None, "--body", help="end-effector body or URDF link instead of a site (its origin)"
    ),
    offset: str = typer.Option(
        None, "--offset", help="end-effector point in the --body frame, e.g. 0,0,0.1 (m)"
    ),
    ignore_meshes: bool = typer.Option(
        False, "--ignore-meshes", help="leave mesh geoms out (mesh files not at hand)"
    ),
    samples: int = typer.Option(101, "--samples", min=2, help="instants sampled on [0, T]"),
    counter_bodies: str = typer.Option(
        None, "--counter-bodies", help="bodies given a counter-mass (default: all moving bodies)"
    ),
    free_masses: bool = typer.Option(
        False, "--free-masses", help="optimise the counter masses too (default: positions only)"
    ),
    conditions: bool = typer.Option(
        False, "--conditions", help="print the force-balancing conditions along the move"
    ),
    ignore_armature: bool = typer.Option(
        False,
        "--ignore-armature",
        help="drop joint armature (rotor inertia without a body, e.g. MuJoCo Menagerie arms)",
    ),
    ignore_passive: bool = typer.Option(
        False, "--ignore-passive", help="drop joint damping, springs and friction loss"
    ),
    ik_free: str = typer.Option(
        None,
        "--ik-free",
        help="joints whose values complete the pose, e.g. j3,j5,j6,j7 (default: the last ones)",
    ),
    keyframe: str = typer.Option(
        None,
        "--keyframe",
        help="start the inverse kinematics from this <key> of the model (default: qpos0)",
    ),
    position_bound: float = typer.Option(
        None,
        "--position-bound",
        help="counter positions within ±B per coordinate (m; default: ≥ −10× the size)",
    ),
    moment_weight: float = typer.Option(
        0.0,
        "--moment-weight",
        help="also lower the RMS shaking moment, with this weight against the force "
        "(each relative to its value at the start)",
    ),
    mass_weight: float = typer.Option(
        0.0,
        "--mass-weight",
        help="weight of the added mass against the force (each relative to its value at "
        "the start); with --free-masses",
    ),
    out: Path = typer.Option(
        None,
        "--out",
        help="write ROBOT with the counter-masses added (same format; relative mesh "
        "paths resolve from its folder)",
    ),
    joints: bool = typer.Option(
        False,
        "--joints",
        help="--start and --end are joint configurations (rad, m): the tool moves on the "
        "straight line between their poses",
    ),
    base_mass: float = typer.Option(
        None,
        "--base-mass",
        help="mass of the frame under the robot (kg, the robot's not included): print the "
        "frame's residual vibration after the move, before and after balancing "
        "(jaxbal.vibration; with --base-frequency)",
    ),
    base_frequency: float = typer.Option(
        None, "--base-frequency", help="natural frequency of the frame alone on its mounts (Hz)"
    ),
    base_damping: float = typer.Option(0.02, "--base-damping", help="damping ratio of the frame"),
):
    """Shaking-force peaks of a move of ROBOT and a force-balancing counter-mass design."""
    from jaxbal._src.robots.mjcf_balance import balance as codesign_counter_masses
    from jaxbal._src.robots.mjcf_balance import (
        configuration_samples,
        pose_samples,
        with_counter_masses,
    )
    from jaxbal._src.robots.mjcf_export import export_balanced
    from jaxbal._src.robots.mjcf_import import from_mjcf
    from jaxbal._src.writable import check_writable

    try:
        if out is not None:  # before the optimisation, not after it
            check_writable(out)
    except OSError as error:
        fail(cannot_write(out, error))
    try:
        objective = _objective(moment_weight, mass_weight)
        bounds = {}
        if position_bound is not None:
            if not (np.isfinite(position_bound) and position_bound > 0):
                raise ValueError(f"--position-bound must be finite and > 0, got {position_bound}")
            bounds = {
                "lower": {"counter_position": -position_bound},
                "upper": {"counter_position": position_bound},
            }
        mechanism = from_mjcf(
            robot,
            actuated=actuated,
            independent=independent,
            end_effector_site=site,
            end_effector_body=body,
            end_effector_offset=None if offset is None else _floats(offset, "--offset"),
            ignore_meshes=ignore_meshes,
            ignore_armature=ignore_armature,
            ignore_passive=ignore_passive,
            keyframe=keyframe,
            ik_free=ik_free,
        )
        sample = configuration_samples if joints else pose_samples
        motion = sample(
            mechanism, _floats(start, "--start"), _floats(end, "--end"), duration, samples
        )
        if not np.any(np.asarray(motion.qd)):  # it printed a design balancing 0 N
            raise ValueError("the move does not move the mechanism (--start equals --end)")
        bodies = None if counter_bodies is None else counter_bodies.split(",")
        start_design = with_counter_masses(mechanism, bodies)
        free = ("counter_position", "counter_mass") if free_masses else ("counter_position",)
        vibration = _base_vibration(base_mass, base_frequency, base_damping, duration, samples)
        result = codesign_counter_masses(
            start_design, motion, free=free, objective=objective, **bounds
        )
        if vibration is not None:
            bare = start_design.with_design({"counter_mass": 0.0 * start_design.counter_mass})
            residuals = [float(vibration(r, motion)) for r in (bare, result.robot)]
        if out is not None:
            try:
                export_balanced(robot, result.robot, out, ignore_meshes=ignore_meshes)
            except OSError as error:
                raise ValueError(cannot_write(out, error)) from None
    except ValueError as error:  # the instants of a move that fails: its ends and count
        fail(shorten_arrays(str(error)))
    typer.echo(f"{robot.name}: {mechanism.dof} coordinates, move of {duration:g} s")
    typer.echo(f"peak shaking force  {result.unbalanced_peak_force:.6g} N")
    typer.echo(f"peak shaking moment {result.unbalanced_peak_moment:.6g} N·m")
    typer.echo("counter-masses (position in the body frame [m]):")
    design = result.robot.design()
    for k, body in enumerate(result.robot.counter_bodies):
        name = result.robot.mass_names()[body]
        mass = float(design["counter_mass"][k])
        x, y, z = (float(v) for v in design["counter_position"][k])
        where = f"({x:.6g}, {y:.6g}, {z:.6g})"
        typer.echo(f"  {name:16s} {mass:10.6g} kg at {where}{_flags(result, k)}")
    typer.echo(f"  added mass {float(np.sum(design['counter_mass'])):.6g} kg")
    contacts = result.solution.at_bound
    if np.any(contacts.get("counter_position", 0)):
        typer.echo("  [!] on a bound: the bound, not the physics, stopped the optimiser there")
        typer.echo("      (widen --position-bound)")
    if np.any(contacts.get("counter_mass", 0)):
        typer.echo("  [!] 0 kg: the optimiser removed that counter-mass")
    typer.echo(f"balanced peak shaking force  {result.peak_force[1]:.6g} N")
    typer.echo(f"balanced peak shaking moment {result.peak_moment[1]:.6g} N·m")
    if result.peak_force[1] > result.unbalanced_peak_force:
        typer.echo(
            "[!] the balanced peak force exceeds the robot's without counter-masses: "
            "the masses or their bounds cannot balance this move (try --free-masses, "
            "a wider --position-bound or other --counter-bodies)"
        )
    if vibration is not None:
        typer.echo(
            f"residual vibration of the frame ({base_mass:g} kg, {base_frequency:g} Hz alone, "
            f"damping {base_damping:g}) after the move: {residuals[0] * 1e6:.6g} µm, "
            f"balanced {residuals[1] * 1e6:.6g} µm"
        )
    if conditions:
        from jaxbal._src.regressor import balancing_conditions

        found = balancing_conditions(start_design, motion)
        typer.echo(f"force-balancing conditions along the move ({found.rank}):")
        for equation in found.equations(6, atol=1e-9):
            typer.echo(f"  {equation}")
        residual = float(np.max(np.abs(found.residuals(result.robot)), initial=0.0))
        typer.echo(f"largest residual of the design {residual:.3g}")
    if out is not None:
        typer.echo(f"wrote {out} (the model with its counter-masses)")


def _objective(moment_weight: float, mass_weight: float):
    """The co-design objective of ``jaxbal balance``: the RMS shaking force, plus the
    RMS moment and the added mass with these weights (each metric relative to its value
    at the start: jaxbal.design.codesign)."""
    for option, weight in (("--moment-weight", moment_weight), ("--mass-weight", mass_weight)):
        if not (np.isfinite(weight) and weight >= 0.0):
            raise ValueError(f"{option} must be finite and >= 0, got {weight}")
    objective = {"rms_force": 1.0, "rms_moment": moment_weight, "added_mass": mass_weight}
    objective = {name: w for name, w in objective.items() if w}
    return "rms_force" if list(objective) == ["rms_force"] else objective


def _flags(result, k: int) -> str:
    """The bound marks of counter-mass ``k`` of a balance ``result``: which position
    coordinates (x, y, z) and whether its mass sit on a bound."""
    contacts = result.solution.at_bound
    marks = []
    if "counter_position" in contacts:
        axes = [a for a, side in zip("xyz", contacts["counter_position"][k], strict=True) if side]
        marks += [f"{''.join(axes)} on a bound"] if axes else []
    if "counter_mass" in contacts and contacts["counter_mass"][k] < 0:
        marks.append("0 kg")
    return f"  [!] {', '.join(marks)}" if marks else ""


app.command("sweep")(sweep_command)
app.command("plot")(plot_command)


if __name__ == "__main__":
    app()


def _base_vibration(mass, frequency, damping, duration, samples):
    """The residual-vibration metric of a rigid frame on springs along x, y, z carrying
    the robot (``None`` without ``--base-mass``); refuses half a base."""
    if (mass is None) != (frequency is None):
        raise ValueError("--base-mass and --base-frequency go together")
    if mass is None:
        return None
    from jaxbal import sample_times
    from jaxbal.vibration import BaseVibration, rigid_base

    frame = rigid_base(mass, frequency, damping, axes=("x", "y", "z"))
    return BaseVibration(frame, sample_times(duration, samples), carries_robot=True)
