"""The README quotes the stored benchmark result: its bench block equals the block
rendered from benchmarks/results/bench_cpu.json (run `make bench` to refresh both); the
stored design sweep has the size of issue 11, agrees with its loops, and its target flags
follow from its numbers."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from readme_block import BENCH_END, BENCH_START, bench_block  # noqa: E402


def test_readme_bench_block_equals_the_stored_result():
    result = json.loads((ROOT / "benchmarks" / "results" / "bench_cpu.json").read_text())
    readme = (ROOT / "README.md").read_text()
    start, end = readme.index(BENCH_START), readme.index(BENCH_END) + len(BENCH_END)
    assert readme[start:end] == bench_block(result)


def test_stored_result_covers_the_five_robots_and_agrees_with_mujoco():
    result = json.loads((ROOT / "benchmarks" / "results" / "bench_cpu.json").read_text())
    assert set(result["robots"]) == {"planar_2r", "planar_3r", "scara", "dual_v", "orthoglide"}
    for name, robot in result["robots"].items():
        assert robot["max_relative_difference_vs_mujoco"] < 1e-9, name
        torques = robot["torques"]  # the two formulations agree, and with MuJoCo C
        assert torques["max_relative_difference_vs_before"] < 1e-12, name
        assert torques.get("max_relative_difference_vs_mujoco", 0.0) < 1e-9, name


def test_stored_sweep_covers_the_issue_size_agrees_with_the_loops_and_states_its_targets():
    result = json.loads((ROOT / "benchmarks" / "results" / "bench_cpu.json").read_text())
    sweep = result["sweep"]
    assert sweep["designs"] >= 100 and sweep["payloads"] >= 20 and sweep["samples"] >= 1000
    assert sweep["direct"]["blocks"] > 1  # the budget cuts the direct sweep into blocks
    assert sweep["direct"]["max_relative_difference_vs_affine"] < 1e-12
    for name, loop in sweep["baselines"].items():
        assert loop["max_relative_difference_vs_sweep"] < 1e-12, name
    target = result["targets"]["sweep_speedup_vs_design_loop"]
    assert sweep["speedup_target_met"] == (sweep["speedup_vs_loop"] >= target)
    memory = sweep["block_memory_per_device"]["total_bytes"]
    assert sweep["memory_within_budget"] == (memory <= sweep["memory_budget_bytes"])
    memory = sweep["direct"]["block_memory_per_device"]["total_bytes"]
    assert sweep["direct"]["memory_within_budget"] == (memory <= sweep["memory_budget_bytes"])


def test_chunked_harness_equals_vmap_when_the_chunk_does_not_divide_the_states():
    # the benchmark's chunked loop slices the inputs in place; its last chunk overlaps
    # the one before it: every state must still be evaluated once, in its own row
    import jax
    import jax.numpy as jnp
    from cases import chunked

    def fn(q, qd, qdd):
        return q * qd[0] + qdd, jnp.sum(q * qdd)  # exact in floating point

    states = [jnp.arange(3.0 * 10).reshape(10, 3) * k for k in (1.0, 0.5, -2.0)]
    for chunk in (1, 3, 4, 10, 16):
        ours, reference = chunked(fn, chunk)(*states), jax.vmap(fn)(*states)
        for a, b in zip(ours, reference, strict=True):
            assert a.shape == b.shape
            assert jnp.array_equal(a, b), chunk


# --- the benchmark scripts' command lines and run.py's result files ---------------------

STORED = ROOT / "benchmarks" / "results" / "bench_cpu.json"


def test_every_robot_name_of_the_command_lines_has_a_benchmark_move():
    from arguments import ROBOTS
    from cases import MOVES

    assert tuple(MOVES) == ROBOTS


@pytest.mark.parametrize("script", ["first_call.py", "codesign_bench.py", "run.py"])
def test_scripts_print_their_usage(script):
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / script), "--help"],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.startswith(f"usage: {script}") and "options:" in out.stdout


def test_every_argument_of_the_scripts_has_help_text():
    import codesign_bench
    import first_call
    import run

    for parser in (first_call.parser(), codesign_bench.parser(), run.parser()):
        for action in parser._actions:
            assert action.help and len(action.help) > 20, (parser.prog, action.dest)


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        ([], "the following arguments are required: ROBOT"),
        (["planar2r"], "invalid choice: 'planar2r' (choose from 'planar_2r', 'planar_3r'"),
    ],
)
def test_first_call_rejects_a_missing_or_misspelled_robot_with_the_valid_names(argv, message):
    # a subprocess: the script parses its arguments before importing JAX (fast)
    out = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "first_call.py"), *argv],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert out.returncode == 2
    assert out.stderr.startswith("usage: first_call.py") and message in out.stderr
    assert "Traceback" not in out.stderr


def test_first_call_parser_takes_a_robot_and_the_check_switch():
    import first_call

    args = first_call.parser().parse_args(["dual_v", "--no-checks"])
    assert args.robot == "dual_v" and args.no_checks
    assert not first_call.parser().parse_args(["scara"]).no_checks


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["scara"], "PROBLEM 'scara' needs a METHOD: jaxbal or scipy"),
        (["all", "scipy"], "PROBLEM 'all' runs both methods"),
        (["scara_x", "jaxbal"], "invalid choice: 'scara_x' (choose from 'all', 'scara'"),
        (["scara", "optax"], "invalid choice: 'optax' (choose from 'jaxbal', 'scipy')"),
        (["all", "--repeats", "0"], "must be at least 1"),
        (["all", "--fresh-runs", "-1"], "must be at least 0"),
    ],
)
def test_codesign_bench_rejects_bad_arguments_with_a_usage_message(argv, message, capsys):
    import codesign_bench

    with pytest.raises(SystemExit) as exit_:
        codesign_bench.main(argv)
    assert exit_.value.code == 2
    error = capsys.readouterr().err
    assert error.startswith("usage: codesign_bench.py") and message in error


def test_run_sizes_default_to_a_full_run_and_to_small_ones_with_quick():
    import run

    full = run.parse_args([])
    assert full.out == run.RESULTS and full.readme == ROOT / "README.md"
    quick = run.parse_args(["--quick"])
    assert quick.out == run.QUICK_OUT and quick.readme is None
    for name, (full_size, quick_size) in run.SIZES.items():
        assert getattr(full, name) == full_size and getattr(quick, name) == quick_size
        if name != "first_call_jobs":  # the one concurrency, not a size
            assert quick_size <= full_size, name
    explicit = run.parse_args(["--quick", "--states", "20000", "--out", "elsewhere"])
    assert explicit.states == 20_000 and explicit.out == Path("elsewhere")
    assert run.parse_args(["--robots", "scara"]).readme is None  # a subset: not the table


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--quick", "--readme", "README.md"], "--quick never writes the README"),
        (["--quick", "--out", str(ROOT / "benchmarks" / "results")], "--quick never writes"),
        (["--robots", "planar2r"], "invalid choice: 'planar2r' (choose from 'planar_2r'"),
        (["--states", "1000"], "--loop-states 2,000 exceeds the states"),
        (["--chunk", "0"], "must be at least 1"),
        (["--sweep-budget-mib", "nan"], "must be a finite number > 0"),
    ],
)
def test_run_rejects_bad_arguments_and_quick_writes_into_the_stored_results(argv, message, capsys):
    import run

    with pytest.raises(SystemExit) as exit_:
        run.parse_args(argv)
    assert exit_.value.code == 2
    error = capsys.readouterr().err
    assert error.startswith("usage: run.py") and message in error


def _stored_sections(monkeypatch, calls: dict, stop_at: str | None = None):
    """Replace run.py's measurements by the stored result's sections (recording their
    sizes in ``calls``); the section ``stop_at`` is interrupted."""
    import run

    stored = json.loads(STORED.read_text())

    def section(name, value):
        def measure(*args):
            calls.setdefault(name, []).append(args)
            if name == stop_at:
                raise KeyboardInterrupt
            return value(*args)

        return measure

    monkeypatch.setattr(
        run.wrench_bench,
        "bench_robot",
        section("robots", lambda name, *sizes: stored["robots"][name]),
    )
    monkeypatch.setattr(
        run.wrench_bench,
        "chunk_scan",
        section("chunk_scan", lambda *_: stored["chunk_scan_2r_states_per_second"]),
    )
    monkeypatch.setattr(
        run,
        "first_calls",
        section(
            "first_call",
            lambda name, checks, _: stored["first_call"][name][
                "checks_on" if checks else "checks_off"
            ],
        ),
    )
    monkeypatch.setattr(run, "codesign_section", section("codesign", lambda *_: stored["codesign"]))
    monkeypatch.setattr(run, "sweep_section", section("sweep", lambda *_: stored["sweep"]))
    return stored


def test_a_full_run_keeps_the_stored_schema_and_writes_the_readme_block(tmp_path, monkeypatch):
    import jax
    import run
    from readme_block import bench_block

    calls = {}
    stored = _stored_sections(monkeypatch, calls)
    readme = tmp_path / "README.md"
    readme.write_text(f"before\n{BENCH_START}\nold\n{BENCH_END}\nafter\n")
    run.main(["--out", str(tmp_path), "--readme", str(readme)])
    result = json.loads((tmp_path / f"bench_{jax.default_backend()}.json").read_text())
    assert list(result) == list(stored)  # the same sections, in the same order
    measured = ("robots", "chunk_scan_2r_states_per_second", "first_call", "codesign", "sweep")
    assert {k: result[k] for k in measured} == {k: stored[k] for k in measured}
    assert list(result["machine"]) == list(stored["machine"])
    assert readme.read_text() == f"before\n{bench_block(result)}\nafter\n"
    assert not list(tmp_path.glob("*.partial.json"))
    assert calls["robots"][0] == ("planar_2r", 1_000_000, 2_000, 10_000, 1024)
    assert calls["codesign"] == [(5, 3)] and calls["sweep"] == [(500, 64.0, 3)]
    assert {args[2] for args in calls["first_call"]} == {3}


def test_a_quick_run_uses_small_sizes_and_never_writes_the_readme(tmp_path, monkeypatch):
    import run

    calls = {}
    _stored_sections(monkeypatch, calls)
    monkeypatch.setattr(run, "update_readme", lambda *_: pytest.fail("README written"))
    run.main(["--quick", "--out", str(tmp_path)])
    (path,) = tmp_path.glob("bench_*.json")
    assert json.loads(path.read_text())["quick"] is True
    assert calls["robots"][0] == ("planar_2r", 5_000, 1_000, 1_000, 1_000)
    assert calls["robots"][1] == ("planar_3r", 1_000, 1_000, 1_000, 1_000)
    assert calls["chunk_scan"] == [("planar_2r", 2_500)]
    assert calls["codesign"] == [(1, 1)] and calls["sweep"] == [(20, 4.0, 1)]
    assert {args[2] for args in calls["first_call"]} == {1}


def test_a_run_stopped_in_the_codesign_section_keeps_the_sections_before_it(tmp_path, monkeypatch):
    import jax
    import run

    stored = _stored_sections(monkeypatch, {}, stop_at="codesign")
    final = tmp_path / f"bench_{jax.default_backend()}.json"
    final.write_text("{}\n")  # a stored result: left as it was
    with pytest.raises(KeyboardInterrupt):
        run.main(["--out", str(tmp_path), "--readme", str(tmp_path / "absent.md")])
    assert final.read_text() == "{}\n"
    partial = json.loads(final.with_name(f"{final.stem}.partial.json").read_text())
    assert partial["robots"] == stored["robots"]
    assert partial["first_call"] == stored["first_call"]
    assert "codesign" not in partial and "sweep" not in partial
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes leave no temporary file
