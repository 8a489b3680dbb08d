"""The robot contract: the same generic code on all five robots.

References and tolerances are named per test: MuJoCo C (`confirm`, 1e-9 relative), the
robot's own inverse kinematics (forward/inverse round trip, 1e-12 m), Lagrange's
equations (`inverse_dynamics`, serial robots: τ = Q exactly), the DUAL-V's independent
virtual-work model (1e-10 relative) and central finite differences.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import slow_for

import jaxbal
from jaxbal import robots
from jaxbal._src.com_components import planned_com
from jaxbal.planning import EndEffectorLine, com_line
from jaxbal.profiles import BangBang, Quintic

#: name -> (robot, reachable start pose, reachable end pose, unreachable pose)
CASES = {
    "planar_2r": (robots.planar_2r(), (0.4, 0.3), (0.2, 0.5), (5.0, 5.0)),
    "planar_3r": (robots.planar_3r(), (0.4, 0.3, 0.5), (0.2, 0.5, 1.0), (5.0, 5.0, 0.0)),
    "scara": (robots.scara(), (0.15, 0.2, 1.4, 0.0), (-0.15, 0.2, 2.7, 0.05), (5.0, 5.0, 0, 0)),
    "dual_v": (robots.dual_v(), (0.0, -0.05, 0.0), (0.05, 0.05, 0.0), (5.0, 5.0, 0.0)),
    "orthoglide": (
        robots.orthoglide(payload=1.0),
        (0.0, 0.0, 0.0),
        (-0.1, 0.07, -0.11),
        (5.0, 5.0, 5.0),
    ),
}
DURATION = 0.2


def _motion(name):
    robot, start, end, _ = CASES[name]
    line = jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), DURATION)
    return robot, EndEffectorLine(robot, line)


@eqx.filter_jit
def _state(robot, path, t):
    """``(q, q̇, q̈, valid)`` compiled (the tests' boundary)."""
    return jaxbal.joint_motion(robot, path, t, return_valid=True)


def _consistent_state(robot, path, t):
    *state, valid = _state(robot, path, jnp.asarray(t, dtype=float))
    assert bool(valid)
    return state


@pytest.mark.parametrize("name", sorted(CASES))
def test_constructor_names_are_the_public_robots(name):
    """`jaxbal.robots.ROBOTS` keys equal the constructor names (CLI names too)."""
    assert robots.ROBOTS[name] is getattr(robots, name)
    assert type(robots.by_name(name)) is type(CASES[name][0])


def test_by_name_aliases_and_unknown():
    assert isinstance(robots.by_name("2r"), robots.PlanarArm)
    assert isinstance(robots.by_name("dual-v"), robots.DualV)
    with pytest.raises(ValueError, match="unknown robot 'bogus'"):
        robots.by_name("bogus")


@pytest.mark.parametrize("name", sorted(CASES))
def test_ik_unreachable_masks_without_raising(name):
    """With return_valid=True no exception and mask False; eagerly a ValueError naming
    the pose; under jit the mask is False too."""
    robot, start, _, bad = CASES[name]
    q, valid = robot.inverse_kinematics(jnp.asarray(bad), return_valid=True)
    assert not bool(valid) and q.shape == (robot.dof,) and np.all(np.isfinite(q))
    with pytest.raises(ValueError, match="5"):
        robot.inverse_kinematics(jnp.asarray(bad))
    jitted = jax.jit(lambda p: robot.inverse_kinematics(p, return_valid=True)[1])
    assert not bool(jitted(jnp.asarray(bad)))
    assert bool(jitted(jnp.asarray(start)))
    nan_pose = jnp.full(len(bad), jnp.nan)
    assert not bool(robot.inverse_kinematics(nan_pose, return_valid=True)[1])


@pytest.mark.parametrize("name", sorted(CASES))
def test_ik_round_trip_and_branch_validation(name):
    """end_effector(inverse_kinematics(pose)) = pose (1e-12); a bad branch raises."""
    robot, start, _, _ = CASES[name]
    pose = jnp.asarray(start)
    np.testing.assert_allclose(robot.end_effector(robot.inverse_kinematics(pose)), pose, atol=1e-12)
    other = tuple(-s for s in robot.default_branch)
    np.testing.assert_allclose(
        robot.end_effector(robot.inverse_kinematics(pose, branch=other)), pose, atol=1e-12
    )
    for bad in (2, 0, (1,) * (robot.branch_size + 1), "up"):
        with pytest.raises(ValueError, match="branch"):
            robot.inverse_kinematics(pose, branch=bad)


# the closed chains: test_mujoco_closure.py (MuJoCo closes their loops itself); the 3R
# (the 2R's class, PlanarArm) in make test-all
@pytest.mark.parametrize("name", slow_for(sorted(CASES), "dual_v", "orthoglide", "planar_3r"))
def test_shaking_wrench_confirmed_by_mujoco(name):
    """Generic joint motion + shaking wrench vs MuJoCo C mj_inverse (1e-9 relative)."""
    robot, path = _motion(name)
    q, qd, qdd = _consistent_state(robot, path, 0.3 * DURATION)
    force, moment = jaxbal.shaking_wrench(robot, q, qd, qdd)
    assert float(jnp.linalg.norm(force)) > 1e-3
    check = jaxbal.confirm(robot, q, qd, qdd)
    assert check.relative < 1e-9, check


@pytest.mark.parametrize("name", slow_for(sorted(CASES), "dual_v", "scara", "orthoglide"))
def test_com_line_on_every_robot(name):
    """The COM plan moves the total COM on the straight line (1e-9 m) for every robot,
    with exact derivatives (velocity vs central differences of the position, 1e-6)."""
    robot, start, end, _ = CASES[name]
    q0, q1 = (robot.inverse_kinematics(jnp.asarray(p)) for p in (start, end))
    # the arms' default IK branch is the COM inverse kinematics' −1 (com_line refuses a
    # COM branch that does not join q0 and q1; this test had planned the other elbow)
    branch = -1 if name in ("planar_2r", "planar_3r") else None
    plan = com_line(robot, q0, q1, BangBang(), DURATION, branch=branch)
    h = 1e-6
    times = jnp.array([0.03, 0.13, 0.13 + h, 0.13 - h])
    q, valid, (_, qd, _, state_ok) = _com_plan_samples(plan, times)
    assert bool(jnp.all(valid)) and bool(state_ok)
    for k in range(2):
        com = planned_com(robot, q[k], robot.com_components)
        np.testing.assert_allclose(com, plan.line(times[k]), atol=1e-9)
    np.testing.assert_allclose(qd, (q[2] - q[3]) / (2 * h), rtol=1e-5, atol=1e-5)


@eqx.filter_jit
def _com_plan_samples(plan, times):
    return jax.vmap(plan)(times), plan.valid(times), _state(plan.robot, plan, times[1])


# the DUAL-V in make test-all (the Orthoglide, a closed chain too, stays)
@pytest.mark.parametrize("name", slow_for(sorted(CASES), "dual_v"))
def test_joint_motion_vmap_equals_loop(name):
    robot, path = _motion(name)
    times = jnp.linspace(0.0, DURATION, 4)
    batched = eqx.filter_jit(jax.vmap(_state, in_axes=(None, None, 0)))(robot, path, times)
    for k, t in enumerate(times):
        single = _consistent_state(robot, path, t)
        for a, b in zip(single, batched[:3], strict=True):
            np.testing.assert_allclose(a, b[k], rtol=1e-13, atol=1e-13)
    assert bool(jnp.all(batched[3]))


# the DUAL-V in make test-all: the same generic closure checks as the Orthoglide's (and
# the MJCF five-bar's in test_mjcf_robot)
@pytest.mark.parametrize("name", slow_for(["dual_v", "orthoglide"], "dual_v"))
def test_violated_loop_closure_is_flagged(name):
    """A parallel-robot state off its loop closures is refused, not evaluated."""
    robot, path = _motion(name)
    q, qd, qdd = _consistent_state(robot, path, 0.05)
    assert bool(jaxbal.state_valid(robot, q, qd, qdd))
    assert not bool(jaxbal.state_valid(robot, q.at[0].add(1e-3), qd, qdd))
    assert not bool(jaxbal.state_valid(robot, q, qd.at[0].add(1e-2), qdd))
    with pytest.raises(ValueError, match="loop closures"):
        jaxbal.check_state(robot, q.at[0].add(1e-3), qd, qdd)
    with pytest.raises(ValueError, match="loop closures"):
        jaxbal.joint_motion(robot, lambda t: path(t).at[0].add(1e-3), 0.05)


@pytest.mark.parametrize("name", sorted(CASES))
def test_actuator_torques_by_virtual_work(name):
    """Serial robots: τ = Q (Lagrange). Parallel robots: the power of the actuators
    equals the power of the generalised forces, τ·q̇_a = Q·q̇ (virtual work)."""
    robot, path = _motion(name)
    q, qd, qdd = _consistent_state(robot, path, 0.07)
    tau, forces = eqx.filter_jit(
        lambda r, *s: (jaxbal.actuator_torques(r, *s), jaxbal.inverse_dynamics(r, *s))
    )(robot, q, qd, qdd)
    assert tau.shape == (len(robot.actuated),)
    power = float(forces @ qd)
    np.testing.assert_allclose(float(tau @ qd[np.asarray(robot.actuated)]), power, rtol=1e-10)
    if not robot.constraint(q).shape[0]:
        np.testing.assert_array_equal(tau, forces)


def test_dual_v_generic_torques_equal_the_minimum_norm_model():
    """The generic minimum-norm torques equal the DUAL-V's own virtual-work model,
    computed with the IK Jacobian instead of the loop closures (1e-10 relative)."""
    from jaxbal.robots.dual_v_dynamics import virtual_work_torques

    robot = robots.dual_v()
    u, ud, udd = (
        jnp.array([0.01, 0.02, 0.05]),
        jnp.array([0.3, -0.2, 0.5]),
        jnp.array([10, 20, 5.0]),
    )
    generic = eqx.filter_jit(lambda r, *m: jaxbal.actuator_torques(r, *jaxbal.pose_motion(r, *m)))(
        robot, u, ud, udd
    )
    own = eqx.filter_jit(virtual_work_torques)(robot, u, ud, udd)
    np.testing.assert_allclose(generic, own, rtol=1e-10)


@pytest.mark.parametrize("name", sorted(CASES))
def test_design_round_trip(name):
    """design() -> with_design() reproduces the shaking wrench (1e-12 relative); each
    variable is reachable by name; unknown names and wrong shapes raise."""
    robot, path = _motion(name)
    design = robot.design()
    assert "payload" in design and "counter_mass" in design
    same = robot.with_design(design)
    state = _consistent_state(robot, path, 0.05)
    wrench = eqx.filter_jit(jaxbal.shaking_wrench)
    np.testing.assert_allclose(wrench(same, *state)[0], wrench(robot, *state)[0], rtol=1e-12)
    heavier = robot.with_design({"payload": design["payload"] + 0.5})
    assert float(jaxbal.total_mass(heavier) - jaxbal.total_mass(robot)) == pytest.approx(0.5)
    assert set(robot.design_lower_bounds()) == set(design)
    with pytest.raises(ValueError, match="unknown design variable"):
        robot.with_design({"no_such": 1.0})
    with pytest.raises(ValueError, match="shape"):
        robot.with_design({"counter_mass": jnp.ones(7)})


@pytest.mark.parametrize("name", sorted(CASES))
def test_payload_gradient_through_with_design(name):
    """d(total mass)/d(payload) = 1 exactly, through with_design under jit."""
    robot = CASES[name][0]

    def mass(payload):
        return jaxbal.total_mass(robot.with_design({"payload": payload}))

    gradient = jax.jit(jax.grad(mass))(jnp.asarray(1.0))
    assert float(gradient) == pytest.approx(1.0, abs=1e-14)


def test_mujoco_tree_is_a_robot_method_and_changes_with_tree_at():
    """Each robot brings its own tree; the tree follows the robot's geometry."""
    arm = robots.planar_2r()
    longer = eqx.tree_at(lambda r: r.lengths, arm, jnp.array([0.6, 0.3]))
    assert longer.mujoco_tree().bodies[2].pos[0] == pytest.approx(0.6)
    for robot, _, _, _ in CASES.values():
        tree = robot.mujoco_tree()
        assert tree.independent
        names = set(robot.mass_properties().names)
        assert names <= {b.name for b in tree.bodies}


@pytest.fixture(scope="module")
def motions():
    """32 samples of a robot's move (loop closures checked by motion_samples), sampled
    on first use: the robots of make test-all only cost a sampling compile there."""
    out = {}

    def sampled(name):
        if name not in out:
            robot, path = _motion(name)
            times = jaxbal.sample_times(DURATION, 32)
            out[name] = jaxbal.design.motion_samples(robot, [path], times)
        return out[name]

    return sampled


# the 3R in make test-all (the 2R's class; test_design co-designs the 3R with an added-mass
# budget in make test)
@pytest.mark.parametrize(
    "name", slow_for(sorted(CASES), "dual_v", "orthoglide", "scara", "planar_3r")
)
def test_codesign_reduces_peak_force_and_payload_sensitivity_matches_fd(name, motions):
    """Generic co-design of the counter-masses lowers the peak shaking force of the move
    on every robot; the payload sensitivity of the RMS force equals central finite
    differences (1e-6 relative)."""
    robot, _ = _motion(name)
    motion = motions(name)
    free = ("counter_mass", "vertical_counterweight") if name == "scara" else ("counter_mass",)
    start = None
    if name.startswith("planar"):  # counterweights 0.2 m behind each joint (Briot §3.3)
        start = {"counter_distance": jnp.full(robot.dof, 0.2)}
        robot = robot.with_design(start)
    solution = jaxbal.design.codesign(
        robot, motion, "peak_force", free=free, start=start, max_steps=60
    )
    before = jaxbal.design.peak_force(robot, motion)
    after = jaxbal.design.peak_force(solution.robot, motion)
    assert float(after) < 0.9 * float(before), (float(before), float(after))
    assert np.all(np.asarray(solution.design["counter_mass"]) >= 0.0)
    result = jaxbal.sensitivity.sensitivity(
        robot, motion, "rms_force", wrt=("payload",), check=True, rtol=1e-6
    )
    assert np.isfinite(float(result.gradient["payload"]))
    assert result.max_relative_error <= 1e-6
