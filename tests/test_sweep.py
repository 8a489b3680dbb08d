"""``jaxbal.sweep``: labels, chunking, two host devices against a plain ``vmap`` bit for
bit, a sweep killed by SIGKILL and resumed against an uninterrupted one, and the Ray
backend on a local two-worker cluster (a worker killed mid-sweep) against the local run.

The multi-device and Ray checks run in fresh interpreters: the device count is fixed
when JAX starts, and Ray workers must unpickle the metric (a ``__main__`` function is
sent by value).
"""

import json
import os
import subprocess
import sys
import textwrap

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
import zarr
from conftest import com_move_2r

import jaxbal
from jaxbal.design import METRICS, motion_samples

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

#: shared by the child scripts: the Briot 2R, a bang-bang COM line P5 -> P9, 64 samples.
SETUP = """
import os, sys, json, signal
import numpy as np, jax, jax.numpy as jnp
import jaxbal
robot = jaxbal.robots.planar_2r()
q0 = robot.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
q1 = robot.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
plan = jaxbal.planning.com_line(robot, q0, q1, jaxbal.profiles.BangBang(), 0.5)
motion = jaxbal.design.motion_samples(robot, [plan], jaxbal.sample_times(0.5, 64))
"""


def _child(script: str, *, devices: int = 1, timeout: int = 300, check=True):
    env = dict(os.environ)
    env["XLA_FLAGS"] = f"--xla_force_host_platform_device_count={devices}"
    env["JAXBAL_CACHE_DIR"] = "off"
    env["PYTHONPATH"] = ROOT + os.pathsep + env.get("PYTHONPATH", "")
    code = SETUP + textwrap.dedent(script)
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=timeout
    )
    if check and out.returncode != 0:
        raise AssertionError(f"child failed ({out.returncode}):\n{out.stderr[-4000:]}")
    return out


def _json(out) -> dict:
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.fixture(scope="module")
def arm():
    return com_move_2r(32)


def _with(robot, **design):
    current = robot.design()
    return robot.with_design(
        {k: jnp.broadcast_to(v, jnp.shape(current[k])) for k, v in design.items()}
    )


def test_labels_units_and_values_equal_the_metric_per_point(arm):
    robot, motion = arm
    cm, pl = np.linspace(0.0, 3.0, 4), np.linspace(0.0, 1.0, 3)
    ds = jaxbal.sweep(
        "peak_force", robot, motion, {"counter_mass": cm, "payload": pl}, progress=False
    )
    assert ds["value"].dims == ("counter_mass", "payload")
    np.testing.assert_array_equal(ds["counter_mass"].values, cm)
    np.testing.assert_array_equal(ds["payload"].values, pl)
    assert ds["value"].attrs["units"] == "N"
    assert ds.attrs["metric"] == "peak_force" and ds.attrs["blocks_done"] == "1/1"
    metric = jax.jit(METRICS["peak_force"])
    for i, c in enumerate(cm):
        for j, p in enumerate(pl):
            expected = float(metric(_with(robot, counter_mass=c, payload=p), motion))
            assert ds["value"].values[i, j] == pytest.approx(expected, rel=1e-13)


def _link1_mass(robot, value):
    import equinox as eqx

    return eqx.tree_at(lambda r: r.masses, robot, robot.masses.at[0].set(value))


def test_where_setter_broadcasts_to_the_leaf(arm):
    robot, motion = arm
    axes = {"m": jaxbal.sweep.grid([1.0, 2.0], where=lambda r: r.masses)}
    ds = jaxbal.sweep("peak_force", robot, motion, axes, progress=False)
    import equinox as eqx

    heavy = eqx.tree_at(lambda r: r.masses, robot, jnp.full_like(robot.masses, 2.0))
    expected = float(jax.jit(METRICS["peak_force"])(heavy, motion))
    assert ds["value"].values[1] == pytest.approx(expected, rel=1e-13)


