"""Validation that survives jit and tree_at: bad values are refused, never silently
evaluated (shape errors at trace time, value errors eagerly and at run time)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.profiles import Quintic
from jaxbal.robots.dual_v_balancing import with_counter_mass_moments


@pytest.fixture(scope="module")
def dual_v_state():
    robot = jaxbal.robots.dual_v()
    # a state on its loops (the wrench checks them): the IK's motion at the centre
    return (robot, *jaxbal.pose_motion(robot, jnp.zeros(3), jnp.full(3, 0.5), jnp.full(3, 5.0)))


def test_negative_derived_mass_is_refused_eagerly_and_under_jit(dual_v_state):
    """Zero counter-mass moments drive the DUAL-V's brass mass (m_cm − m_tun) negative:
    the old code returned 1.7e12 N silently."""
    robot, q, qd, qdd = dual_v_state
    bad = with_counter_mass_moments(robot, 0.0)
    with pytest.raises(ValueError, match="non-negative|>= 0"):
        jaxbal.shaking_wrench(bad, q, qd, qdd)
    wrench = eqx.filter_jit(jaxbal.shaking_wrench)
    with pytest.raises(Exception, match="body masses must be finite and >= 0"):
        jax.block_until_ready(wrench(bad, q, qd, qdd))
    assert jnp.all(jnp.isfinite(wrench(robot, q, qd, qdd)[0]))


def test_tree_at_negative_payload_is_refused_under_jit_and_vmap():
    robot = jaxbal.robots.planar_2r()
    state = (jnp.ones(2), jnp.ones(2), jnp.ones(2))

    def force(payload):
        changed = eqx.tree_at(lambda r: r.payload, robot, payload)
        return jaxbal.shaking_wrench(changed, *state)[0]

    with pytest.raises(Exception, match="body masses"):
        jax.block_until_ready(jax.jit(jax.vmap(force))(jnp.array([1.0, -1.0])))
    assert jnp.all(jnp.isfinite(jax.jit(jax.vmap(force))(jnp.array([1.0, 2.0]))))


def test_runtime_checks_can_be_switched_off_for_speed():
    robot = jaxbal.robots.planar_2r()
    state = (jnp.ones(2), jnp.ones(2), jnp.ones(2))
    bad = eqx.tree_at(lambda r: r.payload, robot, jnp.asarray(-1.0))
    with jaxbal.runtime_checks(False):
        force = jax.jit(lambda r: jaxbal.shaking_wrench(r, *state)[0])(bad)
    assert jnp.all(jnp.isfinite(force))


@pytest.mark.parametrize(
    "args,match",
    [
        ((jnp.ones(2), jnp.ones(3), jnp.ones(2)), "qd must have shape"),
        ((jnp.ones(2), jnp.ones(2), jnp.ones((2, 1))), "qdd must have shape"),
        ((jnp.ones(3), jnp.ones(3), jnp.ones(3)), "q must have shape"),
    ],
)
def test_wrong_state_shapes_name_the_argument(args, match):
    with pytest.raises(ValueError, match=match):
        jaxbal.shaking_wrench(jaxbal.robots.planar_2r(), *args)


def test_non_finite_state_and_scalar_gravity_are_refused():
    robot = jaxbal.robots.planar_2r()
    with pytest.raises(ValueError, match="non-finite state"):
        jaxbal.shaking_wrench(robot, jnp.array([jnp.nan, 0.0]), jnp.ones(2), jnp.ones(2))
    with pytest.raises(ValueError, match="gravity must have shape"):
        jaxbal.shaking_wrench(robot, jnp.ones(2), jnp.ones(2), jnp.ones(2), gravity=-9.81)
    # a parameter set to a Python number with tree_at: a TypeError from inside the physics
    loose = eqx.tree_at(lambda r: r.payload, robot, 1.0)
    with pytest.raises(ValueError, match=r"PlanarArm.payload is a Python number \(1.0\)"):
        jaxbal.shaking_wrench(loose, jnp.ones(2), jnp.ones(2), jnp.ones(2))
    # a NaN gravity was reported as an overflow of the robot's largest parameter
    for function in (jaxbal.shaking_wrench, jaxbal.actuator_torques, jaxbal.inverse_dynamics):
        with pytest.raises(ValueError, match=r"gravity must be finite \[m/s\^2\]"):
            function(robot, jnp.ones(2), jnp.ones(2), jnp.ones(2), gravity=[0.0, np.nan, 0.0])


# --- profiles and planning: checked where they are used (eager, jit, tree_at) ---------


@pytest.mark.parametrize("duration", [0.0, -0.5, float("nan"), float("inf")])
def test_straight_line_duration_must_be_positive(duration):
    line = jaxbal.StraightLine(jnp.zeros(2), jnp.ones(2), jaxbal.profiles.Quintic(), 0.5)
    with pytest.raises(ValueError, match=r"duration must be finite and > 0 \[s\]"):
        jaxbal.StraightLine(jnp.zeros(2), jnp.ones(2), jaxbal.profiles.Quintic(), duration)(0.1)
    changed = eqx.tree_at(lambda x: x.duration, line, jnp.asarray(duration))
    with pytest.raises(Exception, match="duration must be finite and > 0"):
        jax.block_until_ready(jax.jit(lambda path: path(0.1))(changed))


@pytest.mark.parametrize("switches", [(0.0, 0.0), (0.3, 0.2), (0.2, 0.5), (float("nan"), 0.3)])
def test_trapezoid_switch_times_must_be_ordered(switches):
    with pytest.raises(ValueError, match=r"0 < u1 <= u2 < 1/2"):
        jaxbal.profiles.TrapezoidalAcceleration(*switches)(0.3)
    good = jaxbal.profiles.TrapezoidalAcceleration(0.1, 0.3)
    changed = eqx.tree_at(lambda p: (p.u1, p.u2), good, tuple(jnp.asarray(s) for s in switches))
    with pytest.raises(Exception, match="switch times must satisfy"):
        jax.block_until_ready(jax.jit(lambda p: p(0.3))(changed))


def test_peak_norm_of_nothing_is_an_error():
    with pytest.raises(ValueError, match=r"t >= 1, got \(0, 3\)"):
        jaxbal.planning.peak_norm(jnp.zeros((0, 3)))


def test_tiny_negative_mass_is_judged_alike_everywhere(dual_v_state):
    """Found by `make fuzz`: m1 = −5e-99 (zero up to rounding) was refused by the
    eager body check (strict < 0) and accepted under jit (−1e-12 tolerance); one
    tolerance (validation.ROUNDING) now serves constructors, eager and compiled code:
    the same wrench both ways (1e-12), as the robot with m1 = 0 (1e-12)."""
    robot, q, qd, qdd = dual_v_state
    tiny = eqx.tree_at(lambda r: r.m1, robot, jnp.full(4, -5e-99))
    zero = eqx.tree_at(lambda r: r.m1, robot, jnp.zeros(4))
    eager = jnp.concatenate(jaxbal.shaking_wrench(tiny, q, qd, qdd))
    compiled = jnp.concatenate(eqx.filter_jit(jaxbal.shaking_wrench)(tiny, q, qd, qdd))
    reference = jnp.concatenate(jaxbal.shaking_wrench(zero, q, qd, qdd))
    assert jnp.allclose(eager, compiled, rtol=0, atol=1e-12)
    assert jnp.allclose(eager, reference, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match="non-negative|>= 0"):
        jaxbal.shaking_wrench(eqx.tree_at(lambda r: r.m1, robot, jnp.full(4, -1e-9)), q, qd, qdd)


def test_branch_given_as_a_float_sign():
    """Found by `make fuzz`: branch=1.0 was refused while (1.0,) was accepted; a real
    number equal to ±1 now means that sign for every entry, anything else is refused."""
    arm = jaxbal.robots.planar_2r()
    pose = jnp.array([0.4, 0.3])
    for sign in (1, -1):
        expected = arm.inverse_kinematics(pose, branch=sign)
        assert jnp.array_equal(arm.inverse_kinematics(pose, branch=float(sign)), expected)
    for bad in (1.5, 0.0, float("nan")):
        with pytest.raises(ValueError, match="branch"):
            arm.inverse_kinematics(pose, branch=bad)


def test_trapezoid_with_a_tiny_jerk_phase_is_the_bang_bang_limit():
    """Found by `make fuzz`: u1 = 1.9e-71 gave s(1/2) = 0.077 (cancellation of two cubes
    times 1/u1) and eager ≠ compiled. Written without the cancellation, it is the
    limit u1 → 0: symmetric (s(u) + s(1 − u) = 1 to 1e-15), plateau a on [0, u2] and a
    linear fall to 0 over h = 1/2 − u2, so s(1/2) = a (u2²/2 + u2 h + h²/3) = 1/2 and
    s(u2) = a u2²/2 (closed form, 1e-12); eager = compiled."""
    u2 = 0.25
    profile = jaxbal.profiles.TrapezoidalAcceleration(1.871730137410757e-71, u2)
    u = jnp.linspace(0.0, 1.0, 41)
    s = jax.vmap(profile)(u)
    assert float(jnp.max(jnp.abs(s + jax.vmap(profile)(1.0 - u) - 1.0))) < 1e-15
    peak = float(profile.peak_acceleration)
    h = 0.5 - u2
    expected_peak = 1.0 / (2.0 * (u2**2 / 2.0 + u2 * h + h**2 / 3.0))
    assert abs(peak / expected_peak - 1.0) < 1e-12
    assert abs(float(profile(u2)) - peak * u2**2 / 2.0) < 1e-15
    compiled = eqx.filter_jit(lambda p, x: jax.vmap(p)(x))(profile, u)
    assert jnp.allclose(compiled, s, rtol=0, atol=1e-15)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_non_finite_state_is_named_when_the_check_guards_the_outputs():
    """The state's finiteness guards the wrench / torques computed from it (it is no
    longer threaded through the check, which split the compiled loop): a NaN row in a
    vmapped batch still raises the state's error first, under jit, vmap and
    checked_jit (with the offending values), and a concrete NaN state inside a jit is a
    ValueError at once."""
    robot = jaxbal.robots.dual_v()
    motion = jaxbal.design.motion_samples(
        robot,
        jaxbal.planning.EndEffectorLine(
            robot,
            jaxbal.StraightLine(
                jnp.array([0.0, -0.05, 0.0]), jnp.array([0.05, 0.05, 0.0]), Quintic(), 0.2
            ),
        ),
        jnp.linspace(0.0, 0.2, 5),
    )
    q, qd, qdd = motion
    bad_qd = qd.at[3, 2].set(jnp.nan)
    for evaluate in (jaxbal.shaking_wrench, jaxbal.actuator_torques):
        batch = jax.jit(jax.vmap(lambda a, b, c, f=evaluate: f(robot, a, b, c)))
        assert all(
            np.all(np.isfinite(np.asarray(x))) for x in jax.tree_util.tree_leaves(batch(q, qd, qdd))
        )
        with pytest.raises(Exception, match="non-finite state"):
            jax.block_until_ready(batch(q, bad_qd, qdd))
        checked = jaxbal.checked_jit(batch)
        with pytest.raises(ValueError, match=r"non-finite state \(q, qd, qdd\): \["):
            checked(q, bad_qd, qdd)
    with pytest.raises(ValueError, match="non-finite state"):
        state = (q[0], bad_qd[3], qdd[0])  # concrete arrays, closed over by the jit
        jax.jit(lambda r: jaxbal.shaking_wrench(r, *state))(robot)


@pytest.mark.parametrize(
    ("max_steps", "gtol", "match"),
    [
        (0, 1e-10, "max_steps"),
        (-3, 1e-10, "max_steps"),
        (2.5, 1e-10, "max_steps"),
        (True, 1e-10, "max_steps"),
        (10, float("nan"), "gtol"),
        (10, -1e-9, "gtol"),
        (10, float("inf"), "gtol"),
        (10, "tight", "gtol"),
    ],
)
def test_optimisers_refuse_a_bad_stopping_rule(max_steps, gtol, match):
    """A NaN gtol used to run silently to max_steps and report no convergence; every
    optimiser entry point names the bad value before anything compiles."""
    arm = jaxbal.robots.planar_2r()
    q = jnp.zeros((4, 2))
    motion = jaxbal.design.Motion(q, q, q)
    with pytest.raises(ValueError, match=match):
        jaxbal.design.codesign(arm, motion, max_steps=max_steps, gtol=gtol)
    with pytest.raises(ValueError, match=match):
        jaxbal.minimize(lambda x: jnp.sum(x**2), jnp.ones(2), max_steps=max_steps, gtol=gtol)
    with pytest.raises(ValueError, match=match):
        jaxbal.design.joint_codesign(
            arm, None, {}, trajectory_lower={}, trajectory_upper={},
            max_steps=max_steps, gtol=gtol,
        )  # fmt: skip


def test_a_good_stopping_rule_passes():
    """The check accepts NumPy integers, a zero tolerance and a traced tolerance."""
    from jaxbal._src.validation import check_stopping

    check_stopping(np.int64(5), 0.0)
    jax.jit(lambda g: check_stopping(3, g) or g)(1e-8)
