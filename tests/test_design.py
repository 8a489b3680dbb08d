"""Co-design on every robot (jaxbal.design): closed forms, force reduction, penalties,
compilation reuse and input errors."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.design import (
    METRICS,
    Motion,
    added_inertia,
    added_mass,
    as_motion,
    codesign,
    motion_samples,
    rms_force,
)
from jaxbal.planning import EndEffectorLine
from jaxbal.profiles import Quintic
from jaxbal.robots import planar_arm, scara_balancing

SAMPLES = 31
COUNTER_DISTANCES_2R = jnp.array([0.35, 0.2])  # Briot et al. (2012), §3.3 footnote 1


def _line(robot, start, end, duration):
    trajectory = EndEffectorLine(robot, jaxbal.StraightLine(start, end, Quintic(), duration))
    return motion_samples(robot, trajectory, jnp.linspace(0.0, duration, SAMPLES))


def _arm_2r(payload=5.0):
    return jaxbal.robots.planar_2r(payload).with_design({"counter_distance": COUNTER_DISTANCES_2R})


@pytest.fixture(scope="module")
def motion_2r():
    return _line(_arm_2r(), [0.6, 0.1], [0.1, 0.6], 0.3)


@pytest.fixture(scope="module")
def scara_case():
    robot = jaxbal.robots.scara()
    move = jaxbal.robots.PickAndPlace(
        [0.15, 0.2, np.deg2rad(83.0)], [-0.15, 0.2, np.deg2rad(157.0)], 0.3, lift=0.03
    )
    trajectory = jaxbal.robots.joint_trajectory(robot, move)
    return robot, motion_samples(robot, trajectory, jnp.linspace(0.0, 0.3, SAMPLES))


_TRACES = []


def counted_rms_force(robot, motion):
    """The RMS shaking force; records each trace (it runs only while JAX traces)."""
    _TRACES.append(type(robot).__name__)
    return rms_force(robot, motion)


def test_planar_2r_reaches_closed_form(motion_2r):
    """2R, counterweights free at 0.35 m and 0.2 m (a callable objective): the optimum
    is the closed form of planar_arm.force_balanced (Briot et al. 2012, §3.3), masses to
    1e-6 relative, and the RMS shaking force vanishes (< 1e-6 of the unbalanced one)."""
    arm = _arm_2r()
    solution = codesign(arm, motion_2r, counted_rms_force, free=["counter_mass"])
    expected = planar_arm.force_balanced(arm, COUNTER_DISTANCES_2R).counter_masses
    np.testing.assert_allclose(solution.design["counter_mass"], expected, rtol=1e-6)
    before, after = solution.metrics["counted_rms_force"]
    assert after < 1e-6 * before
    assert bool(solution.converged)
    np.testing.assert_allclose(solution.design["counter_distance"], COUNTER_DISTANCES_2R)
    assert float(solution.value) < 1e-12 < float(solution.initial_value)


def test_at_bound_marks_the_active_bounds(motion_2r):
    """2R counterweight masses (RMS force, convex): free, the closed form is inside (no
    mark); with the first mass capped at half its closed form, the optimum puts it on
    the cap (+1) and the second on 0 kg (-1: removed), with the default optimiser and
    with optax's L-BFGS alike, the values on the bounds to 1e-9 kg."""
    import optax

    arm = _arm_2r()
    expected = planar_arm.force_balanced(arm, COUNTER_DISTANCES_2R).counter_masses
    free = codesign(arm, motion_2r, free=["counter_mass"])
    np.testing.assert_array_equal(free.at_bound["counter_mass"], [0, 0])
    cap = {"counter_mass": jnp.array([0.5 * expected[0], 2.0 * expected[1]])}
    for optimizer in (None, optax.lbfgs()):
        capped = codesign(arm, motion_2r, free=["counter_mass"], upper=cap, optimizer=optimizer)
        assert set(capped.at_bound) == {"counter_mass"}
        np.testing.assert_array_equal(capped.at_bound["counter_mass"], [1, -1])
        np.testing.assert_allclose(
            capped.design["counter_mass"], [0.5 * expected[0], 0.0], rtol=1e-12, atol=1e-9
        )


