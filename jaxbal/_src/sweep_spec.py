"""A sweep described in a TOML file: the robot, the motion, the metric and the axes
(``jaxbal sweep SPEC.toml --out sweep.zarr``).

Example (``experiments/sweeps/dual_v_payload.toml``)::

    metric = ["peak_force", "rms_torque"]     # a name of jaxbal.design.METRICS, or a list
    memory_budget_mib = 256                   # optional; or chunk_size = 4096
    linear = "auto"                           # optional: the affine fast path (jaxbal.sweep)

    [robot]
    name = "dual_v"                           # built-in (jaxbal.robots.ROBOTS), or
    # mjcf = "five_bar.xml"                   # a file, with end_effector_site, actuated,
    # end_effector_site = "tip"               # independent, payload_body (from_mjcf)
    [robot.options]                           # keyword arguments of the constructor
    counter_masses = true

    [motion]
    kind = "end_effector"                     # straight end-effector line, or "trapezoid"
    start = [0.0, -0.05, 0.0]                 # poses as robot.inverse_kinematics takes them
    end = [0.05, 0.05, 0.0]
    duration = 0.1                            # s
    samples = 101
    profile = "quintic"                       # "quintic" or "bang_bang" (kind end_effector)
    # branch = [1, 1, 1, 1]                   # IK branch, both kinds (default: the robot's)
    # u2 = 0.25, ratio = 1.0                  # kind "trapezoid": θ, 0 < u2 < 1/2, 0 < ratio ≤ 1

    [axes.payload]
    linspace = [0.0, 0.5, 20]                 # or values = [...]
    units = "kg"

    [axes.design]                             # a sample of several parameters together
    sample = "sobol"                          # "sobol", "halton" or "uniform"
    n = 64
    seed = 0
    bounds = { counter_mass = [2.0, 8.0] }
    units = { counter_mass = "kg" }

An axis's parameters are design variables of the robot (``robot.design()``) or, with
``kind = "trapezoid"``, the switch-time variables ``u2`` and ``ratio`` of
:class:`jaxbal.design.TrapezoidLine`. Relative paths are relative to the spec file.
A key of the other motion kind (``profile`` with a trapezoid, ``u2`` with an
end-effector line) is refused. Every error is a :class:`ValueError` naming the offending
key (values are read by :mod:`jaxbal._src.sweep_spec_values`: a TOML boolean is no
number; a pose must have as many coordinates as the robot's end-effector pose).
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from jaxbal._src.sweep_spec_values import (
    branch_signs,
    check_options,
    has_boolean,
    integer,
    is_number,
    number,
    numbers,
    refuse,
)
from jaxbal._src.sweep_spec_values import table as as_table

__all__ = ["SweepSpec", "load_spec"]

_MOTION_KINDS = ("end_effector", "trapezoid")
_PROFILES = ("quintic", "bang_bang")
_SAMPLES = ("sobol", "halton", "uniform")
_MOTION_KEYS = {  # the keys of each kind of [motion]
    "end_effector": {"kind", "start", "end", "duration", "samples", "branch", "profile"},
    "trapezoid": {"kind", "start", "end", "duration", "samples", "branch", "u2", "ratio"},
}
_TOP = {"metric", "memory_budget_mib", "chunk_size", "linear", "robot", "motion", "axes"}


@dataclass
class SweepSpec:
    """What :func:`jaxbal.sweep` is called with (see the module docstring).

    Attributes:
        robot: the robot; motion: a :class:`jaxbal.design.Motion` or a factory.
        metric: a metric name, or a function returning ``{name: value}``.
        axes: name ↦ :class:`jaxbal.sweep.Axis`; trajectory: fixed θ of a factory.
        options: keyword arguments of :func:`jaxbal.sweep` (memory budget, chunk size).
    """

    robot: object
    motion: object
    metric: object
    axes: dict
    trajectory: dict = field(default_factory=dict)
    options: dict = field(default_factory=dict)
    description: dict = field(default_factory=dict)


def _unknown(table: dict, allowed, where: str) -> None:
    extra = sorted(set(table) - set(allowed))
    if extra:
        raise ValueError(f"unknown key(s) {extra} in {where}; allowed: {sorted(allowed)}")


def _need(table: dict, key: str, where: str):
    if key not in table:
        raise ValueError(f"{where} needs {key!r}")
    return table[key]


def _robot(table: dict, folder: Path):
    from jaxbal._src.robots import ALIASES, ROBOTS
    from jaxbal._src.robots.mjcf_import import from_mjcf

    _unknown(
        table,
        {"name", "mjcf", "options", "end_effector_site", "actuated", "independent", "payload_body"},
        "[robot]",
    )
    options = dict(as_table(table.get("options", {}), "[robot] options", "a table of keyword "
                            "arguments of the constructor ([robot.options])"))  # fmt: skip
    if ("name" in table) == ("mjcf" in table):
        raise ValueError("[robot] needs exactly one of 'name' (built-in) or 'mjcf' (a file)")
    if "mjcf" in table:
        path = (folder / table["mjcf"]).resolve()
        if not path.exists():
            raise ValueError(f"[robot] mjcf = {table['mjcf']!r}: no such file ({path})")
        keys = ("end_effector_site", "actuated", "independent", "payload_body")
        kwargs = {k: table[k] for k in keys if k in table}
        check_options(from_mjcf, options)
        try:
            return from_mjcf(path, **kwargs, **options)
        except TypeError as error:
            raise ValueError(f"[robot] {error}") from None
    name = str(table["name"]).strip().lower()
    key = ALIASES.get(name, name)
    if key not in ROBOTS:
        raise ValueError(f"[robot] name = {table['name']!r} is unknown; choose one of "
                         f"{sorted(ROBOTS)}")  # fmt: skip
    check_options(ROBOTS[key], options)
    try:
        return ROBOTS[key](**options)
    except TypeError as error:
        raise ValueError(f"[robot.options] {options} not accepted by {key}(): {error}") from None
    except ValueError as error:  # e.g. a negative payload, refused by the robot
        raise ValueError(f"[robot.options] {error}") from None


def _pose_size(robot) -> int | None:
    """Coordinates of the robot's end-effector pose (``None`` if it cannot say)."""
    import jax
    import jax.numpy as jnp

    try:
        q = jax.ShapeDtypeStruct((robot.dof,), jnp.float64)
        shape = jax.eval_shape(robot.end_effector, q).shape
    except Exception:  # noqa: BLE001 - no end effector: the IK reports it
        return None
    return shape[0] if len(shape) == 1 else None


