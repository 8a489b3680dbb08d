"""MuJoCo models (MJCF) generated from jaxbal robots, for an independent check.

A jaxbal :class:`~jaxbal.robot.Robot` knows its bodies' mass properties and their
poses, not its joints. To let MuJoCo compute the dynamics *independently*, a robot's
kinematic topology is described once by a :class:`Tree`: MuJoCo bodies, each the
frame of one jaxbal body (so the mass, COM and inertia from
:meth:`~jaxbal.robot.Robot.mass_properties` apply unchanged), joined by hinge/slide
joints, plus ``connect`` equality constraints that close kinematic loops. Builders
are registered per robot class with :func:`robot_tree` (``functools.singledispatch``;
see :mod:`jaxbal.mjx_trees`).

Every generated model carries the whole robot under one ``base`` body moved by three
slide joints (x, y, z) and three hinge joints (about x, y, z) through the base origin,
held at zero. ``-qfrc_inverse`` on these six dofs is then the force and the moment
(about the base origin, base frame) that the robot exerts on its base -- the quantity
:func:`jaxbal.shaking_wrench` computes. Contacts are disabled and gravity is
configurable (default zero, as the papers' shaking forces).

MuJoCo's compiler needs physically realisable inertias (positive definite for bodies
with joints, triangle inequality ``A + B ≥ C`` everywhere). jaxbal's planar bodies
carry only ``I_zz``; the principal moments that violate the inequality are padded
(:func:`realisable_inertia`) in the directions *perpendicular* to the violating
principal axis. A rotation about that axis -- every motion of a planar robot -- is
unaffected, exactly. The ``base`` body needs a mass to hold joints; it is
:data:`BASE_MASS`, never accelerated (its dofs are held at zero), and its weight is
subtracted when gravity is on.

:func:`prescribed_tree` is a generic fallback for any robot: every jaxbal body hangs
from the base on 3 slides and a ball joint whose motion is *prescribed* from
``robot.body_frames``. It checks the mass properties and the momentum bookkeeping
(Newton-Euler), not the kinematics, so it is less independent than a registered tree.

References:
    MuJoCo XML reference, https://mujoco.readthedocs.io/en/stable/XMLreference.html
    (``inertial``, ``joint``, ``equality/connect``).
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from collections.abc import Callable
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal.robot import Robot

#: Mass [kg] and isotropic inertia [kg·m²] of the (never accelerated) base body and of
#: helper bodies that are not jaxbal bodies (MuJoCo needs mass on bodies with joints).
BASE_MASS = 1e-12
#: Names and types of the six base dofs, in qpos/qvel order.
BASE_JOINTS = ("base_x", "base_y", "base_z", "base_rx", "base_ry", "base_rz")
_BASE_TYPES = ("slide",) * 3 + ("hinge",) * 3


class Joint(NamedTuple):
    """A 1-dof joint of a :class:`TreeBody`.

    Attributes:
        name: unique joint name.
        type: ``"hinge"`` or ``"slide"``.
        axis: ``(3,)`` joint axis in the body frame.
        pos: ``(3,)`` anchor in the body frame [m] (hinges).
    """

    name: str
    type: str
    axis: tuple[float, float, float] = (0.0, 0.0, 1.0)
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)


class TreeBody(NamedTuple):
    """One MuJoCo body, whose frame is the frame of a jaxbal body.

    Attributes:
        name: the jaxbal body name (from ``mass_properties().names``); the mass,
            COM and inertia of that body are used. A name that is not a jaxbal body
            gives a massless helper body (only allowed without joints).
        parent: parent body name, ``None`` for the base.
        pos: ``(3,)`` frame origin in the parent frame at ``qpos = 0`` [m].
        rotation: ``(3, 3)`` frame orientation in the parent frame at ``qpos = 0``.
        joints: the joints moving this body relative to its parent.
        visual_to: optional ``(3,)`` end of a visual capsule from the frame origin [m].
    """

    name: str
    parent: str | None
    pos: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    joints: tuple[Joint, ...] = ()
    visual_to: tuple[float, float, float] | None = None


class Connect(NamedTuple):
    """A ``connect`` equality (ball joint) closing a kinematic loop.

    Attributes:
        body1, body2: the two bodies it joins.
        anchor: ``(3,)`` the joint centre in ``body1``'s frame [m].
    """

    body1: str
    body2: str
    anchor: tuple[float, float, float]


class Tree(NamedTuple):
    """Kinematic description of a robot for MuJoCo.

    Attributes:
        bodies: parents before children.
        coordinates: ``q (dof,) -> qpos (nq_robot,)`` of the tree joints in the order
            they appear in ``bodies``; any smooth JAX function (velocities and
            accelerations follow by forward-mode differentiation).
        connects: loop-closure constraints.
        actuated: names of the actuated joints (motors in the MJCF), if known.
        independent: False for :func:`prescribed_tree`.
        state: optional ``(q, qd, qdd) -> (qpos, qvel, qacc)`` overriding the default
            (derivatives of ``coordinates``), see :func:`tree_state`.
    """

    bodies: tuple[TreeBody, ...]
    coordinates: Callable
    connects: tuple[Connect, ...] = ()
    actuated: tuple[str, ...] = ()
    independent: bool = True
    state: Callable | None = None

    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for b in self.bodies for j in b.joints)


@functools.singledispatch
def _tree_builder(robot: Robot) -> Tree:
    raise NotImplementedError(
        f"no MuJoCo tree is registered for {type(robot).__name__}; register one with "
        "jaxbal.mjcf.register_tree or use jaxbal.mjcf.prescribed_tree(robot)"
    )


def register_tree(cls):
    """Decorator registering a ``builder(robot) -> Tree`` for robot class ``cls``."""
    return _tree_builder.register(cls)


def robot_tree(robot: Robot, fallback: bool = False) -> Tree:
    """The registered :class:`Tree` of ``robot`` (or :func:`prescribed_tree` if
    ``fallback`` and none is registered)."""
    import jaxbal.mjx_trees  # noqa: F401  (registers the builders)

    try:
        return _tree_builder(robot)
    except NotImplementedError:
        if fallback:
            return prescribed_tree(robot)
        raise


def has_tree(robot: Robot) -> bool:
    """True when a kinematic tree builder is registered for ``robot``'s class."""
    import jaxbal.mjx_trees  # noqa: F401

    return _tree_builder.dispatch(type(robot)) is not _tree_builder.dispatch(object)


