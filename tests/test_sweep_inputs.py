"""``jaxbal.sweep``'s inputs: a store resumed only by the same code (the metric's and
the setters' bodies), a closed chain's motion held on a changed robot refused on the
fast path too, inputs refused naming the axis or variable, and the CLI's wording.

Each test failed before its fix (exploratory testing, /tmp/explore_b): the store's
fingerprint saw the metric's name only and nothing of the setters (a resumed store mixed
old and new code: 1,500 of 10,000 points differed from a fresh run); the affine path
returned numbers for a DUAL-V / Orthoglide motion off its loops; a ``(n, 3)`` grid of a
``(2,)`` variable, an axis named ``value`` and a missing θ entry gave JAX's, zarr's and
a bare ``KeyError`` message; the CLI said ``resume=True``; ``jaxbal list`` outside the
repository exited 1 with a traceback.
"""

import os
import subprocess
import sys
import textwrap

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import com_move_2r
from typer.testing import CliRunner

import jaxbal
from jaxbal._src import reproduce
from jaxbal._src.cli import app
from jaxbal._src.sweep_digest import value_digest
from jaxbal.design import motion_samples

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: the user's script, run in a child and exec'd here as ``__main__`` (same source)
USER = """
import numpy as np, jax.numpy as jnp, equinox as eqx
import jaxbal
from jaxbal._src.sweep_digest import value_digest
INDEX = {index}
def scaled(x):
    return 1.0 * x
def my_metric(r, m):  # a frozenset constant: its iteration order is salted per process
    return scaled(jaxbal.design.peak_force(r, m)) if "peak" in {{"peak", "force"}} else 0.0
def setter(r, v):
    return eqx.tree_at(lambda r: r.counter_masses, r, r.counter_masses.at[INDEX].set(v))
"""


@pytest.fixture(scope="module")
def arm():
    return com_move_2r(16)


def _user(index=0, body="1.0 * x") -> dict:
    namespace = {"__name__": "__main__"}
    exec(USER.format(index=index).replace("1.0 * x", body), namespace)  # noqa: S102
    return namespace


