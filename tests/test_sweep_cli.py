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
