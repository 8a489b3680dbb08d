"""Aggregation over a payload grid (mean, quadratic mean, smooth maximum) and the kinks
of the mean. References: closed forms on small hand-computed arrays; the gradient of
the quadratic mean against finite differences; the co-design's own behaviour at a kink
is in tests/test_joint_codesign.py."""

from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

from jaxbal._src.payload_aggregate import (
    aggregate,
    aggregate_numpy,
    check_aggregable,
    kinks,
    warn_at_kink,
)

VALUES = np.array([[3.0, 2.0], [0.0, 2.0], [4.0, 2.0]])  # (payloads, metrics)
SCALES = jnp.array([5.0, 2.0])


def test_closed_forms():
    # reference: hand computation; the second metric does not depend on the payload
    np.testing.assert_allclose(aggregate(VALUES, SCALES, "mean", 200.0), [7 / 3, 2.0])
    rms = aggregate(VALUES, SCALES, "rms", 200.0)
    np.testing.assert_allclose(rms, [np.sqrt(25 / 3), 2.0], rtol=1e-15)
    smooth = np.asarray(aggregate(VALUES, SCALES, "max", 200.0))
    # log-mean-exp: max v - s log(n)/k <= smax v <= max v, and exact for a constant
    assert 4.0 - 5.0 * np.log(3) / 200.0 <= smooth[0] <= 4.0
    assert smooth[1] == pytest.approx(2.0, rel=1e-14)
    for robust in ("mean", "rms"):
        np.testing.assert_allclose(
            aggregate_numpy(VALUES, robust), aggregate(VALUES, SCALES, robust, 200.0), rtol=1e-14
        )
    np.testing.assert_array_equal(aggregate_numpy(VALUES, "max"), [4.0, 2.0])  # the hard max


def test_quadratic_mean_is_smooth_at_a_balanced_payload():
    """The loss squares the aggregate: the quadratic mean squared is the mean of v²,
    whose derivative in the zero payload's value is 0 (smooth), while the mean's square
    has slope 2·mean/n there from either side of v = |x| (a kink)."""

    @partial(jax.jit, static_argnums=1)
    def squared(x, robust):
        values = jnp.stack(
            [jnp.array([3.0, 2.0]), jnp.stack([jnp.abs(x), 2.0]), jnp.array([4.0, 2.0])]
        )
        return jnp.sum(aggregate(values, SCALES, robust, 200.0) ** 2)

    rms_slope = jax.jit(jax.grad(squared), static_argnums=1)(1e-9, "rms")
    assert abs(float(rms_slope)) < 1e-8  # reference: 2x/n -> 0
    check_grads(lambda x: squared(x, "rms"), (0.3,), order=1, modes=("rev",))
    mean = jax.jit(jax.grad(squared), static_argnums=1)
    assert float(mean(1e-9, "mean")) == pytest.approx(2 * (7 / 3) / 3, rel=1e-6)
    assert float(mean(-1e-9, "mean")) == pytest.approx(-2 * (7 / 3) / 3, rel=1e-6)
    # every payload balanced: zero, with a zero (not NaN) gradient
    zero = jax.grad(lambda v: aggregate(v, SCALES, "rms", 200.0).sum())(jnp.zeros((3, 2)))
    np.testing.assert_array_equal(zero, np.zeros((3, 2)))


def test_kinks_name_the_balanced_payload_only():
    values = VALUES.copy()
    values[1, 0] = 1e-13  # rounding-level zero at payload 2.5 kg
    payloads = [0.0, 2.5, 5.0]
    found = kinks(values, SCALES, ("rms_force", "added_mass"), payloads)
    assert found == ["rms_force = 1e-13 at payload 2.5 kg"]
    # a metric zero at every payload (no counter-mass) is smooth, not a kink
    assert kinks(np.zeros((3, 1)), [1.0], ("added_mass",), payloads) == []
    assert kinks(VALUES + 1.0, SCALES, ("a", "b"), payloads) == []
    with pytest.warns(RuntimeWarning, match=r"gradient norm 0.03\) at a kink .*2.5 kg"):
        warn_at_kink(values, SCALES, ("rms_force", "added_mass"), payloads, 0.03)


def test_quadratic_mean_refuses_negative_metrics():
    with pytest.raises(ValueError, match=r"robust='rms' needs objective metrics >= 0, .*-1\."):
        check_aggregable("rms", np.array([[1.0], [-1.0]]))
    check_aggregable("mean", np.array([[1.0], [-1.0]]))  # a mean of signed values is fine