def test_dict_metric_where_setter_sobol_axis_and_output_dims(arm):
    robot, motion = arm

    def both(robot, motion):
        force, moment = jax.vmap(lambda *x: jaxbal.shaking_wrench(robot, *x))(*motion)
        return {"force": jnp.linalg.norm(force, axis=-1), "moment": moment[:, 2]}

    axes = {
        "link1": jaxbal.sweep.grid([1.0, 2.0], units="kg", set=_link1_mass),
        "sample": jaxbal.sweep.sobol(4, {"payload": (0.0, 1.0)}, units={"payload": "kg"}),
    }
    ds = jaxbal.sweep(
        both, robot, motion, axes, output_dims={"force": "t", "moment": "t"},
        units={"force": "N", "moment": "N·m"}, progress=False,
    )  # fmt: skip
    assert ds["force"].dims == ("link1", "sample", "t") and ds.sizes["t"] == 32
    assert ds["payload"].dims == ("sample",) and ds["payload"].attrs["units"] == "kg"
    payloads = ds["payload"].values
    assert np.all((payloads >= 0) & (payloads <= 1)) and len(set(payloads)) == 4
    import equinox as eqx

    changed = eqx.tree_at(lambda r: r.masses, robot, robot.masses.at[0].set(2.0))
    loaded = _with(changed, payload=payloads[3])
    force, moment = jax.jit(jax.vmap(lambda *x: jaxbal.shaking_wrench(loaded, *x)))(*motion)
    np.testing.assert_allclose(ds["force"].values[1, 3], np.linalg.norm(force, axis=-1), 1e-13)
    np.testing.assert_allclose(ds["moment"].values[1, 3], moment[:, 2], 1e-13, 1e-12)


def test_array_valued_and_renamed_grids(arm):
    robot, motion = arm
    per_link = np.array([[0.0, 0.5], [1.0, 0.0], [2.0, 1.0]])  # (n, 2): one mass per link
    ds = jaxbal.sweep(
        "peak_force", robot, motion,
        {"counter_mass": jaxbal.sweep.grid(per_link, units="kg"),
         "load": jaxbal.sweep.grid([0.0, 0.5], units="kg", name="payload")},
        progress=False,
    )  # fmt: skip
    np.testing.assert_array_equal(ds["counter_mass"].values, [0, 1, 2])  # index coordinate
    np.testing.assert_array_equal(ds["counter_mass_values"].values, per_link)
    assert ds["counter_mass_values"].attrs["units"] == "kg" and ds["load"].attrs["units"] == "kg"
    expected = METRICS["peak_force"](_with(robot, counter_mass=per_link[2], payload=0.5), motion)
    assert ds["value"].values[2, 1] == pytest.approx(float(expected), rel=1e-13)


@pytest.mark.parametrize(("linear", "budget"), [(False, 64 * 2**10), ("auto", 8 * 2**10)])
def test_memory_budget_cuts_blocks_and_the_values_do_not_change(arm, linear, budget):
    """Direct and affine evaluation (whose points need far less memory) alike."""
    robot, motion = arm
    axes = {"counter_mass": np.linspace(0, 3, 16), "payload": np.linspace(0, 1, 8)}
    whole = jaxbal.sweep("rms_force", robot, motion, axes, progress=False, linear=linear)
    cut = jaxbal.sweep(
        "rms_force", robot, motion, axes, memory_budget=budget, progress=False, linear=linear
    )
    assert (cut.attrs.get("evaluation") == "affine") == (linear == "auto")
    blocks = int(cut.attrs["blocks_done"].split("/")[1])
    assert blocks > 1 and whole.attrs["blocks_done"] == "1/1"
    # small blocks run XLA's small-batch loops: equal to rounding (see MIN_DEVICE_BATCH)
    np.testing.assert_allclose(whole["value"].values, cut["value"].values, rtol=2e-15, atol=0)


def test_blocks_of_batched_solves_are_capped(arm):
    """jaxlib's CPU LU can deadlock on large batches (see MAX_LU_BATCH): a metric solving
    400 systems per point gets blocks of 4096 // 400 = 10 points, values unchanged."""
    from jaxbal._src.sweep import MAX_LU_BATCH

    robot, motion = arm

    def solves(robot, motion):
        p = robot.design()["payload"]
        one = lambda b: jnp.linalg.solve(jnp.eye(3) * (1.0 + p + b[0] ** 2) + 0.1, b)  # noqa: E731
        return jnp.sum(jax.vmap(one)(jnp.ones((400, 3)) + motion.q[:1, :1]))

    ds = jaxbal.sweep(solves, robot, motion, {"payload": np.linspace(0, 1, 25)}, progress=False)
    assert ds.attrs["blocks_done"] == f"3/{-(-25 // (MAX_LU_BATCH // 400))}"
    expected = jax.jit(solves)(_with(robot, payload=0.5), motion)
    assert float(ds["value"].sel(payload=0.5)) == pytest.approx(float(expected), rel=1e-13)


