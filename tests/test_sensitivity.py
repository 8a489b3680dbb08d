"""Design sensitivities on every robot (jaxbal.sensitivity): automatic differentiation
against central finite differences, re-planned motions and input errors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.design import Motion, motion_samples, rms_force
from jaxbal.planning import EndEffectorLine, com_line
from jaxbal.profiles import Quintic
from jaxbal.robots import planar_arm
from jaxbal.sensitivity import payload_sensitivity, sensitivity

SAMPLES = 31
ORTHOGLIDE_START, ORTHOGLIDE_END, ORTHOGLIDE_DURATION = (
    jnp.zeros(3),
    jnp.array([-0.1, 0.07, -0.11]),
    0.1,
)


def _line(robot, start, end, duration):
    trajectory = EndEffectorLine(robot, jaxbal.StraightLine(start, end, Quintic(), duration))
    return motion_samples(robot, trajectory, jnp.linspace(0.0, duration, SAMPLES))


def _planar_2r():
    robot = jaxbal.robots.planar_2r().with_design(
        {"counter_mass": jnp.array([2.0, 1.0]), "counter_distance": jnp.array([0.35, 0.2])}
    )
    return robot, _line(robot, [0.6, 0.1], [0.1, 0.6], 0.3)


def _planar_3r():
    robot = jaxbal.robots.planar_3r()
    return robot, _line(robot, [0.6, 0.1, 0.0], [0.1, 0.6, 1.0], 0.3)


def _scara():
    robot = jaxbal.robots.scara(payload=0.5)
    move = jaxbal.robots.PickAndPlace(
        [0.15, 0.2, np.deg2rad(83.0)], [-0.15, 0.2, np.deg2rad(157.0)], 0.3, lift=0.03
    )
    trajectory = jaxbal.robots.ScaraTrajectory(robot, move)  # reachable: see test_design
    return robot, motion_samples(robot, trajectory, jnp.linspace(0.0, 0.3, SAMPLES))


def _dual_v():
    robot = jaxbal.robots.dual_v(payload=0.5)
    return robot, _line(robot, [0.0, -0.05, 0.0], [0.05, 0.05, 0.0], 0.1)


def _orthoglide():
    robot = jaxbal.robots.orthoglide(payload=1.0)
    return robot, _line(robot, ORTHOGLIDE_START, ORTHOGLIDE_END, ORTHOGLIDE_DURATION)


CASES = {
    "planar_2r": _planar_2r,
    "planar_3r": _planar_3r,
    "scara": _scara,
    "dual_v": _dual_v,
    "orthoglide": _orthoglide,
}
#: cases whose gradient compiles for long: make test-all
LONG_COMPILES = {"dual_v", "orthoglide"}


@jax.jit
def _rms_force_with_payload(robot, motion, payload):
    return rms_force(robot.with_design({"payload": payload}), motion)


@pytest.mark.parametrize(
    "name",
    [pytest.param(n, marks=pytest.mark.slow) if n in LONG_COMPILES else n for n in CASES],
)
def test_gradient_matches_central_differences(name):
    """∂ rms_force / ∂(payload, counter_mass) on each robot equals central finite
    differences to 1e-6 relative (sensitivity's own check, relative step 1e-6), and the
    payload entry equals an independent central difference of the test (step 1e-4 kg,
    truncation error ~1e-9) to 1e-6 relative."""
    robot, motion = CASES[name]()
    result = sensitivity(
        robot, motion, "rms_force", wrt=("payload", "counter_mass"), check=True, rtol=1e-6
    )
    assert float(result.max_relative_error) <= 1e-6
    assert set(result.gradient) == {"payload", "counter_mass"}
    assert result.gradient["counter_mass"].shape == robot.design()["counter_mass"].shape
    payload, step = float(robot.design()["payload"]), 1e-4
    central = (
        _rms_force_with_payload(robot, motion, payload + step)
        - _rms_force_with_payload(robot, motion, payload - step)
    ) / (2 * step)
    np.testing.assert_allclose(result.gradient["payload"], central, rtol=1e-6)
    value = _rms_force_with_payload(robot, motion, payload)
    np.testing.assert_allclose(result.value, value, rtol=1e-12)


PLAN_START, PLAN_END, PLAN_DURATION = jnp.array([0.3, 1.2]), jnp.array([1.4, 0.6]), 0.3


def com_plan_2r(robot):
    """The 2R's motion re-planned for its design: the total COM on a straight line
    (quintic) between its positions in two fixed configurations (Briot et al. 2012,
    eqs 3 and 8-12): the joint motion depends on the payload and counterweights."""
    # the COM branch that joins these configurations (com_line refuses another; this
    # test had planned in the other elbow mode)
    plan = com_line(robot, PLAN_START, PLAN_END, Quintic(), PLAN_DURATION, branch=-1)
    return motion_samples(robot, plan, jnp.linspace(0.0, PLAN_DURATION, SAMPLES))


@pytest.mark.slow
def test_replanned_motion_includes_the_plan():
    """With the motion re-planned from the design (COM plan of the 2R), the payload and
    counter-mass sensitivities of the RMS force equal central finite differences of
    the re-planned metric (1e-6 relative, relative step 1e-6) and differ from those
    with the motion held fixed (by > 1 %: the plan depends on the design)."""
    robot, _ = _planar_2r()
    wrt = ("payload", "counter_mass")
    replanned = sensitivity(robot, com_plan_2r, "rms_force", wrt=wrt, check=True)
    assert float(replanned.max_relative_error) <= 1e-6
    fixed_motion = com_plan_2r(robot)
    fixed = sensitivity(robot, fixed_motion, "rms_force", wrt=wrt)
    np.testing.assert_allclose(fixed.value, replanned.value, rtol=1e-12)
    ratio = fixed.gradient["payload"] / replanned.gradient["payload"]
    assert abs(float(ratio) - 1.0) > 1e-2
    payload_only = payload_sensitivity(robot, fixed_motion, "rms_force")
    np.testing.assert_allclose(payload_only, fixed.gradient["payload"], rtol=1e-12)


def test_balanced_robot_has_finite_gradient():
    """A force-balanced 2R (planar_arm.force_balanced) has zero RMS shaking force
    (< 1e-9 N) and a finite gradient there (the zero-safe RMS norm gives no NaN)."""
    robot, motion = _planar_2r()
    balanced = planar_arm.force_balanced(robot, jnp.array([0.35, 0.2]))
    result = sensitivity(balanced, motion, "rms_force")
    assert float(result.value) < 1e-9
    for grad in result.gradient.values():
        assert np.all(np.isfinite(np.asarray(grad)))


def test_check_failure_and_bad_inputs_raise():
    """A check with an unattainable tolerance (1e-30) raises; so do an unknown metric or
    design variable (the message lists the valid ones) and an empty wrt."""
    robot, motion = _planar_2r()
    with pytest.raises(ValueError, match="finite differences"):
        sensitivity(robot, motion, "rms_force", wrt="payload", check=True, rtol=1e-30)
    with pytest.raises(ValueError, match="rms_force"):
        sensitivity(robot, motion, "rms_forces")
    with pytest.raises(ValueError, match="counter_distance"):
        sensitivity(robot, motion, wrt=("counter_masses",))
    with pytest.raises(ValueError, match="no design variable"):
        sensitivity(robot, motion, wrt=())
    assert isinstance(motion, Motion)
