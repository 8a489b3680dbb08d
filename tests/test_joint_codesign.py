"""Joint counter-mass + trajectory co-design and Pareto fronts on a small instance (2R).

References: optimality by the gradient of the loss (KKT residual of the bounded problem
in its smooth parametrisation), constraints by their values, the front by dominance and
by independent single-objective solves.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest

import jaxbal
from jaxbal.design import (
    TrapezoidLine,
    constraint_excess,
    dominance,
    joint_codesign,
    nondominated,
    pareto_front,
    payload_metrics,
)

THETA = {"u2": 0.25, "ratio": 0.5}
LOWER = {"u2": 0.05, "ratio": 0.05}
UPPER = {"u2": 0.45, "ratio": 1.0}
PAYLOADS = jnp.array([0.0, 2.5, 5.0])
DESIGN_UPPER = {"counter_distance": 0.3}


@pytest.fixture(scope="module")
def problem():
    arm = jaxbal.robots.planar_2r()
    move = TrapezoidLine(
        jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70]), jaxbal.sample_times(0.5, 16)
    )
    return arm, move


def _solve(arm, move, objective, **options):
    options = {"payloads": PAYLOADS, "upper": DESIGN_UPPER, "max_steps": 150, **options}
    return joint_codesign(
        arm, move, THETA, objective, trajectory_lower=LOWER, trajectory_upper=UPPER, **options
    )


def test_joint_optimum_is_stationary_and_feasible(problem):
    arm, move = problem
    budget = 3.0  # (the quadratic mean: one compiled program with the test below)
    options = {"constraints": {"added_mass": budget}, "robust": "rms", "gtol": 1e-9}
    solution = _solve(arm, move, "rms_force", **options)
    # KKT residual in the bound parametrisation (reference: gtol of the solver)
    assert float(solution.grad_norm) < 1e-6
    value, bound = solution.constraints["added_mass"]
    assert float(value) <= float(bound) * (1 + 1e-6)
    assert bool(solution.feasible)
    before, after = solution.metrics["rms_force"]
    assert float(after) < float(before)
    # trajectory inside its bounds; the bound marks where the values touch them
    for name, x in solution.trajectory.items():
        assert LOWER[name] <= float(x) <= UPPER[name]
        side = int(solution.trajectory_at_bound[name])
        touching = (float(x) - LOWER[name] < 1e-9, UPPER[name] - float(x) < 1e-9)
        assert side == (-1 if touching[0] else 1 if touching[1] else 0), (name, x, side)
    assert set(solution.at_bound) == {"counter_mass", "counter_distance"}
    mass = np.asarray(solution.design["counter_mass"])
    np.testing.assert_array_equal(solution.at_bound["counter_mass"] == -1, mass < 1e-9)


@pytest.mark.slow
def test_joint_no_worse_than_sequential(problem):
    arm, move = problem
    box = ({k: v - 1e-9 for k, v in THETA.items()}, {k: v + 1e-9 for k, v in THETA.items()})
    options = {"payloads": PAYLOADS, "upper": DESIGN_UPPER, "max_steps": 80, "robust": "max"}
    options["constraints"] = {"added_mass": 3.0}
    objective = {"peak_force": 1.0, "added_mass": 0.0}
    sequential = joint_codesign(
        arm, move, THETA, objective, trajectory_lower=box[0], trajectory_upper=box[1], **options
    )
    joint = joint_codesign(
        sequential.robot, move, THETA, objective, trajectory_lower=LOWER,
        trajectory_upper=UPPER, **options,
    )  # fmt: skip
    metrics = ("peak_force",)
    worst = [
        float(payload_metrics(s.robot, move, s.trajectory, PAYLOADS, metrics).max())
        for s in (sequential, joint)
    ]
    assert worst[1] <= worst[0] * (1 + 1e-9)
    assert float(joint.constraints["added_mass"][0]) <= 3.0 * (1 + 1e-6)


def test_robust_max_reports_the_worst_payload_exactly(problem):
    """The loss of ``robust="max"`` takes the smooth maximum (up to s·log(n)/k below the
    worst payload); ``metrics`` reports the worst payload itself, as ``payload_metrics``
    gives it (it reported the smooth one: a "worst case" 0.9 % below the true worst)."""
    arm, move = problem
    objective = {"rms_force": 1.0, "added_mass": 0.1}
    solution = _solve(arm, move, objective, robust="max", sharpness=200.0, max_steps=1)
    values = payload_metrics(solution.robot, move, solution.trajectory, PAYLOADS, ("rms_force",))
    assert float(solution.metrics["rms_force"][1]) == pytest.approx(float(values.max()), rel=1e-12)
    # and exactly the value of a metric the payload does not change (closed form)
    added = float(jaxbal.design.added_mass(solution.robot))
    assert added > 0.0
    assert float(solution.metrics["added_mass"][1]) == pytest.approx(added, rel=1e-12)


@pytest.mark.slow
def test_optax_optimizer_agrees_with_the_default(problem):
    """``optimizer=optax.lbfgs()`` (optax's compiled loop) reaches the optimum of the
    default host-driven L-BFGS (reference: the same stationary point, tol 1e-6 in the
    value, 1e-5 relative or 1e-9 SI in the variables; one counter-mass sits at its bound 0)."""
    arm, move = problem
    options = {"constraints": {"added_mass": 3.0}, "gtol": 1e-9}
    default = _solve(arm, move, "rms_force", **options)
    compiled = _solve(arm, move, "rms_force", optimizer=optax.lbfgs(), **options)
    assert bool(default.converged) and bool(compiled.converged)
    np.testing.assert_allclose(float(compiled.value), float(default.value), rtol=1e-6)
    # the distance of the counter-mass left at zero is free (flat): masses only
    np.testing.assert_allclose(
        compiled.design["counter_mass"], default.design["counter_mass"], rtol=1e-5, atol=1e-9
    )
    for name, x in default.trajectory.items():
        np.testing.assert_allclose(float(compiled.trajectory[name]), float(x), rtol=1e-5)


SKEWED = jnp.array([0.0, 1.0, 5.0])  # payloads [kg]: mean 2, median 1


def _balanced_payload_ratios(solution, move):
    values = payload_metrics(solution.robot, move, solution.trajectory, SKEWED, ("rms_force",))
    return np.asarray(values[:, 0])


def test_quadratic_mean_converges_balancing_the_mean_payload(problem):
    """A design that balances payload p* leaves the force (p - p*)·a_E(t) at payload p
    (eq 3 of Briot et al. 2012), so the RMS force at p is |p - p*|·RMS(a_E): the
    quadratic mean over 0, 1, 5 kg is least at p* = their mean, 2 kg (reference: the
    closed form, RMS forces 2 : 1 : 3). Its square is smooth, so L-BFGS converges.
    (An added-mass bound that does not bind: the program of the test above.)"""
    arm, move = problem
    options = {"constraints": {"added_mass": 1e3}, "robust": "rms", "gtol": 1e-9}
    solution = _solve(arm, move, "rms_force", payloads=SKEWED, **options)
    assert bool(solution.converged) and float(solution.grad_norm) <= 1e-9
    values = _balanced_payload_ratios(solution, move)
    np.testing.assert_allclose(values / values[1], [2.0, 1.0, 3.0], rtol=1e-6)
    # reported: the quadratic mean of the payloads' values (closed form)
    rms = float(np.sqrt(np.mean(values**2)))
    np.testing.assert_allclose(float(solution.metrics["rms_force"][1]), rms, rtol=1e-10)


@pytest.mark.slow
def test_mean_stalls_at_the_median_payload_and_says_why(problem):
    """The mean of the RMS forces |p - p*|·RMS(a_E) is least at the median payload,
    1 kg, where that payload's RMS force is exactly zero: a kink like |x| at 0. L-BFGS
    stops there unconverged (its gradient norm stays ~1e-2) and the co-design warns,
    naming the metric and the payload (reference: the closed form, zero at 1 kg)."""
    arm, move = problem
    with pytest.warns(RuntimeWarning, match=r"kink .*rms_force = .* at payload 1 kg"):
        solution = _solve(arm, move, "rms_force", payloads=SKEWED, gtol=1e-9)
    assert not bool(solution.converged)
    values = _balanced_payload_ratios(solution, move)
    assert values[1] <= 1e-9 * values[2]
    np.testing.assert_allclose(values[0] / values[2], 1.0 / 4.0, rtol=1e-6)


def test_invalid_start_raises_naming_the_value(problem):
    """A negative link mass set with ``eqx.tree_at`` (no constructor check) is refused
    before anything compiles, with a ``ValueError`` naming the masses."""
    arm, move = problem
    bad = eqx.tree_at(lambda r: r.masses, arm, jnp.array([-1.0, 1.0]))
    with pytest.raises(ValueError, match=r"body masses must be .*-1\."):
        _solve(bad, move, "rms_force", max_steps=2)
    with pytest.raises(ValueError, match=r"body masses must be .*-1\."):
        payload_metrics(bad, move, THETA, PAYLOADS, ("rms_force",))


def test_payload_metrics_vmaps_the_payload(problem):
    arm, move = problem
    values = payload_metrics(arm, move, THETA, PAYLOADS, ("rms_force",))
    one = payload_metrics(arm.with_design({"payload": PAYLOADS[1]}), move, THETA,
                          PAYLOADS[1:2], ("rms_force",))  # fmt: skip
    np.testing.assert_allclose(values[1], one[0], rtol=1e-12)  # reference: same computation
    # under jit, the robot traced (the eager robot check steps aside for the traced guards)
    compiled = jax.jit(lambda r: payload_metrics(r, move, THETA, PAYLOADS, ("rms_force",)))
    np.testing.assert_allclose(compiled(arm), values, rtol=1e-12)


def test_nondominated_known_set():
    values = np.array([[1.0, 3.0], [2.0, 2.0], [3.0, 1.0], [2.5, 2.5], [1.0, 3.0]])
    np.testing.assert_array_equal(nondominated(values), [True, True, True, False, True])


@pytest.mark.slow
def test_front_end_points_and_dominance(problem):
    """The w = 0 end point equals an independent single-objective solve (1e-8). With
    the mean over payloads (the default) neither solve converged: the mean of the RMS
    forces has its minimum on a kink, the middle payload balanced exactly (see the
    test above), where the line search stalled at a point that rounding decided
    (9.2462 or 9.2518 N). The quadratic mean is smooth there: both converge, to one
    value, although the optimal designs form a valley (only the moments m·r count)."""
    arm, move = problem
    options = {"payloads": PAYLOADS, "upper": DESIGN_UPPER, "max_steps": 300, "gtol": 1e-9}
    options.update(trajectory_lower=LOWER, trajectory_upper=UPPER, robust="rms")
    metrics = ("rms_force", "added_mass")
    front = pareto_front(arm, move, THETA, metrics, [0.0, 0.3, 1.0], **options)
    assert bool(front.efficient.all())
    assert bool(front.feasible.all())
    single = joint_codesign(arm, move, THETA, "rms_force", **options)
    assert bool(single.converged) and bool(front.solutions[0].converged)
    # reference: an independent single-objective solve (end point w = 0)
    np.testing.assert_allclose(front.values[0, 0], single.metrics["rms_force"][1], rtol=1e-8)
    # w = 1: the added mass alone is minimised -> zero counter-mass (reference: 0, within
    # the 0.1 g that the r² bound parametrisation approaches it by, START_OFFSET)
    assert float(front.values[-1, 1]) < 1e-4
    assert jax.numpy.all(jnp.diff(front.values[:, 1]) <= 1e-9)


def test_dominance_matrix_known_set():
    values = np.array([[1.0, 3.0], [2.0, 2.0], [2.5, 2.5]])
    expected = np.zeros((3, 3), dtype=bool)
    expected[1, 2] = True  # (2, 2) dominates (2.5, 2.5); nothing else dominates
    np.testing.assert_array_equal(dominance(values), expected)


def test_constraint_excess_is_relative_to_the_bound():
    class Solved:  # the constraints of a JointSolution: name -> (worst value, bound)
        constraints = {"added_mass": (3.003, 3.0), "peak_torque": (-1.0, -2.0)}

    # reference: hand computation, (3.003 - 3) / 3 = 1e-3 and (-1 + 2) / 2 = 0.5
    assert constraint_excess(Solved()) == pytest.approx(0.5)
    Solved.constraints = {"added_mass": (3.003, 3.0)}
    assert constraint_excess(Solved()) == pytest.approx(1e-3)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_design_that_balances_a_com_plan_away_is_refused():
    """The 2R's ComTrapezoid with free counter-masses against the RMS force: the
    optimiser drives the design to force balance, where the COM barely moves and the
    COM plan no longer joins P5 and P9. The compiled co-design saw a finite motion of
    that degenerate plan and reported RMS force 47 → 3e-8 N as the move's, a design
    its own factory refused. Now a motion that does not join is NaN to the optimiser,
    which stays where the plan joins, and the returned design's motion is rebuilt with
    the checks on: either the co-design refuses (naming the remedy; at the edge of
    validity, rounding decides) or its motion is valid and its metric re-evaluates."""
    from jaxbal.design import ComTrapezoid

    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    move = ComTrapezoid(q0, q1, jaxbal.sample_times(0.5, 51))
    try:
        solution = joint_codesign(
            arm, move, {"u2": 0.3, "ratio": 0.5}, "rms_force",
            trajectory_lower=LOWER, trajectory_upper={"u2": 0.4999, "ratio": 1.0},
            upper={"counter_distance": 0.2},
        )  # fmt: skip
    except ValueError as error:
        assert "no valid motion at payload 5 kg" in str(error) and "bound the counter" in str(error)
        return
    motion = move(solution.robot, solution.trajectory)  # raised before: the plan did not join
    np.testing.assert_allclose(motion.q[0], q0, atol=1e-6)
    again = payload_metrics(solution.robot, move, solution.trajectory, [5.0], ("rms_force",))
    np.testing.assert_allclose(again[0, 0], solution.metrics["rms_force"][1], rtol=1e-6)