def test_bad_axes_are_refused_with_the_name(arm):
    robot, motion = arm
    with pytest.raises(ValueError, match="unknown sweep parameter 'bogus'"):
        jaxbal.sweep("peak_force", robot, motion, {"bogus": [1.0, 2.0]}, progress=False)
    with pytest.raises(ValueError, match="non-finite"):
        jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0, np.nan]}, progress=False)
    with pytest.raises(ValueError, match="at least one axis"):
        jaxbal.sweep("peak_force", robot, motion, {}, progress=False)


def test_non_physical_points_raise_naming_the_axis_or_the_block(arm):
    robot, motion = arm
    with pytest.raises(ValueError, match=r"axis 'payload': payload = -1.0 is below"):
        jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0, -1.0]}, progress=False)
    negative = {"m": jaxbal.sweep.grid([1.0, -1.0], where=lambda r: r.masses)}
    with pytest.raises(ValueError, match=r"block 0 \(m in \[-1, 1\]\): body masses must be"):
        jaxbal.sweep("peak_force", robot, motion, negative, progress=False)


def test_existing_store_needs_resume_and_the_same_sweep(arm, tmp_path):
    robot, motion = arm
    path = tmp_path / "s.zarr"
    jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0, 0.5]}, store=path, progress=False)
    with pytest.raises(FileExistsError, match="resume=True"):
        jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0, 0.5]}, store=path)
    with pytest.raises(ValueError, match="different sweep; .*: the axes or their values\\. A"):
        jaxbal.sweep("peak_force", robot, motion, {"payload": [0.0, 0.6]}, store=path, resume=True)
    again = jaxbal.sweep(
        "peak_force", robot, motion, {"payload": [0.0, 0.5]}, store=path, resume=True
    )
    np.testing.assert_array_equal(again["value"].values, jaxbal.sweep.open_sweep(path)["value"])
    # the store's values belong to its robot, motion and metric: a store resumed with
    # other ones returned the first robot's values as the second's
    heavier = eqx.tree_at(lambda r: r.counter_masses, robot, robot.counter_masses + 1.0)
    slower = type(motion)(*(part * 0.5 for part in motion))
    others = {"robot": (heavier, motion, "peak_force"), "motion": (robot, slower, "peak_force"),
              "metric": (robot, motion, "rms_force")}  # fmt: skip
    for part, (r, m, metric) in others.items():
        with pytest.raises(ValueError, match=f"changed since it was written: the {part}"):
            jaxbal.sweep(metric, r, m, {"payload": [0.0, 0.5]}, store=path, resume=True)
    # the same values as points instead of a grid: the refusal blamed the setters' code
    points = {"payload": jaxbal.sweep.points({"payload": [0.0, 0.5]})}
    with pytest.raises(ValueError, match=r"written: the kinds of axes \('payload': grid in the "
                       r"store, points now\)\. A"):  # fmt: skip
        jaxbal.sweep("peak_force", robot, motion, points, store=path, resume=True)
    rebuilt = jaxbal.robots.planar_2r()  # the same robot, built again: resumed
    assert bool(eqx.tree_equal(rebuilt, robot))
    jaxbal.sweep("peak_force", rebuilt, motion, {"payload": [0.0, 0.5]}, store=path, resume=True)