def tree_state(tree: Tree, q, qd, qdd):
    """``(qpos, qvel, qacc)`` of the tree joints (base dofs excluded) for jaxbal's
    ``(q, q̇, q̈)``: ``qpos = c(q)``, ``qvel = c'(q) q̇``, ``qacc = c''(q)[q̇, q̇] + c'(q) q̈``
    by nested ``jax.jvp`` (exact), unless ``tree.state`` is given."""
    if tree.state is not None:
        return tree.state(q, qd, qdd)
    q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))

    def velocity(q_, qd_):
        return jax.jvp(tree.coordinates, (q_,), (qd_,))

    (qpos, qvel), (_, qacc) = jax.jvp(velocity, (q, qd), (qd, qdd))
    return qpos, qvel, qacc


# --- generic fallback -----------------------------------------------------------------


def _matrix_to_quat(rotation):
    """Unit quaternion ``(w, x, y, z)`` of a rotation matrix (Shepperd, branch-free).

    The largest of the four candidate components is chosen with ``argmax`` so the
    division is well conditioned; the result is differentiable almost everywhere.
    """
    r = rotation
    trace = r[0, 0] + r[1, 1] + r[2, 2]
    candidates = jnp.stack(
        [
            jnp.stack([1 + trace, r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]]),
            jnp.stack(
                [r[2, 1] - r[1, 2], 1 + 2 * r[0, 0] - trace, r[0, 1] + r[1, 0], r[0, 2] + r[2, 0]]
            ),
            jnp.stack(
                [r[0, 2] - r[2, 0], r[0, 1] + r[1, 0], 1 + 2 * r[1, 1] - trace, r[1, 2] + r[2, 1]]
            ),
            jnp.stack(
                [r[1, 0] - r[0, 1], r[0, 2] + r[2, 0], r[1, 2] + r[2, 1], 1 + 2 * r[2, 2] - trace]
            ),
        ]
    )
    diag = jnp.stack([trace, r[0, 0], r[1, 1], r[2, 2]])
    k = jnp.argmax(diag)
    row = candidates[k]
    quat = row / (2.0 * jnp.sqrt(jnp.maximum(row[k], 1e-300)))
    return quat * jnp.sign(quat[0] + (quat[0] == 0))


