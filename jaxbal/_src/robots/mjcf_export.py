"""The user's own model file with the designed counter-masses added.

After a co-design (:func:`~jaxbal._src.robots.mjcf_balance.balance`, ``jaxbal balance
--out``) the counter-masses exist only in jaxbal's robot. :func:`export_balanced`
writes them into the text of the file they came from, in its own format: in an MJCF a
``<body>`` without joints (welded) inside its carrying body, with an ``<inertial>``; in
a URDF a ``<link>`` with that ``<inertial>`` on a ``fixed`` ``<joint>`` to its carrying
link. Everything else (meshes, actuators, keyframes, comments) stays as it was, and
every number is written to 17 significant digits (MuJoCo's own writer keeps 6), so the
design can be simulated, rendered or machined from the file.

The text is checked before it is written: read back by
:func:`~jaxbal._src.robots.mjcf_import.from_mjcf` (from a file in the target directory,
so relative mesh and include paths resolve as they will), its shaking wrench must equal
the robot's at random states (:data:`EXPORT_RTOL`); a robot whose other parameters were
changed in jaxbal (``with_body``, ``eqx.tree_at``) is refused instead of written with
the file's values. The file is written atomically.

References:
    MuJoCo XML reference, ``body``, ``inertial``; ROS URDF specification, ``link``,
    ``inertial``, ``joint`` (http://wiki.ros.org/urdf/XML).
"""

from __future__ import annotations

import functools
import os
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.config import compiler_options
from jaxbal._src.momentum import tree_wrench
from jaxbal._src.mujoco.confirm import _gross_scales
from jaxbal._src.mujoco.mjcf import _fmt, realisable_inertia
from jaxbal._src.mujoco.tree import matrix_to_quat
from jaxbal._src.robots.mjcf_parse import text_or_path
from jaxbal._src.robots.mjcf_robot import MjcfRobot

__all__ = ["EXPORT_RTOL", "export_balanced"]

#: the written model's shaking wrench equals the robot's within this fraction of the
#: gross inertial force and moment (``Σ m_i |a_i|``, ``Σ |dL_i/dt|``) at
#: :data:`EXPORT_STATES` random states.
EXPORT_RTOL = 1e-9
EXPORT_STATES = 3


def _source_text(source) -> tuple[str, Path | None]:
    import mujoco

    if isinstance(source, mujoco.MjModel):
        raise ValueError("export_balanced writes into the model's file: pass its path or text")
    text, path = text_or_path(source)
    return (text, None) if path is None else (path.read_text(), path)


def _counters(robot: MjcfRobot):
    """``(name, carrier, position (3,), mass, inertia (3, 3))`` of each counter-mass."""
    names = robot.mass_names()
    arrays = (robot.counter_position, robot.counter_mass, robot.counter_inertia)
    position, mass, inertia = (np.asarray(a, dtype=float) for a in arrays)
    for k, name in enumerate(robot.counter_names):
        yield name, names[robot.counter_bodies[k]], position[k], mass[k], inertia[k]


def _find(root, tag: str, name: str, what: str):
    found = [e for e in root.iter(tag) if e.get("name") == name]
    if not found:
        raise ValueError(
            f"{what} {name!r} carrying a counter-mass is not in this file (an included "
            "file, or another model?)"
        )
    return found[0]


def _add_to_mjcf(root, robot: MjcfRobot) -> None:
    taken = {e.get("name") for e in root.iter("body")}
    for name, carrier, position, mass, inertia in _counters(robot):
        if name in taken:
            raise ValueError(f"the model already has a body named {name!r} (a counter-mass)")
        moments, axes, _ = realisable_inertia(inertia)
        body = ET.SubElement(_find(root, "body", carrier, "body"), "body", name=name)
        body.set("pos", _fmt(position))
        quat = np.asarray(matrix_to_quat(axes, xp=np))
        attributes = {"pos": "0 0 0", "quat": _fmt(quat), "mass": _fmt(mass)}
        ET.SubElement(body, "inertial", **attributes, diaginertia=_fmt(moments))


