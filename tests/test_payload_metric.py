"""A metric aggregated over a payload grid (``jaxbal.design.over_payloads``).

References: a Python loop over the payloads (the metric of each loaded robot); the
closed form of a counter-mass error on a design balanced for the grid's middle payload
(the aggregate's square is a parabola in the error: the force is affine in a mass along
a fixed joint motion, and the cross term of the payloads cancels on a symmetric grid)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.design import TrapezoidLine, codesign, over_payloads, rms_force
from jaxbal.robots.planar_arm import force_balanced

GRID = jnp.array([1.0, 2.5, 4.0])  # [kg], symmetric about the balanced 2.5 kg
THETA = {"u2": 0.25, "ratio": 0.5}


@pytest.fixture(scope="module")
def balanced():
    line = TrapezoidLine(
        jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70]), jaxbal.sample_times(0.5, 16)
    )
    arm = force_balanced(jaxbal.robots.planar_2r(payload=2.5), jnp.array([0.3, 0.2]))
    return arm, line, line(arm, THETA)


@jax.jit
def _evaluate(metric, arm, motion):
    return metric(arm, motion)


def _loop(arm, motion):
    return np.array([float(rms_force(arm.with_design({"payload": p}), motion)) for p in GRID])


def test_values_are_the_aggregates_of_a_loop_over_the_payloads(balanced):
    arm, line, motion = balanced
    values = _loop(arm, motion)
    assert values[1] < 1e-9 * values[0]  # balanced for 2.5 kg (force_balanced)
    expected = {"mean": values.mean(), "rms": np.sqrt(np.mean(values**2)), "max": values.max()}
    for robust, value in expected.items():
        metric = over_payloads("rms_force", GRID, robust)
        np.testing.assert_allclose(float(_evaluate(metric, arm, motion)), value, rtol=1e-12)
    # re-planned for each loaded robot by the factory (the given motion is not used)
    planned = over_payloads("rms_force", GRID, "rms", line, THETA)
    np.testing.assert_allclose(float(_evaluate(planned, arm, None)), expected["rms"], rtol=1e-12)


def test_bad_inputs_are_refused_by_name(balanced):
    _, line, _ = balanced
    for args, match in [
        (("rms_force", GRID, "median"), "robust must be 'mean', 'rms' or 'max', got 'median'"),
        (("rms_force", [1.0, -2.0]), r"payloads must be finite and >= 0 kg, got \[-2.0\]"),
        (("rms_forces", GRID), "unknown metric 'rms_forces'"),
        (("rms_force", GRID, "rms", line), "a motion factory and its trajectory"),
    ]:
        with pytest.raises(ValueError, match=match):
            over_payloads(*args)


def test_without_a_factory_it_is_a_term_of_codesign_with_one_it_is_refused(balanced):
    """A term of ``codesign`` is static (hashable): so is the metric without a factory;
    with one (arrays) ``codesign`` refuses it by name, before anything compiles."""
    arm, line, motion = balanced
    assert hash(over_payloads("rms_force", GRID)) == hash(over_payloads("rms_force", GRID))
    with pytest.raises(ValueError, match="must be hashable .* got OverPayloads"):
        codesign(arm, motion, over_payloads("rms_force", GRID, "rms", line, THETA))


def test_codesign_of_the_quadratic_mean_balances_the_mean_payload(balanced):
    """The counter-masses of the 2R co-designed for the quadratic mean of the RMS
    forces over 0, 1, 5 kg along a fixed motion: the force at payload p of a design
    balanced for p* is (p − p*)·a_E(t), so the optimum balances the mean payload, 2 kg
    (reference: the closed form, RMS forces 2 : 1 : 3)."""
    arm, _, motion = balanced
    skewed = (0.0, 1.0, 5.0)
    objective = over_payloads("rms_force", skewed, "rms")
    solution = codesign(arm, motion, objective, upper={"counter_distance": 0.3})
    assert bool(solution.converged)
    values = np.array(
        [float(rms_force(solution.robot.with_design({"payload": p}), motion)) for p in skewed]
    )
    np.testing.assert_allclose(values / values[1], [2.0, 1.0, 3.0], rtol=1e-6)


@pytest.mark.slow  # make test-all (make test's 10-minute budget): ~15 s of compilation
def test_tolerance_of_the_robust_objective_is_the_parabolas(balanced):
    """The machining tolerance of link 2's counter-mass for a 1 % rise of the quadratic
    mean of the RMS forces over 1, 2.5, 4 kg: with A the aggregate's square at the
    design and B its rise per kg² (two loops over the payloads), ±√((1.01² − 1) A/B)."""
    arm, _, motion = balanced

    def squared(error):
        masses = arm.design()["counter_mass"].at[1].add(error)
        return float(np.mean(_loop(arm.with_design({"counter_mass": masses}), motion) ** 2))

    a = squared(0.0)
    b = squared(1.0) - a
    assert squared(-1.0) - a == pytest.approx(b, rel=1e-9)  # no linear term: a parabola
    expected = np.sqrt((1.01**2 - 1.0) * a / b)
    objective = over_payloads("rms_force", GRID, "rms")
    tol = jaxbal.sensitivity.tolerance(arm, motion, objective, wrt=("counter_mass",))
    below, above = tol.interval["counter_mass"]
    np.testing.assert_allclose([below[1], above[1]], [expected, expected], rtol=1e-7)
    assert tol.minimum  # balanced for the grid's mean payload: the optimum of "rms"
