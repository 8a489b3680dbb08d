"""Base reactions from MuJoCo (C ``mj_inverse``) and MJX (``mjx.inverse``).

The robot is compiled to MJCF by :mod:`jaxbal.mjcf`: the whole robot hangs from one
``base`` body moved by six dofs (slides x, y, z then hinges about x, y, z through the
base origin), held at rest. MuJoCo's inverse dynamics gives the generalised force
``qfrc_inverse`` the world must apply on those dofs to keep the base still, so the
force and moment the robot exerts on its base, about the base origin and in the base
frame, are

    f = -qfrc_inverse[0:3] - m_base g,     m = -qfrc_inverse[3:6]

(``m_base`` = :data:`jaxbal.mjcf.BASE_MASS` sits at the origin), the same quantity
and sign as :func:`jaxbal.shaking_wrench`.

How MuJoCo's coordinates map to jaxbal's: ``qpos = (0_6, c(q))`` where the first six
entries are the base dofs and ``c`` is the robot tree's ``coordinates`` map
(:mod:`jaxbal.mjx_trees`; for the planar arms ``c(q) = q``, the relative joint angles).
``qvel = (0_6, c'(q) q̇)`` and ``qacc = (0_6, c''(q)[q̇, q̇] + c'(q) q̈)``, evaluated
exactly by forward-mode differentiation. The remaining entries of ``qfrc_inverse``
are the joint torques/forces of the tree (the actuator efforts for a serial robot).

For closed chains the ``connect`` constraints act between robot bodies only; when
the state satisfies them (jaxbal's IK) their Jacobian has no base component, so the
base reaction does not depend on how MuJoCo's soft constraint model splits the
internal forces; what remains is the constraint residual times the stiffness.

References:
    Todorov, Erez, Tassa (2012). MuJoCo: A physics engine for model-based control.
    IROS. ``mj_inverse``: https://mujoco.readthedocs.io/en/stable/computation.
"""

from __future__ import annotations

import functools
from typing import NamedTuple

import jax.numpy as jnp
import mujoco
import numpy as np

from jaxbal.mjcf import BASE_MASS, Tree, robot_tree, to_mjcf, tree_state
from jaxbal.robot import Robot
from jaxbal.validation import check_shape


@functools.lru_cache(maxsize=64)
def _compile(xml: str) -> mujoco.MjModel:
    return mujoco.MjModel.from_xml_string(xml)


class MujocoRobot(NamedTuple):
    """A jaxbal robot compiled for MuJoCo C.

    Attributes:
        model: the compiled ``mujoco.MjModel`` (base dofs first).
        tree: the :class:`~jaxbal.mjcf.Tree` it was built from.
        gravity: ``(3,)`` gravity of the model [m/s²].
        xml: the MJCF text.
    """

    model: mujoco.MjModel
    tree: Tree
    gravity: np.ndarray
    xml: str

    def qpos(self, q) -> np.ndarray:
        """Full MuJoCo ``qpos`` (base dofs zero) for jaxbal coordinates ``q``."""
        return self.state(q, jnp.zeros_like(q), jnp.zeros_like(q))[0]

    def state(self, q, qd, qdd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Full MuJoCo ``(qpos, qvel, qacc)`` for jaxbal ``(q, q̇, q̈)`` (one sample)."""
        qpos, qvel, qacc = tree_state(self.tree, q, qd, qdd)
        return (
            np.concatenate([np.zeros(6), np.asarray(qpos)]),
            np.concatenate([np.zeros(6), np.asarray(qvel)]),
            np.concatenate([np.zeros(6), np.asarray(qacc)]),
        )

    def base_reaction(self, data: mujoco.MjData) -> tuple[np.ndarray, np.ndarray]:
        """``(force, moment)`` on the base from ``data.qfrc_inverse`` (after ``mj_inverse``)."""
        force = -data.qfrc_inverse[0:3] - BASE_MASS * self.gravity
        return force, -data.qfrc_inverse[3:6].copy()


def mujoco_model(robot: Robot, gravity=None, tree: Tree | None = None) -> MujocoRobot:
    """Compile ``robot`` for MuJoCo C (cached on the MJCF text).

    Args:
        robot: a concrete robot (not traced).
        gravity: ``(3,)`` [m/s²], default zero.
        tree: default :func:`jaxbal.mjcf.robot_tree` (registered builder, else the
            less independent :func:`jaxbal.mjcf.prescribed_tree`).
    """
    tree = robot_tree(robot, fallback=True) if tree is None else tree
    gravity = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=float)
    xml = to_mjcf(robot, tree, gravity=gravity)
    return MujocoRobot(model=_compile(xml), tree=tree, gravity=gravity, xml=xml)


def mujoco_inverse(robot: Robot, q, qd, qdd, gravity=None, tree=None) -> np.ndarray:
    """``qfrc_inverse`` of MuJoCo C for one state, shape ``(nv,)`` (base dofs first)."""
    compiled = mujoco_model(robot, gravity, tree)
    data = mujoco.MjData(compiled.model)
    data.qpos[:], data.qvel[:], data.qacc[:] = compiled.state(q, qd, qdd)
    mujoco.mj_inverse(compiled.model, data)
    return data.qfrc_inverse.copy()


def mujoco_base_reaction(
    robot: Robot, q, qd, qdd, gravity=None, tree: Tree | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Force [N] and moment [N·m] the robot exerts on its base, from MuJoCo C.

    Same convention as :func:`jaxbal.shaking_wrench` (about the base origin, base
    frame, dynamic part only unless ``gravity`` is given).

    Args:
        robot: a concrete robot.
        q, qd, qdd: ``(dof,)`` jaxbal coordinates and derivatives, or ``(T, dof)``.
        gravity: ``(3,)`` [m/s²] or ``None``.
        tree: optional :class:`~jaxbal.mjcf.Tree` (default: registered, else prescribed).

    Returns:
        ``(force, moment)``, each ``(3,)`` (or ``(T, 3)`` for batched input), numpy.
    """
    compiled = mujoco_model(robot, gravity, tree)
    q, qd, qdd = (np.asarray(a, dtype=float) for a in (q, qd, qdd))
    batched = q.ndim == 2
    check_shape("q", q, (None, robot.dof) if batched else (robot.dof,))
    for name, value in (("qd", qd), ("qdd", qdd)):
        check_shape(name, value, q.shape)
    data = mujoco.MjData(compiled.model)
    forces, moments = [], []
    for sample in zip(*(np.atleast_2d(a) for a in (q, qd, qdd)), strict=True):
        data.qpos[:], data.qvel[:], data.qacc[:] = compiled.state(*sample)
        mujoco.mj_inverse(compiled.model, data)
        force, moment = compiled.base_reaction(data)
        forces.append(force)
        moments.append(moment)
    forces, moments = np.array(forces), np.array(moments)
    return (forces, moments) if batched else (forces[0], moments[0])
