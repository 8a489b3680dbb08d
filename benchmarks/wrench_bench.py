"""Per-robot benchmark of the generic shaking wrench (issue: performance).

For each robot, on consistent states of its benchmark move (cases.py), in one run:
throughput of ``jaxbal.shaking_wrench`` (one device, chunked ``jit(vmap)``; and over
all local devices); the generic evaluation of the same wrench as it was when the
performance issue was filed (the baseline the speed-ups are stated against: the
physics as written, without the straight-line replay, and the state threaded through
its finiteness check, which split the compiled loop; one more output check than then;
no loop-closure check, which ours computes with the wrench of a closed chain);
the MuJoCo C ``mj_inverse`` Python loop and MJX ``inverse`` (``jit(vmap)``) on the
same model and states; compile time of the first call; peak temporary memory per state
(XLA's memory analysis); and the cost of ``jax.grad`` of a peak-force objective along
the 1,000-sample move relative to its value. For the 2R, also the hand-written closed
form (the limit). The actuator torques (``jaxbal.actuator_torques``, loop closures
included) against their former evaluation (Lagrange's equations by differentiating the
kinetic energy twice) and, for the serial robots whose MuJoCo model has one joint per
coordinate, against MuJoCo C ``mj_inverse``'s ``qfrc_inverse``.
"""

from __future__ import annotations

import time

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from cases import chunked, closed_form_2r, robot_and_motion, sharded, tiled_states

import jaxbal
from jaxbal._src.actuation import _actuator_torques
from jaxbal._src.dynamics import lagrange_forces
from jaxbal._src.momentum import _shaking_wrench  # the generic evaluation, not replayed
from jaxbal._src.state_checks import checked_state
from jaxbal.design import peak_force
from jaxbal.mujoco import mjx_base_reaction, mjx_model, mujoco_model


def best_time(fn, repeats: int = 5) -> float:
    """Best wall time of ``fn()`` over ``repeats`` runs (after one warm-up run) [s]."""
    jax.block_until_ready(fn())
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        times.append(time.perf_counter() - start)
    return min(times)


def first_call(fn, *args) -> float:
    """Wall time of the first call (trace + compile + run) [s]."""
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    return time.perf_counter() - start


def memory_per_state(fn, states, count: int) -> float:
    """XLA's temporary + output bytes of the compiled ``fn`` per state [B]."""
    analysis = jax.jit(fn).lower(*(a[:count] for a in states)).compile().memory_analysis()
    if analysis is None:
        return float("nan")
    return (analysis.temp_size_in_bytes + analysis.output_size_in_bytes) / count


def mujoco_loop(robot, states, count: int):
    """Per-state time of a Python loop of MuJoCo C ``mj_inverse`` [s] and the base
    reactions ``(count, 6)`` it gives."""
    compiled = mujoco_model(robot)
    data = mujoco.MjData(compiled.model)
    qpos, qvel, qacc = compiled.state(*(a[:count] for a in states))
    reactions = np.empty((count, 6))

    def loop():
        for k in range(count):
            data.qpos[:], data.qvel[:], data.qacc[:] = qpos[k], qvel[k], qacc[k]
            mujoco.mj_inverse(compiled.model, data)
            reactions[k, :3], reactions[k, 3:] = compiled.base_reaction(data)

    return best_time(loop, 3) / count, reactions


def mjx_rate(robot, states, count: int, chunk: int) -> tuple[float, float]:
    """Per-state time of MJX ``inverse`` under chunked ``jit(vmap)`` [s] and its first
    call [s]."""
    compiled = mjx_model(robot)
    fn = chunked(lambda q, qd, qdd: mjx_base_reaction(compiled, robot, q, qd, qdd), chunk)
    args = tuple(a[:count] for a in states)
    first = first_call(fn, *args)
    return best_time(lambda: fn(*args), 3) / count, first


def gradient_cost(robot, motion) -> dict:
    """Value, gradient and first-call times of the peak shaking force along the move,
    as a function of the robot's design variables."""
    design = robot.design()

    def objective(d):
        return peak_force(robot.with_design(d), motion)

    value, grad = jax.jit(objective), jax.jit(jax.grad(objective))
    first_grad = first_call(grad, design)
    first_value = first_call(value, design)
    t_value = best_time(lambda: value(design), 20)
    t_grad = best_time(lambda: grad(design), 20)
    return {
        "design_variables": sorted(design),
        "value_seconds": t_value,
        "grad_seconds": t_grad,
        "grad_over_value": t_grad / t_value,
        "first_call_value_seconds": first_value,
        "first_call_grad_seconds": first_grad,
    }


