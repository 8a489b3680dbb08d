"""DUAL-V design sweep against Python loops (issue 11), in one fresh process.

``jaxbal.sweep`` of the peak shaking force over counter-mass designs (one mass per arm,
random in [0, 16] kg) × 20 payloads (0 … 0.5 kg) × 1,000 samples of a 0.1 s quintic
platform move (the joint states are held fixed while the design changes): by default
(the headline) with the affine fast path (masses enter the wrench linearly, verified by
the sweep), and with ``linear=False`` (the metric evaluated at every point and sample)
under a memory budget small enough to cut the sweep into several blocks; against three
Python loops
over the same designs calling a jitted evaluation of the same metric on the same
payloads and samples (values checked against the sweep):

* ``loop`` (the headline ratio): per design, ``jit(f)(robot, motion, counter_mass,
  payloads)``, ``f`` ``vmap``-ing the metric over the 20 payloads; the robot and the
  motion are arguments, as they are of the sweep's compiled program;
* ``loop_closure``: the same, robot, motion and payloads captured by the closure (XLA
  then specialises the program on the fixed joint states, as constants);
* ``loop_points``: ``jit(metric)`` called at every design × payload.

Times are the best of interleaved rounds of whole warm calls (the sweep's includes
planning its blocks and assembling the xarray result); beside them: the first calls
(trace + compile + run, compilation cache off) and the sweep at the default budget
(larger blocks). Memory:
XLA's memory analysis of one block's compiled program on one device (arguments,
temporaries, outputs) against the budget, which bounds what one device may use, and the
process's resident memory sampled during a warm sweep.

Prints one JSON line. Usage: ``python benchmarks/sweep_bench.py [--designs N]
[--budget-mib M]`` (run.py runs it).
"""

from __future__ import annotations

import os

os.environ.setdefault("XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count() or 1}")
os.environ.setdefault("JAXBAL_CACHE_DIR", "off")  # the first call compiles

import json  # noqa: E402
import math  # noqa: E402
import resource  # noqa: E402
import threading  # noqa: E402
import time  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import numpy as np  # noqa: E402
from arguments import command_line, positive_float, positive_int  # noqa: E402
from readme_block import SWEEP_LOOPS, TARGETS  # noqa: E402

import jaxbal  # noqa: E402
from jaxbal._src.sweep import prepare  # noqa: E402
from jaxbal._src.sweep_program import chunk_memory, put, run_chunk  # noqa: E402
from jaxbal.design import METRICS, motion_samples  # noqa: E402

METRIC = "peak_force"
PAYLOADS = np.linspace(0.0, 0.5, 20)  # [kg]
SAMPLES = 1000
MIB = 2**20


def dual_v_move():
    """The DUAL-V and 1,000 samples of its README move (platform poses u0 -> u1)."""
    robot = jaxbal.robots.dual_v()
    u0, u1 = jnp.array([0.0, -0.05, 0.0]), jnp.array([0.05, 0.05, 0.0])
    line = jaxbal.StraightLine(u0, u1, jaxbal.profiles.Quintic(), 0.1)
    move = jaxbal.planning.EndEffectorLine(robot, line)
    return robot, motion_samples(robot, [move], jaxbal.sample_times(0.1, SAMPLES))


def timed(fn):
    """``(seconds, value)`` of one call of ``fn`` (its arrays ready)."""
    start = time.perf_counter()
    value = jax.block_until_ready(fn())
    return time.perf_counter() - start, value


class PeakRSS:
    """Resident set size before a ``with`` block and its peak inside (sampled every
    millisecond from ``/proc/self/statm``; else ``getrusage``'s lifetime peak) [B]."""

    def __enter__(self):
        self.before = self.peak = self._now()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, daemon=True)
        self._thread.start()
        return self

    def __exit__(self, *exc):
        self._stop.set()
        self._thread.join()
        self.peak = max(self.peak, self._now())

    def _sample(self):
        while not self._stop.wait(0.001):
            self.peak = max(self.peak, self._now())

    @staticmethod
    def _now() -> int:
        try:
            with open("/proc/self/statm") as f:
                return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
        except OSError:
            return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024