def prescribed_tree(robot: Robot) -> Tree:
    """Generic tree: every jaxbal body on 3 world slides + a ball joint under the base.

    Less independent than a registered tree: the kinematics (poses, velocities,
    accelerations) are jaxbal's own ``body_frames`` and its derivatives; MuJoCo then
    checks the Newton-Euler sum of the bodies' momenta about the base origin. Valid
    for closed chains too. The joints sit on massless helper bodies (mass
    :data:`BASE_MASS`, a relative error ~1e-13) carrying the welded jaxbal bodies.
    Its ``state`` gives slide positions and ball quaternions, the velocities and
    accelerations in MuJoCo's convention (a ball joint's velocity is the angular
    velocity in the body frame, not the derivative of its quaternion).
    """
    bodies = ()
    for name in robot.mass_properties().names:
        slides = tuple(
            Joint(f"{name}_{a}", "slide", tuple(ax)) for a, ax in zip("xyz", np.eye(3), strict=True)
        )
        bodies += (
            TreeBody(
                name=f"{name}_frame", parent=None, joints=slides + (Joint(f"{name}_ball", "ball"),)
            ),
            TreeBody(name=name, parent=f"{name}_frame"),
        )

    def coordinates(q):
        origins, rotations = robot.body_frames(q)
        quats = jax.vmap(_matrix_to_quat)(rotations)
        return jnp.concatenate([origins, quats], axis=-1).reshape(-1)

    def state(q, qd, qdd):
        q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))

        def frames(q_):
            return robot.body_frames(q_)

        def twist(q_, qd_):
            (origins, rotations), (velocities, rates) = jax.jvp(frames, (q_,), (qd_,))
            omega_local = _vee(jnp.einsum("nji,njk->nik", rotations, rates))
            return velocities, omega_local

        (velocities, omega), (accelerations, omega_dot) = jax.jvp(twist, (q, qd), (qd, qdd))
        qvel = jnp.concatenate([velocities, omega], axis=-1).reshape(-1)
        qacc = jnp.concatenate([accelerations, omega_dot], axis=-1).reshape(-1)
        return coordinates(q), qvel, qacc

    return Tree(bodies=bodies, coordinates=coordinates, independent=False, state=state)


def _vee(skew):
    return jnp.stack([skew[..., 2, 1], skew[..., 0, 2], skew[..., 1, 0]], -1)


# --- inertias ---------------------------------------------------------------------------


def realisable_inertia(inertia, rtol: float = 1e-9):
    """Principal moments and axes MuJoCo accepts for a jaxbal inertia tensor.

    Returns ``(moments (3,), axes (3, 3), padding (3,))`` with ``inertia ≈ axes ·
    diag(moments - padding) · axesᵀ``. Where a principal moment exceeds the sum of
    the other two (e.g. a planar body with only ``I_zz``), half the deficit (times
    ``1 + rtol``) is added to each of the other two, which leaves rotations about that
    principal axis exactly unchanged.
    """
    inertia = np.asarray(inertia, dtype=float)
    inertia = 0.5 * (inertia + inertia.T)
    moments, axes = np.linalg.eigh(inertia)
    moments = np.maximum(moments, 0.0)
    if np.linalg.det(axes) < 0:
        axes[:, 0] = -axes[:, 0]
    padding = np.zeros(3)
    largest = int(np.argmax(moments))
    deficit = moments[largest] - (np.sum(moments) - moments[largest])
    if deficit > 0:
        others = [i for i in range(3) if i != largest]
        padding[others] = 0.5 * deficit * (1.0 + rtol)
    return moments + padding, axes, padding


def _quat_of(matrix) -> np.ndarray:
    return np.asarray(_matrix_to_quat(jnp.asarray(matrix, dtype=float)))


# --- MJCF ------------------------------------------------------------------------------


def _fmt(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in np.atleast_1d(np.asarray(values, dtype=float)))


