"""Inputs a user's own mechanism or move can carry, found by an exploratory session: an
inertia no body has, time samples outside the move or of a zero duration, and a
regressor column that is rounding. Each gave a finite, wrong number without a message.

References: the triangle inequality of principal moments (any mass distribution;
MuJoCo refuses a violating ``<inertial>``); Briot et al. (2012), eqs (2)-(3) (a move
``x0 + s(t/T)(x1 − x0)`` on ``[0, T]``).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.balancing import balancing_conditions, linear_wrench
from jaxbal.design import Motion, motion_samples, peak_force
from jaxbal.profiles import BangBang, BoundaryPolynomial, Quintic, TrapezoidalAcceleration
from jaxbal.robots import PickAndPlace

# a spatial two-link arm, its frames rotated by quaternions (their rounding gives the
# regressor column of ``link.h_z``, along the first hinge, a norm of ~1e-14, not 0)
ARM = """<mujoco><worldbody><body name="base" pos="0.1 -0.05 0.2" quat="0.9659 0 0 0.2588">
<body name="link" pos="0 0 0.15" quat="0.9239 0.3827 0 0"><joint name="j" axis="0 0 1"/>
<inertial pos="0.02 0.03 0.1" mass="2.5" diaginertia="0.03 0.025 0.01"/>
<body name="link2" pos="0.05 0.02 0.2" quat="0.8 0.0 0.6 0.0">
<joint name="j2" axis="0 1 0" pos="0 0 0.01"/><site name="tip" pos="0.3 0 0"/>
<inertial pos="0.15 0.01 -0.02" mass="1.7" diaginertia="0.005 0.02 0.021"/>
</body></body></body></worldbody></mujoco>"""

STATE = (jnp.array([0.3, 0.5]), jnp.array([1.0, 2.0]), jnp.array([0.5, -1.0]))

UNPHYSICAL = {
    "not positive semi-definite": [[0.01, 0.02, 0], [0.02, 0.01, 0], [0, 0, 0.01]],
    "not symmetric": [[0.01, 0.005, 0], [-0.005, 0.01, 0], [0, 0, 0.01]],
    "triangle inequality": [[0.001, 0, 0], [0, 0.001, 0], [0, 0, 0.01]],
}


@pytest.fixture(scope="module")
def arm():
    return jaxbal.robots.from_mjcf(ARM, end_effector_site="tip")


@pytest.mark.parametrize("inertia", UNPHYSICAL.values(), ids=UNPHYSICAL.keys())
def test_an_inertia_no_body_has_is_refused(arm, inertia):
    """Each of these changed the shaking moment with no message (only a negative
    diagonal was refused); now eagerly, under ``jit`` and set by ``eqx.tree_at`` inside
    the program, as every other parameter check."""
    bad = arm.with_body("link2", inertia=inertia)
    with pytest.raises(ValueError, match=r"positive semi-definite.*triangle.*'link2'"):
        jaxbal.shaking_wrench(bad, *STATE)
    with pytest.raises(Exception, match="positive semi-definite"):
        jax.block_until_ready(jax.jit(jaxbal.shaking_wrench)(bad, *STATE))
    index = arm.body_index("link2")

    @jax.jit
    def moment(inertia):
        robot = eqx.tree_at(lambda r: r.inertia, arm, arm.inertia.at[index].set(inertia))
        return jaxbal.shaking_wrench(robot, *STATE)[1]

    with pytest.raises(Exception, match="positive semi-definite"):
        jax.block_until_ready(moment(jnp.asarray(inertia)))
    assert np.all(np.isfinite(moment(arm.inertia[index])))


def test_physical_inertias_pass_and_planar_ones_too(arm):
    """A rod (one zero principal moment, the triangle inequality an equality), a
    rotated full tensor and a point mass pass; the planar built-in robots give only
    ``I_zz`` (no triangle inequality asked of them) and pass."""
    rotation = np.linalg.qr(np.random.default_rng(0).normal(size=(3, 3)))[0]
    for inertia in (np.diag([0.0, 0.02, 0.02]), rotation @ np.diag([1, 2, 2.5]) @ rotation.T, 0):
        robot = arm.with_body("link2", inertia=np.broadcast_to(inertia, (3, 3)))
        assert np.all(np.isfinite(jaxbal.shaking_wrench(robot, *STATE)[1]))
    planar = jaxbal.robots.planar_2r()
    force, _ = jaxbal.shaking_wrench(planar, jnp.array([0.3, 0.5]), jnp.ones(2), jnp.zeros(2))
    assert np.all(np.isfinite(force))


def test_sample_times_refuse_a_duration_or_count_that_is_no_move():
    """``sample_times(0.0)`` gave instants all zero, so a peak force of 0 N."""
    for duration in (0.0, -1.0, np.nan):
        with pytest.raises(ValueError, match="duration must be finite and > 0"):
            jaxbal.sample_times(duration)
    for count in (0, 1, 2.0, True):
        with pytest.raises(ValueError, match="count must be an integer >= 2"):
            jaxbal.sample_times(1.0, count)
    with pytest.raises(Exception, match="duration must be finite and > 0"):
        jax.block_until_ready(jax.jit(jaxbal.sample_times)(jnp.asarray(0.0)))
    np.testing.assert_allclose(jaxbal.sample_times(0.5, 3), [0.0, 0.25, 0.5], rtol=0, atol=0)


@pytest.mark.parametrize(
    "profile",
    [Quintic(), BangBang(), TrapezoidalAcceleration(0.1, 0.3), BoundaryPolynomial([0.3, -0.2])],
    ids=["quintic", "bangbang", "trapezoid", "poly8"],
)
def test_a_move_rests_outside_its_duration(profile):
    """Past ``u = 1`` (before 0) every profile is its end (start) at rest, its
    derivatives zero, where the polynomial extrapolated (the bang-bang went back); at
    ``u = 0`` and ``1`` the derivatives are the move's (right- and left-hand), as
    before: ``where``, not ``clip``, which halves them at the ends."""
    inside = [jaxbal.time_derivatives(profile, u, 3) for u in (0.0, 1.0)]
    for u, end in ((-0.5, 0.0), (1.5, 1.0), (1e300, 1.0), (-1e300, 0.0)):
        values = np.array(jaxbal.time_derivatives(profile, u, 3))
        np.testing.assert_array_equal(values, [end, 0.0, 0.0, 0.0])
    a = np.array(jaxbal.time_derivatives(BangBang(), 1.0, 2))
    np.testing.assert_allclose(a, [1.0, 0.0, -4.0], atol=1e-12)  # left-hand, as before
    assert all(np.all(np.isfinite(x)) for x in inside)
    grads = jax.grad(lambda c: profile(jnp.asarray(1.5)) + profile(jnp.asarray(-0.5)))(0.0)
    assert np.isfinite(grads)


def test_sampling_past_the_duration_adds_rest_not_force():
    """A 0.5 s move sampled on [0, 1] s gave 50× its peak force (the quintic
    extrapolated); now its samples on [0, 0.5] s are the move's, those after it the end
    pose at rest, and the peak force is the move's."""
    arm = jaxbal.robots.planar_2r()
    start, end = jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70])  # P5, P9 of Fig 3
    line = jaxbal.StraightLine(start, end, Quintic(), 0.5)
    move = jaxbal.planning.EndEffectorLine(arm, line, branch=-1)
    short = motion_samples(arm, [move], jaxbal.sample_times(0.5, 51))
    long = motion_samples(arm, [move], jaxbal.sample_times(1.0, 101))
    np.testing.assert_allclose(long.q[:51], short.q, atol=1e-12)
    np.testing.assert_allclose(long.qd[:51], short.qd, atol=1e-10)
    np.testing.assert_allclose(long.q[51:], np.broadcast_to(short.q[-1], (50, 2)), atol=1e-12)
    np.testing.assert_array_equal(long.qd[51:], 0.0)
    np.testing.assert_array_equal(long.qdd[51:], 0.0)
    np.testing.assert_allclose(peak_force(arm, long), peak_force(arm, short), rtol=1e-10)


