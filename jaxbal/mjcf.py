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

:func:`jaxbal.mjx_trees.prescribed_tree` is a generic fallback for any robot: every
jaxbal body hangs from the base on 3 slides and a ball joint whose motion is
*prescribed* from ``robot.body_frames``. It checks the mass properties and the momentum bookkeeping
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
BASE_MASS = 1e-14
#: Names and types of the six base dofs, in qpos/qvel order.
BASE_JOINTS = ("base_x", "base_y", "base_z", "base_rx", "base_ry", "base_rz")
_BASE_TYPES = ("slide",) * 3 + ("hinge",) * 3
#: Soft-constraint settings of the loop closures: ``solref = (time constant [s],
#: damping ratio)``, ``solimp`` impedance (0.99..0.9999 over 1 mm). They only matter
#: in forward simulation (inverse dynamics of consistent states gives no constraint
#: force on the base); see :mod:`jaxbal.mjx_simulate`.
CONNECT = {"solref": "0.002 1", "solimp": "0.99 0.9999 0.001 0.5 2"}


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
    """A ``connect`` equality (spherical joint) closing a kinematic loop.

    Written with two sites (``site1``/``site2``), so the joint centre is given on both
    bodies and does not depend on MuJoCo's reference configuration ``qpos0``.

    Attributes:
        body1, anchor1: first body and the joint centre in its frame ``(3,)`` [m].
        body2, anchor2: second body and the joint centre in its frame ``(3,)`` [m].
    """

    body1: str
    anchor1: tuple[float, float, float]
    body2: str
    anchor2: tuple[float, float, float]


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
        "jaxbal.mjcf.register_tree or use jaxbal.mjx_trees.prescribed_tree(robot)"
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
            from jaxbal.mjx_trees import prescribed_tree

            return prescribed_tree(robot)
        raise


def has_tree(robot: Robot) -> bool:
    """True when a kinematic tree builder is registered for ``robot``'s class."""
    import jaxbal.mjx_trees  # noqa: F401

    return _tree_builder.dispatch(type(robot)) is not _tree_builder.dispatch(object)


def _quat_mul(a, b):
    w1, v1 = a[0], a[1:]
    w2, v2 = b[0], b[1:]
    return jnp.concatenate([(w1 * w2 - v1 @ v2)[None], w1 * v2 + w2 * v1 + jnp.cross(v1, v2)])


def tree_state(tree: Tree, q, qd, qdd):
    """``(qpos, qvel, qacc)`` of the tree joints (base dofs excluded) for jaxbal's
    ``(q, q̇, q̈)``, unless ``tree.state`` is given.

    ``qpos = c(q)``; a hinge/slide velocity is ``ċ = c'(q) q̇``; a ball joint's is its
    angular velocity in the child frame, ``ω = 2 vec(Q* ⊗ Q̇)`` (MuJoCo's convention);
    accelerations are their time derivatives. All by nested ``jax.jvp`` (exact).
    """
    if tree.state is not None:
        return tree.state(q, qd, qdd)
    q, qd, qdd = (jnp.asarray(a, dtype=float) for a in (q, qd, qdd))
    types = [j.type for b in tree.bodies for j in b.joints]

    def velocity(q_, qd_):
        qpos, rate = jax.jvp(tree.coordinates, (q_,), (qd_,))
        if "ball" not in types:
            return qpos, rate
        pieces, i = [], 0
        for kind in types:
            if kind == "ball":
                quat, quat_rate = qpos[i : i + 4], rate[i : i + 4]
                conjugate = quat * jnp.array([1.0, -1.0, -1.0, -1.0])
                pieces.append(2.0 * _quat_mul(conjugate, quat_rate)[1:])
                i += 4
            else:
                pieces.append(rate[i : i + 1])
                i += 1
        return qpos, jnp.concatenate(pieces)

    (qpos, qvel), (_, qacc) = jax.jvp(velocity, (q, qd), (qd, qdd))
    return qpos, qvel, qacc


# --- rotations ----------------------------------------------------------------------


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