def test_start_outside_the_bounds_is_named(motion_2r):
    """A start outside its bounds names the entry, its value and the bounds."""
    with pytest.raises(ValueError, match=r"\[1\] = 3 not in \[0, 2\]"):
        codesign(
            _arm_2r(), motion_2r, free=["counter_mass"], start={"counter_mass": [1.0, 3.0]},
            upper={"counter_mass": 2.0},
        )  # fmt: skip


def test_second_call_does_not_retrace(motion_2r):
    """A second co-design of a 2R with another payload and start reuses the compiled
    L-BFGS loop and evaluation: the objective is not traced again (trace count), and
    the answer is the new closed form (force_balanced, 1e-6 relative)."""
    codesign(_arm_2r(5.0), motion_2r, counted_rms_force, free=["counter_mass"])
    traced = len(_TRACES)
    assert traced > 0
    arm = _arm_2r(2.0)
    start = {"counter_mass": jnp.array([3.0, 1.0])}
    solution = codesign(arm, motion_2r, counted_rms_force, free=["counter_mass"], start=start)
    assert len(_TRACES) == traced
    expected = planar_arm.force_balanced(arm, COUNTER_DISTANCES_2R).counter_masses
    np.testing.assert_allclose(solution.design["counter_mass"], expected, rtol=1e-6)


def test_scara_reaches_closed_form(scara_case):
    """SCARA, counter-masses and vertical counterweight free from zero: the optimum is
    the closed form of scara_balancing.force_balanced (Arakelian & Briot 2008, eqs 1-3
    and Fig 5) to 1e-6 kg (masses of 0 to 5 kg); added_mass is their sum (1e-6 kg)."""
    robot, motion = scara_case
    solution = codesign(robot, motion, free=["counter_mass", "vertical_counterweight"])
    expected = scara_balancing.force_balanced(robot)
    np.testing.assert_allclose(
        solution.design["counter_mass"], expected.counter_masses, rtol=1e-6, atol=1e-6
    )
    np.testing.assert_allclose(
        solution.design["vertical_counterweight"], expected.vertical_counterweight, atol=1e-6
    )
    np.testing.assert_allclose(
        added_mass(solution.robot),
        jnp.sum(expected.counter_masses) + expected.vertical_counterweight,
        atol=1e-6,
    )


def _reduced(solution, before_factor):
    """The RMS and the peak force both fall below ``before_factor`` × their start."""
    for name in ("rms_force", "peak_force"):
        before, after = solution.metrics[name]
        assert float(after) < before_factor * float(before), (name, before, after)


def test_planar_3r_added_mass_budget():
    """3R with counterweights at 0.35, 0.2, 0.1 m and an added-mass budget of half the
    closed form's (planar_arm.force_balanced): the budget is active and met to
    FEASIBILITY_RTOL (1e-3 relative; penalty weight 1e4) and the RMS and peak forces
    fall (reference: the unbalanced 3R on the same motion, factor < 0.9)."""
    distances = jnp.array([0.35, 0.2, 0.1])
    robot = jaxbal.robots.planar_3r().with_design({"counter_distance": distances})
    motion = _line(robot, [0.6, 0.1, 0.0], [0.1, 0.6, 1.0], 0.3)
    balanced = planar_arm.force_balanced(robot, distances).counter_masses
    budget = 0.5 * float(jnp.sum(balanced))
    objective = {"rms_force": 1.0, "peak_force": 0.0}
    constraints = {"added_mass": budget}
    solution = codesign(robot, motion, objective, free=["counter_mass"], constraints=constraints)
    value, bound = solution.constraints["added_mass"]
    assert float(bound) == budget and bool(solution.feasible)
    np.testing.assert_allclose(value, budget, rtol=1e-3)
    assert float(solution.metrics["added_mass"][0]) == 0.0
    _reduced(solution, 0.9)


@pytest.mark.slow
def test_dual_v_full_force_balance_within_bounds():
    """DUAL-V without counter-masses, distances bounded to [0, 0.1] m (two-sided map):
    co-design balances it completely (RMS and peak force < 1e-6 of the unbalanced
    robot's on the same motion) and the bounds hold exactly."""
    robot = jaxbal.robots.dual_v(counter_masses=False)
    motion = _line(robot, [0.0, -0.05, 0.0], [0.05, 0.05, 0.0], 0.1)
    start = {"counter_mass": jnp.ones(4), "counter_distance": jnp.full(4, 0.05)}
    solution = codesign(
        robot,
        motion,
        {"rms_force": 1.0, "peak_force": 0.0},
        start=start,
        upper={"counter_distance": 0.1},
    )
    assert bool(solution.converged)
    _reduced(solution, 1e-6)
    distance = np.asarray(solution.design["counter_distance"])
    assert np.all((distance >= 0.0) & (distance <= 0.1))
    assert np.all(np.asarray(solution.design["counter_mass"]) >= 0.0)


