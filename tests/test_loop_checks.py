"""The physics of a closed chain refuses a state off its loop closures.

Found by ``make fuzz``: an Orthoglide whose parallelogram length was changed with
``eqx.tree_at`` while its motion was held gave finite, meaningless torques (3e42 N·m).
The reference of each test is the robot's own loop-closure test
(:func:`jaxbal.state_valid`, an independent evaluation of ``Φ, Φ̇, Φ̈``): the fused check
inside the wrench/torques must refuse exactly the states it rejects, and leave every
value of a consistent state unchanged (to rounding, against the unchecked program).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import slow_for

import jaxbal
from jaxbal import robots
from jaxbal._src.motion import LOOP_TOLERANCE
from jaxbal.design import motion_samples, peak_force, peak_torque, rms_force
from jaxbal.planning import EndEffectorLine
from jaxbal.profiles import Quintic

#: name -> (robot, start pose, end pose, a length field that moves the loops)
CASES = {
    "dual_v": (robots.dual_v(), (0.0, -0.05, 0.0), (0.05, 0.05, 0.0), "l1"),
    "orthoglide": (robots.orthoglide(payload=1.0), (0.0, 0.0, 0.0), (-0.1, 0.07, -0.11), "length"),
}
LOOPS = "loop closures"


def _robot_and_motion(name, samples=21):
    robot, start, end, _ = CASES[name]
    line = jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), 0.2)
    return robot, motion_samples(robot, EndEffectorLine(robot, line), jnp.linspace(0, 0.2, samples))


def _lengthened(name, robot, factor):
    field = CASES[name][3]
    return eqx.tree_at(lambda r: getattr(r, field), robot, getattr(robot, field) * factor)


@eqx.filter_jit
def _everything(robot, motion):
    q, qd, qdd = (x[3] for x in motion)
    return (
        jaxbal.shaking_wrench(robot, q, qd, qdd),
        jaxbal.actuator_torques(robot, q, qd, qdd),
        peak_force(robot, motion),
        peak_torque(robot, motion),
    )


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
@pytest.mark.parametrize("name", slow_for(sorted(CASES), "orthoglide"))
def test_held_motion_of_a_changed_geometry_is_refused(name):
    """A length changed by 1 % under a held motion: every motion physics function is
    refused eagerly (ValueError naming the loops and the residual), compiled (runtime
    error) and in a checked_jit (ValueError); the unchanged robot passes everywhere."""
    robot, motion = _robot_and_motion(name)
    changed = _lengthened(name, robot, 1.01)
    state = tuple(x[3] for x in motion)
    assert bool(jnp.all(jaxbal.design.METRICS["peak_force"](robot, motion) > 0))
    assert not bool(jaxbal.state_valid(changed, *state))  # the reference
    calls = {
        "shaking_wrench": lambda r: jaxbal.shaking_wrench(r, *state),
        "actuator_torques": lambda r: jaxbal.actuator_torques(r, *state),
        "peak_force": lambda r: peak_force(r, motion),
        "rms_force": lambda r: rms_force(r, motion),
        "peak_torque": lambda r: peak_torque(r, motion),
    }
    for what, call in calls.items():
        with pytest.raises(ValueError, match=rf"{LOOPS}.*Residual / tolerance"):
            call(changed)
        assert np.all(np.isfinite(jax.tree.leaves(call(robot))[0])), what
    with pytest.raises(Exception, match=LOOPS):
        jax.block_until_ready(_everything(changed, motion))
    with pytest.raises(ValueError, match=LOOPS):
        jaxbal.checked_jit(lambda r: peak_torque(r, motion))(changed)
    with pytest.raises(Exception, match=LOOPS):
        grad = eqx.filter_jit(jax.grad(lambda r: peak_force(r, motion)))
        jax.block_until_ready(grad(changed))


@pytest.mark.parametrize("name", slow_for(sorted(CASES), "orthoglide"))
def test_consistent_motion_values_unchanged_by_the_check(name):
    """The fused loop check changes no value: the checked compiled program equals the
    unchecked one (runtime checks off; 1e-14 relative, XLA fuses the two programs
    differently) and the eager call; a mass changed with
    ``eqx.tree_at`` (the loops unchanged) is accepted."""
    robot, motion = _robot_and_motion(name)
    heavier = eqx.tree_at(lambda r: r.payload, robot, robot.payload + 0.5)
    for r in (robot, heavier):
        checked = jax.block_until_ready(_everything(r, motion))
        with jaxbal.runtime_checks(False):
            unchecked = eqx.filter_jit(lambda a, b: _everything.__wrapped__(a, b))(r, motion)
        for a, b in zip(jax.tree.leaves(checked), jax.tree.leaves(unchecked), strict=True):
            np.testing.assert_allclose(a, b, rtol=1e-14, atol=1e-14)  # XLA's fusion
        eager = (peak_force(r, motion), peak_torque(r, motion))
        np.testing.assert_allclose(eager, checked[2:], rtol=1e-12)


def test_compiled_check_refuses_exactly_the_positions_off_the_loops():
    """Orthoglide states pushed off the loops by 1e-11 … 1e-5 m along a slider: the
    compiled wrench raises exactly where the positions' residual ``max|Φ(q)|`` (the
    robot's own constraint, evaluated apart) exceeds the tolerance (states within 30 %
    of it left out: rounding of two evaluations), and the eager call where
    :func:`jaxbal.state_valid` is False (the whole state: Φ, Φ̇, Φ̈)."""
    robot, motion = _robot_and_motion("orthoglide")
    q, qd, qdd = (x[7] for x in motion)
    wrench = eqx.filter_jit(jaxbal.shaking_wrench)
    decided = 0
    for shift in 10.0 ** np.arange(-11.0, -4.5, 0.5):
        moved = q.at[3].add(shift)  # a slider: |Φ| grows with the shift
        residual = float(jnp.max(jnp.abs(robot.constraint(moved)))) / LOOP_TOLERANCE
        if 0.7 < residual < 1.3:
            continue
        decided += 1
        if residual < 1.0:
            jax.block_until_ready(wrench(robot, moved, qd, qdd))
        else:
            with pytest.raises(Exception, match=LOOPS):
                jax.block_until_ready(wrench(robot, moved, qd, qdd))
        if bool(jaxbal.state_valid(robot, moved, qd, qdd)):
            jaxbal.shaking_wrench(robot, moved, qd, qdd)
        else:
            with pytest.raises(ValueError, match=LOOPS):
                jaxbal.shaking_wrench(robot, moved, qd, qdd)
    assert decided >= 10


def test_rates_made_by_hand_are_refused_eagerly():
    """Rates off the loops (q̇ doubled, q̈ not ×4): ``Φ̇ = 0`` still (linear in q̇), ``Φ̈ ≠ 0``.
    The eager calls and the motion's metrics refuse them; the compiled check, which
    tests the positions only (loop_checks module doc), does not."""
    robot, motion = _robot_and_motion("dual_v")
    q, qd, qdd = (x[3] for x in motion)
    assert bool(jaxbal.state_valid(robot, q, 2.0 * qd, 4.0 * qdd))  # a faster move
    assert not bool(jaxbal.state_valid(robot, q, 2.0 * qd, qdd))
    with pytest.raises(ValueError, match=LOOPS):
        jaxbal.shaking_wrench(robot, q, 2.0 * qd, qdd)
    with pytest.raises(ValueError, match=LOOPS):
        jaxbal.actuator_torques(robot, q, 2.0 * qd, qdd)
    hand_made = jaxbal.design.Motion(motion.q, 2.0 * motion.qd, motion.qdd)
    with pytest.raises(ValueError, match=LOOPS):
        peak_force(robot, hand_made)
    force, _ = eqx.filter_jit(jaxbal.shaking_wrench)(robot, q, 2.0 * qd, qdd)
    assert np.all(np.isfinite(force))


def test_batch_with_one_sample_off_the_loops_is_refused():
    """``jit(vmap)`` of the wrench: one sample of 21 moved off the loops fails the batch;
    the consistent batch equals a Python loop of eager calls."""
    robot, motion = _robot_and_motion("orthoglide")
    batched = eqx.filter_jit(jax.vmap(jaxbal.shaking_wrench, in_axes=(None, 0, 0, 0)))
    force, moment = batched(robot, *motion)
    for k in (0, 10, 20):
        f, m = jaxbal.shaking_wrench(robot, *(x[k] for x in motion))
        np.testing.assert_allclose(force[k], f, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(moment[k], m, rtol=1e-12, atol=1e-12)
    q = motion.q.at[10, 3].add(1e-4)
    with pytest.raises(Exception, match=LOOPS):
        jax.block_until_ready(batched(robot, q, motion.qd, motion.qdd))
    with pytest.raises(ValueError, match=r"at samples \{sample: residual\}: \{10: "):
        peak_force(robot, jaxbal.design.Motion(q, motion.qd, motion.qdd))


def test_robot_fault_is_named_before_the_loops_it_opens():
    """A negative length opens the loops too: the error names the length (the cause),
    eagerly and compiled."""
    robot, motion = _robot_and_motion("dual_v")
    mirrored = eqx.tree_at(lambda r: r.l2, robot, -robot.l2)
    state = tuple(x[3] for x in motion)
    with pytest.raises(ValueError, match=r"must be >= 0.*DualV\.l2"):
        jaxbal.shaking_wrench(mirrored, *state)
    with pytest.raises(ValueError, match=r"must be >= 0.*DualV\.l2"):
        jaxbal.actuator_torques(mirrored, *state)
    with pytest.raises(Exception, match=r"must be >= 0"):
        jax.block_until_ready(_everything(mirrored, motion))


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_generalised_forces_and_checks_off_accept_any_state():
    """``inverse_dynamics`` (generalised forces of all coordinates) is defined for any
    state: the bias ``h(q, q̇)`` at ``q̈ = 0`` of a forward dynamics, off the loops, equals
    Lagrange's form. With the runtime checks off the compiled wrench is not checked
    (the documented switch of the sweeps' and optimisers' inner loops)."""
    from jaxbal._src.dynamics import lagrange_forces

    robot, motion = _robot_and_motion("dual_v")
    q, qd = motion.q[3], motion.qd[3]
    zero = jnp.zeros_like(q)
    assert not bool(jaxbal.state_valid(robot, q, qd, zero))
    bias = jaxbal.inverse_dynamics(robot, q, qd, zero)
    np.testing.assert_allclose(bias, lagrange_forces(robot, q, qd, zero, None), atol=1e-9)
    changed = _lengthened("dual_v", robot, 1.01)
    with jaxbal.runtime_checks(False):
        wrench = eqx.filter_jit(lambda r, a, b, c: jaxbal.shaking_wrench(r, a, b, c))
        force, _ = wrench(changed, q, qd, motion.qdd[3])
    assert np.all(np.isfinite(force))


def test_codesign_refuses_a_held_motion():
    """``codesign`` of a DUAL-V whose motion was held while ``l1`` grew 1 % optimised
    the counter-masses of that wrong mechanism (its callback-free compiled programs
    have no loop check: RMS force 1.59 → 0.50 N, no message); now it is refused before
    anything compiles, naming the samples. The consistent motion still co-designs."""
    robot, motion = _robot_and_motion("dual_v")
    changed = _lengthened("dual_v", robot, 1.01)
    for metric in ("rms_force", "peak_torque"):
        with pytest.raises(ValueError, match=rf"{LOOPS}.*at samples"):
            jaxbal.design.codesign(changed, motion, metric, max_steps=2)
    best = jaxbal.design.codesign(robot, motion, "rms_force", max_steps=2)
    assert np.all(np.isfinite(best.metrics["rms_force"]))
