"""Test configuration: float64 on (jaxbal does it on import), strict dtype promotion off.

The persistent compilation cache is off in the tests (``JAXBAL_CACHE_DIR=off``, set
before jaxbal is imported): the tests that count compilations must see every one, not
a disk hit left by an earlier run. tests/test_config.py checks the cache in a
subprocess with its default settings.
"""

import os

os.environ["JAXBAL_CACHE_DIR"] = "off"
# Faster compiles for the suite (it is compile-bound): LLVM -O0 and XLA:CPU's elemental
# emitters, the options jaxbal already gives its co-design program (config.py); neither
# enables fast-math, so the arithmetic, and every tolerance, is the same. Measured on
# the 2-core CPU: test_peak_derivative + test_contract 105 -> 58 s. Subprocesses
# (notebooks, the CLI, the cache test) inherit it. JAXBAL_TEST_FAST_COMPILE=0 in the
# environment runs the suite with XLA's default options (what users run).
_FAST_COMPILE = "--xla_backend_optimization_level=0 --xla_cpu_use_fusion_emitters=false"


def _with_fast_compile_flags() -> None:
    """Add :data:`_FAST_COMPILE` to ``XLA_FLAGS`` if this jaxlib knows them (an unknown
    flag aborts the process: probed once in a subprocess; pytest-xdist's workers inherit
    the decision through the environment)."""
    import subprocess
    import sys

    if os.environ.get("JAXBAL_TEST_FAST_COMPILE") is not None:
        return
    flags = f"{os.environ.get('XLA_FLAGS', '')} {_FAST_COMPILE}".strip()
    probe = "import jax; jax.jit(lambda x: x + 1.0)(1.0).block_until_ready()"
    known = subprocess.run(
        [sys.executable, "-c", probe], env={**os.environ, "XLA_FLAGS": flags},
        capture_output=True, timeout=120,
    ).returncode == 0  # fmt: skip
    os.environ["JAXBAL_TEST_FAST_COMPILE"] = "1" if known else "0"
    if known:
        os.environ["XLA_FLAGS"] = flags


_with_fast_compile_flags()

import jax  # noqa: E402
import pytest  # noqa: E402

import jaxbal  # noqa: E402, F401  (enables float64)

jax.config.update("jax_enable_x64", True)


def slow_for(values, *slow):
    """``values`` for ``pytest.mark.parametrize``, those in ``slow`` marked for
    ``make test-all`` (long compiles whose check another case already makes in
    ``make test``)."""
    return [pytest.param(v, marks=pytest.mark.slow) if v in slow else v for v in values]


def random_states(robot, count, seed=0):
    """``count`` random states ``(q, q̇, q̈)``, each ``(count, dof)``, of any robot: for a
    serial robot q ∈ 0.1 ± 0.1, q̇ ~ N(0, 2), q̈ ~ N(0, 20); for a closed chain, whose
    states must close its loops, the robot's inverse kinematics (``jaxbal.pose_motion``)
    of random end-effector motions about the centre of its workspace (poses ± 0.02,
    rates N(0, 0.5), accelerations N(0, 5), SI)."""
    import jax.numpy as jnp
    import numpy as np

    rng = np.random.default_rng(seed)
    probe = jax.ShapeDtypeStruct((robot.dof,), jnp.float64)
    if jax.eval_shape(robot.constraint, probe).shape[0] == 0:
        q = 0.1 + rng.uniform(-0.1, 0.1, (count, robot.dof))
        qd, qdd = rng.normal(0, 2, q.shape), rng.normal(0, 20, q.shape)
        return tuple(jnp.asarray(a) for a in (q, qd, qdd))
    size = jnp.shape(robot.end_effector(robot.inverse_kinematics(jnp.zeros(3))))[0]
    poses = rng.uniform(-0.02, 0.02, (count, size))
    rates, accelerations = rng.normal(0, 0.5, poses.shape), rng.normal(0, 5, poses.shape)
    motion = jax.jit(jax.vmap(lambda u, v, w: jaxbal.pose_motion(robot, u, v, w)))
    return motion(jnp.asarray(poses), jnp.asarray(rates), jnp.asarray(accelerations))


def com_move_2r(samples: int):
    """``(robot, motion)``: the 2R's bang-bang COM move P5 → P9 (elbow down, 0.5 s) at
    ``samples`` instants, the sweep tests' robot and motion."""
    import jax.numpy as jnp

    from jaxbal.design import motion_samples

    robot = jaxbal.robots.planar_2r()
    q0 = robot.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = robot.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    plan = jaxbal.planning.com_line(robot, q0, q1, jaxbal.profiles.BangBang(), 0.5)
    return robot, motion_samples(robot, [plan], jaxbal.sample_times(0.5, samples))
