"""Derivatives of the peak metrics (peak_force, peak_moment, peak_torque,
peak_torque_rate) taken at the peak sample: equal to reverse mode through every sample
(the former formulation), to central finite differences (``check_grads``, first and
second order, forward and
reverse), finite at ties, and ``vmap`` equal to a loop."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal import robots
from jaxbal._src.metrics import _torques, _wrench, torque_rate
from jaxbal._src.planning import peak_norm
from jaxbal.design import (
    as_motion,
    motion_samples,
    peak_force,
    peak_moment,
    peak_torque,
    peak_torque_rate,
)
from jaxbal.planning import EndEffectorLine
from jaxbal.profiles import Quintic

#: name -> (robot, start pose, end pose) of a 0.2 s quintic line (as tests/test_contract)
CASES = {
    "planar_2r": (robots.planar_2r(), (0.4, 0.3), (0.2, 0.5)),
    "dual_v": (robots.dual_v(), (0.0, -0.05, 0.0), (0.05, 0.05, 0.0)),
    "orthoglide": (robots.orthoglide(payload=1.0), (0.0, 0.0, 0.0), (-0.1, 0.07, -0.11)),
}

#: the former formulation: reverse mode through the peak of every sample
ALL_SAMPLES = {
    peak_force: lambda r, m: peak_norm(_wrench(r, m)[0]),
    peak_moment: lambda r, m: peak_norm(_wrench(r, m)[1]),
    peak_torque: lambda r, m: peak_norm(_torques(r, m)),
}


def _case(name, samples=24):
    robot, start, end = CASES[name]
    line = jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), 0.2)
    path = EndEffectorLine(robot, line)
    return robot, motion_samples(robot, [path], jaxbal.sample_times(0.2, samples))


def _objective(metric, robot, motion):
    return jax.jit(lambda design: metric(robot.with_design(design), motion))


SLOW = pytest.mark.slow  # make test-all: each metric and robot stays in make test
PAIRS = [
    pytest.param("planar_2r", peak_force, marks=SLOW),  # FD-checked below
    pytest.param("planar_2r", peak_moment, marks=SLOW),
    ("planar_2r", peak_torque),
    # make test keeps one closed chain (the Orthoglide); the DUAL-V's design gradients
    # are checked against their closed form (eq 30) in test_dual_v
    pytest.param("dual_v", peak_force, marks=SLOW),
    pytest.param("dual_v", peak_torque, marks=SLOW),
    pytest.param("orthoglide", peak_force, marks=SLOW),
    ("orthoglide", peak_moment),
]


@pytest.mark.parametrize(("name", "metric"), PAIRS, ids=lambda x: getattr(x, "__name__", x))
def test_gradient_equals_reverse_mode_through_every_sample(name, metric):
    """Same value (to rounding) and the same gradient (1e-10 of the largest entry) as
    ``jax.grad`` of ``peak_norm`` over all samples, on a move whose peak is unique."""
    robot, motion = _case(name)
    design = robot.with_design({"payload": jnp.asarray(2.0)}).design()
    new, old = _objective(metric, robot, motion), _objective(ALL_SAMPLES[metric], robot, motion)
    np.testing.assert_allclose(float(new(design)), float(old(design)), rtol=1e-12)
    eager = metric(robot.with_design(design), motion)
    np.testing.assert_allclose(float(new(design)), float(eager), rtol=1e-12)
    g_new, g_old = jax.grad(new)(design), jax.grad(old)(design)
    # round-off scale: the largest entry, or the value per unit of design (the Orthoglide's
    # peak moment does not depend on the payload at its centre: a gradient of 1e-16)
    scale = max([float(jnp.max(jnp.abs(g))) for g in jax.tree.leaves(g_old)] + [float(eager)])
    for key in design:
        assert np.all(np.isfinite(np.asarray(g_new[key]))), key
        np.testing.assert_allclose(g_new[key], g_old[key], rtol=0, atol=1e-10 * scale, err_msg=key)


@pytest.mark.parametrize(
    "metric",
    [peak_force, pytest.param(peak_moment, marks=SLOW), pytest.param(peak_torque, marks=SLOW)],
    ids=lambda f: getattr(f, "__name__", f),
)
def test_derivatives_equal_finite_differences(metric):
    """First and second derivatives, forward and reverse, against central differences
    (``check_grads``) in the payload and the counter-masses of the 2R."""
    robot, motion = _case("planar_2r")
    robot = robot.with_design({"counter_distance": jnp.array([0.3, 0.2])})

    @jax.jit  # compiled: check_grads's eager jvp/vjp of order 2 ran op by op (~40 s)
    def f(payload, counter_mass):
        return metric(robot.with_design({"payload": payload, "counter_mass": counter_mass}), motion)

    check_grads(f, (jnp.asarray(1.5), jnp.array([2.0, 1.0])), order=2, modes=("fwd", "rev"),
                eps=1e-4, rtol=1e-5)  # fmt: skip


def test_gradient_through_the_motion():
    """Derivatives reach the motion too (joint co-design: trajectory parameters): the
    derivative in a scaling of the accelerations equals reverse mode over all samples."""
    robot, motion = _case("planar_2r")

    def scaled(metric):
        def f(k):
            return metric(robot, motion._replace(qdd=k * motion.qdd, qd=jnp.sqrt(k) * motion.qd))

        return jax.jit(jax.grad(f))

    g_new, g_old = scaled(peak_force)(1.3), scaled(ALL_SAMPLES[peak_force])(1.3)
    np.testing.assert_allclose(float(g_new), float(g_old), rtol=1e-10)
    check_grads(jax.jit(lambda k: peak_force(robot, motion._replace(qdd=k * motion.qdd))),
                (1.3,), order=1, modes=("fwd", "rev"), eps=1e-5, rtol=1e-6)  # fmt: skip


def test_exact_tie_gives_the_derivative_at_one_peak_sample():
    """A motion repeated twice has every peak exactly tied; the derivative is that of the
    single motion's peak (finite, equal to 1e-12)."""
    robot, motion = _case("planar_2r")
    twice = as_motion((motion, motion))

    def g(m):
        return jax.grad(lambda p: peak_force(robot.with_design({"payload": p}), m))(2.0)

    np.testing.assert_allclose(float(jax.jit(g)(twice)), float(jax.jit(g)(motion)), rtol=1e-12)
    assert np.isfinite(float(jax.jit(g)(twice)))


