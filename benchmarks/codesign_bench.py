"""Co-design speed: ``jaxbal.design.codesign`` (L-BFGS-B driven from the host around one
compiled value-and-gradient, exact gradients) against ``scipy.optimize.minimize``
(SLSQP with finite-difference gradients) on the same objective, the same bounds and the
same start, in the same run.

Problems (each objective has an interior optimum, so both methods must agree):
- SCARA: the three counter-masses, distances fixed (Arakelian & Briot 2008 layout);
- DUAL-V: the four counter-masses, distances fixed (van der Wijk et al. 2013);
- a 10-link planar arm: ten counter-masses and ten distances (20 variables).
The objective is :class:`Objective` along a fixed motion. Times include compilation
(first call) and exclude it (the median of :data:`REPEATS` calls from a second start,
which reuse the compiled code). Accuracy: the relative difference of the two optimal objectives and
designs (a flat optimum, as on the 20-variable arm, shows in the design difference).

``benchmarks/run.py`` runs this section in a process of its own with JAX's default
devices (one CPU device, as in a user's notebook), not in run.py's process, which
splits the CPU into one device per core for the throughput benchmark: there both
methods ran ~2× slower after compilation (XLA's per-device thread pools contend for
the two cores), jaxbal's compiled 20-variable co-design 7.9 ms instead of 3.9 ms.

The times with compilation are also measured each in a fresh process with an empty
compilation cache (``python codesign_bench.py PROBLEM jaxbal|scipy``; the median of
three such processes), so that neither
method profits from what the other compiled or traced first in the same process.

Usage: ``python benchmarks/codesign_bench.py all [--repeats N] [--fresh-runs N]`` (the
whole section, one JSON line, as run.py runs it) or ``python benchmarks/codesign_bench.py
PROBLEM METHOD`` (one first co-design, ``{"seconds": …}``); ``--help`` for more.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from arguments import command_line, count, positive_int
from cases import robot_and_motion
from scipy.optimize import minimize as scipy_minimize

import jaxbal
from jaxbal._src.lbfgsb import one_blas_thread
from jaxbal.design import Motion, added_inertia, added_mass, base_inertia, codesign, rms_force


@dataclasses.dataclass(frozen=True)
class Objective:
    """``(rms_force/F)² + (added_mass/M)² + (added_inertia/I)²`` (dimensionless), with
    the bare robot's RMS force ``F`` [N], total mass ``M`` [kg] and base inertia ``I``
    [kg m²] as scales. Hashable: a static part of ``codesign``'s compiled structure."""

    force_scale: float
    mass_scale: float
    inertia_scale: float

    def __call__(self, robot, motion):
        return (
            (rms_force(robot, motion) / self.force_scale) ** 2
            + (added_mass(robot) / self.mass_scale) ** 2
            + (added_inertia(robot, motion) / self.inertia_scale) ** 2
        )


def make_objective(robot, motion) -> Objective:
    design = robot.design()
    bare = robot.with_design({n: jnp.zeros_like(design[n]) for n in ("counter_mass",)})
    return Objective(
        float(rms_force(bare, motion)),
        float(jaxbal.total_mass(bare)),
        float(base_inertia(bare, motion.q[0])),
    )


def arm_problem(links: int = 10, samples: int = 500):
    """A ``links``-link planar arm on a joint-space sinusoidal motion (no IK needed)."""
    lengths = np.linspace(0.3, 0.1, links)
    arm = jaxbal.robots.PlanarArm(
        lengths=lengths,
        com_ratios=np.full(links, 0.4),
        masses=10.0 * lengths,
        inertias=10.0 * lengths**3 / 12.0,
        payload=1.0,
        counter_distances=np.full(links, 0.1),
    )
    t = jnp.linspace(0.0, 0.5, samples)[:, None]
    amplitude, omega = jnp.linspace(0.8, 0.2, links), 2 * jnp.pi / 0.5
    phase = jnp.linspace(0.0, 1.0, links)
    q = amplitude * jnp.sin(omega * t + phase)
    qd = amplitude * omega * jnp.cos(omega * t + phase)
    qdd = -amplitude * omega**2 * jnp.sin(omega * t + phase)
    return arm, Motion(q, qd, qdd), ("counter_mass", "counter_distance")


def _built_in(name):
    robot, motion = robot_and_motion(name)
    return robot, motion, ("counter_mass",)


