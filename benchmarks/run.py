"""jaxbal benchmarks: throughput of the shaking wrench and the cost of its gradient.

Run with ``make bench``; results go to ``benchmarks/results/*.json`` (atomic writes).

1. ``shaking_wrench`` of the Briot 2R on N ≥ 10⁶ random states, ``jit(vmap(...))``,
   against (a) a plain NumPy loop over the hand-derived closed form and (b) a loop of
   MuJoCo C ``mj_inverse`` on the same states and the same robot (base dofs whose
   ``qfrc_inverse`` is the reaction, :mod:`jaxbal.mujoco`). The two loops are timed on a
   subset and reported per state. Target: jaxbal ≥ 25× the MuJoCo C loop.
2. ``jax.grad`` of a scalar objective (peak shaking force along a planned 2R move)
   relative to evaluating it. Target ≤ 3×.
"""

from __future__ import annotations

import os

# Expose every CPU core as a JAX device (set before JAX is imported) so the throughput
# benchmark can shard states over them with pmap; on a GPU this has no effect.
os.environ.setdefault("XLA_FLAGS", f"--xla_force_host_platform_device_count={os.cpu_count() or 1}")

import argparse  # noqa: E402
import json  # noqa: E402
import platform  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
import mujoco  # noqa: E402
import numpy as np  # noqa: E402

import jaxbal  # noqa: E402
from jaxbal.mujoco import mujoco_model  # noqa: E402
from jaxbal.planning import EndEffectorLine, peak_norm, wrench_along  # noqa: E402
from jaxbal.profiles import Quintic  # noqa: E402
from jaxbal.report import atomic_write_text  # noqa: E402

CHUNK = 64  # states per vmap chunk (good on a 2-core CPU; use a large one on GPU)
BENCH_START, BENCH_END = "<!-- bench:start -->", "<!-- bench:end -->"


def best_time(fn, repeats: int = 5) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def numpy_wrench_2r(arm, q, qd, qdd):
    """Plain NumPy closed form of the 2R shaking wrench (one state)."""
    l1, l2 = arm["lengths"]
    r1, r2 = arm["ratios"]
    m1, m2, mt = arm["masses"]
    i1, i2 = arm["inertias"]
    t1, t12 = q[0], q[0] + q[1]
    w1, w12 = qd[0], qd[0] + qd[1]
    a1, a12 = qdd[0], qdd[0] + qdd[1]
    c1, s1, c12, s12 = np.cos(t1), np.sin(t1), np.cos(t12), np.sin(t12)
    e1, n1 = np.array([c1, s1]), np.array([-s1, c1])
    e12, n12 = np.array([c12, s12]), np.array([-s12, c12])
    acc1 = a1 * n1 - w1**2 * e1
    acc12 = a12 * n12 - w12**2 * e12
    points = [r1 * l1 * e1, l1 * e1 + r2 * l2 * e12, l1 * e1 + l2 * e12]
    accels = [r1 * l1 * acc1, l1 * acc1 + r2 * l2 * acc12, l1 * acc1 + l2 * acc12]
    force = -sum(m * a for m, a in zip((m1, m2, mt), accels, strict=True))
    moment = -sum(
        m * (p[0] * a[1] - p[1] * a[0])
        for m, p, a in zip((m1, m2, mt), points, accels, strict=True)
    )
    return force, moment - i1 * a1 - i2 * a12


