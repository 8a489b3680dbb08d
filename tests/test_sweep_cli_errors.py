"""Error handling of ``jaxbal.sweep`` and of ``jaxbal sweep|plot|balance``: every error
is one line (``error: …``, exit status 2) naming what is at fault, found before the
long computation and before a store is created, and never touching the user's files.

Each test reproduces a defect a tester found (an uncaught ``TypeError``, a traceback, a
message naming no key or block, an empty store left behind, PNG bytes in a ``.pdf``).
No Ray cluster is started: the Ray backend's connection is tested with a stand-in
``ray`` module.
"""

import sys
import types

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import zarr
from conftest import com_move_2r
from test_sweep_cli import SPEC, TRAPEZOID, _write
from typer.testing import CliRunner

import jaxbal
from jaxbal._src.cli import app
from jaxbal._src.sweep import Chunks
from jaxbal._src.sweep_axes import Layout, grid
from jaxbal._src.sweep_run import block_error
from jaxbal._src.sweep_store import SweepStore


def _sweep_cli(tmp_path, text, *extra, out="bad.zarr"):
    spec, store = _write(tmp_path, text), tmp_path / out
    command = ["sweep", str(spec), "--out", str(store), "--no-progress", *extra]
    return CliRunner().invoke(app, command), store


def _one_line_error(result, *messages):
    assert result.exit_code == 2, (result.exit_code, result.output, result.exception)
    assert result.output.startswith("error: ") and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    for message in messages:
        assert message in result.output, result.output


HALTON = "n = 4\n"
DURATION = "duration = 0.5"


@pytest.mark.parametrize(
    "edit, message",
    [
        ((HALTON, 'n = 4\nseed = "x"\n'), "[axes.designs] seed must be an integer ≥ 0, got 'x'"),
        ((HALTON, "n = 4\nseed = -1\n"), "[axes.designs] seed must be an integer ≥ 0, got -1"),
        ((DURATION, "duration = [0.5]"), "[motion] duration must be > 0 s"),
        ((DURATION, 'duration = "fast"'), "[motion] duration must be > 0 s"),
        ((DURATION, "duration = true"), "[motion] duration must be > 0 s (a number), got True"),
        (('name = "planar_2r"', 'name = "planar_2r"\noptions = 5'), "[robot] options must be a"),
        (("start = [0.225, 0.25]", 'start = ["a", "b"]'), "[motion] start must be a list"),
        (("start = [0.225, 0.25]", "start = [0.225, 0.25, 0.1]"),
         "[motion] start must be a list of finite numbers, the 2 coordinates of the "
         "end-effector pose of PlanarArm, got [0.225, 0.25, 0.1]"),
        (("branch = -1", 'branch = [1, "a"]'), "[motion] branch must be ±1 or a list"),
        (('name = "planar_2r"', 'name = "planar_2r"\n[robot.options]\npayload = "heavy"'),
         "[robot.options] payload must be a finite number, got 'heavy'"),
        (("linspace = [0.0, 1.0, 3]", "values = [true, false]"),
         "[axes.payload] values must be numbers, not booleans, got [True, False]"),
    ],
)  # fmt: skip
def test_spec_values_of_the_wrong_type_name_their_key(tmp_path, edit, message):
    """Were an uncaught TypeError (seed, duration list, options = 5), a message naming
    no key (could not convert string to float), or accepted (booleans as numbers)."""
    assert edit[0] in SPEC
    result, store = _sweep_cli(tmp_path, SPEC.replace(*edit))
    _one_line_error(result, message)
    assert not store.exists()