def loops(robot, motion, designs: np.ndarray) -> dict:
    """``{name: (first call, whole loop)}``: the baselines, as functions of no argument
    (the loop returns the ``(designs, payloads)`` values)."""
    metric = METRICS[METRIC]
    payloads = jnp.asarray(PAYLOADS)

    def at(robot, motion, counter_mass, payload):
        return metric(robot.with_design({"counter_mass": counter_mass, "payload": payload}), motion)

    over_payloads = jax.jit(
        lambda r, m, c, p: jax.vmap(lambda x: at(r, m, c, x))(p)  # one design, all payloads
    )
    closure = jax.jit(lambda c: jax.vmap(lambda x: at(robot, motion, c, x))(payloads))
    point = jax.jit(at)
    return {
        "loop": (
            lambda: over_payloads(robot, motion, designs[0], payloads),
            lambda: np.stack(
                [np.asarray(over_payloads(robot, motion, c, payloads)) for c in designs]
            ),
        ),
        "loop_closure": (
            lambda: closure(designs[0]),
            lambda: np.stack([np.asarray(closure(c)) for c in designs]),
        ),
        "loop_points": (
            lambda: point(robot, motion, designs[0], PAYLOADS[0]),
            lambda: np.array(
                [[float(point(robot, motion, c, p)) for p in PAYLOADS] for c in designs]
            ),
        ),
    }