@pytest.mark.slow
def test_orthoglide_counter_sliders_reduce_force():
    """Orthoglide, counter-sliders from zero, EndEffectorLine (0,0,0) -> (-0.1,0.07,-0.11)
    in 0.1 s: the RMS and peak shaking forces fall below 0.5 of the unbalanced robot's
    (counter-sliders cannot balance the parallelograms, so not to zero)."""
    robot = jaxbal.robots.orthoglide()
    motion = _line(robot, [0.0, 0.0, 0.0], [-0.1, 0.07, -0.11], 0.1)
    solution = codesign(robot, motion, {"rms_force": 1.0, "peak_force": 0.0})
    assert bool(solution.converged)
    _reduced(solution, 0.5)
    assert np.all(np.asarray(solution.design["counter_mass"]) > 0.0)
    assert float(solution.design["payload"]) == 0.0


def test_added_inertia_of_counterweights(motion_2r):
    """added_inertia of a 2R = Σ m_cw,k |c_cw,k|² of its point counterweights about the
    base z axis at the motion's first sample (closed form, 1e-12 relative)."""
    arm = planar_arm.force_balanced(_arm_2r(), COUNTER_DISTANCES_2R)
    q1, q2 = motion_2r.q[0]
    joint_a = 0.5 * jnp.array([jnp.cos(q1), jnp.sin(q1)])
    second = joint_a - 0.2 * jnp.array([jnp.cos(q1 + q2), jnp.sin(q1 + q2)])
    mass = arm.counter_masses
    expected = mass[0] * 0.35**2 + mass[1] * jnp.sum(second**2)
    np.testing.assert_allclose(jax.jit(added_inertia)(arm, motion_2r), expected, rtol=1e-12)
    assert float(jax.jit(added_inertia)(_arm_2r(), motion_2r)) == 0.0


def test_motion_samples_stacks_and_checks_loop_closures(motion_2r):
    """motion_samples stacks several trajectories (the 2R fixture's samples, exactly) and
    raises ValueError, naming the instants, for a state off the Orthoglide's loop
    closures (tolerance LOOP_TOLERANCE = 1e-8 m; the state is 1e-3 m off)."""
    arm = _arm_2r()
    line = EndEffectorLine(arm, jaxbal.StraightLine([0.6, 0.1], [0.1, 0.6], Quintic(), 0.3))
    times = jnp.linspace(0.0, 0.3, SAMPLES)
    motion = motion_samples(arm, [line, line], [times, times])
    assert isinstance(motion, Motion) and motion.q.shape == (2 * SAMPLES, 2)
    for stacked, single in zip(motion, motion_2r, strict=True):
        np.testing.assert_array_equal(stacked, jnp.concatenate([single, single]))
    robot = jaxbal.robots.orthoglide()
    q_home = robot.inverse_kinematics(jnp.zeros(3))
    with pytest.raises(ValueError, match="loop closures"):
        motion_samples(robot, lambda t: q_home.at[0].add(1e-3 + 0.0 * t), jnp.zeros(1))
    single = motion_samples(arm, line, [float(t) for t in times])
    assert as_motion([single, single]).q.shape == (2 * SAMPLES, 2)
    with pytest.raises(ValueError, match="time arrays"):
        motion_samples(arm, [line, line], [times])


