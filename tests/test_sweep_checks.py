"""``jaxbal.sweep``'s refusals of inputs it ignored or passed on to JAX, zarr or NumPy.

Each test failed before its fix (exploratory testing, /tmp/explore_sweep): θ given to a
fixed motion (even NaN) was silently ignored; a resume with other units or output_dims
kept the store's old labels; a ``where=`` grid of the wrong shape gave JAX's broadcast
error; a spec grid with NaN did not name its ``[axes.X]``; ``jaxbal plot --reduce
median`` exited 0 on a sweep of one axis; a spec ``linspace`` of 10¹² points ended in a
MemoryError traceback; ``--resume`` on an empty folder printed zarr's "No group found".
"""

import jax.numpy as jnp
import numpy as np
import pytest
import xarray as xr
from conftest import com_move_2r
from test_sweep_inputs import SPEC  # a 2R payload sweep, 9 samples
from typer.testing import CliRunner

import jaxbal
from jaxbal._src.cli import app
from jaxbal._src.sweep_plot import plot_sweep


@pytest.fixture(scope="module")
def arm():
    return com_move_2r(9)


def _payloads(robot, motion):
    """Two numbers per point (an output with a dimension of its own), cheap to compile."""
    payload = robot.design()["payload"]
    return jnp.stack([payload, 2.0 * payload])


def _cli(tmp_path, spec_text, *extra, out="s.zarr"):
    spec = tmp_path / "spec.toml"
    spec.write_text(spec_text)
    command = ["sweep", str(spec), "--out", str(tmp_path / out), "--no-progress", *extra]
    return CliRunner().invoke(app, command)


def test_trajectory_of_a_fixed_motion_or_not_finite_is_refused(arm):
    robot, motion = arm
    axes = {"payload": jaxbal.sweep.grid([0.0, 1.0])}
    with pytest.raises(ValueError, match=r"trajectory=\{'u2': nan\} is given, but the motion "
                       r"Motion is fixed"):  # fmt: skip
        jaxbal.sweep("peak_force", robot, motion, axes, trajectory={"u2": np.nan}, progress=False)
    move = jaxbal.design.TrapezoidLine(
        jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70]), jaxbal.sample_times(0.5, 9)
    )
    with pytest.raises(ValueError, match="trajectory 'ratio' must be finite, got inf"):
        jaxbal.sweep("peak_force", robot, move, {"u2": jaxbal.sweep.grid([0.1, 0.3])},
                     trajectory={"ratio": np.inf}, progress=False)  # fmt: skip


def test_resume_with_other_units_or_output_dims_is_refused_naming_them(arm, tmp_path):
    robot, motion = arm
    path = tmp_path / "s.zarr"

    def axes(units="kg"):
        return {"payload": jaxbal.sweep.grid([0.0, 1.0], units=units)}

    def run(**kw):
        return jaxbal.sweep(_payloads, robot, motion, kw.pop("axes", axes()), store=path,
                            progress=False, **kw)  # fmt: skip

    first = run(units="N", output_dims={"value": "statistic"})
    changed = {
        r"units of 'value' 'N' in the store, 'kN' now": {"units": "kN"},
        r"units of axis 'payload' 'kg' in the store, 'g' now": {"axes": axes("g")},
        r"output_dims of 'value' \['statistic'\] in the store, \['value_dim0'\] now": {
            "output_dims": None
        },
    }
    for message, kw in changed.items():
        kw = {"units": "N", "output_dims": {"value": "statistic"}} | kw
        with pytest.raises(ValueError, match=f"written with other labels: {message}"):
            run(resume=True, **kw)
    again = run(resume=True, units="N", output_dims={"value": "statistic"})  # the same call
    xr.testing.assert_identical(again, first)


def test_a_where_grid_of_the_wrong_shape_names_the_axis_and_shapes(arm):
    robot, motion = arm
    axes = {"m": jaxbal.sweep.grid(np.ones((2, 3)), where=lambda r: r.masses)}
    with pytest.raises(ValueError, match=r"sweep axis 'm': m is the where= leaf of shape "
                       r"\(2,\).*need shape \(2, 2\).*got values of shape \(2, 3\)"):  # fmt: skip
        jaxbal.sweep("peak_force", robot, motion, axes, progress=False)


@pytest.mark.parametrize(
    "axis, message",
    [
        ("values = [0.0, nan]", "[axes.payload] grid has non-finite values"),
        ('values = ["a"]', "[axes.payload] could not convert"),
        ("linspace = [0, 1, 1e12]", "[axes.payload] linspace must be [start, stop, count]"),
        ("linspace = [0, 1, inf]", "count an integer from 1 to 1e+08"),
        ("linspace = [0, nan, 3]", "[axes.payload] linspace must be"),
        ('sample = "sobol"\nn = 1e12\nbounds = { payload = [0, 1] }',
         "[axes.payload] a sample needs an integer count from 1 to 1e+08, got 1000000000000.0"),
    ],
)  # fmt: skip
def test_bad_grids_in_a_spec_exit_2_naming_the_axis(tmp_path, axis, message):
    result = _cli(tmp_path, SPEC.replace("values = [0.0, 1.0]", axis))
    assert result.exit_code == 2, result.output
    assert message in result.output and "Traceback" not in result.output
    assert not (tmp_path / "s.zarr").exists()


