"""First calls in a fresh process: host code runs in NumPy or as one compiled program,
never as a stream of eager JAX operations (in a fresh process each of them is a
compilation of its own, ~20-120 ms on the 2-core CPU). Counted with JAX's
backend-compile events, never timed."""

import subprocess
import sys

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src.mujoco.confirm import _reference_and_scales
from jaxbal._src.mujoco.tree import matrix_to_quat
from jaxbal._src.validation import runtime_checks
from jaxbal.design import Motion, peak_force, rms_force

_COMPILES = []


def _listener(event, duration, **kwargs):
    if "backend_compile" in event:
        _COMPILES.append(event)


jax.monitoring.register_event_duration_secs_listener(_listener)

_IMPORT_PROBE = """
import sys, jax
compiles = []
jax.monitoring.register_event_duration_secs_listener(
    lambda event, duration, **kw: compiles.append(event) if "backend_compile" in event else None
)
import jaxbal
print(len(compiles), "scipy.optimize" in sys.modules, "mujoco.mjx" in sys.modules)
"""


def test_import_compiles_nothing_and_defers_heavy_modules():
    """``import jaxbal`` compiles no program (module constants are NumPy) and leaves
    ``scipy.optimize`` and ``mujoco.mjx`` to their first use (~1 s of import time)."""
    out = subprocess.run(
        [sys.executable, "-c", _IMPORT_PROBE], capture_output=True, text=True, check=True
    )
    assert out.stdout.split() == ["0", "False", "False"], out.stdout + out.stderr


def _motion(robot, samples: int, seed: int) -> Motion:
    """Random states of ``robot`` (a serial arm: every state is consistent) of an unusual
    length, so that no program of another test has these shapes."""
    rng = np.random.default_rng(seed)
    return Motion(*(jnp.asarray(rng.normal(size=(samples, robot.dof))) for _ in range(3)))


def test_eager_metrics_compile_a_few_programs():
    """An eager ``peak_force``/``rms_force`` compiles at most the robot check, the
    samples and the reduction (it compiled ~20 single-operation programs before)."""
    robot = jaxbal.robots.planar_3r()
    motion = _motion(robot, 37, 0)
    before = len(_COMPILES)
    peak = peak_force(robot, motion)
    assert len(_COMPILES) - before <= 3
    before = len(_COMPILES)
    rms = rms_force(robot, motion)
    assert len(_COMPILES) - before <= 2
    force = np.asarray(jax.vmap(lambda *s: jaxbal.shaking_wrench(robot, *s)[0])(*motion))
    norms = np.linalg.norm(force, axis=-1)
    np.testing.assert_allclose(peak, np.max(norms), rtol=1e-13)
    np.testing.assert_allclose(rms, np.sqrt(np.mean(norms**2)), rtol=1e-13)


def _rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


@pytest.mark.parametrize("seed", range(4))
def test_matrix_to_quat_numpy_equals_jax_and_rebuilds_the_rotation(seed):
    """The MJCF writer's NumPy quaternion is the traceable one, and its rotation matrix
    (closed form of a unit quaternion) is the given matrix; also the half-turns, where
    the trace is -1 and another component is the largest."""
    rng = np.random.default_rng(seed)
    for rotation in (_rotation(rng), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, -1.0, 1.0])):
        quat = matrix_to_quat(rotation, xp=np)
        assert isinstance(quat, np.ndarray)
        np.testing.assert_allclose(quat, matrix_to_quat(jnp.asarray(rotation)), atol=1e-15)
        w, x, y, z = quat
        rebuilt = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
            ]
        )
        np.testing.assert_allclose(rebuilt, rotation, atol=1e-14)


def _primitives(jaxpr) -> set[str]:
    names = set()
    for eqn in jaxpr.eqns:
        names.add(eqn.primitive.name)
        for param in eqn.params.values():
            for sub in param if isinstance(param, (tuple, list)) else (param,):
                inner = getattr(sub, "jaxpr", sub)
                if hasattr(inner, "eqns"):
                    names |= _primitives(inner)
    return names


def test_confirm_reference_has_no_host_callback_and_bad_robot_raises():
    """The reference wrench of :func:`jaxbal.mujoco.confirm` is traced without runtime
    checks (no host callback: the persistent cache keeps it), so ``confirm`` checks the
    robot itself: a negative mass set with ``eqx.tree_at`` is a ``ValueError``."""
    robot = jaxbal.robots.planar_2r()
    motion = _motion(robot, 5, 1)
    g = jnp.zeros(3)
    with runtime_checks(False):
        closed = jax.make_jaxpr(_reference_and_scales)(robot, *motion, g)
    names = _primitives(closed.jaxpr)
    assert not any("callback" in name for name in names), sorted(names)
    with runtime_checks(True):  # the checked wrench has them: the probe above can fail
        checked = jax.make_jaxpr(
            lambda *s: jax.vmap(lambda *x: jaxbal.shaking_wrench(robot, *x))(*s)
        )(*motion)
    assert any("callback" in name for name in _primitives(checked.jaxpr))
    assert jaxbal.mujoco.confirm(robot, *motion).relative < 1e-9
    bad = eqx.tree_at(lambda r: r.masses, robot, robot.masses.at[0].set(-1.0))
    with pytest.raises(ValueError, match="-1"):
        jaxbal.mujoco.confirm(bad, *motion)


