"""The affine fast path of jaxbal.sweep (jaxbal._src.sweep_affine): mass-type sweeps of
the wrench metrics equal the direct evaluation to rounding on a serial arm and on the
closed-chain DUAL-V; a nonlinear parameter is detected and evaluated directly (or
refused with linear=True); stores of the two evaluations never mix."""

import jax.numpy as jnp
import numpy as np
import pytest
from conftest import slow_for

import jaxbal
from jaxbal._src.sweep_affine import TOLERANCE, affine_model
from jaxbal.design import motion_samples


@pytest.fixture(scope="module")
def arm():
    robot = jaxbal.robots.planar_2r().with_design({"counter_distance": jnp.array([0.3, 0.2])})
    q0 = robot.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = robot.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    plan = jaxbal.planning.com_line(robot, q0, q1, jaxbal.profiles.BangBang(), 0.5)
    return robot, motion_samples(robot, [plan], jaxbal.sample_times(0.5, 32))


AXES = {"counter_mass": np.linspace(0.0, 3.0, 7), "payload": np.linspace(0.0, 1.0, 5)}


# each reduction (peak, RMS) and each half of the wrench (force, moment) once here
METRICS = ["peak_force", "rms_force", "peak_moment", "rms_moment"]


@pytest.mark.parametrize("metric", slow_for(METRICS, "rms_force", "peak_moment"))
def test_equals_the_direct_metric(arm, metric):
    robot, motion = arm
    fast = jaxbal.sweep(metric, robot, motion, AXES, progress=False)
    direct = jaxbal.sweep(metric, robot, motion, AXES, progress=False, linear=False)
    assert fast.attrs["evaluation"] == "affine" and "evaluation" not in direct.attrs
    np.testing.assert_allclose(fast["value"].values, direct["value"].values, rtol=1e-12)
    assert fast["value"].attrs == direct["value"].attrs  # units


def test_closed_chain_counter_masses_and_payload():
    """DUAL-V (loop closure inside the wrench): four counter-masses as one axis of
    designs, the payload as another; nearly balanced designs (cancellation) included."""
    robot = jaxbal.robots.dual_v()
    line = jaxbal.StraightLine(
        jnp.array([0.0, -0.05, 0.0]), jnp.array([0.05, 0.05, 0.0]), jaxbal.profiles.Quintic(), 0.1
    )
    move = jaxbal.planning.EndEffectorLine(robot, line)
    motion = motion_samples(robot, [move], jaxbal.sample_times(0.1, 16))
    nominal = np.asarray(robot.design()["counter_mass"])
    designs = np.concatenate([nominal[None], np.random.default_rng(1).uniform(0, 16, (5, 4))])
    axes = {
        "design": jaxbal.sweep.points({"counter_mass": designs}),
        "payload": jaxbal.sweep.grid([0.0, 0.3]),
    }
    fast = jaxbal.sweep("peak_force", robot, motion, axes, progress=False)
    direct = jaxbal.sweep("peak_force", robot, motion, axes, progress=False, linear=False)
    assert fast.attrs["evaluation"] == "affine"
    # the balanced design's force is ~1e-2 N from terms of ~10 N: compare on that scale
    scale = float(np.max(direct["value"].values))
    np.testing.assert_allclose(fast["value"].values, direct["value"].values, atol=1e-12 * scale)


def test_nonlinear_parameter_is_evaluated_directly_or_refused(arm):
    """A counter-mass distance enters the wrench nonlinearly (m·r and m·r²): the check
    fails by orders of magnitude, "auto" evaluates directly, linear=True raises. (With
    the default zero counter-masses the wrench does not depend on their distance at all,
    which the check rightly finds affine.)"""
    robot, motion = arm
    robot = robot.with_design({"counter_mass": jnp.array([2.0, 1.0])})
    axes = {"counter_distance": np.linspace(0.1, 0.4, 4), "payload": [0.0, 1.0]}
    plan = jaxbal._src.sweep.plan_parameters(jaxbal._src.sweep._axes(axes), robot, motion)
    _, deviation = affine_model("peak_force", robot, motion, jaxbal._src.sweep._axes(axes), plan)
    assert deviation > 1e3 * TOLERANCE
    _, mass_deviation = affine_model(
        "peak_force",
        robot,
        motion,
        jaxbal._src.sweep._axes(AXES),
        jaxbal._src.sweep.plan_parameters(jaxbal._src.sweep._axes(AXES), robot, motion),
    )
    assert mass_deviation < 1e-13
    auto = jaxbal.sweep("peak_force", robot, motion, axes, progress=False)
    assert "evaluation" not in auto.attrs
    direct = jaxbal.sweep("peak_force", robot, motion, axes, progress=False, linear=False)
    np.testing.assert_array_equal(auto["value"].values, direct["value"].values)
    with pytest.raises(ValueError, match="not affine in the swept parameters"):
        jaxbal.sweep("peak_force", robot, motion, axes, progress=False, linear=True)


def test_linear_true_needs_a_named_wrench_metric_and_a_fixed_motion(arm):
    robot, motion = arm
    with pytest.raises(ValueError, match="linear=True needs one of the metrics"):
        jaxbal.sweep("peak_torque", robot, motion, AXES, progress=False, linear=True)
    with pytest.raises(ValueError, match="linear must be"):
        jaxbal.sweep("peak_force", robot, motion, AXES, progress=False, linear="yes")


@pytest.mark.slow
def test_huge_masses_do_not_overflow(arm):
    """Payloads up to 1e160 kg: forces of ~1e162 N whose squares would overflow are
    scaled by a power of two, as the direct metric scales them."""
    robot, motion = arm
    axes = {"payload": [0.0, 1e100, 1e160]}
    fast = jaxbal.sweep("peak_force", robot, motion, axes, progress=False)
    direct = jaxbal.sweep("peak_force", robot, motion, axes, progress=False, linear=False)
    assert fast.attrs["evaluation"] == "affine"
    assert np.all(np.isfinite(fast["value"].values))
    np.testing.assert_allclose(fast["value"].values, direct["value"].values, rtol=1e-12)


def test_a_store_of_one_evaluation_is_not_resumed_by_the_other(arm, tmp_path):
    robot, motion = arm
    path = tmp_path / "s.zarr"
    jaxbal.sweep("peak_force", robot, motion, AXES, store=path, progress=False, linear=False)
    with pytest.raises(ValueError, match="different sweep"):
        jaxbal.sweep("peak_force", robot, motion, AXES, store=path, resume=True, progress=False)
    again = jaxbal.sweep(
        "peak_force", robot, motion, AXES, store=path, resume=True, progress=False, linear=False
    )
    assert "evaluation" not in again.attrs


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_massless_point_gives_an_exact_zero(arm):
    """Linearised at zero masses: a point whose swept masses are all zero (links and
    payload here, counter-masses zero by default) is an exact zero, as directly (found by
    the fuzz: linearised at the first point it was 1e-15 N)."""
    robot, motion = arm
    axes = {
        "payload": jaxbal.sweep.grid([3.0, 0.0]),
        "m": jaxbal.sweep.grid([0.0, 1.0], where=lambda r: r.masses),
    }
    fast = jaxbal.sweep("peak_force", robot, motion, axes, progress=False)
    assert fast.attrs["evaluation"] == "affine"
    assert float(fast["value"].sel(payload=0.0, m=0.0)) == 0.0
    direct = jaxbal.sweep("peak_force", robot, motion, axes, progress=False, linear=False)
    np.testing.assert_allclose(fast["value"].values, direct["value"].values, rtol=1e-12)