def _axes(user) -> dict:
    return {
        "m": jaxbal.sweep.grid([0.0, 0.5], set=user["setter"]),
        "payload": jaxbal.sweep.grid([0.0, 1.0]),
    }


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_resume_refuses_a_changed_metric_body_setter_or_constant_naming_it(arm, tmp_path):
    """The store's fingerprint saw ``my_metric``'s name and nothing of the setter: each
    change below resumed and returned the old code's values."""
    robot, motion = arm
    path, user = tmp_path / "s.zarr", _user()
    first = jaxbal.sweep(user["my_metric"], robot, motion, _axes(user), store=path, progress=False)
    # the metric's body changed (same name): rms_moment instead of peak_force
    other = _user()
    exec(  # noqa: S102
        "def my_metric(r, m):\n    return jaxbal.design.rms_moment(r, m)", other
    )
    changed = {
        "the metric \\(its name or code\\)": (other["my_metric"], _axes(user)),
        "the metric": (_user(body="2.0 * x")["my_metric"], _axes(user)),  # a helper it calls
        "the axes' setters": (user["my_metric"], _axes(_user(index=1))),  # a global it reads
    }
    for message, (metric, axes) in changed.items():
        with pytest.raises(ValueError, match=f"changed since it was written: {message}"):
            jaxbal.sweep(metric, robot, motion, axes, store=path, resume=True, progress=False)
    # two lambdas of other bodies
    lam = tmp_path / "lambda.zarr"
    axes = {"payload": jaxbal.sweep.grid([0.0, 1.0])}
    jaxbal.sweep(lambda r, m: jaxbal.design.peak_force(r, m), robot, motion, axes, store=lam,
                 progress=False)  # fmt: skip
    with pytest.raises(ValueError, match="start afresh \\(remove .*lambda.zarr"):
        jaxbal.sweep(lambda r, m: jaxbal.design.rms_force(r, m), robot, motion, axes,
                     store=lam, resume=True, progress=False)  # fmt: skip
    # the same source again (new function objects): resumed
    again = _user()
    resumed = jaxbal.sweep(
        again["my_metric"], robot, motion, _axes(again), store=path, resume=True, progress=False
    )
    np.testing.assert_array_equal(resumed["value"].values, first["value"].values)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_an_unchanged_script_in_a_new_process_resumes(arm, tmp_path):
    """A store written by a child interpreter (another ``PYTHONHASHSEED``: a set of
    strings iterates in another order) is resumed here by the same source: the code's
    digest holds no address, salted hash or line number."""
    path = tmp_path / "child.zarr"
    script = USER.format(index=0) + textwrap.dedent(f"""
        robot = jaxbal.robots.planar_2r()
        q0 = robot.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
        q1 = robot.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
        plan = jaxbal.planning.com_line(robot, q0, q1, jaxbal.profiles.BangBang(), 0.5)
        motion = jaxbal.design.motion_samples(robot, [plan], jaxbal.sample_times(0.5, 16))
        axes = {{"m": jaxbal.sweep.grid([0.0, 0.5], set=setter),
                "payload": jaxbal.sweep.grid([0.0, 1.0])}}
        jaxbal.sweep(my_metric, robot, motion, axes, store={str(path)!r}, progress=False)
        print(value_digest(my_metric), value_digest(setter))
    """)
    env = {**os.environ, "PYTHONHASHSEED": "12345", "JAXBAL_CACHE_DIR": "off"}
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, timeout=300)  # fmt: skip
    assert out.returncode == 0, out.stderr[-3000:]
    user = _user()
    digests = out.stdout.split()[-2:]
    assert digests == [value_digest(user["my_metric"]), value_digest(user["setter"])]
    robot, motion = arm
    ds = jaxbal.sweep(
        user["my_metric"], robot, motion, _axes(user), store=path, resume=True, progress=False
    )
    assert ds.attrs["blocks_done"].split("/")[0] == ds.attrs["blocks_done"].split("/")[1]


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_closed_chain_motion_held_on_a_changed_robot_is_refused_on_the_fast_path():
    """The Orthoglide's parallelograms 1 % longer than the motion was solved for: the
    affine path (default) returned finite, wrong forces; now the metrics' loop-closure
    error, before anything compiles (also with linear=True)."""
    robot = jaxbal.robots.orthoglide(payload=1.0)
    line = jaxbal.StraightLine(jnp.zeros(3), jnp.full(3, 0.02), jaxbal.profiles.Quintic(), 0.2)
    motion = motion_samples(robot, jaxbal.planning.EndEffectorLine(robot, line),
                            jaxbal.sample_times(0.2, 11))  # fmt: skip
    longer = eqx.tree_at(lambda r: r.length, robot, robot.length * 1.01)
    axes = {"payload": jaxbal.sweep.grid([0.0, 1.0])}
    for linear in ("auto", True):
        with pytest.raises(ValueError, match="state violates the loop closures .* at samples"):
            jaxbal.sweep("peak_force", longer, motion, axes, progress=False, linear=linear)
    ds = jaxbal.sweep("peak_force", robot, motion, axes, progress=False)
    assert ds.attrs["evaluation"] == "affine" and np.all(np.isfinite(ds["value"].values))


def test_inputs_are_refused_naming_the_axis_or_variable(arm):
    robot, motion = arm
    sweep = jaxbal.sweep
    # a (2,) design variable swept with (n, 3) values: was JAX's "Incompatible types"
    with pytest.raises(ValueError, match=r"axis 'counter_mass': counter_mass is a design "
                       r"variable of shape \(2,\).*need shape \(2, 2\).*got values of shape "
                       r"\(2, 3\)"):  # fmt: skip
        sweep("peak_force", robot, motion, {"counter_mass": sweep.grid(np.ones((2, 3)))})
    # an axis named like the metric's output or the manifest: was zarr's ContainsArrayError
    named = {"value": sweep.grid([0.0, 1.0], name="payload")}
    with pytest.raises(ValueError, match=r"axis 'value': the name 'value' is reserved.*"
                       r"\['_jaxbal', 'value'\]"):  # fmt: skip
        sweep("peak_force", robot, motion, named, progress=False)
    with pytest.raises(ValueError, match="axis '_jaxbal': the name '_jaxbal' is reserved"):
        sweep(lambda r, m: {"peak": jaxbal.design.peak_force(r, m)}, robot, motion,
              {"_jaxbal": sweep.grid([0.0], name="payload")}, progress=False)  # fmt: skip
    # an axis named like another axis's parameter: was zarr's ContainsArrayError
    collide = {"payload": sweep.grid([1.0, 2.0], name="counter_mass"),
               "s": sweep.sobol(2, {"payload": (0.0, 1.0)})}  # fmt: skip
    with pytest.raises(ValueError, match=r"axis 'payload' is named like the parameter "
                       r"'payload' of axis 's'"):  # fmt: skip
        sweep("peak_force", robot, motion, collide, progress=False)
    # a swept payload that over_payloads replaces by its own: the axis had no effect
    robust = jaxbal.design.over_payloads("rms_force", jnp.array([0.0, 1.0]), "rms")
    with pytest.raises(ValueError, match=r"axis 'load' sets the payload, but the metric "
                       r"over_payloads\('rms_force', …\) sets its own payloads "
                       r"\[0.0, 1.0\]"):  # fmt: skip
        sweep(robust, robot, motion, {"load": sweep.grid([0.0, 5.0], name="payload")})
    # a trajectory variable neither swept nor given: was a bare KeyError: 'ratio'
    move = jaxbal.design.TrapezoidLine(
        jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70]), jaxbal.sample_times(0.5, 16)
    )
    with pytest.raises(ValueError, match=r"TrapezoidLine needs the trajectory variable 'ratio'"
                       r".*\['u2'\].*trajectory=\{'ratio': value\}"):  # fmt: skip
        sweep("peak_force", robot, move, {"u2": sweep.grid([0.1, 0.3])}, progress=False)
    ds = sweep("peak_force", robot, move, {"u2": sweep.grid([0.1, 0.3])},
               trajectory={"ratio": 1.0}, progress=False)  # fmt: skip
    assert np.all(np.isfinite(ds["value"].values))