def test_bad_inputs_raise(motion_2r):
    """Unknown metric / design names list the valid ones; empty free, non-finite start,
    negative weight, start outside bounds and a wrong motion shape are ValueErrors."""
    arm = _arm_2r()
    with pytest.raises(ValueError, match="rms_force"):
        codesign(arm, motion_2r, "rms_shaking")
    with pytest.raises(ValueError, match="counter_mass"):
        codesign(arm, motion_2r, free=["counter_masses"])
    with pytest.raises(ValueError, match="no design variable"):
        codesign(arm, motion_2r, free=[])
    with pytest.raises(ValueError, match="finite"):
        codesign(arm, motion_2r, start={"counter_mass": jnp.array([jnp.nan, 1.0])})
    with pytest.raises(ValueError, match="non-negative"):
        codesign(arm, motion_2r, {"rms_force": 1.0, "added_mass": -1.0})
    with pytest.raises(ValueError, match="outside its bounds"):
        codesign(arm, motion_2r, free=["counter_mass"], lower={"counter_mass": 1.0})
    with pytest.raises(ValueError, match="must exceed"):
        codesign(arm, motion_2r, upper={"counter_distance": 0.0})
    with pytest.raises(ValueError, match="shape"):
        codesign(arm, Motion(*(v[:, :1] for v in motion_2r)))
    with pytest.raises(ValueError, match="added_inertia"):
        codesign(arm, motion_2r, constraints={"mass": 1.0})
    assert set(METRICS) >= {"peak_force", "rms_force", "peak_moment", "rms_moment"}


@pytest.mark.slow
@pytest.mark.parametrize("name", ["dual_v", "scara"])
def test_codesign_cannot_reach_a_negative_mass(name, scara_case):
    """An objective whose unconstrained optimum has negative counter-masses (the RMS
    actuator torque falls as a counter-mass gets lighter, past zero): the co-design stops
    at zero mass and every body mass the physics sees stays >= 0 (issue 12)."""
    if name == "scara":
        robot, motion = scara_case
    else:
        robot = jaxbal.robots.dual_v()
        motion = _line(robot, [0.0, -0.05, 0.0], [0.05, 0.05, 0.0], 0.1)
    small = {"counter_mass": jnp.full_like(robot.design()["counter_mass"], 0.05)}
    # reference: the gradient at a light design pushes the masses down (towards < 0)
    slope = jax.grad(
        lambda m: METRICS["rms_torque"](robot.with_design({"counter_mass": m}), motion)
    )(small["counter_mass"])
    assert np.all(np.asarray(slope) > 0.0)
    solution = codesign(
        robot, motion, "rms_torque", free=("counter_mass",), start=small, max_steps=40
    )
    masses = np.asarray(solution.design["counter_mass"])
    assert np.all(masses >= 0.0) and np.all(masses < 0.05)
    assert np.all(np.asarray(solution.robot.mass_properties().mass) >= 0.0)


def test_default_optimiser_agrees_with_optax_lbfgs(scara_case):
    """The default co-design (host-driven L-BFGS-B, jaxbal._src.lbfgsb) and the compiled
    optax L-BFGS (optimizer=optax.lbfgs()) reach the same SCARA optimum (RMS force plus
    added mass, three counter-masses): designs to 1e-7 relative, losses to 1e-10, same
    starting metrics and initial loss."""
    import optax

    robot, motion = scara_case
    objective = {"rms_force": 1.0, "added_mass": 0.05}
    kwargs = {"free": ["counter_mass"], "max_steps": 300, "gtol": 1e-11}
    ours = codesign(robot, motion, objective, **kwargs)
    reference = codesign(robot, motion, objective, optimizer=optax.lbfgs(), **kwargs)
    assert bool(ours.converged) and bool(reference.converged)
    np.testing.assert_allclose(
        ours.design["counter_mass"], reference.design["counter_mass"], rtol=1e-7, atol=1e-9
    )
    np.testing.assert_allclose(ours.value, reference.value, rtol=1e-10)
    np.testing.assert_allclose(ours.initial_value, reference.initial_value, rtol=1e-14)
    for name, (before, after) in reference.metrics.items():
        np.testing.assert_allclose(ours.metrics[name][0], before, rtol=1e-14)
        np.testing.assert_allclose(ours.metrics[name][1], after, rtol=1e-7)