def throughput(count: int, loop_count: int) -> dict:
    robot = jaxbal.robots.planar_2r()
    rng = np.random.default_rng(0)
    q = rng.uniform(-np.pi, np.pi, (count, 2))
    qd = rng.normal(0, 3, (count, 2))
    qdd = rng.normal(0, 30, (count, 2))
    jq, jqd, jqdd = (jnp.asarray(a) for a in (q, qd, qdd))

    def wrench(a, b, c):
        return jaxbal.shaking_wrench(robot, a, b, c)

    # Plain jit(vmap) over all states, and the same vmap applied chunk by chunk
    # (lax.map with batch_size): small chunks keep the intermediates in cache, which on
    # CPU is several times faster than materialising them for 10⁶ states.
    plain = jax.jit(jax.vmap(wrench))
    batched = jax.jit(
        lambda a, b, c: jax.lax.map(lambda s: wrench(*s), (a, b, c), batch_size=CHUNK)
    )
    jax.block_until_ready(plain(jq, jqd, jqdd))
    t_plain = best_time(lambda: jax.block_until_ready(plain(jq, jqd, jqdd)), 3)
    jax.block_until_ready(batched(jq, jqd, jqdd))
    t_one_device = best_time(lambda: jax.block_until_ready(batched(jq, jqd, jqdd)), 3)
    # The same chunked vmap sharded over all local devices (CPU cores here).
    devices = jax.local_device_count()
    usable = count - count % devices
    sharded_args = tuple(
        x[:usable].reshape(devices, usable // devices, -1) for x in (jq, jqd, jqdd)
    )
    sharded = jax.pmap(
        lambda a, b, c: jax.lax.map(lambda s: wrench(*s), (a, b, c), batch_size=CHUNK)
    )
    jax.block_until_ready(sharded(*sharded_args))
    t_jax = best_time(lambda: jax.block_until_ready(sharded(*sharded_args)), 3) * count / usable

    params = {
        "lengths": np.asarray(robot.lengths),
        "ratios": np.asarray(robot.com_ratios),
        "masses": np.array([*np.asarray(robot.masses), float(robot.payload)]),
        "inertias": np.asarray(robot.inertias),
    }

    def numpy_loop():
        for k in range(loop_count):
            numpy_wrench_2r(params, q[k], qd[k], qdd[k])

    t_numpy = best_time(numpy_loop, 3) / loop_count

    compiled = mujoco_model(robot)
    data = mujoco.MjData(compiled.model)
    reactions = np.empty((loop_count, 6))

    def mujoco_loop():
        for k in range(loop_count):
            data.qpos[6:] = q[k]
            data.qvel[6:] = qd[k]
            data.qacc[6:] = qdd[k]
            mujoco.mj_inverse(compiled.model, data)
            reactions[k] = -data.qfrc_inverse[:6]

    t_mujoco = best_time(mujoco_loop, 3) / loop_count
    # Same numbers: MuJoCo and jaxbal agree on the timed states.
    force, moment = batched(jq[:loop_count], jqd[:loop_count], jqdd[:loop_count])
    agreement = float(
        np.max(np.abs(reactions - np.concatenate([force, moment], axis=1)))
        / np.max(np.abs(reactions))
    )
    per_state_jax = t_jax / count
    return {
        "states": count,
        "loop_states": loop_count,
        "jaxbal_seconds_per_state": per_state_jax,
        "jaxbal_chunk": CHUNK,
        "jaxbal_devices": devices,
        "jaxbal_one_device_seconds_per_state": t_one_device / count,
        "jaxbal_plain_vmap_seconds_per_state": t_plain / count,
        "numpy_loop_seconds_per_state": t_numpy,
        "mujoco_c_loop_seconds_per_state": t_mujoco,
        "speedup_vs_numpy_loop": t_numpy / per_state_jax,
        "speedup_vs_mujoco_c_loop": t_mujoco / per_state_jax,
        "target_speedup_vs_mujoco_c_loop": 25.0,
        "max_relative_difference_jaxbal_vs_mujoco": agreement,
    }


def gradient_cost() -> dict:
    base = jaxbal.robots.planar_2r()
    q0, q1 = jnp.array([1.0, -1.0]), jnp.array([1.6, -0.6])
    times = jnp.linspace(0.0, 0.5, 1001)

    def peak_force(params):
        masses, payload = params
        arm = jaxbal.robots.PlanarArm(base.lengths, base.com_ratios, masses, base.inertias, payload)
        line = jaxbal.StraightLine(arm.end_effector(q0), arm.end_effector(q1), Quintic(), 0.5)
        path = EndEffectorLine(arm, line, branch=-1)
        return peak_norm(wrench_along(arm, path, times)[0])

    params = (base.masses, base.payload)
    value = jax.jit(peak_force)
    grad = jax.jit(jax.grad(peak_force))
    jax.block_until_ready(value(params))
    jax.block_until_ready(grad(params))
    t_value = best_time(lambda: jax.block_until_ready(value(params)), 20)
    t_grad = best_time(lambda: jax.block_until_ready(grad(params)), 20)
    return {
        "objective": "peak ‖f_sh‖ of a 2R quintic move, 1001 samples",
        "value_seconds": t_value,
        "grad_seconds": t_grad,
        "grad_over_value": t_grad / t_value,
        "target_grad_over_value": 3.0,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/results"))
    parser.add_argument("--states", type=int, default=1_000_000)
    parser.add_argument("--loop-states", type=int, default=20_000)
    parser.add_argument("--readme", type=Path, default=Path("README.md"))
    args = parser.parse_args()
    result = {
        "machine": {
            "platform": platform.platform(),
            "python": platform.python_version(),
            "jax": jax.__version__,
            "mujoco": mujoco.__version__,
            "devices": [str(d) for d in jax.devices()],
        },
        "shaking_wrench_2r": throughput(args.states, args.loop_states),
        "gradient_cost": gradient_cost(),
    }
    text = json.dumps(result, indent=2)
    atomic_write_text(args.out / f"bench_{jax.default_backend()}.json", text + "\n")
    print(text)
    if args.readme.exists():
        update_readme(args.readme, result)


def update_readme(readme: Path, result: dict) -> None:
    """Quote the measured ratios between the bench markers of README.md."""
    wrench, grad = result["shaking_wrench_2r"], result["gradient_cost"]
    block = "\n".join(
        [
            BENCH_START,
            f"Measured on {result['machine']['devices'][0]} ({result['machine']['platform']}), "
            f"jax {result['machine']['jax']}, mujoco {result['machine']['mujoco']}:",
            "",
            "| quantity | value | target |",
            "|---|---:|---:|",
            f"| 2R shaking wrench, jaxbal vmap in chunks of {wrench['jaxbal_chunk']}, pmap over "
            f"{wrench['jaxbal_devices']} devices, {wrench['states']:,} states | "
            f"{1e9 * wrench['jaxbal_seconds_per_state']:.0f} ns/state | |",
            f"| same on one device | {1e9 * wrench['jaxbal_one_device_seconds_per_state']:.0f} "
            "ns/state | |",
            f"| same, one jit(vmap) over all states | "
            f"{1e9 * wrench['jaxbal_plain_vmap_seconds_per_state']:.0f} ns/state | |",
            f"| MuJoCo C `mj_inverse` Python loop | "
            f"{1e9 * wrench['mujoco_c_loop_seconds_per_state']:.0f} ns/state | |",
            f"| speed-up vs MuJoCo C `mj_inverse` loop | {wrench['speedup_vs_mujoco_c_loop']:.1f}× "
            f"| ≥ {wrench['target_speedup_vs_mujoco_c_loop']:.0f}× |",
            f"| speed-up vs plain NumPy loop | {wrench['speedup_vs_numpy_loop']:.1f}× | |",
            f"| jaxbal vs MuJoCo, max relative difference | "
            f"{wrench['max_relative_difference_jaxbal_vs_mujoco']:.1e} | |",
            f"| cost of `jax.grad` / value ({grad['objective']}) | "
            f"{grad['grad_over_value']:.2f}× | ≤ {grad['target_grad_over_value']:.0f}× |",
            BENCH_END,
        ]
    )
    text = readme.read_text()
    start, end = text.find(BENCH_START), text.find(BENCH_END)
    if start < 0 or end < 0:
        return
    atomic_write_text(readme, text[:start] + block + text[end + len(BENCH_END) :])


if __name__ == "__main__":
    main()