@pytest.mark.slow
def test_two_host_devices_equal_plain_vmap_bit_for_bit():
    result = _json(
        _child(
            """
            cm, pl = np.linspace(0.0, 3.0, 16), np.linspace(0.0, 1.0, 8)
            out = {"devices": jax.local_device_count()}
            metric = jaxbal.design.METRICS["peak_force"]
            def point(c, p):
                d = robot.design()
                r = robot.with_design({"counter_mass": jnp.broadcast_to(c, d["counter_mass"].shape),
                                       "payload": jnp.broadcast_to(p, d["payload"].shape)})
                return metric(r, motion)
            C, P = np.meshgrid(cm, pl, indexing="ij")
            plain = np.asarray(jax.jit(jax.vmap(point))(C.ravel(), P.ravel())).reshape(C.shape)
            from jaxbal._src.sweep import prepare
            axes = {"counter_mass": cm, "payload": pl}
            # the affine fast path's own plain vmap (one device, no shard_map)
            _, program, dynamic, _, how = prepare("peak_force", robot, motion, axes, mesh=False)
            flat = {"counter_mass": C.ravel(), "payload": P.ravel()}
            affine = np.asarray(jax.jit(program.batch)(dynamic, flat)["value"]).reshape(C.shape)
            out["how"] = how
            for chunk in (128, 64, 7):
                ds = jaxbal.sweep("peak_force", robot, motion, axes, chunk_size=chunk,
                                  progress=False, linear=False)
                fast = jaxbal.sweep("peak_force", robot, motion, axes, chunk_size=chunk,
                                    progress=False)
                out[str(chunk)] = [bool(np.array_equal(ds["value"].values, plain)),
                                   ds.attrs["blocks_done"],
                                   float(np.max(np.abs(ds["value"].values / plain - 1))),
                                   bool(np.array_equal(fast["value"].values, affine)),
                                   float(np.max(np.abs(fast["value"].values / affine - 1))),
                                   float(np.max(np.abs(fast["value"].values / plain - 1))),
                                   fast.attrs.get("evaluation")]
            print(json.dumps(out))
            """,
            devices=2,
        )
    )
    assert result["devices"] == 2 and result["how"] == "affine"
    # direct (linear=False): one block, or device batches of 32 points x 64 samples
    # (>= 2,048 elements, see jaxbal._src.sweep.MIN_DEVICE_BATCH): bit for bit
    assert result["128"][:2] == [True, "1/1"] and result["64"][:2] == [True, "2/2"]
    # blocks of 7 points padded to 8, 4 per device: XLA's small-batch loops, last bit only
    assert result["7"][1] == "32/32" and result["7"][2] < 2e-15
    # the affine fast path (default): one block bit for bit its own plain vmap; smaller
    # device batches (< MIN_DEVICE_BATCH elements) to the last bit; the direct metric to
    # rounding
    assert result["128"][3] is True
    for chunk in ("128", "64", "7"):
        assert result[chunk][4] <= 4.5e-16 and result[chunk][6] == "affine", chunk
        assert result[chunk][5] < 1e-13, chunk


KILLED = """
from jaxbal._src import sweep_store
path, kill_at = sys.argv[1], int(sys.argv[2])
def both(robot, motion):
    force, moment = jax.vmap(lambda *x: jaxbal.shaking_wrench(robot, *x))(*motion)
    return {"peak": jnp.max(jnp.linalg.norm(force, axis=-1)), "moment": moment[:, 2]}
if kill_at >= 0:
    write = sweep_store.SweepStore.write
    def dying(self, k, outputs):
        if k == kill_at:  # one output of this block written, the other not, no done mark
            name = sorted(outputs)[0]
            self.group[name][self.layout.region(k)] = outputs[name]
            os.kill(os.getpid(), signal.SIGKILL)
        write(self, k, outputs)
    sweep_store.SweepStore.write = dying
axes = {"counter_mass": np.linspace(0, 3, 12), "payload": np.linspace(0, 1, 5)}
jaxbal.sweep(both, robot, motion, axes, store=path, resume=True, chunk_size=5, progress=False)
print(json.dumps({"done": True}))
"""


def _arrays(path) -> dict:
    group = zarr.open_group(str(path), mode="r")
    found = {}

    def visit(g, prefix=""):
        for name, item in g.members():
            if isinstance(item, zarr.Group):
                visit(item, prefix + name + "/")
            else:
                found[prefix + name] = (np.asarray(item[...]), dict(item.attrs))

    visit(group)
    return found, dict(group.attrs)