#: problem name -> constructor of ``(robot, motion, free names)``
PROBLEMS = {
    "scara": lambda: _built_in("scara"),
    "dual_v": lambda: _built_in("dual_v"),
    "planar_10r_20_variables": arm_problem,
}


def problems():
    return {name: make() for name, make in PROBLEMS.items()}


def _flat(design, free):
    return np.concatenate([np.ravel(np.asarray(design[n], dtype=float)) for n in free])


def _unflat(x, template, free):
    out, k = {}, 0
    for name in free:
        size = int(np.size(template[name]))
        out[name] = jnp.asarray(x[k : k + size]).reshape(np.shape(template[name]))
        k += size
    return out


def scipy_objective(objective, robot, motion, free):
    """The objective as a jitted function of the flat design vector (compiled on its
    first call, then shared by every SLSQP run of the problem)."""
    template = robot.design()

    @jax.jit
    def value(x):
        return objective(robot.with_design(_unflat(x, template, free)), motion)

    return value


def run_scipy(value, start, free, tol):
    """SLSQP with 2-point finite differences on the jitted objective ``value``; returns
    ``(x, seconds, evaluations)``."""
    evaluations = [0]

    def fun(x):
        evaluations[0] += 1
        return float(value(jnp.asarray(x)))

    x0 = _flat(start, free)
    bounds = [(0.0, None)] * x0.size
    began = time.perf_counter()
    # one BLAS thread, as jaxbal's co-design runs its host optimiser (jaxbal/_src/lbfgsb.py
    # wraps SciPy's L-BFGS-B alike above 64 variables): SLSQP's matrices are as small, and
    # OpenBLAS's spinning threads would fight XLA's
    with one_blas_thread():
        result = scipy_minimize(
            fun, x0, method="SLSQP", bounds=bounds, options={"ftol": tol, "maxiter": 2000}
        )
    return result.x, time.perf_counter() - began, evaluations[0]


def run_jaxbal(objective, robot, motion, free, start):
    began = time.perf_counter()
    solution = codesign(robot, motion, objective, free=free, start=start, max_steps=500, gtol=1e-12)
    jax.block_until_ready(solution.value)
    return _flat(solution.design, free), time.perf_counter() - began, solution


def _relative(a, b) -> float:
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


#: runs of each method from the second start (compiled); their median is reported (a
#: single few-millisecond run varied by up to 2× on the 2-core CPU)
REPEATS = 5


def bench_problem(robot, motion, free, repeats: int = REPEATS) -> dict:
    design = robot.design()
    start_a = {n: np.asarray(design[n], dtype=float) * 0.5 + 0.5 for n in free}
    start_b = {n: np.asarray(design[n], dtype=float) * 0.7 + 0.3 for n in free}
    objective = make_objective(robot, motion)
    x_j1, t_j1, _ = run_jaxbal(objective, robot, motion, free, start_a)
    value = scipy_objective(objective, robot, motion, free)
    x_s1, t_s1, evals_1 = run_scipy(value, start_a, free, 1e-16)
    # compiled: the median of `repeats` runs from the second start, alternating methods
    jaxbal_runs, scipy_runs = [], []
    for _ in range(repeats):
        jaxbal_runs.append(run_jaxbal(objective, robot, motion, free, start_b))
        scipy_runs.append(run_scipy(value, start_b, free, 1e-16))
    x_j2, _, solution = jaxbal_runs[-1]
    x_s2, _, evals_2 = scipy_runs[-1]
    t_j2 = float(np.median([run[1] for run in jaxbal_runs]))
    t_s2 = float(np.median([run[1] for run in scipy_runs]))
    template = robot.design()

    def f(x):
        return float(objective(robot.with_design(_unflat(x, template, free)), motion))

    return {
        "variables": int(x_j2.size),
        "jaxbal_seconds_with_compile": t_j1,
        "jaxbal_seconds_compiled": t_j2,
        "jaxbal_steps": int(solution.steps),
        "jaxbal_converged": bool(solution.converged),
        "scipy_slsqp_fd_seconds_with_compile": t_s1,
        "scipy_slsqp_fd_seconds_compiled": t_s2,
        "scipy_objective_evaluations": evals_2,
        "speedup_with_compile": t_s1 / t_j1,
        "speedup_compiled": t_s2 / t_j2,
        "relative_design_difference": _relative(x_j2, x_s2),
        "relative_design_difference_between_starts_jaxbal": _relative(x_j1, x_j2),
        "objective_jaxbal": f(x_j2),
        "objective_scipy": f(x_s2),
        "evaluations_first_scipy_run": evals_1,
    }


