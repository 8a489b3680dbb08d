"""Torque-rate-limited trapezoidal planning (Briot et al. 2012, eqs 5-6)."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src.robots.planar_arm_studies import ComPath
from jaxbal.planning import plan_rate_limited, torque_rate_along

DURATION = 0.5


@pytest.fixture(scope="module")
def move():
    """The 2R's COM line from P5 to P9 (elbow down), a path factory and its data."""
    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    data = (arm, jaxbal.center_of_mass(arm, q0)[:2], jaxbal.center_of_mass(arm, q1)[:2])
    return arm, ComPath(DURATION, 1, None), data


def test_the_plan_meets_the_limit_along_the_whole_move(move):
    """Independent check: the torque rates of the planned profile, sampled densely
    over the whole move, stay within the limit the plan reports meeting."""
    arm, path, data = move
    limit = 28000.0
    plan = plan_rate_limited(arm, path, data, DURATION, limit, grid=8, refinements=1)
    times = jnp.linspace(0.0, DURATION, 4001)
    rates = np.abs(np.asarray(torque_rate_along(arm, path(plan.profile, data), times)))
    assert float(plan.peak_rate) <= limit
    assert rates.max() <= limit * (1 + 1e-3), rates.max()
    assert np.isfinite(float(plan.peak_acceleration)) and float(plan.peak_acceleration) > 4


@pytest.mark.parametrize(
    ("duration", "limit", "named"),
    [
        (0.0, 28000.0, "duration"),
        (-0.5, 28000.0, "duration"),
        (np.nan, 28000.0, "duration"),
        (DURATION, -5.0, "rate_limit"),
        (DURATION, np.inf, "rate_limit"),
    ],
)
def test_a_non_positive_duration_or_limit_is_refused(move, duration, limit, named):
    """T <= 0 sampled the torque rates at t <= 0 only and reported a plan "within" the
    limit whose move broke it 267-fold; NaN was an equinox runtime error."""
    arm, path, data = move
    with pytest.raises(ValueError, match=f"{named} must be finite and > 0"):
        plan_rate_limited(arm, path, data, duration, limit)
