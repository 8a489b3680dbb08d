"""A trajectory written as a lambda (or a closure) compiles once: an equivalent new one
(same code, new closed-over values) reuses the compilation (counted with JAX's
backend-compile events, as in test_recompilation.py)."""

import jax
import jax.numpy as jnp
import numpy as np

import jaxbal
from jaxbal._src.callables import PytreeFunction, as_pytree
from jaxbal.planning import EndEffectorLine
from jaxbal.profiles import Quintic

_COMPILES = []
jax.monitoring.register_event_duration_secs_listener(
    lambda event, duration, **kw: _COMPILES.append(event) if "backend_compile" in event else None
)


def _line(robot, end_x):
    line = jaxbal.StraightLine(jnp.array([0.4, 0.3]), jnp.array([end_x, 0.5]), Quintic(), 0.2)
    return EndEffectorLine(robot, line)


def test_equivalent_lambdas_compile_once():
    robot = jaxbal.robots.planar_2r()
    times = jaxbal.sample_times(0.2, 11)
    results = []
    counts = []
    for end_x in (0.2, 0.25):
        path = _line(robot, end_x)
        before = len(_COMPILES)
        # a new lambda object each time, as a notebook cell would make it
        results.append(jaxbal.design.motion_samples(robot, lambda t: path(t), times))  # noqa: B023
        counts.append(len(_COMPILES) - before)
    assert counts[0] > 0 and counts[1] == 0, counts
    # the second lambda really used its own closure (another end pose)
    assert not np.allclose(results[0].q[-1], results[1].q[-1])
    direct = jaxbal.design.motion_samples(robot, _line(robot, 0.25), times)
    np.testing.assert_allclose(results[1].q, direct.q, rtol=0, atol=1e-15)


def test_eager_sample_is_one_program_compiled_once():
    """``jaxbal.sample`` called eagerly: an equivalent new lambda compiles nothing, and
    the samples equal the closed form ``(sin ωt, ω cos ωt, −ω² sin ωt, −ω³ cos ωt)``
    (tol 1e-12) with their own closure's ``ω``."""
    times = jnp.linspace(0.0, 1.0, 7)
    counts = []
    for omega in (2.0, 3.0):
        w = jnp.asarray(omega)
        before = len(_COMPILES)
        s, sd, sdd, sddd = jaxbal.sample(lambda t: jnp.sin(w * t), times, order=3)  # noqa: B023
        counts.append(len(_COMPILES) - before)
        sin, cos = jnp.sin(omega * times), jnp.cos(omega * times)
        expected = (sin, omega * cos, -(omega**2) * sin, -(omega**3) * cos)
        for got, want in zip((s, sd, sdd, sddd), expected, strict=True):
            np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    assert counts[0] > 0 and counts[1] == 0, counts


def test_pytree_function_is_the_same_function():
    scale = jnp.asarray(3.0)

    def f(x, offset=1.0):
        return scale * x + offset

    g = as_pytree(f)
    assert isinstance(g, PytreeFunction)
    assert float(g(2.0)) == float(f(2.0)) == 7.0
    assert float(g(2.0, offset=0.0)) == 6.0
    # closed-over arrays are leaves (traced by jit), the code is static
    assert len(jax.tree_util.tree_leaves(g)) == 2
    assert float(jax.jit(lambda h: h(1.0))(g)) == 4.0


def test_other_callables_are_unchanged():
    line = _line(jaxbal.robots.planar_2r(), 0.2)
    assert as_pytree(line) is line
    assert as_pytree(np.sin) is np.sin