class Inertials(NamedTuple):
    """What :func:`to_mjcf` writes for each jaxbal body (``mass_properties`` order).

    Attributes:
        mass: ``(n,)`` masses written [kg] (jaxbal's plus ``mass_floor``).
        mass_floor: ``(n,)`` :data:`BASE_MASS` for a moving body (one with joints) whose
            welded group is massless, else 0 [kg].
        moments: ``(n, 3)`` principal moments written [kg·m²].
        axes: ``(n, 3, 3)`` principal axes (columns) in the body frame.
        padding: ``(n, 3)`` ``moments`` minus jaxbal's principal moments [kg·m²].
    """

    mass: np.ndarray
    mass_floor: np.ndarray
    moments: np.ndarray
    axes: np.ndarray
    padding: np.ndarray


def mujoco_inertials(robot: Robot, tree: Tree) -> Inertials:
    """Masses and inertias MuJoCo accepts, as close to jaxbal's as it allows.

    Principal moments violating the triangle inequality are padded as in
    :func:`realisable_inertia`; a moving body gets at least :data:`BASE_MASS` in each
    principal moment, and :data:`BASE_MASS` of mass if it and the bodies welded to it
    are massless (MuJoCo's ``mjMINVAL`` check); the induced error is ~1e-14 of the
    body's acceleration [N] or angular acceleration [N·m].
    """
    bodies = robot.mass_properties()
    mass = np.asarray(bodies.mass, dtype=float)
    index = {name: i for i, name in enumerate(bodies.names)}
    moving = {b.name for b in tree.bodies if b.joints}
    welded = {}
    for b in tree.bodies:
        if not b.joints and b.parent is not None:
            welded.setdefault(b.parent, []).append(b.name)

    def group_mass(name):
        own = mass[index[name]] if name in index else 0.0
        return own + sum(group_mass(child) for child in welded.get(name, ()))

    floor = np.zeros_like(mass)
    moments, axes, padding = [], [], []
    for i, name in enumerate(bodies.names):
        m, a, p = realisable_inertia(np.asarray(bodies.inertia[i]))
        if name in moving:
            extra = np.maximum(BASE_MASS - m, 0.0)
            m, p = m + extra, p + extra
            if group_mass(name) <= 0.0:
                floor[i] = BASE_MASS
        moments.append(m)
        axes.append(a)
        padding.append(p)
    return Inertials(mass + floor, floor, np.array(moments), np.array(axes), np.array(padding))


def _quat_of(matrix) -> np.ndarray:
    return np.asarray(_matrix_to_quat(jnp.asarray(matrix, dtype=float)))


# --- MJCF ------------------------------------------------------------------------------


def _fmt(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in np.atleast_1d(np.asarray(values, dtype=float)))