def _pose(robot, table: dict, key: str):
    import jax.numpy as jnp

    size, what = _pose_size(robot), "a list of finite numbers"
    if size is not None:
        try:  # an MJCF robot names its pose's components
            named = f": {', '.join(robot.pose_labels())}"
        except (AttributeError, ValueError):
            named = ""
        what += f", the {size} coordinates of the end-effector pose of {type(robot).__name__}"
        what += named
    return jnp.asarray(numbers(_need(table, key, "[motion]"), f"[motion] {key}", what, size))


def _motion(robot, table: dict):
    import jax.numpy as jnp

    from jaxbal._src.metrics import motion_samples
    from jaxbal._src.motion_factories import TrapezoidLine
    from jaxbal._src.planning import EndEffectorLine
    from jaxbal._src.profiles import BangBang, Quintic
    from jaxbal._src.trajectory import StraightLine, sample_times

    _unknown(table, set().union(*_MOTION_KEYS.values()), "[motion]")
    kind = table.get("kind", "end_effector")
    if kind not in _MOTION_KINDS:
        raise ValueError(f"[motion] kind = {kind!r} is unknown; choose one of {_MOTION_KINDS}")
    misplaced = sorted(set(table) - _MOTION_KEYS[kind])
    if misplaced:
        raise ValueError(f"[motion] key(s) {misplaced} do not apply to kind = {kind!r}")
    start, end = _pose(robot, table, "start"), _pose(robot, table, "end")
    duration = _need(table, "duration", "[motion]")
    duration = number(duration, "[motion] duration", "> 0 s (a number)", lambda v: v > 0)
    samples = table.get("samples", 101)
    samples = integer(samples, "[motion] samples", "an integer ≥ 2", lambda v: v >= 2)
    times = sample_times(duration, samples)
    branch = branch_signs(table.get("branch"), "[motion] branch")
    if kind == "trapezoid":
        theta = {"u2": _switch(table, "u2", 0.25), "ratio": _switch(table, "ratio", 1.0)}
        path = {} if branch is None else {"path": _BranchPath(branch)}
        return TrapezoidLine(start, end, jnp.asarray(times), **path), theta
    profile = table.get("profile", "quintic")
    if profile not in _PROFILES:
        raise ValueError(f"[motion] profile = {profile!r} is unknown; choose one of {_PROFILES}")
    shape = Quintic() if profile == "quintic" else BangBang()
    line = EndEffectorLine(robot, StraightLine(start, end, shape, duration), branch=branch)
    return motion_samples(robot, [line], times), {}