@pytest.mark.parametrize(
    "axis, message",
    [
        ("[axes.u2]\nvalues = [0.2, 0.7]\n", "sweep axis 'u2': u2 = 0.7 is outside its domain"),
        ("[axes.ratio]\nvalues = [0.0, 0.5]\n", "sweep axis 'ratio': ratio = 0 is outside"),
    ],
)
def test_trapezoid_switch_times_out_of_their_domain_are_refused_before_a_store(
    tmp_path, axis, message
):
    """Failed in block 0 at run time and left a store of 0 done blocks behind."""
    text = TRAPEZOID.split("[axes.payload]")[0] + axis
    result, store = _sweep_cli(tmp_path, text)
    _one_line_error(result, message, "0 < u2 < 0.5" if "u2" in axis else "0 < ratio ≤ 1")
    assert not store.exists()


@pytest.mark.parametrize("resume", [False, True])
@pytest.mark.parametrize("user_files", [False, True])
def test_a_folder_that_is_no_sweep_store_is_said_so_at_once(tmp_path, resume, user_files):
    """Was "exists: pass --resume", then, with --resume, "not a jaxbal sweep store"."""
    folder = tmp_path / "mine"
    folder.mkdir()
    if user_files:
        (folder / "data.csv").write_text("hello")
    result, _ = _sweep_cli(tmp_path, SPEC, *(["--resume"] if resume else []), out="mine")
    _one_line_error(result, "mine is not a jaxbal sweep store", "choose another path")
    assert "pass --resume" not in result.output
    assert sorted(p.name for p in folder.iterdir()) == (["data.csv"] if user_files else [])
    plotted = CliRunner().invoke(app, ["plot", str(folder), "--out", str(tmp_path / "p.png")])
    _one_line_error(plotted, "is not a jaxbal sweep store")
    assert "remove" not in plotted.output  # a read-only command


def test_an_out_that_cannot_be_written_is_refused_before_the_sweep_compiles(tmp_path, monkeypatch):
    """Were rich tracebacks (NotADirectoryError, OSError read-only file system)."""
    import jaxbal._src.sweep as sweep_module

    def compiled(*args, **kwargs):
        raise AssertionError("the sweep was prepared before its store was checked")

    monkeypatch.setattr(sweep_module, "prepare", compiled)
    a_file = _write(tmp_path, "hi", "afile")
    proc = ["/proc/jaxbal-test/x.zarr"] if sys.platform.startswith("linux") else []
    for out in (a_file / "x.zarr", *proc):
        result, _ = _sweep_cli(tmp_path, SPEC, out=str(out))
        _one_line_error(result, f"cannot write {out}: ")
    assert "Not a directory" in _sweep_cli(tmp_path, SPEC, out=str(a_file / "x"))[0].output
    robot, motion = com_move_2r(8)
    with pytest.raises(NotADirectoryError):
        jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0]}, store=a_file / "x")


def test_plot_and_balance_out_that_cannot_be_written(tmp_path):
    """``balance --out`` failed after its optimisation, ``plot --out`` with a traceback."""
    a_file = _write(tmp_path, "hi", "afile")
    plot = CliRunner().invoke(app, ["plot", str(tmp_path / "s.zarr"), "--out", f"{a_file}/x.png"])
    _one_line_error(plot, f"cannot write {a_file}/x.png: Not a directory")
    # the check comes first: the robot file is not even read
    command = ["balance", str(tmp_path / "none.xml"), "--start", "0,0", "--end", "1,1"]
    balance = CliRunner().invoke(app, [*command, "--out", f"{a_file}/b.xml"])
    _one_line_error(balance, f"cannot write {a_file}/b.xml: Not a directory")


def _partial_store(path):
    """A two-block store of ``value`` over ``payload`` (0, 1, 2, 3 kg), block 0 done."""
    axes = {"payload": grid([0.0, 1.0, 2.0, 3.0], units="kg").named("payload")}
    outputs = {"value": jax.ShapeDtypeStruct((), jnp.float64)}
    meta = {"units": {"value": "N"}, "fingerprint": "f", "parts": {}}
    store = SweepStore.create(path, axes, Layout.for_chunk((4,), 2), outputs, meta)
    store.write(0, {"value": np.array([1.0, 2.0])})


