"""Open-loop forward simulation in MuJoCo: do jaxbal's actuator efforts reproduce the
planned motion?

The planned joint motion ``q(t)`` gives MuJoCo's initial state; jaxbal's actuator
torques/forces ``τ(t)`` drive the robot's motors open-loop (no feedback) through
MuJoCo's forward dynamics, with the closed loops held by MuJoCo's soft ``connect``
constraints; the simulated joint positions are compared with the plan. This is the
check of van der Wijk et al. (2013), Fig 6, with MuJoCo in place of Spacar.

Settings (stated, and returned with the result):

* integrator RK4, time step ``timestep`` (default 1e-4 s, the paper's maximal ODE45
  step); the control is held over a step at its mid-step value, so the input is
  second-order accurate;
* loop closures: ``solref = (2·timestep, 1)`` (time constant [s], critical damping),
  ``solimp = (0.9999, 0.9999, ...)`` (impedance: 99.99 % of the constraint force
  comes from the exact constraint solution, 0.01 % is left to the stabilising spring);
  Newton solver, tolerance 1e-14, up to 200 iterations. MuJoCo's soft constraints
  always allow a violation proportional to the residual impedance ``1 − d`` times the
  unconstrained acceleration times the time constant squared -- here ~1e-4 × 100 m/s²
  × (2e-4 s)² ≈ 4e-10 m -- far below the integration error.

References:
    van der Wijk, Krut, Pierrot & Herder (2013), §3.3 and Fig 6.
    MuJoCo documentation, "Solver parameters" (solref, solimp).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import mujoco
import numpy as np

from jaxbal._src.mujoco.mjcf import to_mjcf
from jaxbal._src.mujoco.tree import Tree, tree_state
from jaxbal._src.robot import Robot
from jaxbal._src.trajectory import sample


@eqx.filter_jit
def _evaluate(function, times):
    return jax.vmap(function)(times)


@eqx.filter_jit
def _sample_positions_velocities(joint_path, times):
    return sample(joint_path, times, 1)[:2]


class Tracking(NamedTuple):
    """Result of :func:`simulate_open_loop`.

    Attributes:
        times: ``(k,)`` recorded instants [s].
        planned, simulated: ``(k, m)`` positions of the ``tracked`` joints (rad or m).
        tracked: their joint names.
        error: ``(m,)`` maximum absolute tracking error of each tracked joint.
        constraint_violation: maximum norm of the loop-closure residuals [m].
        settings: the MuJoCo settings used (timestep, solref, solimp, solver).
    """

    times: np.ndarray
    planned: np.ndarray
    simulated: np.ndarray
    tracked: tuple[str, ...]
    error: np.ndarray
    constraint_violation: float
    settings: dict


def _constraint_xml(xml: str, timestep: float) -> str:
    solref = f'solref="{2.0 * timestep:.17g} 1"'
    solimp = 'solimp="0.9999 0.9999 0.001 0.5 2"'
    xml = xml.replace('solref="0.002 1"', solref).replace(
        'solimp="0.99 0.9999 0.001 0.5 2"', solimp
    )
    return xml.replace(
        'integrator="RK4"', 'integrator="RK4" solver="Newton" tolerance="1e-14" iterations="200"'
    )


def simulate_open_loop(
    robot: Robot,
    joint_path: Callable,
    efforts: Callable,
    duration: float,
    tracked: tuple[str, ...] | None = None,
    timestep: float = 1e-4,
    record_every: int = 10,
    tree: Tree | None = None,
    effort_scale: float = 1.0,
) -> Tracking:
    """Simulate ``robot`` in MuJoCo driven open-loop by ``efforts(t)`` and compare.

    Args:
        robot: a concrete robot with a registered tree with ``actuated`` joints.
        joint_path: ``t -> q (dof,)``, the planned motion in jaxbal coordinates
            (differentiable; its derivatives give the initial velocity).
        efforts: ``t -> (n_actuated,)`` actuator torques [N·m] / forces [N], in the
            order of the tree's ``actuated`` joints (jaxbal's inverse dynamics).
        duration: simulated time [s].
        tracked: joint names to compare (default: every tree joint).
        timestep: MuJoCo time step [s].
        record_every: record one step in this many.
        tree: default ``robot.mujoco_tree()``.
        effort_scale: factor applied to the efforts (1; e.g. 1.001 measures how much
            a 0.1 % torque error moves the platform, the check's sensitivity).

    Returns:
        A :class:`Tracking`.

    Raises:
        ValueError: no actuated joints, a tracked joint that is not a hinge/slide, or
            an initial state that does not close the loops.
    """
    tree = robot.mujoco_tree() if tree is None else tree
    if not tree.actuated:
        raise ValueError("the robot's tree has no actuated joints to drive")
    xml = _constraint_xml(to_mjcf(robot, tree, base_joints=False, timestep=timestep), timestep)
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    names = tree.joint_names() if tracked is None else tuple(tracked)
    joints = [model.joint(name) for name in names]
    if any(
        int(j.type[0]) not in (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
        for j in joints
    ):
        raise ValueError("tracked joints must be hinges or slides")
    qpos_index = np.array([int(j.qposadr[0]) for j in joints])

    steps = int(round(duration / timestep))
    mid_times = (np.arange(steps) + 0.5) * timestep
    controls = effort_scale * np.asarray(_evaluate(efforts, jnp.asarray(mid_times)))
    record_steps = np.arange(0, steps + 1, record_every)
    times = record_steps * timestep
    q, qd = _sample_positions_velocities(joint_path, jnp.asarray(times))
    planned_qpos = np.asarray(jax.vmap(lambda a: tree_state(tree, a, a * 0, a * 0)[0])(q))

    qpos0, qvel0, _ = tree_state(tree, q[0], qd[0], jnp.zeros_like(q[0]))
    data.qpos[:] = np.asarray(qpos0)
    data.qvel[:] = np.asarray(qvel0)
    mujoco.mj_forward(model, data)
    simulated = [data.qpos[qpos_index].copy()]
    violation = float(np.max(np.abs(data.efc_pos), initial=0.0))
    if violation > 1e-9:
        raise ValueError(
            f"the planned initial state violates the loop closures by {violation:.3g} m "
            "(is the path inside the workspace?)"
        )
    for k in range(steps):
        data.ctrl[:] = controls[k]
        mujoco.mj_step(model, data)
        if (k + 1) % record_every == 0:
            simulated.append(data.qpos[qpos_index].copy())
            eq = data.efc_type == mujoco.mjtConstraint.mjCNSTR_EQUALITY
            violation = max(violation, float(np.max(np.abs(data.efc_pos[eq]), initial=0.0)))
    simulated = np.array(simulated)
    planned = planned_qpos[:, qpos_index]
    return Tracking(
        times=times,
        planned=planned,
        simulated=simulated,
        tracked=names,
        error=np.max(np.abs(simulated - planned), axis=0),
        constraint_violation=violation,
        settings={
            "timestep": timestep,
            "integrator": "RK4",
            "solref": (2.0 * timestep, 1.0),
            "solimp": (0.9999, 0.9999, 0.001, 0.5, 2),
            "solver": "Newton, tolerance 1e-14, 200 iterations",
        },
    )


def mujoco_actuator_efforts(robot: Robot, coordinates: Callable, u, ud, udd, tree=None):
    """Minimum-norm actuator efforts from MuJoCo C inverse dynamics (``mj_inverse``).

    MuJoCo gives the generalised forces ``Q`` on the open tree's joints for the motion;
    with ``G = ∂c(q(u))/∂u`` (tree joints w.r.t. the independent coordinates ``u``) and
    ``J = G[actuated]``, every admissible ``τ`` satisfies ``Jᵀ τ = Gᵀ Q`` (the loop
    closure forces do no work along ``G``); the minimum-norm one is returned. For a
    serial robot it is simply ``Q`` on the actuated joints.

    Args:
        robot: a concrete robot with a registered tree (hinge/slide joints only).
        coordinates: ``u -> q``, jaxbal's coordinates (the IK of a parallel robot).
        u, ud, udd: independent coordinates and their derivatives.

    Returns:
        ``(n_actuated,)`` efforts [N·m or N], in the tree's ``actuated`` order.
    """
    from jaxbal._src.mujoco.inverse import mujoco_model

    tree = robot.mujoco_tree() if tree is None else tree
    compiled = mujoco_model(robot, tree=tree)
    model = compiled.model
    balls = [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_JOINT, j)
        for j in range(model.njnt)
        if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_BALL
    ]
    if balls:  # qpos (4 per ball) and qvel (3) differ: it was a shape error of NumPy
        raise ValueError(
            f"mujoco_actuator_efforts: hinge and slide joints only; the tree of "
            f"{type(robot).__name__} has ball joints {balls} (use jaxbal.actuator_torques)"
        )
    u, ud, udd = (jnp.asarray(a, dtype=float) for a in (u, ud, udd))

    @jax.jit
    def motion_and_basis(u_, ud_, udd_):
        q, qd = jax.jvp(coordinates, (u_,), (ud_,))
        qdd = jax.jvp(lambda a, b: jax.jvp(coordinates, (a,), (b,))[1], (u_, ud_), (ud_, udd_))[1]
        basis = jax.jacfwd(lambda a: tree.coordinates(coordinates(a)))(u_)
        return tree_state(tree, q, qd, qdd), basis

    (qpos, qvel, qacc), g = motion_and_basis(u, ud, udd)
    data = mujoco.MjData(compiled.model)
    data.qpos[6:], data.qvel[6:], data.qacc[6:] = qpos, qvel, qacc
    mujoco.mj_inverse(compiled.model, data)
    generalised = data.qfrc_inverse[6:]
    g = np.asarray(g)
    names = tree.joint_names()
    actuated = np.array([names.index(name) for name in tree.actuated])
    return np.linalg.pinv(g[actuated].T) @ (g.T @ generalised)
