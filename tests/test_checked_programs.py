"""Programs jaxbal compiles itself trace their runtime checks as functional errors
(validation.checked_call, checkify): no host callback (the persistent compilation cache
keeps them), the same ValueError on the host. And an unreachable pose is refused under
``jit`` too: inverse kinematics without ``return_valid`` returned a clipped, silently
wrong ``q`` when traced (e.g. a straight line that leaves the workspace, sampled by
``motion_samples``)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src import validation
from jaxbal._src.motion_samples import _sample
from jaxbal.design import motion_samples
from jaxbal.planning import EndEffectorLine
from jaxbal.profiles import Quintic

TIMES = jnp.linspace(0.0, 0.2, 11)


def _line(start, end):
    return jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), 0.2)


#: robot, a reachable pose, an unreachable one, the IK's message
CASES = {
    "planar_2r": (jaxbal.robots.planar_2r, (0.4, 0.3), (2.2, 0.5), "outside the workspace"),
    "scara": (
        jaxbal.robots.scara, (0.15, 0.2, 1.4, 0.0), (2.0, 0.2, 1.4, 0.0), "out of reach",
    ),
    "dual_v": (
        jaxbal.robots.dual_v, (0.0, -0.05, 0.0), (3.0, 0.0, 0.0), "outside the workspace",
    ),
    "orthoglide": (
        jaxbal.robots.orthoglide, (0.0, 0.0, 0.0), (3.0, 0.0, 0.0), "out of reach",
    ),
}  # fmt: skip


@pytest.mark.parametrize("name", sorted(CASES))
def test_a_line_leaving_the_workspace_is_refused_by_motion_samples(name):
    make, inside, outside, message = CASES[name]
    robot = make()
    motion = motion_samples(robot, EndEffectorLine(robot, _line(inside, inside)), TIMES)
    assert np.all(np.isfinite(np.asarray(motion.q)))
    with pytest.raises(ValueError, match=message):
        motion_samples(robot, EndEffectorLine(robot, _line(inside, outside)), TIMES)


@pytest.mark.parametrize("name", sorted(CASES))
def test_inverse_kinematics_refuses_an_unreachable_pose_under_jit(name):
    make, inside, outside, message = CASES[name]
    robot = make()
    ik = jax.jit(lambda pose: robot.inverse_kinematics(pose))
    assert np.all(np.isfinite(np.asarray(ik(jnp.asarray(inside)))))
    with pytest.raises(Exception, match=message):  # equinox's runtime error
        jax.block_until_ready(ik(jnp.asarray(outside)))
    # the mask of return_valid is unchanged: no error, q finite, valid False
    q, valid = jax.jit(lambda p: robot.inverse_kinematics(p, return_valid=True))(
        jnp.asarray(outside)
    )
    assert not bool(valid) and np.all(np.isfinite(np.asarray(q)))


def test_sampling_program_has_no_host_callback_and_raises_the_named_error():
    robot = jaxbal.robots.planar_2r()
    path = EndEffectorLine(robot, _line((0.4, 0.3), (0.2, 0.5)))
    with validation._FUNCTIONAL(True):
        program = validation.checked_jit(_sample).compiled("functional")
        text = program.lower(robot, path, TIMES, 2).as_text()
    assert "callback" not in text.lower()
    assert "sine" in text  # the program samples the move
    # a duration made negative by eqx.tree_at: the functional check names it
    bad = eqx.tree_at(lambda p: p.line.duration, path, jnp.asarray(-1.0))
    with pytest.raises(ValueError, match=r"duration must be finite and > 0 \[s\]: -1.0$"):
        motion_samples(robot, bad, TIMES)


def test_checked_call_with_checks_off_or_traced_arguments_is_a_plain_call():
    def double(x):
        return 2.0 * validation.guard(x, x < 0, "x must be >= 0", x)

    assert float(validation.checked_call(double, jnp.asarray(2.0))) == 4.0
    with pytest.raises(ValueError, match="x must be >= 0"):
        validation.checked_call(double, jnp.asarray(-1.0))
    with validation.runtime_checks(False):
        assert float(validation.checked_call(double, jnp.asarray(-1.0))) == -2.0
    # traced: fn itself, its guard an equinox runtime error
    traced = jax.jit(lambda x: validation.checked_call(double, x))
    assert float(traced(jnp.asarray(3.0))) == 6.0
    with pytest.raises(Exception, match="x must be >= 0"):
        jax.block_until_ready(traced(jnp.asarray(-3.0)))


def test_orthoglide_forward_kinematics_refuses_unassemblable_inputs_under_jit():
    robot = jaxbal.robots.orthoglide()
    bad = jnp.array([0.9, 0.1, 0.1])
    with pytest.raises(ValueError, match="not assemblable"):
        robot.forward_kinematics(bad)
    with pytest.raises(Exception, match="not assemblable"):
        jax.block_until_ready(jax.jit(lambda r: robot.forward_kinematics(r))(bad))
    _, valid = robot.forward_kinematics(bad, return_valid=True)  # a mask, no error
    assert not bool(valid)


def test_checked_jit_of_a_user_gradient_equals_jit_has_no_callback_and_names_errors():
    from jaxbal.design import peak_force

    robot = jaxbal.robots.planar_2r()
    motion = motion_samples(robot, EndEffectorLine(robot, _line((0.4, 0.3), (0.2, 0.5))), TIMES)

    def objective(design):
        return peak_force(robot.with_design(design), motion)

    design = robot.design()
    checked = jaxbal.checked_jit(jax.grad(objective))
    ours, reference = checked(design), jax.jit(jax.grad(objective))(design)
    for name in design:
        assert np.all(np.isfinite(np.asarray(ours[name])))
        np.testing.assert_allclose(np.asarray(ours[name]), np.asarray(reference[name]), rtol=1e-12)
    with validation._FUNCTIONAL(True):
        text = checked.compiled("functional").lower(design).as_text()
    assert "callback" not in text.lower()
    # a negative counter-mass (as an optimiser could set it): the named ValueError
    bad = {**design, "counter_mass": jnp.asarray([-1.0, 0.5])}
    with pytest.raises(ValueError, match="body masses must be finite and >= 0"):
        checked(bad)


def test_com_trapezoid_valid_marks_the_samples_its_call_would_refuse():
    from jaxbal.design import ComTrapezoid

    arm = jaxbal.robots.planar_2r()
    q_a = arm.inverse_kinematics(jnp.array([0.4, 0.3]))
    q_b = arm.inverse_kinematics(jnp.array([0.2, 0.5]))
    theta = {"u2": 0.25, "ratio": 0.5}
    move = ComTrapezoid(q_a, q_b, jaxbal.sample_times(0.5, 11), branch=-1)
    assert np.all(np.asarray(move.valid(arm, theta)))
    assert np.all(np.isfinite(np.asarray(move(arm, theta).q)))
    # nearly stretched along +x, then along −x (exactly stretched is the singular
    # boundary, refused): the straight COM line crosses the hole of the 2R's annular
    # COM workspace (|x_S| ≥ |k1 − k2| / m > 0) in the middle of the move
    move = ComTrapezoid(  # the same structure (branch): the programs are reused
        jnp.array([0.0, -0.1]), jnp.array([jnp.pi, -0.1]), jaxbal.sample_times(0.5, 11), branch=-1
    )
    mask = np.asarray(move.valid(arm, theta))
    assert mask[0] and mask[-1] and not mask[5]
    with pytest.raises(ValueError, match="COM target not reachable"):
        move(arm, theta)


def test_checked_jit_reports_the_first_failed_check_whatever_was_traced_before():
    """checkify reports the failed check of lowest code, numbered as checks are traced:
    each guard is traced anew (first_failure.functional_check), so a check of the same
    message and shapes traced earlier in the process (here "later" alone) does not keep
    an older code and win over the check that comes first in this program (as a
    non-finite wrench's message had replaced that of the non-finite state causing it)."""

    def later(x):
        return validation.guard(x, ~jnp.isfinite(x), "later", x)

    def both(x, y):
        y = validation.guard(y, ~jnp.isfinite(y), "first", y)
        return later(x) + jnp.sum(y)

    x, y = jnp.ones(2), jnp.ones(3)
    assert np.all(np.asarray(jaxbal.checked_jit(later)(x)) == 1.0)
    checked = jaxbal.checked_jit(both)
    with pytest.raises(ValueError, match=r"^first: \[ 1\. nan  1\.\]"):
        checked(x.at[0].set(jnp.nan), y.at[1].set(jnp.nan))
    with pytest.raises(ValueError, match=r"^later: \[nan  1\.\]"):
        checked(x.at[0].set(jnp.nan), y)


def test_checked_jit_pauses_the_garbage_collector_only_during_its_call():
    """The collector is off while checked_jit traces (validation.collection_paused),
    and as it was after the call, a failed one included."""
    import gc

    seen = []

    def f(x):
        seen.append(gc.isenabled())
        return validation.guard(x, x < 0, "negative", x)

    checked = jaxbal.checked_jit(f)
    assert gc.isenabled()
    checked(jnp.ones(2))
    assert seen == [False] and gc.isenabled()
    with pytest.raises(ValueError, match="negative"):
        checked(-jnp.ones(2))
    assert gc.isenabled()
    gc.disable()
    try:
        checked(jnp.ones(3))
        assert not gc.isenabled()
    finally:
        gc.enable()