def _switch(table: dict, key: str, default: float) -> float:
    """Switch-time variable ``u2`` (``0 < u2 < 1/2``) or ``ratio = u1/u2`` (``0 < ratio
    ≤ 1``) of a trapezoid (:data:`~jaxbal._src.motion_factories.THETA_DOMAIN`)."""
    from jaxbal._src.motion_factories import THETA_DOMAIN, in_domain

    least, most, closed = THETA_DOMAIN[key]
    what = f"a number > {least:g} and {'≤' if closed else '<'} {most:g}"
    valid = lambda v: bool(in_domain(key, v))  # noqa: E731
    return number(table.get(key, default), f"[motion] {key}", what, valid)


@dataclass(frozen=True)
class _BranchPath:
    """The ``path`` of a :class:`~jaxbal.design.TrapezoidLine` on IK branch ``branch``."""

    branch: object

    def __call__(self, robot, line):
        from jaxbal._src.planning import EndEffectorLine

        return EndEffectorLine(robot, line, branch=self.branch)


def _axis(name: str, table: dict):
    from jaxbal._src import sweep_axes

    where = f"[axes.{name}]"
    if not isinstance(table, dict):
        raise ValueError(f"{where} must be a table (values, linspace or sample), got {table!r}")
    if "sample" in table:
        _unknown(table, {"sample", "n", "seed", "bounds", "units"}, where)
        kind = table["sample"]
        if kind not in _SAMPLES:
            raise ValueError(f"{where} sample = {kind!r} is unknown; choose one of {_SAMPLES}")
        bounds = _need(table, "bounds", where)
        if not isinstance(bounds, dict) or not bounds:
            raise ValueError(f"{where} bounds must be a table {{parameter = [low, high]}}")
        units = table.get("units", {})
        if not isinstance(units, dict):
            raise ValueError(f"{where} units must be a table {{parameter = unit}}, got {units!r}")
        build = getattr(sweep_axes, kind)
        n = _need(table, "n", where)  # refused by the sample, naming the count
        seed = integer(table.get("seed", 0), f"{where} seed", "an integer ≥ 0", lambda v: v >= 0)
        try:
            return build(n, bounds, seed=seed, units=units)
        except ValueError as error:
            raise ValueError(f"{where} {error}") from None
    _unknown(table, {"values", "linspace", "units"}, where)
    if ("values" in table) == ("linspace" in table):
        raise ValueError(f"{where} needs exactly one of 'values', 'linspace' or 'sample'")
    if "linspace" in table:
        spec = table["linspace"]
        if not (
            isinstance(spec, list) and len(spec) == 3 and all(is_number(v) for v in spec)
            and np.all(np.isfinite(spec)) and spec[2] == int(spec[2])
            and 1 <= spec[2] <= sweep_axes.MAX_POINTS
        ):  # fmt: skip
            raise ValueError(
                f"{where} linspace must be [start, stop, count], finite, count an integer "
                f"from 1 to {sweep_axes.MAX_POINTS:.0e}, got {spec!r}"
            )
        values = np.linspace(float(spec[0]), float(spec[1]), int(spec[2]))
    else:
        values = table["values"]
        if has_boolean(values):  # NumPy reads true as 1.0
            refuse(f"{where} values", "numbers, not booleans", values)
    units = table.get("units", "")
    if not isinstance(units, str):
        raise ValueError(f"{where} units must be a string, got {units!r}")
    try:
        return sweep_axes.grid(values, units=units)
    except ValueError as error:  # NaN, empty or not numbers
        raise ValueError(f"{where} {error}") from None


