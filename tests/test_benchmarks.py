"""The README quotes the stored benchmark result: its bench block equals the block
rendered from benchmarks/results/bench_cpu.json (run `make bench` to refresh both); the
stored design sweep has the size of issue 11, agrees with its loops, and its target flags
follow from its numbers."""

import json
import sys
from pathlib import Path

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