def test_pick_and_place_duration_is_checked():
    """The SCARA's move divided by its duration unchecked: ``T = 0`` gave ``u = inf``,
    the end pose held at every instant."""
    line = PickAndPlace(jnp.array([0.15, 0.2, 1.4]), jnp.array([-0.15, 0.2, 2.7]), 0.0)
    with pytest.raises(ValueError, match="PickAndPlace duration must be finite and > 0"):
        line(0.1)


def test_a_rounding_column_gives_no_condition(arm):
    """The regressor column of ``link.h_z`` is rounding (the force does not depend on
    the first moment along the first hinge); the column equilibration scaled it to unit
    norm, which reported one condition more than the rank and printed an empty
    equation ``' = 0'``."""
    t = jnp.linspace(0.0, 1.0, 200)[:, None]
    w, phase = 2 * jnp.pi * jnp.array([1.3, 2.1]), jnp.array([0.1, 0.5])
    motion = Motion(
        0.5 * jnp.sin(w * t + phase),
        0.5 * w * jnp.cos(w * t + phase),
        -0.5 * w**2 * jnp.sin(w * t + phase),
    )
    stacked = np.asarray(linear_wrench(arm, motion).force).reshape(-1, 20)
    norms = np.linalg.norm(stacked, axis=0)
    column = 3  # link.h_z
    assert 0 < norms[column] < 1e-12 * norms.max()  # the case: rounding, not zero
    conditions = balancing_conditions(arm, motion)
    rank = np.linalg.matrix_rank(stacked, tol=1e-9 * np.linalg.norm(stacked, 2))
    assert conditions.rank == rank == 4
    assert all(e.split("=")[0].strip() for e in conditions.equations())
    assert np.all(conditions.matrix[:, column] == 0.0)