def test_plot_of_an_unfinished_store_warns_and_writes_the_suffix_format(tmp_path):
    """Drew the blocks done silently; ``--out x.pdf`` held PNG bytes."""
    store = tmp_path / "s.zarr"
    _partial_store(store)
    pdf = tmp_path / "x.pdf"
    result = CliRunner().invoke(app, ["plot", str(store), "--out", str(pdf)])
    assert result.exit_code == 0, result.output
    assert "warning: 1 of 2 blocks of the sweep are done" in result.output
    assert pdf.read_bytes().startswith(b"%PDF")
    unknown = CliRunner().invoke(app, ["plot", str(store), "--out", str(tmp_path / "x.foo")])
    _one_line_error(unknown, "matplotlib writes no 'foo' images")
    assert not (tmp_path / "x.foo").exists()


def _fake_ray(monkeypatch, failure):
    """A stand-in ``ray`` module whose ``init`` raises ``failure`` (no cluster)."""
    fake = types.ModuleType("ray")
    fake.is_initialized = lambda: False

    def init(**kwargs):
        raise failure

    fake.init = init
    monkeypatch.setitem(sys.modules, "ray", fake)


@pytest.mark.parametrize(
    "address, message",
    [
        ("auto", "cannot connect to the Ray cluster at 'auto': Could not find any running"),
        ("127.0.0.1:1", "cannot connect to the Ray cluster at '127.0.0.1:1': nothing listens"),
    ],
)
def test_ray_without_a_cluster_is_one_line_and_leaves_no_store(
    tmp_path, monkeypatch, address, message
):
    """Was a ConnectionError traceback (``auto``) or a hang (nothing listening), after
    the empty store was created: the next run then said "exists: pass --resume"."""
    _fake_ray(monkeypatch, ConnectionError("Could not find any running Ray instance.\nmore"))
    result, store = _sweep_cli(tmp_path, SPEC, "--backend", "ray", "--address", address)
    _one_line_error(result, message)
    assert not store.exists() and not list(tmp_path.glob(".bad.zarr*"))


def _chunks():
    axes = {"payload": grid([0.0, 0.5, 1.0, 1.5]).named("payload")}
    return Chunks(axes, Layout.for_chunk((4,), 2), 1)


def test_any_exception_of_a_block_names_the_block_in_one_line():
    """A host callback's RuntimeError came as a 19-line JaxRuntimeError, a Ray task's
    as a 24-line RayTaskError with colour codes, naming no block."""
    ray_text = (
        "\x1b[36mray::evaluate_block()\x1b[39m (pid=1, ip=10.0.0.1)\n"
        '  File "x.py", line 3, in f\n    raise RuntimeError("my simulator rejected it")\n'
        "jax.errors.JaxRuntimeError: INTERNAL: CpuCallback error calling callback: "
        "Traceback (most recent call last):\n"
        '  File "x.py", line 3, in f\n\x1b[31mRuntimeError: my simulator rejected it\x1b[0m'
    )
    error = block_error(_chunks(), 1, RuntimeError(ray_text))
    assert type(error) is RuntimeError
    assert str(error) == "sweep block 1 (payload in [1, 1.5]): my simulator rejected it"
    error = block_error(_chunks(), 0, RuntimeError("Traceback:\nValueError: too heavy"))
    assert type(error) is ValueError
    assert str(error) == "sweep block 0 (payload in [0, 0.5]): too heavy"
    error = block_error(_chunks(), 0, ZeroDivisionError("division by zero"))
    assert str(error).endswith("): ZeroDivisionError: division by zero")


def _host_check(total):
    if np.any(np.asarray(total) > 1.5):
        raise RuntimeError(f"my simulator rejected {np.max(total):g} kg")
    return total