def test_vmap_over_designs_equals_a_loop():
    """Value and gradient of the peak force over a batch of payloads equal a loop."""
    robot, motion = _case("dual_v", samples=16)
    payloads = jnp.array([0.0, 0.5, 2.0, 4.0])

    def f(p):
        return peak_force(robot.with_design({"payload": p}), motion)

    vg = jax.jit(jax.vmap(jax.value_and_grad(f)))(payloads)
    one = jax.jit(jax.value_and_grad(f))  # compiled once for the loop
    loop = [one(p) for p in payloads]
    np.testing.assert_allclose(vg[0], [float(v) for v, _ in loop], rtol=1e-12)
    np.testing.assert_allclose(vg[1], [float(g) for _, g in loop], rtol=1e-10)


def _jerk_case(samples=24):
    robot, start, end = CASES["planar_2r"]
    line = jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), 0.2)
    times = jaxbal.sample_times(0.2, samples)
    return robot, motion_samples(robot, [EndEffectorLine(robot, line)], times, order=3)


def _rates_every_sample(robot, motion):
    """The former peak torque rate: reverse mode through the maximum of every sample."""
    return jnp.max(jnp.abs(jax.vmap(lambda *s: torque_rate(robot, *s))(*motion)))


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_torque_rate_gradient_equals_reverse_mode_through_every_sample():
    """The peak torque rate (max over samples and actuators of |dτ_i/dt|) differentiated
    at its peak sample and actuator: the value and the gradient in the design (payload,
    counter-masses) and in a time scaling of the motion equal reverse mode through every
    sample (1e-10 of the largest entry), and central differences."""
    robot, motion = _jerk_case()
    robot = robot.with_design({"counter_distance": jnp.array([0.3, 0.2])})

    def objective(metric):
        def f(payload, counter_mass, k):
            arm = robot.with_design({"payload": payload, "counter_mass": counter_mass})
            q, qd, qdd, qddd = motion
            return metric(arm, type(motion)(q, k * qd, k**2 * qdd, k**3 * qddd))

        return jax.jit(f)

    args = (jnp.asarray(1.5), jnp.array([2.0, 1.0]), jnp.asarray(1.2))
    new, old = objective(peak_torque_rate), objective(_rates_every_sample)
    np.testing.assert_allclose(float(new(*args)), float(old(*args)), rtol=1e-12)
    g_new = jax.grad(new, argnums=(0, 1, 2))(*args)
    g_old = jax.grad(old, argnums=(0, 1, 2))(*args)
    scale = max(float(jnp.max(jnp.abs(g))) for g in g_old)
    for a, b in zip(g_new, g_old, strict=True):
        assert np.all(np.isfinite(np.asarray(a)))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-10 * scale)
    check_grads(new, args, order=1, modes=("fwd", "rev"), eps=1e-5, rtol=1e-6)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_torque_rate_vmap_over_designs_equals_a_loop():
    """Value and gradient of the peak torque rate over a batch of payloads (each with its
    own peak sample and actuator) equal a loop."""
    robot, motion = _jerk_case(samples=16)
    payloads = jnp.array([0.0, 0.5, 2.0, 4.0])

    def f(p):
        return peak_torque_rate(robot.with_design({"payload": p}), motion)

    vg = jax.jit(jax.vmap(jax.value_and_grad(f)))(payloads)
    one = jax.jit(jax.value_and_grad(f))
    loop = [one(p) for p in payloads]
    np.testing.assert_allclose(vg[0], [float(v) for v, _ in loop], rtol=1e-12)
    np.testing.assert_allclose(vg[1], [float(g) for _, g in loop], rtol=1e-10)
    assert np.all(np.isfinite(np.asarray(vg[1])))