def _five_bar(passive_range: str):
    """The five-bar of ``test_mjcf_robot`` with a range on its passive joint ``pa``."""
    from test_mjcf_robot import FIVE_BAR

    xml = FIVE_BAR.replace('ref="-1.549961"/>', f'ref="-1.549961" {passive_range}/>')
    return jaxbal.robots.from_mjcf(xml, end_effector_site="tip")


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_solution_outside_a_joint_range_is_refused():
    """A pose whose solution puts a limited joint outside its range (MJCF ``range``, a
    URDF ``<limit>``) came back valid (a slide 26 times past its limit); now the IK
    and the loop closure refuse it, naming the joint, eagerly and under ``jit``, and
    ``return_valid`` gives False. Inside the range the solution is the unlimited one."""
    free = _five_bar("")
    start = jnp.array([-0.05, 0.33])
    q = free.inverse_kinematics(start)
    pa = float(q[free.coordinate("pa")])
    inside = _five_bar(f'range="{pa - 0.1} {pa + 0.1}"')
    np.testing.assert_allclose(inside.inverse_kinematics(start), q, atol=1e-12)
    outside = _five_bar(f'range="{pa + 0.05} {pa + 0.2}"')
    assert outside.joint_range[free.joint_names.index("pa")] == (pa + 0.05, pa + 0.2)
    with pytest.raises(ValueError, match=r"range of a limited joint.*pa \[.*\{'pa': "):
        outside.inverse_kinematics(start)
    q_out, valid = outside.inverse_kinematics(start, return_valid=True)
    assert not bool(valid) and np.all(np.isfinite(q_out))
    with pytest.raises(Exception, match="range of a limited joint"):
        jax.block_until_ready(jax.jit(lambda p: outside.inverse_kinematics(p))(start))
    u = q[np.asarray(free.independent)]
    with pytest.raises(ValueError, match="loop closure: the solution leaves the range"):
        outside.closure(u, guess=q)
    assert not bool(outside.closure(u, guess=q, return_valid=True)[1])
    np.testing.assert_allclose(inside.closure(u, guess=q), q, atol=1e-12)