@pytest.mark.slow  # three fresh interpreters (~30 s): make test-all
def test_sigkill_mid_sweep_then_resume_equals_an_uninterrupted_store(tmp_path):
    killed, clean = tmp_path / "killed.zarr", tmp_path / "clean.zarr"
    out = _child(
        KILLED.replace("sys.argv[1], int(sys.argv[2])", f"{str(killed)!r}, 5"), check=False
    )
    assert out.returncode == -9, out.stderr[-2000:]
    done = np.asarray(zarr.open_group(str(killed), mode="r")["_jaxbal"]["done"][:])
    assert 0 < done.sum() < done.size and done[5] == 0  # killed mid-sweep, block 5 unfinished
    with pytest.raises(ValueError, match="not done"):
        jaxbal.sweep.open_sweep(killed)
    _child(KILLED.replace("sys.argv[1], int(sys.argv[2])", f"{str(killed)!r}, -1"))
    _child(KILLED.replace("sys.argv[1], int(sys.argv[2])", f"{str(clean)!r}, -1"))
    (a, a_attrs), (b, b_attrs) = _arrays(killed), _arrays(clean)
    assert a_attrs == b_attrs and sorted(a) == sorted(b)
    for name in a:
        np.testing.assert_array_equal(a[name][0], b[name][0], err_msg=name)
        assert a[name][1] == b[name][1], name
    assert not list(killed.rglob("*.partial"))


def test_resume_recomputes_only_the_missing_blocks(arm, tmp_path, monkeypatch):
    from jaxbal._src import sweep_store

    robot, motion = arm
    path = tmp_path / "r.zarr"
    axes = {"counter_mass": np.linspace(0, 3, 6), "payload": np.linspace(0, 1, 4)}
    first = jaxbal.sweep("peak_force", robot, motion, axes, store=path, chunk_size=4)
    group = zarr.open_group(str(path), mode="r+")
    group["_jaxbal"]["done"][[1, 4]] = 0  # as if the run had stopped before these
    group["value"][1:2, :] = np.nan
    written = []
    original = sweep_store.SweepStore.write
    monkeypatch.setattr(
        sweep_store.SweepStore,
        "write",
        lambda self, k, outputs: (written.append(k), original(self, k, outputs)),
    )
    again = jaxbal.sweep(
        "peak_force", robot, motion, axes, store=path, chunk_size=4, resume=True, progress=False
    )
    assert written == [1, 4]
    np.testing.assert_array_equal(again["value"].values, first["value"].values)


RAY = """
import ray
from jaxbal._src.sweep_ray import RayBackend
store = sys.argv[1]
marker = store + ".kill-one-worker"
open(marker, "w").close()
def dies_once(x):
    # runs on a worker, once per block: kill this worker once, after two blocks are done
    import zarr
    done = int(np.asarray(zarr.open_group(store, mode="r")["_jaxbal"]["done"][:]).sum())
    if done >= 2 and os.path.exists(marker):
        try:
            os.remove(marker)
        except FileNotFoundError:
            return x
        with open(store + ".killed", "w") as f:
            f.write(str(os.getpid()))
        os.kill(os.getpid(), signal.SIGKILL)
    return x
def metric(robot, motion):
    value = jaxbal.design.METRICS["peak_force"](robot, motion)
    return jax.pure_callback(dies_once, jax.ShapeDtypeStruct((), jnp.float64), value,
                             vmap_method="broadcast_all")
axes = {"counter_mass": np.linspace(0, 3, 16), "payload": np.linspace(0, 1, 8)}
local = jaxbal.sweep(jaxbal.design.METRICS["peak_force"], robot, motion, axes, chunk_size=16,
                     progress=False)
ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
backend = RayBackend(max_retries=3)
remote = jaxbal.sweep(metric, robot, motion, axes, chunk_size=16, store=store, backend=backend,
                      progress=False)
killed = open(store + ".killed").read() if os.path.exists(store + ".killed") else None
print(json.dumps({"equal": bool(np.array_equal(local["value"].values, remote["value"].values)),
                  "blocks": remote.attrs["blocks_done"], "killed": killed,
                  "workers": len({w for w in [killed] if w})}))
ray.shutdown()
"""


