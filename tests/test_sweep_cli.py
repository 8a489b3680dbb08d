"""``jaxbal sweep SPEC.toml`` and ``jaxbal plot``: a spec runs, resumes, plots, and bad
specs exit with status 2 and one line naming the key, without a traceback or a store."""

import numpy as np
import pytest
from typer.testing import CliRunner

import jaxbal
from jaxbal._src.cli import app
from jaxbal._src.sweep_spec import load_spec

SPEC = """
metric = ["peak_force", "peak_moment"]

[robot]
name = "planar_2r"

[motion]
start = [0.225, 0.25]
end = [0.225, 0.70]
duration = 0.5
samples = 33
profile = "bang_bang"
branch = -1

[axes.payload]
linspace = [0.0, 1.0, 3]
units = "kg"

[axes.designs]
sample = "halton"
n = 4
bounds = { counter_mass = [0.0, 2.0] }
units = { counter_mass = "kg" }
"""


def _write(tmp_path, text, name="spec.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_cli_sweep_resume_and_plot_equal_the_python_call(tmp_path):
    spec, store = _write(tmp_path, SPEC), tmp_path / "s.zarr"
    runner = CliRunner()
    first = runner.invoke(app, ["sweep", str(spec), "--out", str(store), "--no-progress"])
    assert first.exit_code == 0, first.output
    assert "peak_force, peak_moment over payload=3, designs=4" in first.output
    again = runner.invoke(app, ["sweep", str(spec), "--out", str(store), "--no-progress"])
    assert again.exit_code == 2 and "resume" in again.output
    resumed = runner.invoke(app, ["sweep", str(spec), "--out", str(store), "--resume"])
    assert resumed.exit_code == 0, resumed.output
    ds = jaxbal.sweep.open_sweep(store)
    assert ds["peak_force"].attrs["units"] == "N" and ds["payload"].attrs["units"] == "kg"
    loaded = load_spec(spec)
    direct = jaxbal.sweep(loaded.metric, loaded.robot, loaded.motion, loaded.axes, progress=False)
    np.testing.assert_array_equal(ds["peak_force"].values, direct["peak_force"].values)
    # the 2R itself, a bang-bang end-effector line: the COM-free case of Briot Table 1
    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(np.array([0.225, 0.25]), branch=-1)
    assert np.allclose(loaded.motion.q[0], q0)
    plotted = runner.invoke(app, ["plot", str(store), "--variable", "peak_moment"])
    assert plotted.exit_code == 0, plotted.output
    assert (tmp_path / "s.png").stat().st_size > 1000


@pytest.mark.parametrize(
    "edit, message",
    [
        (('name = "planar_2r"', 'name = "bogus"'), "name = 'bogus' is unknown"),
        (('metric = ["peak_force", "peak_moment"]', 'metric = "force"'), "metric"),
        (('profile = "bang_bang"', 'profile = "cubic"'), "profile = 'cubic'"),
        (("duration = 0.5", "duration = -1"), "duration must be > 0"),
        (("counter_mass = [0.0, 2.0]", "mass = [0.0, 2.0]"), "parameter 'mass'"),
        (("linspace = [0.0, 1.0, 3]", "linspace = [0.0, 1.0]"), "linspace must be"),
        (("samples = 33", "samples = 33\nspeed = 2"), "unknown key(s) ['speed']"),
        (
            ('metric = ["peak_force", "peak_moment"]', 'metric = "peak_force"\nlinear = "yes"'),
            "linear must be true, false",
        ),  # fmt: skip
    ],
)
def test_bad_specs_exit_2_with_one_line_and_no_store(tmp_path, edit, message):
    spec, store = _write(tmp_path, SPEC.replace(*edit)), tmp_path / "bad.zarr"
    result = CliRunner().invoke(app, ["sweep", str(spec), "--out", str(store)])
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not store.exists()


def test_unknown_backend_and_missing_store_exit_2(tmp_path):
    spec = _write(tmp_path, SPEC)
    runner = CliRunner()
    bad = runner.invoke(app, ["sweep", str(spec), "--out", str(tmp_path / "x"), "--backend", "x"])
    assert bad.exit_code == 2 and "['local', 'ray']" in bad.output
    missing = runner.invoke(app, ["plot", str(tmp_path / "none.zarr")])
    assert missing.exit_code == 2 and "no sweep store" in missing.output


@pytest.mark.slow
def test_linear_key_reaches_the_sweep(tmp_path):
    """``linear`` in the spec: one named wrench metric is affine by default, not with
    ``linear = false``."""
    one = SPEC.replace('metric = ["peak_force", "peak_moment"]', 'metric = "peak_force"')
    spec = load_spec(_write(tmp_path, one))
    assert "linear" not in spec.options
    fast = jaxbal.sweep(spec.metric, spec.robot, spec.motion, spec.axes, progress=False,
                        **spec.options)  # fmt: skip
    assert fast.attrs["evaluation"] == "affine"
    spec = load_spec(_write(tmp_path, one.replace('"peak_force"', '"peak_force"\nlinear = false')))
    assert spec.options["linear"] is False
    direct = jaxbal.sweep(spec.metric, spec.robot, spec.motion, spec.axes, progress=False,
                          **spec.options)  # fmt: skip
    assert "evaluation" not in direct.attrs
    np.testing.assert_allclose(fast["value"].values, direct["value"].values, rtol=1e-12)


TRAPEZOID = SPEC.replace('profile = "bang_bang"\n', 'kind = "trapezoid"\n')


def test_trapezoid_spec_moves_on_its_branch(tmp_path):
    """``kind = "trapezoid"`` ignored ``branch``: branch -1 and +1 gave the robot's
    default elbow and the same numbers. Reference: the start configuration equals the
    2R's closed-form inverse kinematics on that branch (to 1e-12 rad)."""
    arm = jaxbal.robots.planar_2r()
    for branch in (-1, 1):
        loaded = load_spec(_write(tmp_path, TRAPEZOID.replace("branch = -1", f"branch = {branch}")))
        q = loaded.motion(loaded.robot, loaded.trajectory).q
        q0 = arm.inverse_kinematics(np.array([0.225, 0.25]), branch=branch)
        np.testing.assert_allclose(q[0], q0, atol=1e-12)


@pytest.mark.parametrize(
    "base, edit, message",
    [
        (TRAPEZOID, ("branch = -1", 'branch = -1\nprofile = "cubic"'),
         "[motion] key(s) ['profile'] do not apply to kind = 'trapezoid'"),
        (SPEC, ("branch = -1", "branch = -1\nu2 = 0.3"),
         "[motion] key(s) ['u2'] do not apply to kind = 'end_effector'"),
        (TRAPEZOID, ("branch = -1", "branch = -1\nu2 = 0.9"), "[motion] u2 must be a number > 0"),
        (TRAPEZOID, ("branch = -1", "branch = -1\nu2 = nan"), "[motion] u2 must be"),
        (TRAPEZOID, ("branch = -1", "branch = -1\nratio = 0"), "[motion] ratio must be"),
        (SPEC, ("[robot]", "memory_budget_mib = inf\n[robot]"), "memory_budget_mib must be"),
        (SPEC, ("[robot]", "memory_budget_mib = 0\n[robot]"), "memory_budget_mib must be"),
        (SPEC, ("[robot]", "chunk_size = inf\n[robot]"), "chunk_size must be an integer ≥ 1"),
        (SPEC, ("[robot]", "chunk_size = -5\n[robot]"), "chunk_size must be an integer ≥ 1"),
        (SPEC, ("[robot]", "chunk_size = 2.5\n[robot]"), "chunk_size must be an integer ≥ 1"),
        (SPEC, ("counter_mass = [0.0, 2.0]", "counter_mass = [2.0]"),
         "[axes.designs] bounds 'counter_mass' must be (low, high)"),
        (SPEC, ("counter_mass = [0.0, 2.0]", "counter_mass = 2.0"),
         "[axes.designs] bounds 'counter_mass' must be (low, high)"),
        (SPEC, ('units = { counter_mass = "kg" }', 'units = "kg"'),
         "[axes.designs] units must be a table"),
        (SPEC, ('metric = ["peak_force", "peak_moment"]', "metric = 5"),
         "metric must be a name or a list of names, got 5"),
        (SPEC, ('[axes.payload]\nlinspace = [0.0, 1.0, 3]\nunits = "kg"', "[axes]\npayload = 5"),
         "[axes.payload] must be a table"),
    ],
)  # fmt: skip
def test_misplaced_or_malformed_spec_keys_exit_2_naming_the_key(tmp_path, base, edit, message):
    """Were silently ignored (a key of the other motion kind), accepted (chunk_size ≤ 0,
    a bad u2 that failed later and left an empty store) or escaped as an
    OverflowError/IndexError/TypeError traceback."""
    assert edit[0] in base
    spec, store = _write(tmp_path, base.replace(*edit)), tmp_path / "bad.zarr"
    result = CliRunner().invoke(app, ["sweep", str(spec), "--out", str(store), "--no-progress"])
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not store.exists()


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_switch_time_off_its_domain_is_one_line_before_anything_runs(tmp_path, caplog):
    """jax logged a traceback (``jax.pure_callback failed``) and equinox's banner for
    the runtime check before the CLI's error line; now the axis is refused up front and
    no store is left (a block's runtime check: tests/test_sweep_cli_errors.py)."""
    bad_u2 = TRAPEZOID.split("[axes.payload]")[0].replace("samples = 33", "samples = 5")
    bad_u2 = bad_u2.replace('["peak_force", "peak_moment"]', '"peak_force"')
    bad_u2 += "[axes.u2]\nvalues = [0.2, 0.7]\n"
    spec, store = _write(tmp_path, bad_u2), tmp_path / "s.zarr"
    result = CliRunner().invoke(app, ["sweep", str(spec), "--out", str(store), "--no-progress"])
    assert result.exit_code == 2, result.output
    assert result.output.startswith("error: sweep axis 'u2': u2 = 0.7 is outside its domain")
    assert len(result.output.strip().splitlines()) == 1 and not store.exists()
    assert not [r for r in caplog.records if r.name.startswith("jax")], caplog.text


def test_out_an_existing_file_is_refused_even_with_resume(tmp_path):
    """Was: "exists: pass --resume to continue it", also with --resume."""
    spec, store = _write(tmp_path, SPEC), tmp_path / "afile.zarr"
    store.write_text("hi")
    for extra in ([], ["--resume"]):
        command = ["sweep", str(spec), "--out", str(store), "--no-progress", *extra]
        result = CliRunner().invoke(app, command)
        assert result.exit_code == 2, result.output
        assert "is a file, not a jaxbal sweep store" in result.output
        assert "pass --resume" not in result.output
    assert store.read_text() == "hi"