def torque_cost(robot, states, chunk: int, loop_count: int) -> dict:
    """Actuator torques: states/s now and before (Lagrange's form), compile time of the
    first call, agreement of the two and, for a serial robot, with MuJoCo C."""

    def generic(q, qd, qdd):
        return jaxbal.actuator_torques(robot, q, qd, qdd)

    def before(q, qd, qdd):
        # as it was: Lagrange's form, no loop-closure check (ours has it, fused)
        return _actuator_torques(robot, q, qd, qdd, None, lagrange_forces, loops=False)

    count = states[0].shape[0]
    fn, fn_before = chunked(generic, chunk), chunked(before, chunk)
    compile_seconds = first_call(fn, *(a[:chunk] for a in states))
    compile_before = first_call(fn_before, *(a[:chunk] for a in states))
    t_generic = best_time(lambda: fn(*states), 3) / count
    t_before = best_time(lambda: fn_before(*states), 3) / count
    ours = np.asarray(fn(*states))
    result = {
        "generic_states_per_second": 1.0 / t_generic,
        "before_states_per_second": 1.0 / t_before,
        "speedup_vs_before": t_before / t_generic,
        "compile_seconds_first_call": compile_seconds,
        "before_compile_seconds_first_call": compile_before,
        "max_relative_difference_vs_before": float(
            np.max(np.abs(ours - np.asarray(fn_before(*states)))) / np.max(np.abs(ours))
        ),
    }
    compiled = mujoco_model(robot)
    # serial, every coordinate actuated (τ = Q) and one MuJoCo joint per coordinate
    if len(robot.actuated) == robot.dof == compiled.model.nv - 6:
        data = mujoco.MjData(compiled.model)
        qpos, qvel, qacc = compiled.state(*(a[:loop_count] for a in states))
        reference = np.empty((loop_count, robot.dof))
        for k in range(loop_count):
            data.qpos[:], data.qvel[:], data.qacc[:] = qpos[k], qvel[k], qacc[k]
            mujoco.mj_inverse(compiled.model, data)
            reference[k] = data.qfrc_inverse[6:]  # after the base's 6 dofs
        difference = np.max(np.abs(ours[:loop_count] - reference)) / np.max(np.abs(reference))
        result["max_relative_difference_vs_mujoco"] = float(difference)
    return result


def bench_robot(name: str, count: int, loop_count: int, mjx_count: int, chunk: int) -> dict:
    robot, motion = robot_and_motion(name)
    states = tiled_states(motion, count)

    def generic(q, qd, qdd):
        return jaxbal.shaking_wrench(robot, q, qd, qdd)

    def before(q, qd, qdd):
        q, qd, qdd = checked_state(robot, q, qd, qdd)  # the check as it was (module doc)
        # no loop-closure check then (ours has it, computed with the wrench)
        return _shaking_wrench(robot, q, qd, qdd, None, replay=False, loops=False)

    fn = chunked(generic, chunk)
    compile_seconds = first_call(fn, *(a[:chunk] for a in states))
    t_generic = best_time(lambda: fn(*states)) / count
    fn_all, devices = sharded(generic, chunk)
    t_devices = best_time(lambda: fn_all(*states)) / (count - count % devices)
    fn_before = chunked(before, chunk)
    t_before = best_time(lambda: fn_before(*states)) / count  # as many repeats as ours
    t_mujoco, reactions = mujoco_loop(robot, states, loop_count)
    ours = np.concatenate([np.asarray(x) for x in fn(*(a[:loop_count] for a in states))], 1)
    agreement = float(np.max(np.abs(reactions - ours)) / np.max(np.abs(reactions)))
    t_mjx, mjx_first = mjx_rate(robot, states, mjx_count, chunk)
    result = {
        "states": count,
        "chunk": chunk,
        "devices": devices,
        "generic_states_per_second": 1.0 / t_generic,
        "generic_all_devices_states_per_second": 1.0 / t_devices,
        "before_states_per_second": 1.0 / t_before,
        "speedup_vs_before": t_before / t_generic,
        "mujoco_c_loop_states_per_second": 1.0 / t_mujoco,
        "speedup_vs_mujoco_c_loop_one_device": t_mujoco / t_generic,
        "speedup_vs_mujoco_c_loop_all_devices": t_mujoco / t_devices,
        "mjx_states_per_second": 1.0 / t_mjx,
        "speedup_vs_mjx": t_mjx / t_generic,
        "max_relative_difference_vs_mujoco": agreement,
        "compile_seconds_first_call": compile_seconds,
        "mjx_compile_seconds_first_call": mjx_first,
        "memory_bytes_per_state_plain_vmap": memory_per_state(
            jax.vmap(generic), states, min(count, 10_000)
        ),
        "memory_bytes_per_state_chunked": memory_per_state(
            lambda *s: jax.lax.map(lambda x: generic(*x), s, batch_size=chunk), states, count
        ),
        "gradient": gradient_cost(robot, motion),
        "torques": torque_cost(robot, states, chunk, loop_count),
    }
    if name == "planar_2r":
        closed = closed_form_2r(robot)
        fn_closed = chunked(closed, chunk)
        t_closed = best_time(lambda: fn_closed(*states)) / count
        diff = [np.max(np.abs(a - b)) for a, b in zip(fn(*states), fn_closed(*states), strict=True)]
        result |= {
            "closed_form_states_per_second": 1.0 / t_closed,
            "generic_over_closed_form_time": t_generic / t_closed,
            "max_abs_difference_vs_closed_form": float(max(diff)),
        }
    return result


def chunk_scan(name: str, count: int, chunks=(64, 256, 1024, 4096, 16384)) -> dict:
    """States/s of the chunked generic wrench for several chunk sizes (one device)."""
    robot, motion = robot_and_motion(name)
    states = tiled_states(motion, count)
    out = {}
    for chunk in chunks:
        fn = chunked(lambda q, qd, qdd: jaxbal.shaking_wrench(robot, q, qd, qdd), chunk)
        out[str(chunk)] = count / best_time(lambda fn=fn: fn(*states), 3)
    return out


def probe(name: str) -> jnp.ndarray:
    """A quick check that the generic wrench runs (used by the tests of the benchmark)."""
    robot, motion = robot_and_motion(name)
    return jax.vmap(lambda *s: jaxbal.shaking_wrench(robot, *s))(*(a[:4] for a in motion))[0]