def _metric(metric):
    from jaxbal._src.metrics import METRICS

    names = [metric] if isinstance(metric, str) else metric
    if not (isinstance(names, list) and all(isinstance(n, str) for n in names)):
        raise ValueError(f"metric must be a name or a list of names, got {metric!r}")
    unknown = [n for n in names if n not in METRICS]
    if not names or unknown:
        raise ValueError(f"metric {unknown or metric!r} is unknown; choose from {sorted(METRICS)}")
    if isinstance(metric, str):
        return metric, None
    chosen = tuple(names)
    return _Metrics(chosen), {n: _metric_unit(n) for n in chosen}


def _metric_unit(name: str) -> str:
    from jaxbal._src.sweep import METRIC_UNITS

    return METRIC_UNITS.get(name, "")


@dataclass(frozen=True)
class _Metrics:
    """Several named metrics as one sweep metric ``{name: value}`` (hashable)."""

    names: tuple

    @property
    def __name__(self) -> str:
        return "+".join(self.names)

    def __call__(self, robot, motion) -> dict:
        from jaxbal._src.metrics import METRICS

        return {n: METRICS[n](robot, motion) for n in self.names}


def _check_parameters(robot, axes: dict, theta: dict) -> None:
    """Every swept parameter is a design variable of the robot or a θ of the motion."""
    known = set(robot.design()) | set(theta)
    for name, axis in axes.items():
        values = axis.values if axis.kind != "grid" else {name: None}
        for parameter in values:
            if parameter not in known:
                raise ValueError(
                    f"[axes.{name}] parameter {parameter!r} is neither a design variable of "
                    f"{type(robot).__name__} ({sorted(robot.design())}) nor a trajectory "
                    f"variable of the motion ({sorted(theta) or 'none for this kind'})"
                )


def load_spec(path) -> SweepSpec:
    """The :class:`SweepSpec` of the TOML file ``path``.

    Raises:
        ValueError: a missing file, invalid TOML, or an unknown/invalid key (named).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"no sweep spec at {path}")
    try:
        table = tomllib.loads(path.read_text())
    except tomllib.TOMLDecodeError as error:
        raise ValueError(f"{path} is not valid TOML: {error}") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ValueError(f"cannot read {path}: {getattr(error, 'strerror', error)}") from None
    _unknown(table, _TOP, path.name)
    robot = _robot(as_table(_need(table, "robot", path.name), "robot", "a table [robot]"),
                   path.parent)  # fmt: skip
    motion, theta = _motion(robot, as_table(_need(table, "motion", path.name), "motion",
                                            "a table [motion]"))  # fmt: skip
    axes_table = _need(table, "axes", path.name)
    if not isinstance(axes_table, dict) or not axes_table:
        raise ValueError(f"{path.name} needs at least one [axes.NAME] table")
    axes = {name: _axis(name, sub) for name, sub in axes_table.items()}
    _check_parameters(robot, axes, theta)
    metric, units = _metric(_need(table, "metric", path.name))
    options = {}
    if "linear" in table:  # the affine fast path: "auto" (default), true or false
        linear = table["linear"]
        if linear not in (True, False, "auto"):
            raise ValueError(f'{path.name}: linear must be true, false or "auto", got {linear!r}')
        options["linear"] = linear
    if "memory_budget_mib" in table:
        key = f"{path.name}: memory_budget_mib"
        budget = number(table["memory_budget_mib"], key, "a number > 0", lambda v: v > 0)
        options["memory_budget"] = max(int(budget * 2**20), 1)
    if "chunk_size" in table:
        key, chunk = f"{path.name}: chunk_size", table["chunk_size"]
        options["chunk_size"] = integer(chunk, key, "an integer ≥ 1", lambda v: v >= 1)
    if units:
        options["units"] = units
    description = {"spec": path.name, "robot_spec": str(table["robot"])}
    return SweepSpec(robot, motion, metric, axes, theta, options, description)
