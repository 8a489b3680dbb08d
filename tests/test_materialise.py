"""Transcendentals computed once per state (jaxbal/_src/materialise.py).

References: the same jaxpr evaluated by JAX without the scheduling (exact equality:
the same operations on the same values), a Python loop for ``vmap``, central finite
differences (``check_grads``), and XLA's compiled program (each sine of the program
appears once, where without the boundary it is copied into every output's loop).
"""

import re

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import random_states
from jax.extend import core
from jax.test_util import check_grads

import jaxbal
from jaxbal._src.materialise import materialise, schedule, scheduled


def scalar_program(q0, q1, w):
    """Two levels of transcendentals (a sine of a cosine), shared by three outputs."""
    c0, s01 = jnp.cos(q0), jnp.sin(q0 + q1)
    inner = jnp.sin(c0 * w)
    return c0 * s01 + inner, s01 - 2.0 * c0 * inner, jnp.exp(0.1 * s01) * w + c0 * inner


ARGS = (jnp.float64(0.3), jnp.float64(-1.1), jnp.float64(2.5))


def closed():
    return jax.make_jaxpr(scalar_program)(*ARGS)


def scheduled_fn(*args):
    return schedule(closed(), *args)


def test_schedule_changes_nothing_in_the_values():
    assert scheduled(closed())
    expected = core.jaxpr_as_fun(closed())(*ARGS)
    for a, e in zip(scheduled_fn(*ARGS), expected, strict=True):
        assert float(a) == float(e)


def test_a_sine_of_fewer_outputs_is_left_to_xla():
    """Copies of a sine into two outputs cost less than the boundary (the 2R's torques)."""

    def two(q):
        s = jnp.sin(q)
        return s * 2.0, s + 1.0

    def three(q):
        s = jnp.sin(q)
        return s * 2.0, s + 1.0, s * q

    assert not scheduled(jax.make_jaxpr(two)(1.0))
    assert scheduled(jax.make_jaxpr(three)(1.0))


def test_vmap_and_nested_vmap_equal_a_loop():
    rng = np.random.default_rng(0)
    batch = [jnp.asarray(rng.uniform(-2, 2, (3, 4))) for _ in range(3)]
    nested = jax.jit(jax.vmap(jax.vmap(scheduled_fn)))(*batch)
    for i in range(3):
        for j in range(4):
            one = scalar_program(*(b[i, j] for b in batch))
            for out, ref in zip(nested, one, strict=True):
                np.testing.assert_allclose(out[i, j], ref, rtol=1e-13, atol=1e-16)


def test_gradients_match_finite_differences():
    def total(args):
        return sum(jnp.sum(o) for o in jax.vmap(scheduled_fn)(*args))

    args = tuple(jnp.linspace(-1.0, 1.0, 5) + k for k in range(3))
    check_grads(total, (args,), order=2, modes=("fwd", "rev"), atol=1e-6, rtol=1e-6)
    grad = jax.grad(total)(args)
    assert all(bool(jnp.all(jnp.isfinite(g))) for g in grad)


def test_materialise_is_the_identity_everywhere():
    x = jnp.array([1.5, -0.0, jnp.inf, -2.0])
    anchor = jnp.array([jnp.nan])
    assert jnp.array_equal(materialise(x, anchor), x)
    assert jnp.array_equal(jax.vmap(materialise, (0, None))(x, anchor), x)
    # the tangent passes through unchanged
    _, tangent = jax.jvp(lambda v: materialise(v, anchor), (x,), (jnp.arange(4.0),))
    assert jnp.array_equal(tangent, jnp.arange(4.0))