def test_invalid_start_raises(motion_2r):
    """A robot changed with eqx.tree_at to a negative link mass, or a NaN in the motion,
    is a ValueError naming it (the robot is checked before the co-design compiles, the
    motion and the start's values on the host), not an optimisation of garbage."""
    import equinox as eqx

    arm = _arm_2r()
    bad = eqx.tree_at(lambda r: r.masses, arm, arm.masses.at[0].set(-1.0))
    with pytest.raises(ValueError, match=r"masses must be .*-1\."):
        codesign(bad, motion_2r, free=["counter_mass"])
    nan = Motion(motion_2r.q.at[3, 0].set(jnp.nan), motion_2r.qd, motion_2r.qdd)
    with pytest.raises(ValueError, match="motion q must be finite"):
        codesign(arm, nan, free=["counter_mass"])


def test_compiled_codesign_has_no_callbacks(motion_2r):
    """The one compiled program of the default co-design carries no host callbacks (no
    runtime-error checks), so JAX's persistent compilation cache can store it: a second
    Python process starts warm."""
    import equinox as eqx

    from jaxbal._src import design_loss as design

    arm = _arm_2r()
    problem = design._Problem(
        free=("counter_mass",), two_sided=(False,), terms=("rms_force",), constrained=(),
        lower=(jnp.zeros(2),), upper=(jnp.zeros(2),), weights=jnp.ones(1),
        scales=jnp.ones(1), bounds=jnp.zeros(0), bound_scales=jnp.zeros(0),
        penalty=jnp.asarray(1.0),
    )  # fmt: skip
    layout = (("counter_mass", (2,)),)
    dynamic, static = eqx.partition((arm, motion_2r, problem), eqx.is_array)
    leaves, treedef = jax.tree_util.tree_flatten(dynamic)
    lowered = design.loss_grad_program().lower(
        layout, design._Structure((treedef, static)), jnp.ones(2), leaves, np.asarray(False)
    )
    text = lowered.as_text()
    assert "callback" not in text.lower()
    assert "sine" in text  # the program does contain the dynamics


@pytest.mark.slow
def test_start_at_the_lower_bounds_leaves_them():
    """DUAL-V without counter-masses (every mass and distance at its lower bound: a
    saddle, where the products m·d have a zero gradient): the default co-design
    (L-BFGS-B from a start moved START_OFFSET inside) leaves the bounds and reaches a
    loss no worse than the compiled optax L-BFGS on the bound map from the same start
    (which stops at a local minimum with two counter-masses: RMS force 149 → 44 N for
    +9.1 kg, against 12 N for +16 kg). The optimum is a KKT point of the loss assembled
    here from the metrics and differentiated by jax.grad: zero gradient in the masses
    (interior), a descent direction only out of the box for distances at their bound."""
    import optax

    robot = jaxbal.robots.dual_v(counter_masses=False)
    motion = _line(robot, [0.0, -0.05, 0.0], [0.05, 0.05, 0.0], 0.1)
    kwargs = {"upper": {"counter_distance": 0.1}}
    objective = {"rms_force": 1.0, "added_mass": 0.01}
    ours = codesign(robot, motion, objective, **kwargs)
    reference = codesign(robot, motion, objective, optimizer=optax.lbfgs(), **kwargs)
    assert bool(ours.converged) and bool(reference.converged)
    assert float(ours.value) <= float(reference.value) * (1.0 + 1e-9)
    before, after = ours.metrics["rms_force"]
    assert float(after) < 0.5 * float(before)
    # the loss of design.py's module doc: scales are the start's RMS force and, for the
    # added mass that starts at zero, the bare robot's total mass
    force_scale, mass_scale = float(before), float(jaxbal.total_mass(robot))

    def loss(design):
        designed = robot.with_design(design)
        return (rms_force(designed, motion) / force_scale) ** 2 + 0.01 * (
            added_mass(designed) / mass_scale
        ) ** 2

    design = {name: jnp.asarray(ours.design[name]) for name in ("counter_mass", "counter_distance")}
    np.testing.assert_allclose(loss(design), ours.value, rtol=1e-9)
    gradient = jax.grad(loss)(design)
    masses, distances = np.asarray(design["counter_mass"]), np.asarray(design["counter_distance"])
    assert np.all(masses > 1.0)  # all four left their bound
    np.testing.assert_allclose(gradient["counter_mass"], 0.0, atol=1e-7)
    at_upper = distances >= 0.1 - 1e-12
    assert np.all(np.asarray(gradient["counter_distance"])[at_upper] < 0.0)
    np.testing.assert_allclose(np.asarray(gradient["counter_distance"])[~at_upper], 0.0, atol=1e-7)
