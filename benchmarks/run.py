"""jaxbal benchmarks: the generic shaking wrench on the five robots, gradients, compile
latency (cold and warm processes), co-design against SciPy and a DUAL-V design sweep
against Python loops, all in one run.

Run with ``make bench``; results go to ``benchmarks/results/bench_<backend>.json``
(atomic write) and the table between the bench markers of README.md. Ratios are always
against a baseline measured in the same run (wrench_bench.py, codesign_bench.py,
first_call.py, sweep_bench.py document each one). Targets are stated beside the measured
values; they are never asserted by the tests. ``--only sweep|codesign|first_call`` reruns
one section alone and merges it into the stored JSON (then rewrites the README block).

While it runs, each section (each robot of the per-robot ones) is saved as it completes
to ``bench_<backend>.partial.json`` beside the result (atomically), which becomes the
result at the end: a run stopped part-way keeps what it measured and leaves the stored
result and the README as they were.

``--quick`` (``make bench-quick``) is a smoke run: small sizes for every section, written
to a temporary folder; it never writes into ``benchmarks/results`` nor the README (its
numbers are not benchmarks). It took 10 min on the 2-core CPU while other jobs kept it
busy (load 3-3.5): compilation, which small sizes do not shorten (MJX's ~20 s per robot,
20 fresh first-call processes of ~10 s, run two at a time); ``--robots`` shortens it.
"""

from __future__ import annotations

import os

if __name__ == "__main__":
    # Expose every CPU core as a JAX device (before JAX is imported) so the throughput
    # benchmark can shard states over them; on a GPU this has no effect.
    os.environ.setdefault(
        "XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count() or 1}"
    )
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
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402
from concurrent.futures import ThreadPoolExecutor  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

from jaxbal.report import atomic_write_text  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import wrench_bench  # noqa: E402
from arguments import ROBOTS, command_line, count, positive_float, positive_int  # noqa: E402
from readme_block import TARGETS, update_readme  # noqa: E402

#: the stored results of full runs (never written by ``--quick``)
RESULTS = HERE / "results"
#: where ``--quick`` writes by default
QUICK_OUT = Path(tempfile.gettempdir()) / "jaxbal-bench-quick"

#: each size option's default in a full run (``make bench``) and with ``--quick``
SIZES = {
    "states": (1_000_000, 5_000),
    # --quick: a chunk of as many states as each robot but the 2R has, which the MuJoCo
    # and MJX comparisons take too, so that one compiled program serves them all (the
    # first call is timed on one chunk; other sizes compile anew)
    "loop_states": (2_000, 1_000),
    "mjx_states": (10_000, 1_000),
    "chunk": (1024, 1_000),
    # pairs of fresh processes (cold, then warm on the same new cache) per robot and
    # check mode; each time reported is the median over the pairs (one pair's first
    # calls varied by up to 30 % from one run to the next on the 2-core CPU)
    "first_call_pairs": (3, 1),
    "first_call_jobs": (1, 2),
    "codesign_repeats": (5, 1),
    "codesign_fresh_runs": (3, 1),
    "sweep_designs": (500, 20),
    "sweep_budget_mib": (64.0, 4.0),
    "sweep_repeats": (3, 1),
}


def _json_line(command: list[str], env: dict, quiet: bool = False) -> dict:
    """The JSON of the last line that ``command`` prints; its stderr is shown (or, when
    ``quiet``, only if it fails) and a failure stops the run with its exit status."""
    out = subprocess.run(
        command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE if quiet else None
    )
    if out.returncode:
        detail = out.stderr.decode(errors="replace")[-4000:] if quiet else ""
        raise SystemExit(f"[bench] {' '.join(command)} failed ({out.returncode})\n{detail}")
    return json.loads(out.stdout.decode().strip().splitlines()[-1])


def first_calls(name: str, checks: bool, pairs: int) -> dict:
    """First-call latency of fresh processes: ``pairs`` pairs, each a cold process and
    a warm one sharing a new compilation cache; the median of each time over the
    pairs."""
    command = [sys.executable, str(HERE / "first_call.py"), name]
    command += [] if checks else ["--no-checks"]
    runs_of_pairs = []
    for _ in range(pairs):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, JAXBAL_CACHE_DIR=cache, PYTHONPATH=str(HERE))
            env.pop("XLA_FLAGS", None)
            runs_of_pairs.append([_json_line(command, env, quiet=True) for _ in range(2)])
    return {
        mode: {
            key: float(np.median([runs[i][key] for runs in runs_of_pairs]))
            for key in runs_of_pairs[0][i]
        }
        for i, mode in enumerate(("cold", "warm"))
    }


def first_call_section(robots, pairs: int, jobs: int, save: Callable[[], None], into: dict) -> None:
    """Fill ``into`` with each robot's first calls, checks on and off, calling ``save``
    after each robot; ``jobs`` of the (robot, check mode) measurements at a time."""
    pool = ThreadPoolExecutor(max_workers=jobs)
    try:
        futures = {
            (name, checks): pool.submit(first_calls, name, checks, pairs)
            for name in robots
            for checks in (True, False)
        }
        for name in robots:
            into[name] = {
                "checks_on": futures[name, True].result(),
                "checks_off": futures[name, False].result(),
            }
            save()
    finally:  # stopped: start no more processes
        pool.shutdown(cancel_futures=True)