def _arm(links: int):
    """A ``links``-link planar arm of equal 0.2 m, 2 kg links."""
    ones = np.ones(links)
    return jaxbal.robots.PlanarArm(0.2 * ones, 0.5 * ones, 2.0 * ones, 0.01 * ones, payload=0.5)


def test_eager_wrench_and_com_are_one_program_each_with_the_eager_errors():
    """An eager ``shaking_wrench`` / ``center_of_mass`` compiles one program per robot
    structure (none for other parameter values), equals the compiled call, and keeps
    the eager errors: a non-finite state, a negative mass set with ``eqx.tree_at``, a
    wrong shape and an overflow are ``ValueError`` naming the value."""
    robot = _arm(6)  # a structure no other test compiles
    state = [np.linspace(-1.0, 1.0, 6) * k for k in (0.5, 2.0, -3.0)]
    before = len(_COMPILES)
    force, moment = jaxbal.shaking_wrench(robot, *state, gravity=(0.0, -9.81, 0.0))
    com = jaxbal.center_of_mass(robot, state[0])
    assert len(_COMPILES) - before <= 2
    other = eqx.tree_at(lambda r: r.masses, robot, robot.masses * 1.5)
    before = len(_COMPILES)
    jaxbal.shaking_wrench(other, *state, gravity=(0.0, -9.81, 0.0))
    jaxbal.center_of_mass(other, state[0])
    assert len(_COMPILES) == before
    g = jnp.array([0.0, -9.81, 0.0])
    expected = jax.jit(lambda *s: jaxbal.shaking_wrench(robot, *s, gravity=g))(*state)
    scale = np.max(np.abs(np.asarray(expected[0])))
    np.testing.assert_allclose(force, expected[0], rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(moment, expected[1], rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(com, jax.jit(jaxbal.center_of_mass)(robot, state[0]), atol=1e-15)
    with pytest.raises(ValueError, match="non-finite state"):
        jaxbal.shaking_wrench(robot, state[0] * np.nan, *state[1:])
    with pytest.raises(ValueError, match="shape"):
        jaxbal.shaking_wrench(robot, state[0][:-1], *state[1:])
    # the fallbacks run operation by operation: checked on the centre of mass, cheaper
    bad = eqx.tree_at(lambda r: r.payload, robot, jnp.asarray(-2.0))
    with pytest.raises(ValueError, match="non-negative"):
        jaxbal.center_of_mass(bad, state[0])
    huge = eqx.tree_at(lambda r: r.lengths, robot, robot.lengths * 1e308)
    with pytest.raises(ValueError, match="overflow"):
        jaxbal.center_of_mass(huge, state[0])


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_sampling_runs_once_with_fast_compile_options_and_metrics_keep_the_defaults():
    """Sampling a motion (a program that runs once per compilation) is compiled with the
    fast-compile options (LLVM level 0); a metric's program, which sweeps and
    optimisers run many times, keeps XLA's defaults. The sampled motion is exact: the
    2R's end-effector follows the line (1e-12)."""
    from jaxbal._src import motion_samples as sampling
    from jaxbal._src import validation
    from jaxbal.planning import EndEffectorLine

    robot = jaxbal.robots.planar_2r()
    start, end = jnp.array([0.6, 0.1]), jnp.array([0.1, 0.6])
    line = jaxbal.StraightLine(start, end, jaxbal.profiles.Quintic(), 0.3)
    motion = jaxbal.design.motion_samples(
        robot, [EndEffectorLine(robot, line)], jnp.linspace(0, 0.3, 7)
    )
    program = validation._LIBRARY[sampling._sample]
    assert program.compiler_options["xla_backend_optimization_level"] == 0
    tip = jax.vmap(robot.end_effector)(motion.q)
    np.testing.assert_allclose(tip, jax.vmap(line)(jnp.linspace(0, 0.3, 7)), atol=1e-12)
    jaxbal.planning.wrench_along(robot, EndEffectorLine(robot, line), jnp.linspace(0, 0.3, 7))
    wrench = next(f for f in validation._LIBRARY if f.__name__ == "_wrench_along")
    assert validation._LIBRARY[wrench].compiler_options is None