def test_an_unknown_reduction_is_refused_with_nothing_to_reduce(tmp_path):
    one_axis = xr.Dataset({"value": ("payload", [1.0, 2.0])}, coords={"payload": [0.0, 1.0]})
    with pytest.raises(ValueError, match=r"unknown reduction 'median'; choose one of"):
        plot_sweep(one_axis, reduce="median", out=tmp_path / "p.png")
    assert not (tmp_path / "p.png").exists()


def test_resume_or_plot_of_an_empty_folder_says_it_is_no_sweep_store(arm, tmp_path):
    robot, motion = arm
    empty = tmp_path / "empty"
    empty.mkdir()
    message = f"{empty} is not a jaxbal sweep store (no zarr group in it)"
    with pytest.raises(ValueError, match="is not a jaxbal sweep store"):
        jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0, 1.0]}, store=empty,
                     resume=True, progress=False)  # fmt: skip
    resumed = _cli(tmp_path, SPEC, "--resume", out="empty")
    plotted = CliRunner().invoke(app, ["plot", str(empty)])
    for result in (resumed, plotted):
        assert result.exit_code == 2, result.output
        assert message in result.output and "No group found" not in result.output
    assert not list(empty.iterdir())


def test_output_dims_of_an_unknown_output_an_axis_or_two_sizes_are_refused_first(arm, tmp_path):
    """``output_dims={"values": …}`` (a typo) was ignored; an output dimension named like
    an axis, or one name for dimensions of two sizes, was refused by xarray only after
    every point was computed and stored. Now refused before the store is created."""
    robot, motion = arm
    axes = {"payload": jaxbal.sweep.grid([0.0, 1.0])}

    def two(robot, motion):
        payload = robot.design()["payload"]
        return {"a": jnp.stack([payload, payload]), "b": jnp.stack([payload] * 3)}

    cases = [
        (_payloads, {"values": "statistic"}, r"unknown outputs \['values'\]; outputs \['value'\]"),
        (_payloads, {"value": "payload"}, "'payload' is a sweep axis"),
        (two, {"a": "k", "b": "k"}, "dimension 'k' has size 3 here and 2"),
    ]
    for k, (metric, dims, message) in enumerate(cases):
        path = tmp_path / f"s{k}.zarr"
        with pytest.raises(ValueError, match=message):
            jaxbal.sweep(metric, robot, motion, axes, output_dims=dims, store=path, progress=False)
        assert not path.exists()
    fine = jaxbal.sweep(two, robot, motion, axes, output_dims={"a": "i", "b": "j"}, progress=False)
    assert dict(fine.sizes) == {"payload": 2, "i": 2, "j": 3}


def test_a_plot_of_a_grid_given_unsorted_draws_its_values_in_order():
    """``grid([4, 0, 2, 1, 3])``: the line joined the points in the given order and the
    heat map put each value beside the wrong label (t16_plot_unsorted.py)."""
    x, y = [4.0, 0.0, 2.0, 1.0, 3.0], [1.0, 0.0, 0.5]
    values = np.add.outer(np.array(x), 10.0 * np.array(y))
    heat = xr.Dataset({"value": (("m", "p"), values)}, coords={"m": x, "p": y})
    mesh = plot_sweep(heat).axes[0].collections[0]
    np.testing.assert_array_equal(mesh.get_array().reshape(5, 3), np.add.outer(
        np.sort(x), 10.0 * np.sort(y)))  # fmt: skip
    line = plot_sweep(heat.isel(p=[0])).axes[0].lines[0]
    np.testing.assert_array_equal(line.get_xdata(), np.sort(x))
    np.testing.assert_array_equal(line.get_ydata(), np.sort(x) + 10.0)
    assert heat["m"].values.tolist() == x  # the dataset keeps its order


def test_a_sweep_killed_while_creating_its_store_resumes(arm, tmp_path, monkeypatch):
    """The store was created in place and its description written last: a run killed in
    between left a store that every resume refused ("no jaxbal_sweep attribute")."""
    import zarr
    from zarr.core.attributes import Attributes

    robot, motion = arm
    path, axes = tmp_path / "s.zarr", {"payload": jaxbal.sweep.grid([0.0, 1.0])}

    def killed(self, *args, **kwargs):
        raise KeyboardInterrupt("killed while the store is created")

    monkeypatch.setattr(Attributes, "update", killed)
    with pytest.raises(KeyboardInterrupt):
        jaxbal.sweep(_payloads, robot, motion, axes, store=path, progress=False)
    monkeypatch.undo()
    assert not path.exists() and not list(tmp_path.iterdir())
    # a half-made store of an older jaxbal (its coordinate only): re-created
    zarr.open_group(str(path), mode="w", zarr_format=3).create_array("payload", shape=(2,),
                                                                     dtype="f8")  # fmt: skip
    ds = jaxbal.sweep(_payloads, robot, motion, axes, store=path, resume=True, progress=False)
    np.testing.assert_array_equal(ds["value"].values, [[0.0, 0.0], [1.0, 2.0]])
    # a zarr group that is no half-made store of this sweep is left alone
    other = tmp_path / "other.zarr"
    zarr.open_group(str(other), mode="w", zarr_format=3).create_array("x", shape=(2,), dtype="f8")
    with pytest.raises(ValueError, match="not a jaxbal sweep store .*: remove it or choose"):
        jaxbal.sweep(_payloads, robot, motion, axes, store=other, resume=True, progress=False)
    assert (other / "x").exists()