def sines_in(compiled_text: str) -> int:
    return len(re.findall(r"= f(?:32|64)\[[^\]]*\][^=]* sine\(", compiled_text))


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the CPU's fusion")
def test_each_sine_is_compiled_once():
    """Without the boundary XLA copies every sine into each output's loop (the
    unscheduled program: 2 sines in the jaxpr, more in the compiled program)."""
    batch = [jnp.linspace(-1.0, 1.0, 256) + k for k in range(3)]
    plain = jax.jit(jax.vmap(core.jaxpr_as_fun(closed()))).lower(*batch).compile().as_text()
    ours = jax.jit(jax.vmap(scheduled_fn)).lower(*batch).compile().as_text()
    assert sines_in(plain) > 2  # the duplication this module removes
    assert sines_in(ours) == 2


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the CPU's fusion")
def test_the_dual_v_wrench_computes_each_joint_sine_once():
    robot = jaxbal.robots.dual_v()
    q = jnp.zeros((64, robot.dof)) + 0.1

    def compiled_text():
        fn = jax.jit(jax.vmap(lambda a, b, c: jaxbal.shaking_wrench(robot, a, b, c)))
        return fn.lower(q, q, q).compile().as_text()

    expected = sines_in(jax.jit(jax.vmap(jnp.sin)).lower(q).compile().as_text())
    assert expected == 1
    with jaxbal.runtime_checks(False):
        # 8 distinct angles (its 8 bodies); previously each copied into both outputs' loops
        assert sines_in(compiled_text()) <= 8
    # the loop-closure check computed with the wrench adds the platform's angle (9
    # distinct); 12 measured, still one per angle and output group, not one per body
    assert sines_in(compiled_text()) <= 12


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the CPU's fusion")
def test_constants_still_fold():
    """Transcendentals of values that are constants of the compiled program (a motion
    captured by ``jit``) fold at compile time, boundary included: the predicate is read
    from an input they depend on, not from the program's first input."""

    def reordered(w, q0, q1):
        return scalar_program(q0, q1, w)

    closed_w = jax.make_jaxpr(reordered)(ARGS[2], ARGS[0], ARGS[1])
    q0, q1, w = (jnp.linspace(-1.0, 1.0, 256) + k for k in range(3))

    def program(w):  # w at run time; q0, q1 (cos q0, sin(q0 + q1)) constants
        return jax.vmap(lambda *a: schedule(closed_w, *a))(w, q0, q1)

    text = jax.jit(program).lower(w).compile().as_text()
    assert " cosine(" not in text  # cos q0 folded
    assert sines_in(text) == 1  # sin(cos q0 · w), at run time
    # one boundary (sin(cos q0 · w)); none on the constants, whose users fold with them
    assert text.count("conditional(") == 1
    for a, e in zip(jax.jit(program)(w), jax.vmap(scalar_program)(q0, q1, w), strict=True):
        np.testing.assert_allclose(a, e, rtol=1e-13, atol=1e-16)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_wrench_derivatives_through_the_boundary_equal_the_plain_evaluation():
    """Per-sample gradients (``vmap`` of ``grad``), forward Jacobians and a Hessian of the
    replayed DUAL-V wrench (boundaries inside) equal those of the physics as written."""
    from jaxbal._src import momentum

    robot = jaxbal.robots.dual_v()
    q, qd, qdd = random_states(robot, 4, seed=1)  # on its loops (the wrench checks them)

    def norm(replay):
        def f(a, b, c):
            force, moment = momentum._shaking_wrench(robot, a, b, c, None, replay=replay)
            return jnp.sum(force**2) + jnp.sum(moment**2)

        return f

    ours, plain = norm(True), norm(False)
    per_sample = jax.jit(jax.vmap(jax.grad(ours, argnums=(0, 1, 2))))(q, qd, qdd)
    expected = jax.jit(jax.vmap(jax.grad(plain, argnums=(0, 1, 2))))(q, qd, qdd)
    for a, e in zip(per_sample, expected, strict=True):
        np.testing.assert_allclose(a, e, rtol=1e-10, atol=1e-9 * float(jnp.max(jnp.abs(e))))
    hess = jax.jit(jax.hessian(ours))(q[0], qd[0], qdd[0])
    hess_plain = jax.jit(jax.hessian(plain))(q[0], qd[0], qdd[0])
    scale = float(jnp.max(jnp.abs(hess_plain)))
    np.testing.assert_allclose(hess, hess_plain, rtol=1e-9, atol=1e-9 * scale)
    assert bool(jnp.all(jnp.isfinite(hess)))


def test_the_other_backends_boundary_gives_the_same_values(monkeypatch):
    """Off the CPU the boundary is an ``optimization_barrier`` (no GPU in CI: traced here
    with the backend reported as ``gpu``): same values, gradients and nested vmaps."""
    from jaxbal._src import materialise as module

    monkeypatch.setattr(module.jax, "default_backend", lambda: "gpu")
    batch = [jnp.linspace(-1.0, 1.0, 6).reshape(2, 3) + k for k in range(3)]
    nested = jax.jit(jax.vmap(jax.vmap(scheduled_fn)))(*batch)
    expected = jax.vmap(jax.vmap(scalar_program))(*batch)
    for a, e in zip(nested, expected, strict=True):
        np.testing.assert_allclose(a, e, rtol=1e-13, atol=1e-16)
    text = jax.jit(jax.vmap(scheduled_fn)).lower(*(b[0] for b in batch)).as_text()
    assert "optimization_barrier" in text and "case" not in text
    check_grads(lambda *a: sum(scheduled_fn(*a)), ARGS, order=1, modes=("rev",))
