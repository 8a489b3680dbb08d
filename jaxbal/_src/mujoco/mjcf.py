"""MuJoCo models (MJCF) generated from jaxbal robots, for an independent check.

The kinematic description comes from the robot itself,
:meth:`~jaxbal.Robot.mujoco_tree` (see :mod:`jaxbal._src.mujoco.tree`); nothing here is
robot-specific.

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

References:
    MuJoCo XML reference, https://mujoco.readthedocs.io/en/stable/XMLreference.html
    (``inertial``, ``joint``, ``equality/connect``).
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import NamedTuple

import equinox as eqx
import numpy as np

from jaxbal._src.mujoco.tree import Tree, matrix_to_quat
from jaxbal._src.robot import Robot

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


@eqx.filter_jit
def host_bodies(robot: Robot):
    """``robot.mass_properties()`` of a concrete robot as one compiled program, for host
    code (the MJCF writer, the MuJoCo models): eagerly each of its small JAX operations
    is a dispatch and, in a fresh process, a compilation of its own (the DUAL-V's ~1 s
    on the 2-core CPU; compiled ~0.15 s, then microseconds)."""
    return robot.mass_properties()


def mujoco_inertials(robot: Robot, tree: Tree) -> Inertials:
    """Masses and inertias MuJoCo accepts, as close to jaxbal's as it allows.

    Principal moments violating the triangle inequality are padded as in
    :func:`realisable_inertia`; a moving body gets at least :data:`BASE_MASS` in each
    principal moment, and :data:`BASE_MASS` of mass if it and the bodies welded to it
    are massless (MuJoCo's ``mjMINVAL`` check); the induced error is ~1e-14 of the
    body's acceleration [N] or angular acceleration [N·m].
    """
    bodies = host_bodies(robot)
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
    return matrix_to_quat(np.asarray(matrix, dtype=float), xp=np)


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
        tree: its :class:`~jaxbal._src.mujoco.tree.Tree`; default
            ``robot.mujoco_tree()``.
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
    tree = robot.mujoco_tree() if tree is None else tree
    bodies = host_bodies(robot)
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
    if tree.couplings:
        equality = root.find("equality")
        equality = ET.SubElement(root, "equality") if equality is None else equality
        for k, c in enumerate(tree.couplings):
            names = {"joint1": c.joint1} | ({"joint2": c.joint2} if c.joint2 else {})
            ET.SubElement(
                equality, "joint", name=f"coupling{k}", polycoef=_fmt(c.polycoef), **names,
                **CONNECT,
            )  # fmt: skip
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


def export_mjcf(robot: Robot, gravity=None, base_joints: bool = False) -> str:
    """Viewer-ready MJCF of ``robot`` (``jaxbal export-mjcf ROBOT > robot.xml``, then
    ``python -m mujoco.viewer --mjcf robot.xml``); base fixed unless ``base_joints``."""
    return to_mjcf(robot, gravity=gravity, base_joints=base_joints)
