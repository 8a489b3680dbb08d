"""The MuJoCo tree of a mechanism read from MJCF, rebuilt from the parsed structure.

:func:`mjcf_tree` writes the moving bodies of an
:class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot` back as a
:class:`~jaxbal._src.mujoco.tree.Tree` (with the current values of every leaf, the
counter-masses welded to their bodies), so that :func:`jaxbal.mujoco.confirm` compares
jaxbal's shaking wrench with MuJoCo's ``mj_inverse`` on a model that MuJoCo assembles
from the joints, not from jaxbal's kinematics. Bodies fixed to the base are folded into
the base (their children hang from it at their world pose); connects to a fixed body
are written to the base.

References:
    MuJoCo XML reference, https://mujoco.readthedocs.io/en/stable/XMLreference.html
    (``body``, ``joint/ref``, ``equality/connect``).
"""

from __future__ import annotations

from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from jaxbal._src.mujoco.tree import Connect, Coupling, Joint, Tree, TreeBody, vec
from jaxbal._src.robots.mjcf_kinematics import world_frames


@dataclass(frozen=True)
class QposOffsets:
    """MuJoCo ``qpos`` of the rebuilt tree, ``q − ref`` (the tree is written at the
    reference joint values, without ``ref``); hashable, so equal trees compare equal."""

    offsets: tuple[float, ...]

    def __call__(self, q):
        return jnp.asarray(q, dtype=float) - jnp.asarray(self.offsets, dtype=float)


def _rotation(matrix) -> tuple:
    return tuple(vec(*row) for row in np.asarray(matrix, dtype=float))


def _visual_end(robot, i: int, body_pos) -> tuple[float, float, float] | None:
    """End of the capsule drawn for body ``i`` in the viewer: its first child off its
    origin, else a connect anchor or the end-effector site on it (body frame) [m]."""
    ends = [body_pos[c] for c, parent in enumerate(robot.parents) if parent == i]
    for c, (b1, b2) in enumerate(robot.connect_bodies):
        ends += [robot.anchor1[c]] if b1 == i else []
        ends += [robot.anchor2[c]] if b2 == i else []
    ends += [robot.site_pos] if robot.site_body == i else []
    ends = [np.asarray(end, dtype=float) for end in ends]
    return next((vec(end) for end in ends if np.linalg.norm(end) > 1e-9), None)


def mjcf_tree(robot) -> Tree:
    """:class:`~jaxbal._src.mujoco.tree.Tree` of ``robot`` (a concrete
    :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot`), see the module docstring."""
    origins, rotations = (np.asarray(a) for a in world_frames(robot, robot.reference))
    body_pos, body_rot = np.asarray(robot.body_pos), np.asarray(robot.body_rot)
    axes, anchors = np.asarray(robot.joint_axis), np.asarray(robot.joint_pos)
    moving = set(robot.moving_bodies)
    bodies = []
    for k, i in enumerate(robot.moving_bodies):
        parent = robot.parents[i]
        if parent in moving:
            pos, rot, parent_name = body_pos[i], body_rot[i], robot.body_names[parent]
        elif parent < 0:
            pos, rot, parent_name = body_pos[i], body_rot[i], None
        else:  # hangs from a body fixed to the base: write it at its world pose
            pos = origins[parent] + rotations[parent] @ body_pos[i]
            rot, parent_name = rotations[parent] @ body_rot[i], None
        joints = tuple(
            Joint(robot.joint_names[j], robot.joint_types[j], vec(axes[j]), vec(anchors[j]))
            for j in robot.body_joints[i]
        )
        name = robot.body_names[i]
        link = _visual_end(robot, i, body_pos)
        bodies.append(TreeBody(name, parent_name, vec(pos), _rotation(rot), joints, link))
        for c, body in enumerate(robot.counter_bodies):
            if body == k:
                bodies.append(TreeBody(robot.counter_names[c], name))

    connects = []
    anchor1, anchor2 = np.asarray(robot.anchor1), np.asarray(robot.anchor2)
    for c, pair in enumerate(robot.connect_bodies):
        ends = []
        for body, anchor in zip(pair, (anchor1[c], anchor2[c]), strict=True):
            if body in moving:
                ends += [robot.body_names[body], vec(anchor)]
            elif body < 0:
                ends += [None, vec(anchor)]  # None: the base, which is the world frame
            else:
                ends += [None, vec(origins[body] + rotations[body] @ anchor)]
        connects.append(Connect(*ends))

    offsets = np.zeros(robot.dof)
    refs = np.asarray(robot.joint_ref)
    for j, kind in enumerate(robot.joint_types):
        if kind != "ball":
            offsets[robot.joint_qpos[j]] = refs[j]
    actuated = tuple(
        robot.joint_names[robot.joint_qpos.index(a)] for a in robot.actuated_coordinates
    )
    # MuJoCo C re-closes the loops itself (jaxbal/_src/mujoco/closure.py): the independent
    # joints are prescribed, the others start from jaxbal's solution (the user's assembly
    # mode) and their velocities and accelerations are MuJoCo's own.
    independent = set(robot.independent_coordinates)
    solved = tuple(
        name
        for name, start in zip(robot.joint_names, robot.joint_qpos, strict=True)
        if (connects or robot.coupling_names) and start not in independent
    )
    coef = np.asarray(robot.coupling_coef)
    couplings = tuple(
        Coupling(robot.joint_names[j1], robot.joint_names[j2] if j2 >= 0 else None, vec(*coef[k]))
        for k, (j1, j2) in enumerate(robot.coupling_joints)
    )
    coordinates = QposOffsets(vec(offsets))
    return Tree(
        bodies=tuple(bodies),
        coordinates=coordinates,
        connects=tuple(connects),
        actuated=actuated,
        solved=solved,
        guess=coordinates,
        couplings=couplings,
    )
