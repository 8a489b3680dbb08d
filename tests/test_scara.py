"""SCARA of Arakelian & Briot (2008): closed-form force balancing, optax co-design, and the
reactionless end-effector rotation law, all checked with the generic shaking wrench."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal.planning import wrench_along as _wrench_along
from jaxbal.robots import PickAndPlace, Scara, joint_trajectory, scara
from jaxbal.robots import scara_balancing as sb

wrench_along = eqx.filter_jit(_wrench_along)
DEG = np.pi / 180
DURATION = 0.3
TIMES = jaxbal.sample_times(DURATION, 61)


def paper_move(lift=0.025):
    """§2: x 0.15 → −0.15 m, y = 0.2 m, φ 83° → 157°, quintic, 0.3 s."""
    return PickAndPlace([0.15, 0.2, 83 * DEG], [-0.15, 0.2, 157 * DEG], DURATION, lift=lift)


def general_scara():
    """A SCARA with an off-axis end-effector COM and a payload (exercises condition 1)."""
    return Scara(
        lengths=[0.2, 0.15],
        com_offsets=[0.08, 0.06, 0.02],
        masses=[2.0, 1.5, 0.4],
        inertias=[0.02, 0.01, 0.002],
        payload=0.3,
        counter_distances=[0.12, 0.1, 0.04],
    )


@pytest.fixture(scope="module")
def unbalanced_wrench():
    robot = scara()
    return wrench_along(robot, joint_trajectory(robot, paper_move()), TIMES)


def test_inverse_kinematics_round_trip_and_paper_working_mode():
    # Reference: forward kinematics (exact to 1e-12); the paper's φ_i = 83°, φ_f = 157°
    # coincide with the link-2 angle θ1 + θ2 of working mode +1 (to 0.3°).
    robot = scara()
    move = paper_move()
    for t in (0.0, 0.1, DURATION):
        pose = move(t)
        np.testing.assert_allclose(
            robot.end_effector(robot.inverse_kinematics(pose)), pose, atol=1e-12
        )
    q0, q1 = robot.inverse_kinematics(move(0.0)), robot.inverse_kinematics(move(DURATION))
    assert abs(float(q0[0] + q0[1]) / DEG - 83.0) < 0.3
    assert abs(float(q1[0] + q1[1]) / DEG - 157.0) < 0.3


def test_closed_form_satisfies_conditions_and_matches_printed_design():
    # Reference: conditions (1)-(3) (zero to 1e-14 kg·m) and the paper's printed balanced
    # m1 = 6.2 kg, l_O1S1 = −0.117 m, m2 = 4.8 kg, l_O2S2 = −0.047 m (0.6% = rounding).
    balanced = sb.force_balanced(scara())
    np.testing.assert_allclose(sb.balance_residuals(balanced), 0.0, atol=1e-14)
    m, s = balanced.masses, balanced.com_offsets
    mc, rc = balanced.counter_masses, balanced.counter_distances
    merged_mass = m[:2] + mc[:2]
    merged_offset = (m[:2] * s[:2] - mc[:2] * rc[:2]) / merged_mass
    np.testing.assert_allclose(merged_mass, [6.2, 4.8], rtol=6e-3)
    np.testing.assert_allclose(merged_offset, [-0.117, -0.047], rtol=6e-3)
    assert float(balanced.vertical_counterweight) == pytest.approx(0.5, rel=1e-15)


def test_closed_form_solving_for_distances_is_the_inverse():
    # Reference: solving for distances at the closed-form masses returns the distances.
    robot = general_scara()
    balanced = sb.force_balanced(robot)
    again = sb.force_balanced(
        Scara(
            robot.lengths,
            robot.com_offsets,
            robot.masses,
            robot.inertias,
            robot.payload,
            counter_masses=balanced.counter_masses,
            counter_distances=[0.5, 0.5, 0.5],
        ),
        solve_for="distances",
    )
    np.testing.assert_allclose(again.counter_distances, robot.counter_distances, rtol=1e-13)
    np.testing.assert_allclose(sb.balance_residuals(again), 0.0, atol=1e-14)


@pytest.mark.parametrize("make", [scara, general_scara])
def test_balanced_robot_has_zero_shaking_force(make):
    # Reference: a force-balanced robot gives zero force (< 1e-9 of the unbalanced one).
    robot = make()
    move = PickAndPlace([0.15, 0.2, 0.3], [-0.1, 0.25, 1.2], DURATION, lift=0.03)
    forces0, _ = wrench_along(robot, joint_trajectory(robot, move), TIMES)
    balanced = sb.force_balanced(robot)
    forces, _ = wrench_along(balanced, joint_trajectory(balanced, move), TIMES)
    assert float(jnp.max(jnp.abs(forces))) < 1e-9 * float(jnp.max(jnp.abs(forces0)))


# make test-all: the generic co-design reaches the same closed form in make test
# (test_design.py::test_scara_reaches_closed_form)
@pytest.mark.slow
def test_codesign_recovers_closed_form():
    # Reference: closed form (eqs 1-3), 1e-6 relative, from a start 60% off.
    robot = general_scara()
    moves = [
        PickAndPlace([0.15, 0.2, 0.0], [-0.15, 0.2, 1.5], DURATION, lift=0.025),
        PickAndPlace([0.25, 0.1, -1.0], [0.0, 0.3, 0.5], 0.4, lift=0.03),
    ]
    paths = [joint_trajectory(robot, move) for move in moves]
    samples = sb.move_samples(paths, [move.duration for move in moves], count=16)
    closed = sb.counter_mass_design(sb.force_balanced(robot))
    solution = sb.codesign_counter_masses(robot, samples, 1.6 * closed)
    error = jnp.linalg.norm(solution.params - closed) / jnp.linalg.norm(closed)
    assert float(error) < 1e-6
    # A mass penalty trades residual force for less added mass.
    penalised = sb.codesign_counter_masses(robot, samples, closed, mass_weight=0.1)
    assert float(sb.added_mass(penalised.params)) < float(sb.added_mass(closed))
    assert bool(jnp.all(penalised.params >= 0))


def test_angular_momentum_coefficients_match_generic_momentum():
    # Reference: jaxbal.momentum (independent, generic) at a random configuration; exact
    # to 1e-14 for the force-balanced robot, whatever the configuration.
    balanced = sb.force_balanced(general_scara())
    j1, j2, j3 = sb.angular_momentum_coefficients(balanced)
    q = jnp.array([0.3, 1.1, -0.4, 0.01])
    lz = [jaxbal.momentum(balanced, q, jnp.eye(4)[k])[1][2] for k in range(3)]
    np.testing.assert_allclose(lz, [j1 + j2 + j3, j2 + j3, j3], rtol=1e-14)


def test_rotation_law_cancels_the_whole_wrench(unbalanced_wrench):
    # Reference: generic shaking_wrench; force and moment < 1e-9 of the unbalanced robot.
    forces0, moments0 = unbalanced_wrench
    balanced = sb.force_balanced(scara())
    forces, moments = wrench_along(
        balanced, sb.ReactionlessTrajectory(balanced, paper_move()), TIMES
    )
    assert float(jnp.max(jnp.abs(forces))) < 1e-9 * float(jnp.max(jnp.abs(forces0)))
    assert float(jnp.max(jnp.abs(moments))) < 1e-9 * float(jnp.max(jnp.abs(moments0)))


def test_eq8_as_printed_leaves_a_moment():
    # Reference: the force-balanced robot's moment; eq (8) with the links' own inertias
    # leaves more than 10% of it (it omits the carried masses' m·l² terms).
    balanced = sb.force_balanced(scara())
    _, moments_fb = wrench_along(balanced, joint_trajectory(balanced, paper_move()), TIMES)
    path = sb.ReactionlessTrajectory(balanced, paper_move(), law=sb.eq8_orientation)
    _, moments = wrench_along(balanced, path, TIMES)
    assert float(jnp.max(jnp.abs(moments[:, 2]))) > 0.1 * float(jnp.max(jnp.abs(moments_fb[:, 2])))


def test_turns_closed_form():
    # Reference: Δφ = −(J1 + J2) Δθ1 / J3 since Δθ1 = Δθ12 on the paper's move (same
    # radius at both ends), to 1e-12.
    balanced = sb.force_balanced(scara())
    j1, j2, j3 = sb.angular_momentum_coefficients(balanced)
    move = paper_move()
    q0, q1 = (balanced.inverse_kinematics(move(t)) for t in (0.0, DURATION))
    expected = -(j1 + j2) * (q1[0] - q0[0]) / j3 / (2 * np.pi)
    turns_phi, _ = sb.reactionless_turns(balanced, move, DURATION)
    assert float(turns_phi) == pytest.approx(float(expected), rel=1e-12)


def test_gradients():
    # Reference: jax.test_util.check_grads (finite differences), forward and reverse.
    robot = general_scara()
    move = paper_move()
    q, qd, qdd = eqx.filter_jit(jaxbal.time_derivatives)(joint_trajectory(robot, move), 0.11)

    @jax.jit
    def force(design):
        return jaxbal.shaking_wrench(sb.with_counter_mass_design(robot, design), q, qd, qdd)[0]

    check_grads(force, (jnp.array([1.0, 0.7, 0.2, 0.5]),), order=1, modes=("fwd", "rev"))

    @jax.jit
    def turns(inertias):
        balanced = sb.force_balanced(eqx_replace_inertias(robot, inertias))
        return sb.reactionless_turns(balanced, move, DURATION)[0]

    inertias = robot.inertias
    check_grads(turns, (inertias,), order=1, modes=("fwd", "rev"), eps=1e-7)
    grad = jax.grad(turns)(inertias)
    assert bool(jnp.all(jnp.isfinite(grad)))


def eqx_replace_inertias(robot, inertias):
    return eqx.tree_at(lambda r: r.inertias, robot, inertias)


def test_vmap_equals_loop():
    # Reference: a Python loop over end-effector inertias (exact to 1e-14).
    balanced = sb.force_balanced(scara())
    move = paper_move()
    values = jnp.array([0.005, 0.0126, 0.05, 0.2])

    def turns(i3):
        return sb.reactionless_turns(
            eqx_replace_inertias(balanced, balanced.inertias.at[2].set(i3)), move, DURATION
        )[0]

    batched = jax.jit(jax.vmap(turns))(values)
    one = jax.jit(turns)  # the loop: one sample per call (op by op it took seconds)
    looped = jnp.stack([one(v) for v in values])
    np.testing.assert_allclose(batched, looped, rtol=1e-14)


def test_unreachable_target_raises():
    robot = scara()
    with pytest.raises(ValueError, match="out of reach"):
        joint_trajectory(robot, PickAndPlace([0.15, 0.2, 0.0], [0.5, 0.0, 0.0], DURATION))
    # Both ends reachable, but the straight line crosses the inner dead zone (r < 0.1 m).
    with pytest.raises(ValueError, match="out of reach"):
        joint_trajectory(robot, PickAndPlace([0.2, 0.0, 0.0], [-0.2, 0.0, 0.0], DURATION))
    with pytest.raises(ValueError, match="out of reach"):
        robot.inverse_kinematics(jnp.array([0.4, 0.0, 0.0, 0.0]))


@pytest.mark.parametrize("bad", [2, 0, -2, (1, -1), (), (0,), "up"])
def test_invalid_branch_raises(bad):
    # Reference: the contract -- a sign other than ±1 or a tuple not of one sign is a
    # structure error (ValueError), with return_valid=True and along a joint trajectory.
    robot = scara()
    pose = paper_move()(0.1)
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(pose, branch=bad)
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(pose, branch=bad, return_valid=True)
    with pytest.raises(ValueError, match="branch"):
        joint_trajectory(robot, paper_move(), branch=bad)(0.1)


def test_branch_is_the_sign_of_sin_theta2():
    # Reference: eq (4), the "±" is the sign of sin θ2; both branches reach the pose
    # (forward kinematics, 1e-12) and (−1,) is −1 (exact).
    robot = scara()
    pose = paper_move()(0.1)
    for sign in (1, -1):
        q = robot.inverse_kinematics(pose, branch=sign)
        assert np.sign(np.sin(float(q[1]))) == sign
        np.testing.assert_allclose(robot.end_effector(q), pose, atol=1e-12)
        np.testing.assert_array_equal(q, robot.inverse_kinematics(pose, branch=(sign,)))
        np.testing.assert_array_equal(q, joint_trajectory(robot, paper_move(), sign)(0.1))


def test_invalid_parameters_raise():
    with pytest.raises(ValueError, match="non-negative"):
        Scara([0.1, 0.2], [0.0, 0.0, 0.0], [1.0, -1.0, 1.0], [0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match="shape"):
        Scara([0.1, 0.2, 0.3], [0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [0.1, 0.1, 0.1])
    with pytest.raises(ValueError, match="shape"):
        scara().body_frames(jnp.zeros(3))
    with pytest.raises(ValueError, match="solve_for"):
        sb.force_balanced(scara(), solve_for="inertias")
    with pytest.raises(ValueError, match="positive"):
        sb.force_balanced(
            Scara(
                [0.1, 0.2],
                [0.05, 0.1, 0.0],
                [1.0, 1.0, 1.0],
                [0.1] * 3,
                counter_distances=[0.0, 0.1, 0.1],
            )
        )


def test_mujoco_confirms_wrench_and_reactionless_motion(unbalanced_wrench):
    # Reference: MuJoCo C inverse dynamics on a tree built from the lengths
    # (Scara.mujoco_tree), 1e-9 relative; gravity included.
    from jaxbal.mujoco import mujoco_base_reaction

    robot = sb.force_balanced(general_scara())
    robot = sb.with_counter_mass_design(robot, 1.1 * sb.counter_mass_design(robot))
    rng = np.random.default_rng(0)
    q, qd, qdd = rng.normal(size=(3, 6, 4)) * np.array([1.0, 3.0, 30.0])[:, None, None]
    gravity = np.array([0.3, -1.0, -9.81])
    force, moment = mujoco_base_reaction(robot, q, qd, qdd, gravity=gravity)
    ref_force, ref_moment = jax.jit(
        jax.vmap(lambda a, b, c: jaxbal.shaking_wrench(robot, a, b, c, gravity=gravity))
    )(q, qd, qdd)
    np.testing.assert_allclose(force, ref_force, atol=1e-9 * np.max(np.abs(ref_force)))
    np.testing.assert_allclose(moment, ref_moment, atol=1e-9 * np.max(np.abs(ref_moment)))
    # The fully balanced robot on the paper's move: MuJoCo sees no reaction either.
    balanced = sb.force_balanced(scara())
    path = sb.ReactionlessTrajectory(balanced, paper_move())
    states = eqx.filter_jit(jaxbal.sample)(path, TIMES[::3])
    force, moment = mujoco_base_reaction(balanced, *states)
    forces0, moments0 = unbalanced_wrench
    assert np.max(np.abs(force)) < 1e-9 * float(jnp.max(jnp.abs(forces0)))
    assert np.max(np.abs(moment)) < 1e-9 * float(jnp.max(jnp.abs(moments0)))


def test_a_zero_counter_mass_where_no_moment_is_needed_is_accepted():
    """The nominal SCARA needs no third counter-mass (l_O3S3 = 0): a zero third
    counter-distance (or mass) was refused eagerly — naming the solved quantity, not the
    given one — while ``jit`` accepted it; with l_O3S3 > 0 ``jit`` gave 3.8e298 kg."""
    r_zero = eqx.tree_at(lambda r: r.counter_distances, scara(), jnp.array([0.16, 0.16, 0.0]))
    eager = sb.force_balanced(r_zero)
    compiled = jax.jit(sb.force_balanced)(r_zero)
    np.testing.assert_allclose(compiled.counter_masses, eager.counter_masses, rtol=1e-15)
    assert float(eager.counter_masses[2]) == 0.0
    np.testing.assert_allclose(sb.balance_residuals(eager), 0.0, atol=1e-12)
    m_zero = eqx.tree_at(lambda r: r.counter_masses, scara(), jnp.array([3.0, 2.0, 0.0]))
    np.testing.assert_allclose(
        sb.balance_residuals(sb.force_balanced(m_zero, solve_for="distances")), 0.0, atol=1e-12
    )
    offset = eqx.tree_at(lambda r: r.com_offsets, r_zero, r_zero.com_offsets.at[2].set(0.02))
    with pytest.raises(ValueError, match="positive given counter-distances"):
        sb.force_balanced(offset)
    with pytest.raises(Exception, match="positive given counter-distances"):
        jax.block_until_ready(jax.jit(sb.force_balanced)(offset).counter_masses)


def test_the_rotation_law_refuses_an_end_effector_of_no_inertia():
    """J3 = 0 gave φ = -inf and NaN turns without a word."""
    robot = eqx.tree_at(lambda r: r.inertias, scara(), jnp.array([0.014, 0.036, 0.0]))
    balanced = sb.force_balanced(robot)
    with pytest.raises(ValueError, match="J3 > 0"):
        sb.ReactionlessTrajectory(balanced, paper_move())(0.1)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_an_exported_balanced_scara_keeps_its_cable():
    """The vertical counterweight's cable (its slide = −d4) was not written to the
    exported MJCF: re-imported, the counterweight stood still and the balanced SCARA
    shook the base with 39 N vertically. Now a joint equality: the re-imported robot
    couples the two slides and gives the same wrench (mapped coordinates, 1e-9)."""
    from jaxbal.mujoco import export_mjcf

    balanced = sb.force_balanced(scara(payload=0.3))
    again = jaxbal.robots.from_mjcf(export_mjcf(balanced))
    assert again.joint_names == ("theta1", "theta2", "cable", "theta3", "d4")
    assert len(again.coupling_names) == 1 and again.independent == (0, 1, 3, 4)
    rng = np.random.default_rng(2)
    q, qd, qdd = (rng.uniform(-s, s, (8, 4)) for s in (2.0, 5.0, 50.0))

    def mapped(x):  # MuJoCo's qpos order (θ1, θ2, cable = −d4, θ3, d4)
        return np.stack([x[:, 0], x[:, 1], -x[:, 3], x[:, 2], x[:, 3]], 1)

    def wrenches(robot, *state):
        return np.asarray(
            jax.vmap(lambda a, b, c: jnp.concatenate(jaxbal.shaking_wrench(robot, a, b, c)))(*state)
        )

    ours = wrenches(balanced, q, qd, qdd)
    np.testing.assert_allclose(ours[:, :3], 0.0, atol=1e-9)
    np.testing.assert_allclose(wrenches(again, *map(mapped, (q, qd, qdd))), ours, atol=1e-9)