#: fresh processes per problem and method; their median is reported (one such run
#: varied by ±15 % from one to the next on the 2-core CPU)
FRESH_RUNS = 3


def first_run(name: str, method: str, runs: int = FRESH_RUNS) -> float:
    """Median seconds of the first co-design of problem ``name`` by ``method``, each in
    a fresh process with an empty compilation cache (imports and the motion excluded),
    over ``runs`` processes."""
    here = Path(__file__).resolve().parent
    seconds = []
    for _ in range(runs):
        with tempfile.TemporaryDirectory() as cache:
            env = dict(os.environ, JAXBAL_CACHE_DIR=cache, PYTHONPATH=str(here))
            env.pop("XLA_FLAGS", None)
            command = [sys.executable, str(here / "codesign_bench.py"), name, method]
            out = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
        seconds.append(float(json.loads(out.stdout.strip().splitlines()[-1])["seconds"]))
    return float(np.median(seconds))


def bench_all(repeats: int = REPEATS, fresh_runs: int = FRESH_RUNS) -> dict:
    """Every problem of :data:`PROBLEMS`; with ``fresh_runs=0`` no fresh process (the
    ``fresh_process…`` entries are then left out)."""
    results = {}
    for name, problem in problems().items():
        result = bench_problem(*problem, repeats=repeats)
        if fresh_runs:
            fresh = {method: first_run(name, method, fresh_runs) for method in METHODS}
            result["fresh_process_seconds_with_compile"] = fresh
            result["speedup_with_compile_fresh_processes"] = fresh["scipy"] / fresh["jaxbal"]
        results[name] = result
    return results


def first_codesign(name: str, method: str) -> None:
    """Print ``{"seconds": …}``: the first co-design of problem ``name`` by ``method``
    in this process (what :func:`first_run` runs in each fresh process)."""
    robot, motion, free = PROBLEMS[name]()
    design = robot.design()
    start = {n: np.asarray(design[n], dtype=float) * 0.5 + 0.5 for n in free}
    objective = make_objective(robot, motion)
    jax.block_until_ready(motion)
    if method == "jaxbal":
        _, seconds, _ = run_jaxbal(objective, robot, motion, free, start)
    else:  # the first evaluation inside SLSQP compiles the objective
        _, seconds, _ = run_scipy(
            scipy_objective(objective, robot, motion, free), start, free, 1e-16
        )
    print(json.dumps({"seconds": seconds}))


#: the two co-design methods compared
METHODS = ("jaxbal", "scipy")


def parser() -> argparse.ArgumentParser:
    parser = command_line("codesign_bench.py", __doc__)
    parser.add_argument(
        "problem",
        choices=("all", *PROBLEMS),
        metavar="PROBLEM",
        help="'all': the whole section (every problem, both methods, fresh processes), "
        "as benchmarks/run.py runs it; or one problem, timed once by METHOD: "
        f"{', '.join(PROBLEMS)}",
    )
    parser.add_argument(
        "method",
        nargs="?",
        choices=METHODS,
        metavar="METHOD",
        help=f"with one PROBLEM (required then): {' or '.join(METHODS)}",
    )
    parser.add_argument(
        "--repeats",
        type=positive_int,
        default=REPEATS,
        metavar="N",
        help="with 'all': compiled runs of each method per problem, their median time "
        "reported (default: %(default)s)",
    )
    parser.add_argument(
        "--fresh-runs",
        type=count,
        default=FRESH_RUNS,
        metavar="N",
        help="with 'all': fresh processes per problem and method timing the first "
        "co-design, their median reported; 0 leaves the fresh-process times out "
        "(default: %(default)s)",
    )
    return parser


def main(argv: list[str] | None = None) -> None:
    cli = parser()
    args = cli.parse_args(argv)
    if args.problem == "all":
        if args.method is not None:
            cli.error(f"PROBLEM 'all' runs both methods: drop METHOD {args.method!r}")
        print(json.dumps(bench_all(args.repeats, args.fresh_runs)))
    elif args.method is None:
        cli.error(f"PROBLEM {args.problem!r} needs a METHOD: {' or '.join(METHODS)}")
    else:
        first_codesign(args.problem, args.method)


if __name__ == "__main__":
    main()