def to_mjcf(robot: Robot, tree: Tree | None = None, gravity=None, model_name: str | None = None):
    """MJCF text of ``robot`` under the six-dof base (see the module docstring).

    Args:
        robot: any :class:`~jaxbal.robot.Robot`.
        tree: its :class:`Tree`; default :func:`robot_tree` (with fallback).
        gravity: ``(3,)`` [m/s²], default zero.
        model_name: the ``<mujoco model=...>`` name.

    Returns:
        The XML string, loadable by ``mujoco.MjModel.from_xml_string`` and the viewer.

    Raises:
        ValueError: a body with joints whose welded group has no mass, or an unknown
            parent/body.
    """
    tree = robot_tree(robot, fallback=True) if tree is None else tree
    bodies = robot.mass_properties()
    index = {name: i for i, name in enumerate(bodies.names)}
    mass = np.asarray(bodies.mass, dtype=float)
    com = np.asarray(bodies.com, dtype=float)
    inertia = np.asarray(bodies.inertia, dtype=float)
    gravity = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=float)
    scale = float(np.max(np.abs([b.pos for b in tree.bodies]), initial=0.0)) or 0.1

    root = ET.Element("mujoco", model=model_name or type(robot).__name__)
    ET.SubElement(root, "compiler", angle="radian", inertiafromgeom="false", autolimits="true")
    option = ET.SubElement(root, "option", gravity=_fmt(gravity), integrator="RK4")
    ET.SubElement(option, "flag", contact="disable")
    default = ET.SubElement(root, "default")
    ET.SubElement(default, "geom", contype="0", conaffinity="0", group="1", rgba="0.4 0.6 0.8 1")
    world = ET.SubElement(root, "worldbody")
    ET.SubElement(world, "light", pos="0 0 3", dir="0 0 -1")
    base = ET.SubElement(world, "body", name="base")
    ET.SubElement(
        base, "inertial", pos="0 0 0", mass=_fmt(BASE_MASS), diaginertia=_fmt([BASE_MASS] * 3)
    )
    for name, kind, axis in zip(
        BASE_JOINTS, _BASE_TYPES, np.concatenate([np.eye(3)] * 2), strict=True
    ):
        ET.SubElement(base, "joint", name=name, type=kind, axis=_fmt(axis))
    ET.SubElement(base, "geom", type="sphere", size=_fmt(0.03 * scale), rgba="0.3 0.3 0.3 1")

    elements = {None: base}
    has_joints = {b.name: bool(b.joints) for b in tree.bodies}
    children = {}
    for b in tree.bodies:
        children.setdefault(b.parent, []).append(b.name)
    for b in tree.bodies:
        if b.parent not in elements:
            raise ValueError(f"body {b.name!r}: parent {b.parent!r} is not defined before it")
        attrs = {"name": b.name, "pos": _fmt(b.pos)}
        if not np.allclose(b.rotation, np.eye(3), atol=0.0):
            attrs["quat"] = _fmt(_quat_of(b.rotation))
        element = ET.SubElement(elements[b.parent], "body", **attrs)
        elements[b.name] = element
        if b.name in index:
            i = index[b.name]
            moments, axes, _ = realisable_inertia(inertia[i])
            ET.SubElement(
                element,
                "inertial",
                pos=_fmt(com[i]),
                quat=_fmt(_quat_of(axes)),
                mass=_fmt(mass[i]),
                diaginertia=_fmt(moments),
            )
        elif b.joints:  # helper body: the smallest mass MuJoCo accepts
            ET.SubElement(
                element,
                "inertial",
                pos="0 0 0",
                mass=_fmt(BASE_MASS),
                diaginertia=_fmt([BASE_MASS] * 3),
            )
        for j in b.joints:
            jattrs = {"name": j.name, "type": j.type}
            if j.type != "ball":
                jattrs["axis"] = _fmt(j.axis)
            ET.SubElement(element, "joint", pos=_fmt(j.pos), **jattrs)
        if b.visual_to is not None:
            ET.SubElement(
                element,
                "geom",
                type="capsule",
                fromto=_fmt(np.concatenate([np.zeros(3), b.visual_to])),
                size=_fmt(0.02 * scale),
            )
        if b.name in index and mass[index[b.name]] > 0 and b.visual_to is None:
            ET.SubElement(
                element,
                "geom",
                type="sphere",
                pos=_fmt(com[index[b.name]]),
                size=_fmt(0.04 * scale),
                rgba="0.8 0.3 0.3 1",
            )
    _check_moving_mass(tree, index, mass, inertia, has_joints, children)

    if tree.connects:
        equality = ET.SubElement(root, "equality")
        for c in tree.connects:
            ET.SubElement(equality, "connect", body1=c.body1, body2=c.body2, anchor=_fmt(c.anchor))
    if tree.actuated:
        actuator = ET.SubElement(root, "actuator")
        for name in tree.actuated:
            ET.SubElement(actuator, "motor", name=name, joint=name, gear="1")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")


def _check_moving_mass(tree, index, mass, inertia, has_joints, children):
    """MuJoCo rejects a body with joints whose welded group has no mass: say so clearly."""

    def welded_mass(name):
        own = mass[index[name]] if name in index else 0.0
        return own + sum(
            welded_mass(child) for child in children.get(name, ()) if not has_joints[child]
        )

    for b in tree.bodies:
        if b.joints and welded_mass(b.name) <= 0.0:
            raise ValueError(
                f"body {b.name!r} moves on joints but it and the bodies welded to it have no "
                "mass; MuJoCo cannot model it"
            )


def export_mjcf(robot: Robot, gravity=None) -> str:
    """MJCF of ``robot`` for ``jaxbal export-mjcf ROBOT > robot.xml`` (viewer-ready)."""
    return to_mjcf(robot, gravity=gravity)