def _add_to_urdf(root, robot: MjcfRobot) -> None:
    taken = {e.get("name") for e in root.iter("link")}
    joints = {e.get("name") for e in root.iter("joint")}
    for name, carrier, position, mass, inertia in _counters(robot):
        if name in taken or f"{name}_joint" in joints:
            raise ValueError(f"the model already has a link or joint named {name!r}")
        _find(root, "link", carrier, "link")
        link = ET.SubElement(root, "link", name=name)
        inertial = ET.SubElement(link, "inertial")
        ET.SubElement(inertial, "origin", xyz=_fmt(position), rpy="0 0 0")
        ET.SubElement(inertial, "mass", value=_fmt(mass))
        entries = {"ixx": (0, 0), "ixy": (0, 1), "ixz": (0, 2), "iyy": (1, 1), "iyz": (1, 2)}
        entries["izz"] = (2, 2)
        ET.SubElement(inertial, "inertia", **{k: _fmt(inertia[ij]) for k, ij in entries.items()})
        joint = ET.SubElement(root, "joint", name=f"{name}_joint", type="fixed")
        ET.SubElement(joint, "parent", link=carrier)
        ET.SubElement(joint, "child", link=name)


def _wrenches_and_scales(robot: MjcfRobot, q, qd, qdd):
    """``((T, 3), (T, 3))`` shaking wrenches of the bodies at any states (the loops not
    required: the two models are compared at random states) and the gross force and
    moment scales."""
    wrenches = jax.vmap(lambda a, b, c: tree_wrench(robot, a, b, c))(q, qd, qdd)
    return wrenches, _gross_scales(robot, q, qd, qdd, jnp.zeros(3))


@functools.cache
def _check_program():
    """:func:`_wrenches_and_scales` compiled with the fast-compile options (it runs once
    per export: :func:`~jaxbal._src.validation.checked_call`'s ``once``); built on first
    use, since the options probe the backend."""
    return jax.jit(_wrenches_and_scales, compiler_options=compiler_options(0))


def _check_same_wrench(robot: MjcfRobot, path: Path, ignore_meshes: bool) -> None:
    """Refuse the model at ``path`` unless its shaking wrench equals ``robot``'s."""
    from jaxbal._src.robots.mjcf_import import from_mjcf

    joint = {q: robot.joint_names[robot.joint_qpos.index(q)] for q in robot.joint_qpos}
    try:
        written = from_mjcf(
            path,
            actuated=[joint[q] for q in robot.actuated_coordinates],
            independent=[joint[q] for q in robot.independent_coordinates],
            ignore_armature=True,
            ignore_passive=True,
            ignore_meshes=ignore_meshes,
        )
    except ValueError as error:
        if "Error opening file" not in str(error):
            raise
        raise ValueError(
            f"the written model cannot be read back from {str(path.parent)!r}: {error}; "
            "write it next to the source (its relative paths resolve from there)"
        ) from None
    rng = np.random.default_rng(0)
    shape = (EXPORT_STATES, robot.dof)
    states = [np.asarray(robot.reference) + rng.uniform(-1, 1, shape)]
    states += [rng.uniform(-3, 3, shape), rng.uniform(-10, 10, shape)]
    # a balanced robot's wrench may vanish at every state: compare to the gross scales
    robot_wrench, scales = _check_program()(robot, *states)
    written_wrench, _ = _check_program()(written, *states)
    for ours, theirs, scale in zip(robot_wrench, written_wrench, scales, strict=True):
        scale = max(float(scale), 1e-300)
        gap = float(np.max(np.abs(np.asarray(ours) - np.asarray(theirs))))
        if gap > EXPORT_RTOL * scale:
            _refuse_changed_counters(robot, written)
            raise ValueError(
                f"the written model's shaking wrench differs from the robot's by {gap:.3g} "
                f"(of {scale:.3g}): the robot was changed besides its counter-masses "
                "(with_body, eqx.tree_at) or is not the robot of this file"
            )


