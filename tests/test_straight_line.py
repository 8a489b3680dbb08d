"""The straight-line replay of a jaxpr (jaxbal/_src/straight_line.py).

References: the same function evaluated by XLA without the replay (``jax.jit`` of the
original), to 1e-13 relative, and central finite differences (``check_grads``).
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import random_states as states
from jax.test_util import check_grads

import jaxbal
from jaxbal._src import momentum
from jaxbal._src.straight_line import straight_line

ROBOTS = ["planar_2r", "planar_3r", "scara", "dual_v", "orthoglide"]


@pytest.mark.parametrize("name", ROBOTS)
def test_wrench_equals_the_plain_xla_evaluation(name):
    robot = getattr(jaxbal.robots, name)()
    q, qd, qdd = states(robot, 16)

    def plain(a, b, c):
        return momentum._shaking_wrench(robot, a, b, c, jnp.array([0.0, 0.0, -9.81]))

    def replayed(a, b, c):
        return jaxbal.shaking_wrench(robot, a, b, c, gravity=(0.0, 0.0, -9.81))

    expected = jax.jit(jax.vmap(plain))(q, qd, qdd)
    actual = jax.jit(jax.vmap(replayed))(q, qd, qdd)
    for a, e in zip(actual, expected, strict=True):
        scale = float(jnp.max(jnp.abs(e)))
        np.testing.assert_allclose(a, e, rtol=0, atol=1e-13 * scale)
        assert scale > 1.0  # a real, non-trivial wrench


@pytest.mark.parametrize(
    "name", ["planar_2r", "scara", pytest.param("orthoglide", marks=pytest.mark.slow)]
)
def test_wrench_gradients_match_finite_differences(name):
    robot = getattr(jaxbal.robots, name)()
    q, qd, qdd = (x[0] for x in states(robot, 1, seed=3))

    @jax.jit
    def force_norm(q_, qd_, qdd_):
        # the bodies' wrench: the finite differences leave a closed chain's loops
        force, moment = momentum.tree_wrench(robot, q_, qd_, qdd_)
        return jnp.sum(force**2) + jnp.sum(moment**2)

    check_grads(force_norm, (q, qd, qdd), order=1, modes=["rev", "fwd"], eps=1e-5, rtol=1e-5)
    grads = jax.grad(force_norm, argnums=(0, 1, 2))(q, qd, qdd)
    assert all(bool(jnp.all(jnp.isfinite(g))) for g in grads)


def test_parameter_gradient_equals_the_plain_evaluation():
    robot = jaxbal.robots.dual_v()
    q, qd, qdd = (x[0] for x in states(robot, 1, seed=5))

    def loss(fn):
        def value(r):
            force, moment = fn(r, q, qd, qdd, None)
            return jnp.sum(force**2) + jnp.sum(moment**2)

        return jax.jit(jax.grad(value))(robot)

    plain = jax.tree_util.tree_leaves(loss(momentum._shaking_wrench))
    replayed = jax.tree_util.tree_leaves(loss(jaxbal.shaking_wrench))
    for a, e in zip(replayed, plain, strict=True):
        np.testing.assert_allclose(a, e, rtol=1e-11, atol=1e-11 * float(jnp.max(jnp.abs(e)) + 1))


def mixed(x, y):
    """Every structural primitive the interpreter rewrites, and some it does not."""
    m = jnp.outer(x, y)  # broadcast / dot_general
    m = jnp.pad(m, ((1, 0), (0, 2)), constant_values=0.5)
    s = jnp.cumsum(m, axis=1)[:, ::-1].T  # cumsum, rev, transpose
    d = jnp.dot(s, x[: s.shape[1]] if s.shape[1] <= x.size else jnp.ones(s.shape[1]))
    r = jnp.concatenate([jnp.sum(m, 0), jnp.max(m, 1), jnp.prod(x)[None]])
    g = x[jnp.array([2, 0])]  # gather: evaluated on arrays
    c = jax.lax.cond(x[0] > 0, lambda v: jnp.sin(v), lambda v: jnp.cos(v), y)
    w = jax.lax.fori_loop(0, 3, lambda i, v: v * 0.5 + 1.0, y)  # while: on arrays
    return jnp.concatenate([d, r, g, c, w, jnp.where(x > 0.3, x, -x), jnp.arctan2(x, y)])


def test_structural_and_fallback_primitives():
    rng = np.random.default_rng(0)
    x, y = (jnp.asarray(rng.uniform(-1, 1, (10, 3))) for _ in range(2))
    expected = jax.jit(jax.vmap(mixed))(x, y)
    actual = jax.jit(jax.vmap(straight_line(mixed)))(x, y)
    np.testing.assert_allclose(actual, expected, rtol=1e-14, atol=1e-14)
    check_grads(jax.jit(straight_line(mixed)), (x[1], y[1]), order=1, modes=["rev"])


def several(x, y):
    """``split`` and ``unstack`` (several results each), as the transposes of a
    ``concatenate`` and a ``stack`` in a ``vjp`` (the actuator torques' projection)."""
    first, rest = jnp.split(x, [1])
    rows = jnp.unstack(jnp.outer(x, y))
    _, pull = jax.vjp(lambda v: jnp.stack([jnp.concatenate([v, v**2]), jnp.sin(v).repeat(2)]), y)
    return jnp.concatenate(
        [first * rest[0], rest, *rows, pull(jnp.outer(x[:2], jnp.concatenate([x, x])))[0]]
    )


def test_split_and_unstack_stay_scalar_code(monkeypatch):
    """Rewritten as scalars, not evaluated on re-assembled arrays (which broke the
    replay of the torques' projection into array kernels: 2R torques ~60× slower)."""
    from jaxbal._src import straight_line as module

    fallbacks = []
    original = module._fallback
    monkeypatch.setattr(
        module, "_fallback", lambda eqn, args: fallbacks.append(eqn) or original(eqn, args)
    )
    rng = np.random.default_rng(1)
    x, y = (jnp.asarray(rng.uniform(-1, 1, (6, 3))) for _ in range(2))
    expected = jax.jit(jax.vmap(several))(x, y)
    actual = jax.jit(jax.vmap(straight_line(several)))(x, y)
    np.testing.assert_allclose(actual, expected, rtol=1e-14, atol=1e-14)
    assert not fallbacks, [e.primitive.name for e in fallbacks]


def test_reductions_over_empty_axes_give_the_identity():
    """jnp.all/any/sum/prod/max/min over zero elements (an MJCF robot without loops or
    parameters to check) equal XLA's own result, as in the plain evaluation."""

    def empty(x):
        none = x[:0]
        return (
            jnp.stack(
                [
                    jnp.all(none > 0).astype(float),
                    jnp.any(none > 0).astype(float),
                    jnp.sum(none),
                    jnp.prod(none),
                    jnp.max(none, initial=-3.0),
                    jnp.min(none, initial=3.0),
                    jnp.max(jnp.arange(0)[None], axis=1, initial=-5)[0].astype(float),
                ]
            )
            + x[0]
        )

    x = jnp.linspace(0.1, 1.0, 8).reshape(4, 2)
    expected = jax.jit(jax.vmap(empty))(x)
    np.testing.assert_array_equal(jax.jit(jax.vmap(straight_line(empty)))(x), expected)


def test_eager_calls_run_the_original_function():
    calls = []

    def f(x):
        calls.append(type(x))
        return x * 2.0

    assert float(straight_line(f)(jnp.asarray(1.5))) == 3.0
    assert not issubclass(calls[0], jax.core.Tracer)


def test_runtime_checks_survive_the_replay():
    robot = jaxbal.robots.scara()
    wrench = jax.jit(lambda q: jaxbal.shaking_wrench(robot, q, q, q))
    with pytest.raises(Exception, match="non-finite state"):
        jax.block_until_ready(wrench(jnp.full(robot.dof, jnp.nan)))
    with pytest.raises(ValueError, match="qd must have shape"):
        jax.jit(lambda q: jaxbal.shaking_wrench(robot, q, q[:1], q))(jnp.zeros(robot.dof))


def test_replay_setting_is_part_of_the_trace_key():
    """A nested compiled function traced with the replay off (e.g. by the co-design,
    ``replayed(False)``) is not reused with the replay on: the switch is a _TraceFlag,
    in JAX's trace keys (it was a plain Python list, read at trace time)."""
    robot = jaxbal.robots.planar_2r()
    q, qd, qdd = (a[0] for a in states(robot, 1))
    inner = jax.jit(lambda a, b, c: jaxbal.shaking_wrench(robot, a, b, c))

    def size(closed):  # equations of the nested program
        (eqn,) = [e for e in closed.jaxpr.eqns if "jaxpr" in e.params]
        return len(eqn.params["jaxpr"].jaxpr.eqns)

    with momentum.replayed(False):
        plain = size(jax.make_jaxpr(inner)(q, qd, qdd))
    replay = size(jax.make_jaxpr(inner)(q, qd, qdd))
    with momentum.replayed(False):
        again = size(jax.make_jaxpr(inner)(q, qd, qdd))
    assert plain == again and replay != plain


def test_code_too_large_to_pay_off_runs_as_written(monkeypatch):
    """Generated code above MAX_GENERATED operations is not used (found with an MJCF
    3-RRR: 9,148 operations compiled in 8 s for a 1.3x faster wrench): the function is
    evaluated as written, with the same values, and the generation stops as soon as it
    passes the limit."""
    from jaxbal._src import straight_line as module

    def f(x):
        return jnp.sum(jnp.sin(x) * jnp.cos(x[::-1]) + x**2)

    from jaxbal._src import scalar_rules

    x = jnp.linspace(0.1, 1.0, 12)
    replayed_code = jax.make_jaxpr(straight_line(f))(x)
    traced = []  # the operations the interpreter emits on traced values
    emit = scalar_rules._emit

    def spy(name, primitive, params, args, dtype):
        traced.append(not all(scalar_rules.concrete(a) for a in args))
        return emit(name, primitive, params, args, dtype)

    monkeypatch.setattr(scalar_rules, "_emit", spy)
    jax.make_jaxpr(straight_line(f))(x)
    emitted_in_full, traced[:] = sum(traced), []
    monkeypatch.setattr(module, "MAX_GENERATED", 5)
    plain = jax.make_jaxpr(straight_line(f))(x)  # a new wrapper: its own cache
    assert str(plain) == str(jax.make_jaxpr(f)(x)) != str(replayed_code)
    # the generation stopped at the limit instead of generating everything first
    assert emitted_in_full > 40 and sum(traced) == 6
    np.testing.assert_allclose(float(jax.jit(straight_line(f))(x)), float(f(x)), rtol=1e-15)


def repeated(q):
    """The same cosine, sine and sum recomputed, as a chain's poses do for each body,
    and a product written in both operand orders."""
    c, s = jnp.cos(q[0]), jnp.sin(q[0])
    again = jnp.cos(q[0]) * q[1] + q[1] * jnp.cos(q[0])
    return jnp.stack([c * s, jnp.sin(q[0]) * jnp.cos(q[0]), again, (q[0] + q[1]) * (q[1] + q[0])])


def test_repeated_operations_are_emitted_once():
    """Common subexpressions of the replay (jaxbal/_src/scalar_rules.py): each distinct
    operation once (commuted sums and products included), the same bits as without."""
    from jax.extend import core

    q = jnp.asarray([0.3, -1.2])

    def names(jaxpr):
        out = []
        for eqn in jaxpr.eqns:
            subs = list(core.jaxprs_in_params(eqn.params))
            out += [n for sub in subs for n in names(sub)] if subs else [eqn.primitive.name]
        return out

    names = names(jax.make_jaxpr(straight_line(repeated))(q).jaxpr)
    assert names.count("cos") == 1 and names.count("sin") == 1, names
    assert names.count("add") == 2, names  # q0 + q1 once; the doubled product once
    expected = jax.jit(repeated)(q)
    actual = jax.jit(straight_line(repeated))(q)
    np.testing.assert_array_equal(actual, expected)
    check_grads(jax.jit(straight_line(repeated)), (q,), order=1, modes=["rev", "fwd"])


def test_as_written_reuses_the_jaxpr_traced_for_the_replay():
    """``straight_line(f).as_written`` (the peak sample's re-evaluation) is ``f`` as
    written, not replayed: the same jaxpr as tracing ``f``, its values and derivatives
    bit for bit; after the replay of the same call it evaluates the jaxpr traced then
    instead of running ``f`` again, and without one it runs ``f``."""
    calls = []

    def f(x, scale):
        calls.append(1)
        return jnp.sin(x) * scale + jnp.cos(x[::-1]) ** 2

    wrapped = straight_line(f)
    x, scale = jnp.linspace(0.1, 1.0, 5), jnp.asarray(2.0)
    as_written = jax.make_jaxpr(wrapped.as_written)(x, scale)  # nothing cached: f traced
    assert len(calls) == 1 and str(as_written) == str(jax.make_jaxpr(f)(x, scale))

    def replay_then_as_written(x, scale):
        return jax.vmap(wrapped, (0, None))(jnp.stack([x, 2 * x]), scale), wrapped.as_written(
            x, scale
        )

    calls.clear()
    replayed, plain = jax.jit(replay_then_as_written)(x, scale)
    assert len(calls) == 1  # traced once, for the replay
    np.testing.assert_array_equal(plain, jax.jit(f)(x, scale))
    np.testing.assert_allclose(replayed[0], plain, rtol=1e-15)
    tangent = jax.jit(lambda s: jax.jvp(lambda s_: wrapped.as_written(x, s_), (s,), (1.0,)))
    expected = jax.jit(lambda s: jax.jvp(lambda s_: f(x, s_), (s,), (1.0,)))(scale)
    for a, b in zip(tangent(scale), expected, strict=True):
        np.testing.assert_array_equal(a, b)