def to_mjcf(
    robot: Robot,
    tree: Tree | None = None,
    gravity=None,
    model_name: str | None = None,
    base_joints: bool = True,
    timestep: float = 0.002,
):
    """MJCF text of ``robot`` under the six-dof base (see the module docstring).

    Args:
        robot: any :class:`~jaxbal.robot.Robot`.
        tree: its :class:`Tree`; default :func:`robot_tree` (with the prescribed
            fallback).
        gravity: ``(3,)`` [m/s²], default zero.
        model_name: the ``<mujoco model=...>`` name.
        base_joints: carry the robot on the six base dofs (for the base reaction);
            ``False`` fixes the base to the world (for forward simulation).
        timestep: the simulation time step [s].

    Returns:
        The XML string, loadable by ``mujoco.MjModel.from_xml_string`` and the viewer.

    Raises:
        ValueError: a body with joints whose welded group has no mass, or an unknown
            parent/body.
    """
    tree = robot_tree(robot, fallback=True) if tree is None else tree
    bodies = robot.mass_properties()
    index = {name: i for i, name in enumerate(bodies.names)}
    com = np.asarray(bodies.com, dtype=float)
    inertials = mujoco_inertials(robot, tree)
    mass = inertials.mass
    gravity = np.zeros(3) if gravity is None else np.asarray(gravity, dtype=float)
    scale = float(np.max(np.abs([b.pos for b in tree.bodies]), initial=0.0)) or 0.1

    root = ET.Element("mujoco", model=model_name or type(robot).__name__)
    ET.SubElement(root, "compiler", angle="radian", inertiafromgeom="false", autolimits="true")
    option = ET.SubElement(
        root, "option", gravity=_fmt(gravity), integrator="RK4", timestep=_fmt(timestep)
    )
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
        if base_joints:
            ET.SubElement(base, "joint", name=name, type=kind, axis=_fmt(axis))
    ET.SubElement(base, "geom", type="sphere", size=_fmt(0.03 * scale), rgba="0.3 0.3 0.3 1")

    _check_order(tree)
    elements = {None: base}
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
            ET.SubElement(
                element,
                "inertial",
                pos=_fmt(com[i]),
                quat=_fmt(_quat_of(inertials.axes[i])),
                mass=_fmt(mass[i]),
                diaginertia=_fmt(inertials.moments[i]),
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

    if tree.connects:
        equality = ET.SubElement(root, "equality")
        for k, c in enumerate(tree.connects):
            sites = []
            for side, body, anchor in ((1, c.body1, c.anchor1), (2, c.body2, c.anchor2)):
                if body not in elements:
                    raise ValueError(f"connect {k}: unknown body {body!r}")
                sites.append(f"connect{k}_{side}")
                ET.SubElement(
                    elements[body],
                    "site",
                    name=sites[-1],
                    pos=_fmt(anchor),
                    size=_fmt(0.01 * scale),
                )
            ET.SubElement(
                equality, "connect", name=f"loop{k}", site1=sites[0], site2=sites[1], **CONNECT
            )
    if tree.actuated:
        actuator = ET.SubElement(root, "actuator")
        for name in tree.actuated:
            ET.SubElement(actuator, "motor", name=name, joint=name, gear="1")
    ET.indent(root)
    return ET.tostring(root, encoding="unicode")


def _check_order(tree: Tree) -> None:
    """``tree.bodies`` must be in MuJoCo's depth-first order (it fixes the qpos order)."""
    children = {}
    for b in tree.bodies:
        children.setdefault(b.parent, []).append(b.name)

    def visit(name):
        return [name] + [n for child in children.get(name, ()) for n in visit(child)]

    order = [n for child in children.get(None, ()) for n in visit(child)]
    if order != [b.name for b in tree.bodies]:
        raise ValueError(
            "tree bodies must be listed depth-first (each body's subtree right after it), "
            f"got {[b.name for b in tree.bodies]}, expected {order}"
        )


#: Robots that ``jaxbal export-mjcf NAME`` knows: name -> (module, constructor).
EXPORTABLE = {
    "2r": ("jaxbal.robots.planar_arm", "planar_2r"),
    "3r": ("jaxbal.robots.planar_arm", "planar_3r"),
    "scara": ("jaxbal.robots.scara", "scara"),
    "dual-v": ("jaxbal.robots.dual_v", "dual_v"),
    "orthoglide": ("jaxbal.robots.orthoglide", "orthoglide"),
}


def export_mjcf(robot: Robot | str, gravity=None, base_joints: bool = False) -> str:
    """MJCF of ``robot`` (or a name of :data:`EXPORTABLE`) for
    ``jaxbal export-mjcf ROBOT > robot.xml``, viewer-ready (``python -m mujoco.viewer
    --mjcf robot.xml``). The nominal robot, base fixed unless ``base_joints``.

    Raises:
        ValueError: an unknown robot name.
    """
    if isinstance(robot, str):
        import importlib

        key = robot.lower().replace("_", "-")
        if key not in EXPORTABLE:
            raise ValueError(f"unknown robot {robot!r}; choose one of {sorted(EXPORTABLE)}")
        module, constructor = EXPORTABLE[key]
        robot = getattr(importlib.import_module(module), constructor)()
    return to_mjcf(robot, gravity=gravity, base_joints=base_joints)