@pytest.mark.slow  # a Ray cluster in a fresh interpreter (~40 s): make test-all
def test_ray_two_workers_equal_local_after_a_worker_is_killed(tmp_path):
    store = str(tmp_path / "ray.zarr")
    result = _json(_child(RAY.replace("sys.argv[1]", repr(store)), timeout=400))
    assert result["killed"] is not None  # a worker really died mid-sweep
    assert result["blocks"] == "8/8"
    assert result["equal"]


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_sweeps_in_a_loop_keep_a_bounded_number_of_programs(arm, monkeypatch):
    """Each sweep with a new ``where=`` lambda is a program of its own; the module-level
    jits kept every one (thousands in a loop crashed XLA's compiler: the kernel's
    memory-map count ran out). Their caches stay within MAX_PROGRAMS (2 here)."""
    from jaxbal._src import sweep_affine, sweep_program

    robot, motion = arm
    monkeypatch.setattr(sweep_program, "MAX_PROGRAMS", 2)
    jits = (sweep_program.run_chunk, sweep_affine._linearise, sweep_affine._direct)
    for k in range(4):
        axes = {"m": jaxbal.sweep.grid([1.0 + k], where=lambda r: r.masses)}
        for fold, linear in ((True, "auto"), (False, False)):
            jaxbal.sweep("peak_force", robot, motion, axes, progress=False, fold=fold,
                         linear=linear)  # fmt: skip
        assert all(f._cache_size() <= 2 for f in jits), [f._cache_size() for f in jits]
    assert sweep_program.PROGRAM_JITS[:2] == [sweep_program.run_chunk, sweep_program._single]
    assert {sweep_affine._linearise, sweep_affine._direct} <= set(sweep_program.PROGRAM_JITS)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_swept_geometry_that_opens_the_loops_of_a_fixed_motion_is_refused():
    """The Orthoglide's parallelogram length swept along a motion solved for 0.31 m: the
    states leave the loop closures, and the torques were finite and wrong (3e42 N·m at
    1e-8 of the length, make fuzz). Refused naming the axis; a swept mass passes, and
    so does the length at its own value."""
    robot = jaxbal.robots.orthoglide(payload=1.0)
    line = jaxbal.StraightLine(jnp.zeros(3), jnp.full(3, 0.02), jaxbal.profiles.Quintic(), 0.2)
    move = jaxbal.planning.EndEffectorLine(robot, line)
    motion = motion_samples(robot, move, jaxbal.sample_times(0.2, 21))
    length = {"L": jaxbal.sweep.grid([0.31, 0.35], where=lambda r: r.length)}
    with pytest.raises(ValueError, match=r"axis 'L' changes the geometry of Orthoglide: at"):
        jaxbal.sweep("peak_torque", robot, motion, length, progress=False)
    mass = {"m": jaxbal.sweep.grid([0.5, 1.0], where=lambda r: r.platform_mass)}
    ds = jaxbal.sweep("peak_torque", robot, motion, mass, progress=False)
    assert np.all(np.isfinite(ds["value"].values))
    same = {"L": jaxbal.sweep.grid([0.31], where=lambda r: r.length)}
    ds = jaxbal.sweep("peak_torque", robot, motion, same, progress=False)
    expected = jaxbal.design.peak_torque(robot, motion)
    np.testing.assert_allclose(ds["value"].values, [expected], rtol=1e-12)


RAY_CHECK = """
from jaxbal._src.sweep_ray import RayBackend
negative = {"m": jaxbal.sweep.grid([1.0, -1.0], where=lambda r: r.masses)}
backend = RayBackend(init={"num_cpus": 1, "include_dashboard": False, "log_to_driver": False})
try:
    jaxbal.sweep("peak_force", robot, motion, negative, backend=backend, progress=False)
except Exception as error:
    print(json.dumps({"type": type(error).__name__, "message": str(error)}))
"""


@pytest.mark.slow  # a Ray cluster in a fresh interpreter (~20 s): make test-all
def test_ray_backend_reports_a_failing_check_like_the_local_one():
    """Was a ``RayTaskError(JaxRuntimeError)`` where the local backend raises the
    ``ValueError`` naming the block (``jaxbal sweep --backend ray``: a traceback)."""
    pytest.importorskip("ray")
    result = _json(_child(RAY_CHECK, timeout=300))
    assert result["type"] == "ValueError", result
    assert result["message"].startswith("sweep block 0 (m in [-1, 1]): body masses must be")
