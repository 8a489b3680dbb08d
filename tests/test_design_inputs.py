"""Bad inputs to the optimisation tools are refused by name before anything optimises.

Each case below used to run (or half run) and return a number: a −9 kg counter-mass
reported as 0 added mass (a negative lower bound on a mass), a smooth *minimum* reported
as the worst case (a negative ``sharpness``), a reward for breaking a constraint (a
negative penalty), a start silently clipped into its bounds, an extra start that changed
the fixed variables and the payload of a multistart, a Pareto "front" of one metric whose
w = 0 point was the unoptimised start, NaN from a NaN starting point of ``minimize``.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.design import (
    TrapezoidLine,
    codesign,
    joint_codesign,
    multistart_joint_codesign,
    pareto_front,
)

THETA = {"u2": 0.25, "ratio": 0.5}
BOX = {
    "trajectory_lower": {"u2": 0.05, "ratio": 0.05},
    "trajectory_upper": {"u2": 0.45, "ratio": 1.0},
}


@pytest.fixture(scope="module")
def arm():
    return jaxbal.robots.planar_2r()


@pytest.fixture(scope="module")
def move():
    return TrapezoidLine(
        jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70]), jaxbal.sample_times(0.5, 12)
    )


@pytest.fixture(scope="module")
def motion(arm, move):
    return move(arm, {k: jnp.asarray(v) for k, v in THETA.items()})


def test_a_negative_lower_bound_on_a_mass_is_refused(arm, motion, move):
    """The planar 2R's counter-mass cannot go below 0 kg: ``lower=-10`` is refused,
    naming the bound and the robot's own; a negative counter-mass *distance* (the mass
    on the other side of the joint) is a robot, and is accepted."""
    upper = {"counter_mass": 10.0, "counter_distance": 0.3}
    refused = r"lower\['counter_mass'\] = \[-10.0, -10.0\] gives an invalid robot"
    with pytest.raises(ValueError, match=refused):
        codesign(arm, motion, "rms_force", lower={"counter_mass": -10.0}, upper=upper)
    with pytest.raises(ValueError, match=r"lower\['counter_mass'\]"):
        joint_codesign(arm, move, THETA, "rms_force", lower={"counter_mass": -1.0}, **BOX)
    solution = codesign(
        arm, motion, {"rms_force": 1.0, "added_mass": 0.01}, free=("counter_distance",),
        lower={"counter_distance": -0.3}, upper={"counter_distance": 0.3},
        start={"counter_mass": jnp.array([1.0, 1.0])},
    )  # fmt: skip
    assert np.all(np.isfinite(np.asarray(solution.design["counter_distance"])))


@pytest.mark.parametrize(
    "options, message",
    [
        ({"robust": "max", "sharpness": -200.0}, "sharpness must be finite and > 0, got -200.0"),
        ({"robust": "max", "sharpness": 0.0}, "sharpness must be finite and > 0"),
        ({"robust": "median"}, r"robust must be one of \('mean', 'rms', 'max'\), got 'median'"),
        ({"penalty": -1.0, "constraints": {"added_mass": 5.0}}, "penalty must be finite and >= 0"),
        ({"constraints": {"added_mass": np.nan}}, "constraint bounds must be finite"),
        ({"constraints": {"added_mass": -1.0}}, r"constraints\['added_mass'\] = -1.0 is negative"),
        ({"rounds": 0, "constraints": {"added_mass": 5.0}}, "rounds must be an integer >= 1"),
        ({"payloads": []}, "payloads must hold at least one payload"),
        ({"payloads": [-4.0, 0.0]}, r"payloads must be finite and >= 0 kg, got \[-4.0\]"),
        ({"payloads": [0.0, np.nan]}, "payloads must be finite and >= 0 kg, got \\[nan\\]"),
        (
            {"start": {"counter_mass": jnp.array([50.0, 50.0])}, "upper": {"counter_mass": 20.0}},
            r"start of 'counter_mass' lies outside its bounds .* = 50 not in \[0, 20\]",
        ),
        (
            {"trajectory_upper": {"u2": np.inf, "ratio": 1.0}},
            r"trajectory_upper\['u2'\] must be finite",
        ),
        # a scale below the metric's floor was silently raised to it, a typo ignored
        ({"scales": {"rms_force": 0.0}}, r"scales\['rms_force'\] must be a finite number > 0"),
        ({"scales": {"rms_force": -1.0}}, r"scales\['rms_force'\] must be a finite number > 0"),
        ({"scales": {"rms_forc": 1.0}}, "scales names 'rms_forc', not an objective metric"),
        # bounds out of the factory's domain let the optimiser leave it
        (
            {"trajectory_lower": {"u2": 0.05, "ratio": 0.0}},
            r"bounds of 'ratio' must lie in its domain 0 < ratio <= 1, got \[0, 1\]",
        ),
        (
            {"trajectory_upper": {"u2": 0.5, "ratio": 1.0}},
            r"bounds of 'u2' must lie in its domain 0 < u2 < 0.5, got \[0.05, 0.5\]",
        ),
    ],
)
def test_joint_codesign_refuses_bad_inputs_by_name(arm, move, options, message):
    """Each returned a number (NaN, a smooth minimum, an infeasible design, a clipped
    start reported unclipped) or failed deep inside; now refused before compiling."""
    options = {**BOX, **options}
    with pytest.raises(ValueError, match=message):
        joint_codesign(arm, move, THETA, "rms_force", **options)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_an_extra_start_takes_only_the_free_variables(arm, move):
    """A solution of another problem (counter distance free, payload 1 kg) as an extra
    start of a multistart that fixes the distance at 0.1 m and the payload at 5 kg: the
    extra start's solution keeps both (it used to carry the other problem's)."""
    objective = {"rms_force": 1.0, "added_mass": 0.01}
    other = joint_codesign(
        arm.with_design({"payload": jnp.asarray(1.0)}), move, THETA, objective,
        upper={"counter_mass": 20.0, "counter_distance": 0.3}, max_steps=20, **BOX,
    )  # fmt: skip
    assert not np.allclose(np.asarray(other.design["counter_distance"]), 0.1)
    given = arm.with_design(
        {"counter_distance": jnp.array([0.1, 0.1]), "payload": jnp.asarray(5.0)}
    )
    several = multistart_joint_codesign(
        given, move, THETA, objective, starts=0, extra_starts=[other],
        free=("counter_mass",), upper={"counter_mass": 20.0}, max_steps=20, **BOX,
    )  # fmt: skip
    for solution in several.solutions:
        np.testing.assert_array_equal(np.asarray(solution.design["counter_distance"]), 0.1)
        assert float(solution.design["payload"]) == 5.0


@pytest.mark.parametrize(
    "metrics, weights, message",
    [
        (("rms_force", "rms_force"), [0.0, 1.0], "two different metrics"),
        (("rms_force", "added_mass", "peak_force"), [0.0, 1.0], "two different metrics"),
        (("rms_force", "added_mass"), [], "at least one w in"),
        (("rms_force", "added_mass"), 0.5, "at least one w in"),
        (("rms_force", "added_mass"), [0.0, 1.5], r"must lie in \[0, 1\], got \[0.0, 1.5\]"),
        (("rms_force", "added_mass"), [0.5, 0.2], "weights must increase"),
    ],
)
def test_pareto_front_refuses_bad_metrics_and_weights(arm, move, metrics, weights, message):
    with pytest.raises(ValueError, match=message):
        pareto_front(arm, move, THETA, metrics, weights, **BOX)


def test_minimize_refuses_a_non_finite_or_integer_start():
    def loss(p):
        return jnp.sum((p["x"] - 1.0) ** 2)

    for start, message in (
        (jnp.array([jnp.nan, 0.0]), r"params\['x'\] must be finite"),
        (jnp.array([jnp.inf, 0.0]), r"params\['x'\] must be finite"),
        (jnp.zeros(2, int), r"params\['x'\] must be a float array, got dtype int"),
    ):
        with pytest.raises(ValueError, match=message):
            jaxbal.minimize(loss, {"x": start})
    solution = jaxbal.minimize(loss, {"x": jnp.zeros(2)})
    np.testing.assert_allclose(np.asarray(solution.params["x"]), 1.0, atol=1e-9)


def test_a_python_number_leaf_is_named_by_the_metrics_and_codesign(arm, motion):
    """``eqx.tree_at(..., 2.0)`` (a Python float where an array belongs): the metrics
    and ``codesign`` name the leaf, as the physics does (it was a TypeError)."""
    changed = eqx.tree_at(lambda r: r.payload, arm, 2.0)
    message = r"robot parameter PlanarArm.payload is a Python number \(2.0\)"
    with pytest.raises(ValueError, match=message):
        jaxbal.design.rms_force(changed, motion)
    with pytest.raises(ValueError, match=message):
        codesign(changed, motion, "rms_force")


def test_a_start_that_the_motion_factory_refuses_is_refused(arm, move):
    """A factory of the user's (not one of jaxbal's, whose θ domain is known) started at
    a cycle time of 0 s: the co-design's compiled programs run with the checks off and
    reported the start's RMS force as 0 N; now the start is planned with the checks on."""

    def timed(robot, theta):
        return move(robot, theta)

    theta = {**THETA, "duration": 0.0}
    lower = {**BOX["trajectory_lower"], "duration": -1.0}
    upper = {**BOX["trajectory_upper"], "duration": 1.0}
    with pytest.raises(ValueError, match="starting robot and trajectory give no valid motion"):
        joint_codesign(arm, timed, theta, "rms_force", trajectory_lower=lower,
                       trajectory_upper=upper)  # fmt: skip