def test_a_limited_hinge_is_turned_into_its_range():
    """From a singular start (the URDF arm drawn straight) Newton wanders whole turns
    away: the shoulder, limited to ±3 rad, came back at −5.54 rad. A limited hinge is
    turned by 2π into its range (the same pose), so the pose is reached and valid."""
    from test_mjcf_spec import NO_MESHES

    arm = jaxbal.robots.from_urdf(NO_MESHES, end_effector_body="tool")
    assert arm.joint_range[0] == (-3.0, 3.0) and arm.joint_range[1] == (-np.inf, np.inf)
    pose = jnp.array([0.45, 0.1])
    q, valid = arm.inverse_kinematics(pose, return_valid=True)
    assert bool(valid) and -3.0 <= float(q[0]) <= 3.0
    np.testing.assert_allclose(arm.end_effector(q), pose, atol=1e-12)


def test_com_line_on_another_branch_than_its_configurations_is_refused():
    """The 2R's P5 and P9 from the inverse kinematics with ``branch=-1``, then
    ``com_line(..., branch=-1)``: the COM inverse kinematics' sign is not the end
    effector's, and the plan ran in the other elbow mode (the same peak force, the peak
    moment 4.2 instead of 22.7 N·m) without a message. Refused, naming the branch that
    joins; the default branch (which joins) is unchanged."""
    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    plan = jaxbal.planning.com_line(arm, q0, q1, BangBang(), 0.5)
    np.testing.assert_allclose(plan(0.0), q0, atol=1e-12)
    np.testing.assert_allclose(plan(0.5), q1, atol=1e-12)
    with pytest.raises(ValueError, match=r"branch=-1 does not start at q_start.*branch=1 joins"):
        jaxbal.planning.com_line(arm, q0, q1, BangBang(), 0.5, branch=-1)
    other = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=1)
    with pytest.raises(ValueError, match="no branch joins them"):
        jaxbal.planning.com_line(arm, q0, other, BangBang(), 0.5)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_com_line_on_another_branch_is_refused_under_jit_vmap_and_grad():
    """Under ``jit``, ``vmap`` or ``grad`` (even with respect to the duration alone) the
    join check was skipped and the plan ran silently in the other elbow mode (peak
    moment 4.2 instead of 22.7 N·m); now a runtime error where the plan is evaluated.
    The joining branch still runs, with the same numbers as eagerly."""
    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    times = jnp.linspace(0.0, 1.0, 51)

    def peak_moment(a, b, duration, branch):
        plan = jaxbal.planning.com_line(arm, a, b, BangBang(), duration, branch=branch)
        _, moment = jaxbal.planning.wrench_along(arm, plan, times * duration)
        return jaxbal.planning.peak_norm(moment)

    eager = float(peak_moment(q0, q1, 0.5, 1))
    assert float(jax.jit(lambda a, b: peak_moment(a, b, 0.5, 1))(q0, q1)) == pytest.approx(
        eager, rel=1e-12
    )
    assert np.isfinite(float(jax.grad(lambda d: peak_moment(q0, q1, d, 1))(0.5)))
    wrong = [
        lambda: jax.jit(lambda a, b: peak_moment(a, b, 0.5, -1))(q0, q1),
        lambda: jax.vmap(lambda a, b: peak_moment(a, b, 0.5, -1))(q0[None], q1[None]),
        lambda: jax.grad(lambda d: peak_moment(q0, q1, d, -1))(0.5),
    ]
    for call in wrong:
        with pytest.raises(Exception, match="does not start at q_start / end at q_end"):
            jax.block_until_ready(call())


def test_com_line_with_a_bad_profile_names_it_eagerly():
    """An invalid trapezoid passed to ``com_line`` eagerly was an
    ``EquinoxRuntimeError`` without its switch times (the profile alone gave a
    ``ValueError`` naming them)."""
    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    profile = eqx.tree_at(lambda p: p.u2, TrapezoidalAcceleration(0.1, 0.2), jnp.asarray(0.05))
    with pytest.raises(ValueError, match=r"switch times.*0\.1.*0\.05"):
        jaxbal.planning.com_line(arm, q0, q1, profile, 0.5)