def _rejecting_metric(robot, motion):
    """The added mass, through a host callback that raises above 1.5 kg."""
    total = jnp.sum(robot.counter_masses)
    shape = jax.ShapeDtypeStruct((), jnp.float64)
    return jax.pure_callback(_host_check, shape, total, vmap_method="broadcast_all")


def test_a_callback_raising_in_a_block_names_it_and_the_blocks_before_are_written(tmp_path):
    """The local backend keeps one call in flight: the block before the failing one
    was lost (not written) when the failure surfaced at the next dispatch."""
    robot, motion = com_move_2r(8)
    path = tmp_path / "s.zarr"
    axes = {"counter_mass": np.linspace(0.0, 2.0, 5)}
    with pytest.raises(RuntimeError) as raised:
        jaxbal.sweep(_rejecting_metric, robot, motion, axes, chunk_size=1, store=path,
                     progress=False)  # fmt: skip
    assert str(raised.value) == "sweep block 2 (counter_mass in [1, 1]): my simulator rejected 2 kg"
    assert raised.value.__cause__ is not None
    done = np.asarray(zarr.open_group(str(path), mode="r")["_jaxbal"]["done"][:])
    assert done.tolist() == [1, 1, 0, 0, 0]


def test_ray_failure_writes_the_blocks_already_finished():
    """On Ray the finished results still in flight were cancelled with the others."""
    from jaxbal._src.sweep_ray import _write_finished

    class Ray:
        def wait(self, refs, num_returns, timeout):
            return [r for r in refs if r != "running"], ["running"]

        def get(self, ref):
            if ref == "failed":
                raise RuntimeError("also failed")
            return {"value": np.array([1.0, 2.0])}

    written = []
    running = {"finished": (0, 2), "failed": (1, 2), "running": (1, 2)}
    _write_finished(Ray(), running, _chunks(), lambda k, out: written.append(k), lambda m: None)
    assert written == [0] and list(running) == ["running"]


@pytest.mark.parametrize("devices", [[], "cpu", 5, [jax.devices()[0], jax.devices()[0]]])
def test_bad_devices_are_refused_before_anything_compiles(devices):
    """Were a ZeroDivisionError, an error from inside JAX and an AttributeError."""
    robot, motion = com_move_2r(8)
    with pytest.raises(ValueError, match="devices"):
        jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0]}, devices=devices)


def test_balance_errors_shorten_long_arrays(tmp_path, monkeypatch):
    """``--start 5,5`` printed the 89 instants of the failing move over ten lines."""
    import jaxbal._src.robots.mjcf_import as mjcf_import
    from jaxbal._src.cli_errors import shorten_arrays

    times = np.linspace(0.0, 0.44, 89)

    def unreachable(*args, **kwargs):
        raise ValueError(f"end-effector line leaves the mechanism's reach at t [s]: {times!r}")

    monkeypatch.setattr(mjcf_import, "from_mjcf", unreachable)
    command = ["balance", str(tmp_path / "r.xml"), "--start", "5,5", "--end", "0.2,0.7"]
    result = CliRunner().invoke(app, command)
    _one_line_error(result, "at t [s]: [0., 0.005, …, 0.44] (89 values)")
    assert shorten_arrays("array([1., 2.])") == "[1., 2.]"


def test_a_failing_runtime_check_is_one_error_without_jax_log(caplog):
    """A runtime check failing in a block (a setter building negative masses; a spec's
    out-of-domain ``u2``, which this checked before, is now refused up front): the
    block's ``ValueError``, and jax logs no traceback of the callback."""
    robot, motion = com_move_2r(8)
    negative = {"m": jaxbal.sweep.grid([1.0, -1.0], where=lambda r: r.masses)}
    with pytest.raises(ValueError, match=r"^sweep block 0 \(m in \[-1, 1\]\): body masses"):
        jaxbal.sweep("peak_force", robot, motion, negative, progress=False)
    assert not [r for r in caplog.records if r.name.startswith("jax")], caplog.text