def block_memory(robot, motion, axes, dataset, linear) -> dict:
    """XLA's memory analysis of one block's compiled program on one device [B] and the
    sweep's own estimate it was sized from."""
    _, program, dynamic, _, _ = prepare(METRIC, robot, motion, axes, linear=linear)
    block = tuple(dataset["value"].encoding["chunks"])
    devices = program.mesh.size
    batch = math.ceil(math.prod(block) / devices) * devices
    designs = axes["design"].values["counter_mass"]
    params = {"counter_mass": np.repeat(designs[:1], batch, 0), "payload": np.repeat(0.0, batch)}
    stats = run_chunk.lower(program, dynamic, put(program, params)).compile().memory_analysis()
    per_point, fixed = chunk_memory(program, dynamic, {k: v[:1] for k, v in params.items()})
    total = stats.argument_size_in_bytes + stats.temp_size_in_bytes + stats.output_size_in_bytes
    point_bytes = sum(v[: batch // devices].nbytes for v in params.values())
    return {
        "block_shape": list(block),
        "block_points": math.prod(block),
        "points_per_device_per_call": batch // devices,
        "argument_bytes": stats.argument_size_in_bytes,
        "argument_bytes_of_the_points": point_bytes,
        "argument_bytes_shared_robot_and_motion": stats.argument_size_in_bytes - point_bytes,
        "temp_bytes": stats.temp_size_in_bytes,
        "output_bytes": stats.output_size_in_bytes,
        "total_bytes": total,
        "estimate_bytes_per_point": per_point,
        "estimate_fixed_bytes": fixed,
    }


def bench(n_designs: int, budget: int, repeats: int = 3, seed: int = 0) -> dict:
    robot, motion = dual_v_move()
    designs = np.random.default_rng(seed).uniform(0.0, 16.0, (n_designs, 4))  # [kg]
    axes = {
        "design": jaxbal.sweep.points({"counter_mass": designs}, units={"counter_mass": "kg"}),
        "payload": jaxbal.sweep.grid(PAYLOADS, units="kg"),
    }
    default = jaxbal.sweep.DEFAULT_MEMORY_BUDGET

    def sweep(budget=budget, linear="auto"):
        return jaxbal.sweep(
            METRIC, robot, motion, axes, memory_budget=budget, progress=False, linear=linear
        )

    def direct(budget=budget):
        return sweep(budget, linear=False)

    # First calls (trace + compile + run), then warm whole calls in interleaved rounds
    # (the best of each): a load change on a shared machine hits every case alike.
    cases = {
        "sweep": (sweep, sweep),
        "sweep_direct": (direct, direct),
        "sweep_default_budget": (lambda: direct(default),) * 2,
    }
    cases.update(loops(robot, motion, designs))
    first, values = {}, {}
    for name, (first_call, run) in cases.items():
        first[name] = timed(first_call)[0]
        values[name] = run()
    with PeakRSS() as fast_rss:
        sweep()
    with PeakRSS() as rss:
        direct()
    seconds = {name: [] for name in cases}
    for _ in range(repeats):
        for name, (_, run) in cases.items():
            seconds[name].append(timed(run)[0])
    best = {name: min(times) for name, times in seconds.items()}

    dataset, by_direct = values["sweep"], values["sweep_direct"]
    swept = dataset["value"].values
    states = n_designs * len(PAYLOADS) * SAMPLES
    memory = block_memory(robot, motion, axes, dataset, "auto")
    direct_memory = block_memory(robot, motion, axes, by_direct, False)
    blocks = int(dataset.attrs["blocks_done"].split("/")[1])
    direct_blocks = int(by_direct.attrs["blocks_done"].split("/")[1])
    result = {
        "robot": "dual_v",
        "metric": METRIC,
        "evaluation": dataset.attrs.get("evaluation", "direct"),
        "designs": n_designs,
        "payloads": len(PAYLOADS),
        "samples": SAMPLES,
        "states": states,
        "devices": jax.local_device_count(),
        "repeats": repeats,
        "memory_budget_bytes": budget,
        "blocks": blocks,
        "padded_points_last_block": blocks * memory["block_points"] - n_designs * len(PAYLOADS),
        "sweep_seconds": best["sweep"],
        "sweep_states_per_second": states / best["sweep"],
        "sweep_first_call_seconds": first["sweep"],
        "direct": {
            "description": "linear=False: the metric evaluated at every point and sample",
            "blocks": direct_blocks,
            "padded_points_last_block": direct_blocks * direct_memory["block_points"]
            - n_designs * len(PAYLOADS),
            "sweep_seconds": best["sweep_direct"],
            "sweep_states_per_second": states / best["sweep_direct"],
            "sweep_first_call_seconds": first["sweep_direct"],
            "speedup_vs_loop": best["loop"] / best["sweep_direct"],
            "max_relative_difference_vs_affine": float(
                np.max(np.abs(by_direct["value"].values - swept)) / np.max(np.abs(swept))
            ),
            "block_memory_per_device": direct_memory,
            "memory_within_budget": bool(direct_memory["total_bytes"] <= budget),
            "rss_before_bytes": rss.before,
            "rss_peak_bytes_during_warm_sweep": rss.peak,
            "rss_growth_bytes_during_warm_sweep": rss.peak - rss.before,
        },
        "default_budget": {
            "description": "linear=False at the default memory budget",
            "memory_budget_bytes": default,
            "blocks": int(values["sweep_default_budget"].attrs["blocks_done"].split("/")[1]),
            "first_call_seconds": first["sweep_default_budget"],
            "sweep_seconds": best["sweep_default_budget"],
            "sweep_states_per_second": states / best["sweep_default_budget"],
        },
        "baselines": {},
        "block_memory_per_device": memory,
        "rss_before_bytes": fast_rss.before,
        "rss_peak_bytes_during_warm_sweep": fast_rss.peak,
        "rss_growth_bytes_during_warm_sweep": fast_rss.peak - fast_rss.before,
    }
    for name in ("loop", "loop_closure", "loop_points"):
        result["baselines"][name] = {
            "description": SWEEP_LOOPS[name],
            "seconds": best[name],
            "states_per_second": states / best[name],
            "first_call_seconds": first[name],
            "speedup_of_sweep": best[name] / best["sweep"],
            "speedup_of_sweep_default_budget": best[name] / best["sweep_default_budget"],
            "max_relative_difference_vs_sweep": float(
                np.max(np.abs(values[name] - swept)) / np.max(np.abs(swept))
            ),
        }
    result["speedup_vs_loop"] = result["baselines"]["loop"]["speedup_of_sweep"]  # headline
    target = TARGETS["sweep_speedup_vs_design_loop"]
    result["speedup_target_met"] = bool(result["speedup_vs_loop"] >= target)
    result["memory_within_budget"] = bool(memory["total_bytes"] <= budget)
    shared = memory["argument_bytes_shared_robot_and_motion"]
    result["memory_within_budget_without_shared_arguments"] = bool(
        memory["total_bytes"] - shared <= budget
    )
    for part, peak in ((result, fast_rss), (result["direct"], rss)):
        part["rss_growth_over_budget_times_devices"] = (peak.peak - peak.before) / (
            budget * result["devices"]
        )
    return result


def main():
    parser = command_line("sweep_bench.py", __doc__)
    parser.add_argument(
        "--designs",
        type=positive_int,
        default=500,
        metavar="N",
        help="random counter-mass designs swept, each over 20 payloads × 1,000 samples "
        "(default: %(default)s)",
    )
    parser.add_argument(
        "--budget-mib",
        type=positive_float,
        default=64.0,
        metavar="MIB",
        help="memory budget of the sweeps that are cut into blocks [MiB] (default: %(default)s)",
    )
    parser.add_argument(
        "--repeats",
        type=positive_int,
        default=3,
        metavar="N",
        help="interleaved rounds of warm calls; the best time of each case is reported "
        "(default: %(default)s)",
    )
    args = parser.parse_args()
    result = bench(args.designs, int(args.budget_mib * MIB), args.repeats)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
