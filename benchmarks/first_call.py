"""First-call latency in a fresh Python process (run twice by run.py with the same
persistent compilation cache: the second process shows the warm start).

Prints one JSON line: seconds to import jaxbal, to sample the benchmark move, and the
first call (trace + compile + run) of the peak-force gradient (``jax.jit``), of a
co-design, and of the same gradient through ``jaxbal.checked_jit`` (last, so that the
others are measured as before).
Usage: ``python benchmarks/first_call.py ROBOT [--no-checks]``.
"""

import json
import sys
import time

began = time.perf_counter()
import jax  # noqa: E402

import jaxbal  # noqa: E402
from jaxbal.design import codesign, peak_force  # noqa: E402

imported = time.perf_counter() - began

from cases import robot_and_motion  # noqa: E402

if "--no-checks" in sys.argv:
    jaxbal.set_runtime_checks(False)
name = sys.argv[1]
start = time.perf_counter()
robot, motion = robot_and_motion(name)
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
