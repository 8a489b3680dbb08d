"""MuJoCo C closes the DUAL-V's and the Orthoglide's loops itself (issue 15, item 5).

Reference: MuJoCo's own kinematics (site positions, ``mj_jacSite``, ``mj_jacDot``) on
models built from the robots' geometric parameters, not from jaxbal's inverse
kinematics, sign tables or orientation rules; the platform pose is the only input.
Tolerances: joint positions 1e-12 rad/m (Newton to 1e-13 of the model size); base
reaction 1e-9 relative as in tests/test_mjx.py (agreement is ~1e-15).
"""

import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

import jaxbal
from jaxbal._src.mujoco.closure import close_loops, closure_index
from jaxbal.mujoco import confirm, mujoco_model
from jaxbal.profiles import Quintic
from jaxbal.robots import CROSSED, dual_v, orthoglide

GRAVITY = jnp.array([0.3, -1.0, -9.81])
MOVES = {  # robot, start and end pose of a 0.1 s quintic move
    "dual_v": (dual_v(), (0.0, -0.05, 0.0), (0.05, 0.05, 0.1)),
    "orthoglide": (
        orthoglide(payload=1.0, counter_masses=(0.3, 0.2, 0.1)),
        (0.0, -0.05, 0.02),
        (0.05, 0.05, 0.1),
    ),
}


def _motion(name, samples=11):
    robot, start, end = MOVES[name]
    line = jaxbal.StraightLine(jnp.asarray(start), jnp.asarray(end), Quintic(), 0.1)
    move = jaxbal.planning.EndEffectorLine(robot, line)
    return robot, jaxbal.design.motion_samples(robot, [move], jaxbal.sample_times(0.1, samples))


@pytest.mark.parametrize("name", sorted(MOVES))
def test_mujoco_closes_the_loops_and_agrees(name):
    """MuJoCo's own loop closure gives jaxbal's joints (1e-12) and, with its velocities
    and accelerations, jaxbal's shaking wrench with gravity (1e-9 relative)."""
    robot, motion = _motion(name)
    check = confirm(robot, motion.q, motion.qd, motion.qdd, gravity=GRAVITY)
    assert check.closed_by_mujoco and check.independent
    assert check.closure_difference < 1e-12, check
    assert check.relative < 1e-9, check


def test_mujoco_velocities_match_finite_differences_of_its_positions():
    """MuJoCo's solved joint velocities equal central differences of its solved positions
    along the DUAL-V move (1e-6 relative): the velocity and position solutions agree."""
    robot, motion = _motion("dual_v", samples=2001)
    compiled = mujoco_model(robot)
    k, h = 1000, 0.1 / 2000
    qpos, qvel, _ = compiled.state(
        motion.q[k - 1 : k + 2], motion.qd[k - 1 : k + 2], motion.qdd[k - 1 : k + 2]
    )
    central = (qpos[2] - qpos[0]) / (2 * h)
    scale = np.max(np.abs(qvel[1]))
    np.testing.assert_allclose(central[6:], qvel[1][6:], atol=1e-6 * scale)


@pytest.mark.slow
def test_another_assembly_mode_is_not_confirmed():
    """MuJoCo finds its own assembly mode, not jaxbal's: jaxbal's CROSSED DUAL-V and an
    Orthoglide leg with s = −1 are refused (their joints differ from MuJoCo's by ~1, the
    message names the gap), not silently compared."""
    robot = dual_v()
    q = robot.inverse_kinematics(jnp.array([0.02, 0.03, 0.05]), branch=CROSSED)
    with pytest.raises(ValueError, match=r"DualV 3\.\d+ rad or m away"):
        confirm(robot, q, jnp.zeros(11), jnp.zeros(11))
    ortho = orthoglide()
    q = ortho.inverse_kinematics(jnp.array([0.02, 0.03, 0.05]), branch=(1, -1, 1))
    with pytest.raises(ValueError, match=r"Orthoglide 0\.\d+ rad or m away"):
        confirm(ortho, q, jnp.zeros(6), jnp.zeros(6))


@pytest.mark.slow
def test_mjx_still_compares_another_assembly_mode():
    """MJX takes jaxbal's coordinates: an Orthoglide leg with s = −1 agrees (1e-9)."""
    ortho = orthoglide()
    q = ortho.inverse_kinematics(jnp.array([0.02, 0.03, 0.05]), branch=(1, -1, 1))
    check = confirm(ortho, q, jnp.zeros(6), jnp.zeros(6), gravity=GRAVITY, engine="mjx")
    assert check.relative < 1e-9, check


def test_unreachable_platform_pose_is_refused():
    """A platform pose no arm reaches: MuJoCo's Newton cannot close the loops and says so
    (ValueError naming the residual), never a silent state."""
    robot = dual_v()
    compiled = mujoco_model(robot)
    index = closure_index(compiled.model, compiled.tree.solved)
    q = np.zeros(11)
    q[8:11] = (0.0, 1.0, 0.0)  # 1 m: beyond l_i1 + l_i2 = 0.56 m of every pivot
    qpos = np.concatenate([np.zeros(6), compiled.tree.guess(q)])
    data = mujoco.MjData(compiled.model)
    with pytest.raises(ValueError, match="could not close the loops"):
        close_loops(
            compiled.model,
            data,
            index,
            qpos,
            np.zeros(compiled.model.nv),
            np.zeros(compiled.model.nv),
        )


def test_closure_refuses_unknown_joint():
    compiled = mujoco_model(dual_v())
    with pytest.raises(ValueError, match="'theta9'"):
        closure_index(compiled.model, ("theta9",))
