"""The straight-line program's call under ``vmap`` (jaxbal/_src/batched_call.py): its
scalar equations bound again on the batched values instead of JAX's batching pass.

References: a Python loop over the samples, ``jax.vmap`` of the unbatched program
(JAX's own batching, bit for bit) and of the function as written (1e-13), finite
differences (``check_grads``)."""

import collections
import re

import jax
import jax.numpy as jnp
import numpy as np
from jax.test_util import check_grads

from jaxbal._src.straight_line import straight_line


def physics(robot_scale, q, qd):
    """Sines shared by several outputs (materialised), an array output, a scalar output
    and an output that does not depend on the batched inputs."""
    c, s = jnp.cos(q), jnp.sin(q)
    force = robot_scale * jnp.stack([c[0] * qd[0] ** 2, s[0] * qd[1] - c[1], s[1] * c[0]])
    return force, jnp.sum(c * s * qd), robot_scale**2 + 1.0


def _inputs(count=7):
    rng = np.random.default_rng(3)
    q, qd = (jnp.asarray(rng.normal(size=(count, 2))) for _ in range(2))
    return jnp.asarray(1.7), q, qd


def test_batched_call_equals_a_loop_and_jax_batching_bit_for_bit():
    scale, q, qd = _inputs()
    wrapped = straight_line(physics)
    batched = jax.jit(jax.vmap(wrapped, in_axes=(None, 0, 0)))(scale, q, qd)
    for k in range(q.shape[0]):
        one = jax.jit(wrapped)(scale, q[k], qd[k])
        for a, b in zip(batched[:2], one[:2], strict=True):
            np.testing.assert_array_equal(a[k], b)
    np.testing.assert_array_equal(batched[2], physics(scale, q[0], qd[0])[2])  # broadcast
    expected = jax.vmap(physics, in_axes=(None, 0, 0))(scale, q, qd)
    for a, b in zip(batched, expected, strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=1e-15)


def test_nested_vmap_and_batched_parameters_equal_a_loop():
    scale, q, qd = _inputs(5)
    scales = jnp.asarray([0.5, 2.0, 3.0])
    wrapped = straight_line(physics)
    both = jax.jit(jax.vmap(jax.vmap(wrapped, in_axes=(None, 0, 0)), in_axes=(0, None, None)))
    out = both(scales, q, qd)
    for i, s in enumerate(scales):
        expected = jax.vmap(physics, in_axes=(None, 0, 0))(s, q, qd)
        for a, b in zip(out, expected, strict=True):
            np.testing.assert_allclose(a[i], b, rtol=1e-13, atol=1e-15)


def test_derivatives_are_the_programs_own():
    """``custom_jvp`` of the batched call: ``grad`` of a batched sum, a Hessian and a
    batched gradient equal those of the function as written, and finite differences."""
    scale, q, qd = _inputs(4)
    wrapped = straight_line(physics)

    def loss(f, s, q_, qd_):
        force, total, constant = jax.vmap(f, in_axes=(None, 0, 0))(s, q_, qd_)
        return jnp.sum(force**2) + jnp.sum(total) + jnp.sum(constant)

    for argnums in (0, 1, 2):
        ours = jax.jit(jax.grad(lambda *a: loss(wrapped, *a), argnums))(scale, q, qd)
        plain = jax.grad(lambda *a: loss(physics, *a), argnums)(scale, q, qd)
        assert np.all(np.isfinite(np.asarray(ours)))
        np.testing.assert_allclose(ours, plain, rtol=1e-12, atol=1e-14)
    hessian = jax.jit(jax.hessian(lambda s: loss(wrapped, s, q, qd)))(scale)
    np.testing.assert_allclose(hessian, jax.hessian(lambda s: loss(physics, s, q, qd))(scale),
                               rtol=1e-12)  # fmt: skip
    per_sample = jax.jit(jax.vmap(jax.grad(lambda s, a, b: wrapped(s, a, b)[1]), (None, 0, 0)))
    expected = jax.vmap(jax.grad(lambda s, a, b: physics(s, a, b)[1]), (None, 0, 0))
    np.testing.assert_allclose(per_sample(scale, q, qd), expected(scale, q, qd), rtol=1e-12)
    check_grads(lambda s, a: loss(wrapped, s, a, qd), (scale, q), order=2, modes=["fwd", "rev"])


def _arithmetic(text):
    ops = collections.Counter(re.findall(r"= stablehlo\.(\w+)", text))
    return {k: ops[k] for k in ("multiply", "add", "subtract", "divide", "sine", "cosine")}


def scalar_program(a, b, c):
    """Scalar code with a dead product, a shared sine and an unbatched constant output."""
    s = jnp.sin(a)
    _dead = s * b * 7.0
    return s * b + c, s * c - a / b, c * 2.0


def test_batched_call_lowers_to_the_operations_of_jax_batching():
    """The batched call lowers to the same arithmetic as ``vmap`` of the unbatched
    program (JAX's batching, dead code removed by JAX): nothing duplicated, and the dead
    product left out (the batched program is opaque to JAX's dead-code elimination, so
    ``_emit`` skips the equations no output depends on)."""
    from jax.extend import core

    from jaxbal._src.batched_call import batchable

    specs = [jax.ShapeDtypeStruct((), jnp.float64)] * 3
    closed = jax.make_jaxpr(scalar_program)(*specs)
    call = batchable(jax.jit(core.jaxpr_as_fun(closed)), closed)
    a, b = jnp.linspace(0.1, 1.0, 6), jnp.linspace(1.0, 2.0, 6)
    c = jnp.asarray(0.3)
    axes = (0, 0, None)
    ours = jax.jit(jax.vmap(call, in_axes=axes))
    reference = jax.jit(jax.vmap(call.program, in_axes=axes))
    for x, y in zip(ours(a, b, c), reference(a, b, c), strict=True):
        np.testing.assert_array_equal(x, np.broadcast_to(y, np.shape(x)))
    counts = _arithmetic(ours.lower(a, b, c).as_text())
    assert counts == _arithmetic(reference.lower(a, b, c).as_text())
    assert counts["multiply"] == 3 and counts["sine"] == 1, counts
    # under vmap the call is a custom_vmap (opaque to checkify's and partial
    # evaluation's re-traces) holding the batched program
    assert "custom_vmap_call" in str(jax.make_jaxpr(jax.vmap(call, in_axes=axes))(a, b, c))