def logger() -> Callable[[str], None]:
    """``log(text)``: print ``text`` with the seconds since this call."""
    began = time.perf_counter()

    def log(text: str) -> None:
        print(f"[bench {time.perf_counter() - began:5.0f} s] {text}", flush=True)

    return log


def sweep_section(designs: int, budget_mib: float, repeats: int) -> dict:
    """The DUAL-V design sweep against Python loops, in a fresh process (sweep_bench.py:
    its first call compiles, its resident memory is its own)."""
    env = dict(os.environ, JAXBAL_CACHE_DIR="off", PYTHONPATH=str(HERE))
    command = [sys.executable, str(HERE / "sweep_bench.py"), "--designs", str(designs)]
    command += ["--budget-mib", str(budget_mib), "--repeats", str(repeats)]
    return _json_line(command, env)


def codesign_section(repeats: int, fresh_runs: int) -> dict:
    """Co-design against SciPy SLSQP (codesign_bench.py) in a fresh process with JAX's
    default devices (see codesign_bench's doc) and no persistent compilation cache."""
    env = dict(os.environ, JAXBAL_CACHE_DIR="off", PYTHONPATH=str(HERE))
    env.pop("XLA_FLAGS", None)
    command = [sys.executable, str(HERE / "codesign_bench.py"), "all"]
    command += ["--repeats", str(repeats), "--fresh-runs", str(fresh_runs)]
    return _json_line(command, env)


def machine() -> dict:
    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "mujoco": mujoco.__version__,
        "devices": [str(d) for d in jax.devices()],
    }


def run(args, save: Callable[[dict], None]) -> dict:
    """Every section, ``save(result)`` after each (and after each robot)."""
    robots, log = args.robots or list(ROBOTS), logger()
    result = {"machine": machine(), "targets": TARGETS}
    if args.quick:
        result["quick"] = True  # smoke-run sizes: never a README table
    result["robots"] = {}
    for name in robots:
        states = args.states if name == "planar_2r" else args.states // 5
        log(f"{name}: {states:,} states")
        result["robots"][name] = wrench_bench.bench_robot(
            name, states, args.loop_states, args.mjx_states, args.chunk
        )
        save(result)
    log("chunk sizes (2R)")
    result["chunk_scan_2r_states_per_second"] = wrench_bench.chunk_scan(
        "planar_2r", args.states // 2
    )
    save(result)
    log("first calls in fresh processes")
    result["first_call"] = {}
    first_call_section(
        robots,
        args.first_call_pairs,
        args.first_call_jobs,
        lambda: save(result),
        result["first_call"],
    )
    log("co-design vs SciPy SLSQP")
    result["codesign"] = codesign_section(args.codesign_repeats, args.codesign_fresh_runs)
    save(result)
    log("DUAL-V design sweep vs Python loops")
    result["sweep"] = sweep_section(args.sweep_designs, args.sweep_budget_mib, args.sweep_repeats)
    log("done")
    return result


def merge_section(args, path: Path) -> dict:
    """The stored result of ``path`` with one section (and the targets) measured anew."""
    if not path.exists():
        raise SystemExit(f"--only merges into {path}, which does not exist: run all first")
    result = json.loads(path.read_text())
    result["targets"] = TARGETS
    log = logger()
    if args.only == "sweep":
        log("DUAL-V design sweep vs Python loops")
        result["sweep"] = sweep_section(
            args.sweep_designs, args.sweep_budget_mib, args.sweep_repeats
        )
    elif args.only == "codesign":
        log("co-design vs SciPy SLSQP")
        result["codesign"] = codesign_section(args.codesign_repeats, args.codesign_fresh_runs)
    else:
        log("first calls in fresh processes")
        result["first_call"] = {}
        first_call_section(
            ROBOTS, args.first_call_pairs, args.first_call_jobs, lambda: None, result["first_call"]
        )
    log("done")
    return result