SPEC = """
metric = "peak_force"
[robot]
name = "planar_2r"
[motion]
start = [0.225, 0.25]
end = [0.225, 0.70]
duration = 0.5
samples = 9
branch = -1
[axes.payload]
values = [0.0, 1.0]
"""


def test_cli_names_its_resume_flag(tmp_path):
    """Was: "pass resume=True", the Python keyword."""
    spec, store = tmp_path / "spec.toml", tmp_path / "s.zarr"
    spec.write_text(SPEC)
    runner = CliRunner()
    command = ["sweep", str(spec), "--out", str(store), "--no-progress"]
    assert runner.invoke(app, command).exit_code == 0
    again = runner.invoke(app, command)
    assert again.exit_code == 2 and "pass --resume to continue it" in again.output
    assert "resume=True" not in again.output


def test_cli_finds_the_experiments_from_any_folder_or_exits_2(tmp_path, monkeypatch):
    """Outside the repository root ``experiments_dir`` looked in jaxbal/experiments (one
    level too deep) and ``jaxbal list`` exited 1 with a traceback."""
    monkeypatch.chdir(tmp_path)
    assert reproduce.experiments_dir() == reproduce.Path(ROOT, "experiments").resolve()
    listed = CliRunner().invoke(app, ["list"])
    assert listed.exit_code == 0 and listed.output.strip(), listed.output
    # an install without experiments/ (a wheel in site-packages), run elsewhere
    fake = tmp_path / "site-packages" / "jaxbal" / "_src" / "reproduce.py"
    monkeypatch.setattr(reproduce, "__file__", str(fake))
    for command in (["list"], ["reproduce", "--out", str(tmp_path / "r")]):
        result = CliRunner().invoke(app, command)
        assert result.exit_code == 2, (command, result.output)
        assert result.output.startswith("error: no experiments/ folder next to the jaxbal")
        assert len(result.output.strip().splitlines()) == 1 and "Traceback" not in result.output


def test_chunk_size_and_memory_budget_are_checked(arm):
    """``chunk_size`` ≤ 0 and ``memory_budget`` ≤ 0 were accepted silently."""
    robot, motion = arm
    axes = {"payload": [0.0, 0.5, 1.0]}
    for bad in (0, -3, 2.5, True):
        with pytest.raises(ValueError, match=rf"chunk_size must be an integer ≥ 1.*{bad!r}"):
            jaxbal.sweep("peak_force", robot, motion, axes, chunk_size=bad, progress=False)
    for bad in (0, -1, float("nan")):
        with pytest.raises(ValueError, match="memory_budget must be a number of bytes ≥ 1"):
            jaxbal.sweep("peak_force", robot, motion, axes, memory_budget=bad, progress=False)


def test_every_named_metric_has_a_unit():
    """``peak_torque_rate`` had none (its docstring: N·m/s, N/s for a prismatic joint)."""
    from jaxbal._src.sweep import METRIC_UNITS

    assert set(jaxbal.design.METRICS) <= set(METRIC_UNITS)
    assert METRIC_UNITS["peak_torque_rate"] == "N·m/s or N/s"