def _refuse_changed_counters(robot: MjcfRobot, written: MjcfRobot) -> None:
    """Raise ``ValueError`` naming the counter-masses whose mass or inertia (trace) MuJoCo
    changed when compiling the written file: a ``<compiler boundmass=… boundinertia=…>``
    (or ``balanceinertia``) raises small ones, a point mass's zero inertia to the bound
    (the export was refused as "the robot was changed")."""
    changed = []
    for name, _, _, mass, inertia in _counters(robot):
        i = written.mass_names().index(name)
        m, trace = float(written.mass[i]), float(np.trace(np.asarray(written.inertia[i])))
        if not (np.isclose(m, mass, rtol=1e-9) and np.isclose(trace, np.trace(inertia), 1e-9)):
            changed.append(
                f"{name}: mass {mass:.6g} -> {m:.6g} kg, inertia trace "
                f"{np.trace(inertia):.6g} -> {trace:.6g} kg m^2"
            )
    if changed:
        raise ValueError(
            f"MuJoCo changed counter-masses when compiling the written file ({'; '.join(changed)}):"
            " the file's <compiler boundmass/boundinertia/balanceinertia> raises small masses"
            " and inertias; give each counter-mass a mass and inertia of at least those"
            " bounds (add_counter_mass(..., inertia=...))"
        )


def export_balanced(source, robot: MjcfRobot, path=None, *, ignore_meshes: bool = False) -> str:
    """The model ``source`` with ``robot``'s counter-masses added (module doc).

    Args:
        source: the MJCF or URDF the robot was loaded from (text or path).
        robot: the robot with its counter-masses (e.g. ``balance(...).robot``).
        path: the file to write (default: none, the text is only returned). Relative
            mesh and include paths resolve from its directory, as from the source's.
        ignore_meshes: check the written model without its meshes (as
            :func:`~jaxbal._src.robots.mjcf_import.from_mjcf`); they stay in the text.

    Returns:
        The model's text with the counter-masses, in the source's format.

    Raises:
        ValueError: a robot without counter-masses, a carrying body not in the file, a
            name taken, or a written model whose shaking wrench is not the robot's.
    """
    if not robot.counter_names:
        raise ValueError("the robot has no counter-masses: nothing to export")
    text, source_path = _source_text(source)
    try:
        root = ET.fromstring(text, parser=ET.XMLParser(target=ET.TreeBuilder(insert_comments=True)))
    except ET.ParseError as error:
        raise ValueError(f"the model is not well-formed XML: {error}") from None
    if root.tag not in ("mujoco", "robot"):
        raise ValueError(f"not an MJCF (<mujoco>) or URDF (<robot>) model: <{root.tag}>")
    (_add_to_urdf if root.tag == "robot" else _add_to_mjcf)(root, robot)
    ET.indent(root)
    written = ET.tostring(root, encoding="unicode") + "\n"
    target = Path(path) if path is not None else None
    folder = (target or source_path or Path(tempfile.gettempdir()) / "x").parent
    folder.mkdir(parents=True, exist_ok=True)
    suffix = ".urdf" if root.tag == "robot" else ".xml"
    handle, temporary = tempfile.mkstemp(dir=folder, prefix=".jaxbal-export-", suffix=suffix)
    try:
        with os.fdopen(handle, "w") as file:
            file.write(written)
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(temporary, 0o666 & ~umask)  # as an ordinary new file (mkstemp: 0600)
        _check_same_wrench(robot, Path(temporary), ignore_meshes)
        if target is not None:
            os.replace(temporary, target)  # atomic: no half-written file
    finally:
        Path(temporary).unlink(missing_ok=True)
    return written
