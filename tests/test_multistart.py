"""Several starts of a joint co-design (2R instance of tests/test_joint_codesign.py).

References: the losses compare because every start uses the same scales (the given
start's run equals a plain ``joint_codesign`` with those scales); a start taken from a
solution cannot end above it (each run keeps its start if it ends above); the random
starts lie inside their bounds and follow the seed.
"""

import jax.numpy as jnp
import numpy as np
import pytest
from test_joint_codesign import LOWER, THETA, UPPER

import jaxbal
from jaxbal._src.design_loss import _bounds
from jaxbal._src.multistart import INSET, _random_starts
from jaxbal.design import (
    TrapezoidLine,
    joint_codesign,
    multistart_joint_codesign,
    payload_metrics,
)

PAYLOADS = jnp.array([0.0, 5.0])
OPTIONS = {
    "trajectory_lower": LOWER,
    "trajectory_upper": UPPER,
    "payloads": PAYLOADS,
    "upper": {"counter_distance": 0.3},
    "constraints": {"added_mass": 3.0},
    "max_steps": 40,
}


@pytest.fixture(scope="module")
def problem():
    """The 2R and move of tests/test_joint_codesign.py (a fixture cannot be imported)."""
    start, end = jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70])
    return jaxbal.robots.planar_2r(), TrapezoidLine(start, end, jaxbal.sample_times(0.5, 16))


@pytest.fixture(scope="module")
def several(problem):
    arm, move = problem
    return multistart_joint_codesign(arm, move, THETA, "rms_force", starts=2, seed=3, **OPTIONS)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_given_start_is_the_plain_run_and_best_is_the_lowest_feasible(problem, several):
    arm, move = problem
    plain = joint_codesign(arm, move, THETA, "rms_force", **OPTIONS)
    # same default scales: the given start's loss equals the plain run's. The scales are
    # the same means computed by two programs (the plain run's, and payload_metrics's
    # averaged in NumPy), equal to rounding, which 40 quasi-Newton steps amplified to
    # 8e-12 (rtol 1e-12 failed with this file run alone, passed in the full suite); a
    # scale 1e-6 off would change the loss by ~2e-6.
    np.testing.assert_allclose(several.values[0], float(plain.value), rtol=1e-9)
    assert several.kinds == ("given", "random", "random")
    assert several.feasible.any()
    assert float(several.best.value) == np.min(several.values[several.feasible])
    assert np.all(np.isfinite(several.values))
    assert several.near[int(np.argmin(np.where(several.feasible, several.values, np.inf)))]
    # the best design's metric, recomputed independently, is what it reports
    worst = payload_metrics(
        several.best.robot, move, several.best.trajectory, PAYLOADS, ("rms_force",)
    )
    assert np.all(np.isfinite(np.asarray(worst)))
    for name, (low, high) in several.spread().items():
        part = "trajectory" if name in THETA else "design"
        value = np.asarray(getattr(several.best, part)[name])
        assert np.all(low <= value) and np.all(value <= high)


def test_a_start_from_a_solution_cannot_end_above_it(problem, several):
    arm, move = problem
    again = multistart_joint_codesign(
        arm, move, THETA, "rms_force", starts=0, extra_starts=[several.best], **OPTIONS
    )
    assert again.kinds == ("given", "extra")
    assert float(again.best.value) <= float(several.best.value) * (1 + 1e-12)


def test_random_starts_inside_bounds_and_reproducible(problem):
    arm, _ = problem
    free = ("counter_mass", "counter_distance")
    lows, highs, two = _bounds(arm, free, None, {"counter_distance": 0.3})
    design = arm.design()

    def draw(seed):
        rng = np.random.default_rng(seed)
        return _random_starts(rng, 5, THETA, LOWER, UPPER, design, free, lows, highs, two)

    first, second, other = draw(1), draw(1), draw(2)
    for (ta, da), (tb, db) in zip(first, second, strict=True):
        assert ta == tb and all(np.array_equal(da[n], db[n]) for n in free)
    assert any(a[0]["u2"] != b[0]["u2"] for a, b in zip(first, other, strict=True))
    for theta, chosen in first:
        for name, value in theta.items():
            span = UPPER[name] - LOWER[name]
            assert LOWER[name] + INSET * span <= value <= UPPER[name] - INSET * span
        assert np.all((0.0 <= chosen["counter_distance"]) & (chosen["counter_distance"] <= 0.3))
        np.testing.assert_array_equal(chosen["counter_mass"], design["counter_mass"])  # 1-sided


def test_refused_start_is_recorded_and_given_one_raises(problem):
    arm, move = problem
    outside = {"trajectory": {"u2": 0.9, "ratio": 0.5}}  # u2 above its bound
    result = multistart_joint_codesign(
        arm, move, THETA, "rms_force", starts=0, extra_starts=[outside], **OPTIONS
    )
    assert result.solutions[1] is None and result.values[1] == np.inf
    assert "u2" in result.errors[1] and not result.feasible[1]
    with pytest.raises(ValueError, match="u2"):
        multistart_joint_codesign(arm, move, {"u2": 0.9, "ratio": 0.5}, starts=0, **OPTIONS)


@pytest.mark.parametrize(
    "bad", [{"starts": -1}, {"starts": 1.5}, {"starts": True}, {"near_rtol": 0.0}]
)
def test_bad_arguments_raise(problem, bad):
    arm, move = problem
    with pytest.raises(ValueError):
        multistart_joint_codesign(arm, move, THETA, **{**OPTIONS, **bad})


def test_bad_extra_start_raises(problem):
    arm, move = problem
    with pytest.raises(ValueError, match="extra start"):
        multistart_joint_codesign(arm, move, THETA, starts=0, extra_starts=[1.0], **OPTIONS)