def test_zero_sample_instants_are_named():
    """``times`` of shape (0,) raised ``ZeroDivisionError: integer modulo by zero``."""
    arm = jaxbal.robots.planar_2r()
    q0, q1 = jnp.array([1.46, -2.43]), jnp.array([1.57, -0.84])
    path = jaxbal.StraightLine(q0, q1, Quintic(), 0.5)
    for call in (
        lambda: jaxbal.planning.wrench_along(arm, path, jnp.zeros(0)),
        lambda: jaxbal.sample(path, jnp.zeros(0)),
        lambda: motion_samples(arm, [path], jnp.zeros(0)),
    ):
        with pytest.raises(ValueError, match=r"times must have shape \(t,\) with t >= 1"):
            call()


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_export_names_counter_masses_the_files_compiler_bounds(tmp_path):
    """A file with ``<compiler boundinertia>``: MuJoCo raises the exported point
    counter-mass's zero inertia to the bound, so the written model shakes otherwise and
    the export was refused as "the robot was changed". Now the message names the
    counter-mass, what MuJoCo made of it and the remedy; a counter-mass with an inertia
    above the bound exports."""
    xml = ARM.replace("<mujoco>", '<mujoco><compiler boundinertia="1e-4"/>')
    source = tmp_path / "arm.xml"
    source.write_text(xml)
    robot = jaxbal.robots.from_mjcf(str(source), end_effector_site="tip")
    point = jaxbal.robots.add_counter_mass(robot, "link", [-0.1, 0, 0], 2.0)
    with pytest.raises(
        ValueError, match=r"counter_link: mass 2 -> 2 kg, inertia trace 0 -> 0.0003"
    ):
        jaxbal.robots.export_balanced(str(source), point, str(tmp_path / "out.xml"))
    body = jaxbal.robots.add_counter_mass(
        robot, "link", [-0.1, 0, 0], 2.0, inertia=1e-3 * np.eye(3)
    )
    jaxbal.robots.export_balanced(str(source), body, str(tmp_path / "out.xml"))
    assert "counter_link" in (tmp_path / "out.xml").read_text()


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_cli_names_an_unreachable_end_and_refuses_a_move_that_does_not_move(tmp_path):
    """``jaxbal balance`` on the exported 2R: an end pose out of reach was blamed on the
    singular start alone (the advice pointed the wrong way); a move with ``--start``
    equal to ``--end`` printed a 37.7 kg design balancing 0 N. Both exit 2 naming it."""
    from typer.testing import CliRunner

    from jaxbal._src.cli import app
    from jaxbal.mujoco import export_mjcf

    path = tmp_path / "planar_2r.xml"
    path.write_text(export_mjcf(jaxbal.robots.planar_2r()))
    move = ["balance", str(path), "--body", "payload", "--start", "0.225,0.25", "--samples", "11"]
    far = CliRunner().invoke(app, [*move, "--end", "5,5"])
    assert far.exit_code == 2 and "out of reach?: end pose [5.0, 5.0]" in far.output, far.output
    still = CliRunner().invoke(app, [*move, "--end", "0.225,0.25"])
    assert still.exit_code == 2 and "does not move the mechanism" in still.output, still.output


def test_confirm_refuses_states_whose_error_scale_overflows():
    """Accelerations of ~1e155 overflowed the error scale to inf, and ``confirm``
    reported a relative error of 0 — agreement — even for a robot off by 1 cm."""
    from jaxbal.mujoco import confirm

    arm = jaxbal.robots.planar_2r()
    q, qd = jnp.array([0.3, 0.5]), jnp.array([1.0, 2.0])
    assert confirm(arm, q, qd, jnp.array([3.0, -1.0])).force_relative < 1e-12
    with pytest.raises(ValueError, match="overflow"):
        confirm(arm, q, qd, jnp.array([3e160, -1e160]))


def test_mujoco_actuator_efforts_names_ball_joints():
    """The Orthoglide's tree has ball joints: a NumPy shape error (18 vs 21) before."""
    from jaxbal.mujoco import mujoco_actuator_efforts

    robot = jaxbal.robots.orthoglide()
    u = jnp.zeros(3)
    with pytest.raises(ValueError, match=r"ball joints \['leg_x', 'leg_y', 'leg_z'\]"):
        mujoco_actuator_efforts(robot, robot.inverse_kinematics, u, u, u)
