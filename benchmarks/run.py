"""jaxbal benchmarks: the generic shaking wrench on the five robots, gradients, compile
latency (cold and warm processes), co-design against SciPy and a DUAL-V design sweep
against Python loops, all in one run.

Run with ``make bench``; results go to ``benchmarks/results/bench_<backend>.json``
(atomic write) and the table between the bench markers of README.md. Ratios are always
against a baseline measured in the same run (wrench_bench.py, codesign_bench.py,
first_call.py, sweep_bench.py document each one). Targets are stated beside the measured
values; they are never asserted by the tests. ``--only sweep|codesign|first_call`` reruns
one section alone and merges it into the stored JSON (then rewrites the README block).
"""

from __future__ import annotations

import os

# Expose every CPU core as a JAX device (before JAX is imported) so the throughput
# benchmark can shard states over them; on a GPU this has no effect.
os.environ.setdefault("XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count() or 1}")
# In-process first calls (first grad, first torques, co-design with compilation) are
# measured cold: with the user's persistent compilation cache they would depend on
# earlier runs. The fresh-process measurements set their own, new cache directories.
os.environ["JAXBAL_CACHE_DIR"] = "off"

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from jaxbal.report import atomic_write_text  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import wrench_bench  # noqa: E402
from cases import MOVES  # noqa: E402
from readme_block import TARGETS, update_readme  # noqa: E402

#: pairs of fresh processes (cold, then warm on the same new cache) per robot and check
#: mode; each time reported is the median over the pairs (one pair's first calls varied
#: by up to 30 % from one run to the next on the 2-core CPU)
FIRST_CALL_PAIRS = 3


def first_calls(name: str, checks: bool) -> dict:
    """First-call latency of fresh processes: :data:`FIRST_CALL_PAIRS` pairs, each a
    cold process and a warm one sharing a new compilation cache; the median of each
    time over the pairs."""
    command = [sys.executable, str(HERE / "first_call.py"), name]
    command += [] if checks else ["--no-checks"]
    pairs = []
    for _ in range(FIRST_CALL_PAIRS):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, JAXBAL_CACHE_DIR=cache, PYTHONPATH=str(HERE))
            env.pop("XLA_FLAGS", None)
            runs = []
            for _ in range(2):
                out = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
                runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
        pairs.append(runs)
    return {
        mode: {key: float(np.median([runs[i][key] for runs in pairs])) for key in pairs[0][i]}
        for i, mode in enumerate(("cold", "warm"))
    }


def sweep_section(designs: int, budget_mib: float) -> dict:
    """The DUAL-V design sweep against Python loops, in a fresh process (sweep_bench.py:
    its first call compiles, its resident memory is its own)."""
    env = dict(os.environ, JAXBAL_CACHE_DIR="off", PYTHONPATH=str(HERE))
    command = [sys.executable, str(HERE / "sweep_bench.py"), "--designs", str(designs)]
    command += ["--budget-mib", str(budget_mib)]
    out = subprocess.run(command, env=env, stdout=subprocess.PIPE, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def codesign_section() -> dict:
    """Co-design against SciPy SLSQP (codesign_bench.py) in a fresh process with JAX's
    default devices (see codesign_bench's doc) and no persistent compilation cache."""
    env = dict(os.environ, JAXBAL_CACHE_DIR="off", PYTHONPATH=str(HERE))
    env.pop("XLA_FLAGS", None)
    command = [sys.executable, str(HERE / "codesign_bench.py"), "all"]
    out = subprocess.run(command, env=env, stdout=subprocess.PIPE, text=True, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def machine() -> dict:
    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "mujoco": mujoco.__version__,
        "devices": [str(d) for d in jax.devices()],
    }


def run(args) -> dict:
    robots = args.robots or list(MOVES)
    result = {"machine": machine(), "targets": TARGETS, "robots": {}}
    for name in robots:
        count = args.states if name == "planar_2r" else args.states // 5
        print(f"[bench] {name}: {count:,} states", flush=True)
        result["robots"][name] = wrench_bench.bench_robot(
            name, count, args.loop_states, args.mjx_states, args.chunk
        )
    print("[bench] chunk sizes (2R)", flush=True)
    result["chunk_scan_2r_states_per_second"] = wrench_bench.chunk_scan(
        "planar_2r", args.states // 2
    )
    print("[bench] first calls in fresh processes", flush=True)
    result["first_call"] = {
        name: {"checks_on": first_calls(name, True), "checks_off": first_calls(name, False)}
        for name in robots
    }
    print("[bench] co-design vs SciPy SLSQP", flush=True)
    result["codesign"] = codesign_section()
    print("[bench] DUAL-V design sweep vs Python loops", flush=True)
    result["sweep"] = sweep_section(args.sweep_designs, args.sweep_budget_mib)
    return result


def merge_section(args, path: Path) -> dict:
    """The stored result of ``path`` with one section (and the targets) measured anew."""
    if not path.exists():
        raise SystemExit(f"--only merges into {path}, which does not exist: run all first")
    result = json.loads(path.read_text())
    result["targets"] = TARGETS
    if args.only == "sweep":
        print("[bench] DUAL-V design sweep vs Python loops", flush=True)
        result["sweep"] = sweep_section(args.sweep_designs, args.sweep_budget_mib)
    elif args.only == "codesign":
        print("[bench] co-design vs SciPy SLSQP", flush=True)
        result["codesign"] = codesign_section()
    else:
        print("[bench] first calls in fresh processes", flush=True)
        result["first_call"] = {
            name: {"checks_on": first_calls(name, True), "checks_off": first_calls(name, False)}
            for name in MOVES
        }
    return result


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=HERE / "results")
    parser.add_argument("--states", type=int, default=1_000_000)
    parser.add_argument("--loop-states", type=int, default=2_000)
    parser.add_argument("--mjx-states", type=int, default=10_000)
    parser.add_argument("--chunk", type=int, default=1024)
    parser.add_argument("--robots", nargs="*", choices=list(MOVES))
    parser.add_argument("--readme", type=Path, default=HERE.parent / "README.md")
    parser.add_argument("--sweep-designs", type=int, default=500)
    parser.add_argument("--sweep-budget-mib", type=float, default=64.0)
    parser.add_argument(
        "--only", choices=["sweep", "codesign", "first_call"], help="rerun one section, merge it"
    )
    args = parser.parse_args()
    path = args.out / f"bench_{jax.default_backend()}.json"
    result = merge_section(args, path) if args.only else run(args)
    text = json.dumps(result, indent=2)
    atomic_write_text(path, text + "\n")
    print(text)
    if args.readme.exists() and not args.robots:
        update_readme(args.readme, result)


if __name__ == "__main__":
    main()
