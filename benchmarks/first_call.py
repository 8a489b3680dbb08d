"""First-call latency in a fresh Python process (run twice by run.py with the same
persistent compilation cache: the second process shows the warm start).

Prints one JSON line: seconds to import jaxbal, to sample the benchmark move, and the
first call (trace + compile + run) of the peak-force gradient (``jax.jit``), of a
co-design, and of the same gradient through ``jaxbal.checked_jit`` (last, so that the
others are measured as before). The compilation cache is ``$JAXBAL_CACHE_DIR`` (run.py
sets a new one per pair of processes).

Usage: ``python benchmarks/first_call.py ROBOT [--no-checks]`` (``--help`` for more).
"""

from __future__ import annotations

import argparse
import json
import time

from arguments import ROBOTS, command_line


def parser() -> argparse.ArgumentParser:
    """The command line (parsed before JAX is imported: ``--help`` and errors are fast
    and the import is timed alone)."""
    parser = command_line("first_call.py", __doc__)
    parser.add_argument(
        "robot",
        choices=ROBOTS,
        metavar="ROBOT",
        help="the robot whose benchmark move (benchmarks/cases.py) is sampled and "
        f"differentiated; one of: {', '.join(ROBOTS)}",
    )
    parser.add_argument(
        "--no-checks",
        action="store_true",
        help="switch jaxbal's runtime checks off (jaxbal.set_runtime_checks(False)) before "
        "the first calls (default: on)",
    )
    return parser


def main(argv: list[str] | None = None) -> None:
    args = parser().parse_args(argv)
    began = time.perf_counter()
    import jax

    import jaxbal
    from jaxbal.design import codesign, peak_force

    imported = time.perf_counter() - began

    from cases import robot_and_motion

    if args.no_checks:
        jaxbal.set_runtime_checks(False)
    start = time.perf_counter()
    robot, motion = robot_and_motion(args.robot)
    sampled = time.perf_counter() - start

    def objective(design):
        return peak_force(robot.with_design(design), motion)

    start = time.perf_counter()
    jax.block_until_ready(jax.jit(jax.grad(objective))(robot.design()))
    gradient = time.perf_counter() - start
    start = time.perf_counter()
    free = ("counter_mass",) if "counter_mass" in robot.design() else None
    jax.block_until_ready(codesign(robot, motion, "rms_force", free=free, max_steps=50).value)
    designed = time.perf_counter() - start
    # the same gradient through jaxbal.checked_jit: its checks are functional (no host
    # callback), so the persistent cache keeps the program with the checks on
    start = time.perf_counter()
    jax.block_until_ready(jaxbal.checked_jit(jax.grad(objective))(robot.design()))
    checked = time.perf_counter() - start
    print(
        json.dumps(
            {
                "import_seconds": imported,
                "motion_seconds": sampled,
                "first_grad_seconds": gradient,
                "first_codesign_seconds": designed,
                "first_checked_jit_grad_seconds": checked,
            }
        )
    )


if __name__ == "__main__":
    main()