def parser() -> argparse.ArgumentParser:
    parser = command_line("run.py", __doc__)

    def sized(option: str, kind, metavar: str, text: str) -> None:
        full, quick = SIZES[option.removeprefix("--").replace("-", "_")]
        parser.add_argument(
            option,
            type=kind,
            metavar=metavar,
            help=f"{text} (default: {full:,}; with --quick: {quick:,})",
        )

    parser.add_argument(
        "--quick",
        action="store_true",
        help="smoke run: every size option not given takes its --quick value; the result "
        f"goes to --out (default: {QUICK_OUT}), never into benchmarks/results, and the "
        "README is left alone",
    )
    parser.add_argument(
        "--out",
        type=Path,
        metavar="FOLDER",
        help="folder of bench_<backend>.json and, while running, bench_<backend>.partial.json "
        f"(default: benchmarks/results; with --quick: {QUICK_OUT})",
    )
    parser.add_argument(
        "--readme",
        type=Path,
        metavar="FILE",
        help="README whose bench block is rewritten from the result (default: the "
        "repository's README.md; left alone with --robots or --quick, which refuses this "
        "option)",
    )
    parser.add_argument(
        "--robots",
        nargs="+",
        choices=ROBOTS,
        metavar="ROBOT",
        help="robots of the wrench and first-call sections (default: all five: "
        f"{', '.join(ROBOTS)}); a subset leaves the README alone",
    )
    sized(
        "--states",
        positive_int,
        "N",
        "states of planar_2r's wrench benchmark; the other robots take a fifth, the 2R "
        "chunk-size scan half",
    )
    sized(
        "--loop-states",
        positive_int,
        "N",
        "states per robot of the MuJoCo C mj_inverse Python loop (timed and compared)",
    )
    sized("--mjx-states", positive_int, "N", "states per robot of the MJX inverse benchmark")
    sized("--chunk", positive_int, "N", "states per chunk of the chunked jit(vmap)")
    sized(
        "--first-call-pairs",
        positive_int,
        "N",
        "pairs of fresh processes (cold, then warm on a new compilation cache) per robot and "
        "runtime-check mode; each first-call time [s] is their median",
    )
    sized(
        "--first-call-jobs",
        positive_int,
        "N",
        "first-call measurements (robot and check mode, each its pairs in turn) run at a "
        "time; above 1 their times contend for the cores (smoke runs)",
    )
    sized(
        "--codesign-repeats",
        positive_int,
        "N",
        "compiled co-design runs of each method per problem; their median time [s] is reported",
    )
    sized(
        "--codesign-fresh-runs",
        count,
        "N",
        "fresh processes per co-design problem and method timing the first co-design; their "
        "median [s] is reported, 0 leaves it out",
    )
    sized(
        "--sweep-designs",
        positive_int,
        "N",
        "counter-mass designs of the DUAL-V sweep, each over 20 payloads × 1,000 samples",
    )
    sized(
        "--sweep-budget-mib",
        positive_float,
        "MIB",
        "memory budget [MiB] of the sweeps that are cut into blocks",
    )
    sized(
        "--sweep-repeats",
        positive_int,
        "N",
        "interleaved rounds of warm sweep calls; the best time [s] of each case is reported",
    )
    parser.add_argument(
        "--only",
        choices=["sweep", "codesign", "first_call"],
        help="rerun one section (first_call: all five robots) and merge it into the stored "
        "bench_<backend>.json of --out, then rewrite the README block",
    )
    return parser


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The parsed command line, sizes filled in (full or ``--quick``), ``out`` and
    ``readme`` resolved (``readme`` is ``None`` where the README is left alone)."""
    cli = parser()
    args = cli.parse_args(argv)
    for name, (full, quick) in SIZES.items():
        if getattr(args, name) is None:
            setattr(args, name, quick if args.quick else full)
    robots = args.robots or list(ROBOTS)
    smallest = args.states if robots == ["planar_2r"] else args.states // 5
    for option in ("loop_states", "mjx_states"):
        if getattr(args, option) > smallest:
            cli.error(
                f"--{option.replace('_', '-')} {getattr(args, option):,} exceeds the states of "
                f"the smallest wrench benchmark ({smallest:,}: --states / 5)"
            )
    if args.quick:
        if args.readme is not None:
            cli.error("--quick never writes the README: its numbers are smoke-test sizes")
        args.out = QUICK_OUT if args.out is None else args.out
        if args.out.resolve() == RESULTS.resolve():
            cli.error(
                f"--quick never writes into {RESULTS}: its numbers are smoke-test sizes; "
                "pick another --out"
            )
    else:
        args.out = RESULTS if args.out is None else args.out
        if args.robots:  # a subset of the robots: not the README's table
            args.readme = None
        elif args.readme is None:
            args.readme = HERE.parent / "README.md"
    return args


def main(argv: list[str] | None = None) -> None:
    args = parse_args(argv)
    path = args.out / f"bench_{jax.default_backend()}.json"
    if args.only:
        result = merge_section(args, path)
    else:
        partial = path.with_name(f"{path.stem}.partial.json")
        print(f"[bench] each section is saved to {partial} as it completes", flush=True)

        def save(result: dict) -> None:
            atomic_write_text(partial, json.dumps(result, indent=2) + "\n")

        try:
            result = run(args, save)
        except BaseException:
            if partial.exists():
                print(f"[bench] stopped: what was measured is in {partial}", file=sys.stderr)
            raise
    text = json.dumps(result, indent=2)
    atomic_write_text(path, text + "\n")
    if not args.only:
        partial.unlink(missing_ok=True)
    print(text)
    if args.readme is not None and args.readme.exists() and not result.get("quick"):
        update_readme(args.readme, result)


if __name__ == "__main__":
    main()
