"""Edits of an MJCF / URDF model before MuJoCo compiles it (``mujoco.MjSpec``).

Two things a user's own file often lacks or has too much of:

* **Mesh files not at hand** (a vendor's URDF with ``package://`` paths, a MuJoCo
  Menagerie model copied without its ``assets/``): with ``ignore_meshes`` the mesh geoms
  and mesh assets are left out. The base reactions need only each body's mass, COM and
  inertia, which then come from its ``<inertial>`` element; a moving body whose inertia
  MuJoCo would compute *from* its mesh geoms (no ``<inertial>``, or
  ``inertiafromgeom="true"``) is refused, named, since dropping the mesh would change it.
* **No site** (a URDF has none: its end-effector is a link): ``end_effector_body``
  adds a site at a point fixed in a body (its origin plus ``end_effector_offset`` in
  its frame). A URDF link joined by a fixed joint is fused into its parent by MuJoCo;
  the site is added before that, so it keeps the link's frame.

References:
    MuJoCo ``mjSpec`` API, https://mujoco.readthedocs.io/en/stable/programming/modeledit.html;
    MuJoCo's URDF import, https://mujoco.readthedocs.io/en/stable/modeling.html#urdf-extensions.
"""

from __future__ import annotations

import math

import numpy as np

from jaxbal._src.robots.mjcf_parse import load_model, text_or_path

__all__ = ["MESH_HINT", "compile_model"]

#: appended to MuJoCo's error when a file it could not open looks like a mesh.
MESH_HINT = (
    " (a mesh file is missing: ignore_meshes=True, or --ignore-meshes, leaves the mesh "
    "geoms out; masses and inertias then come from the <inertial> elements)"
)
_MESH_SUFFIXES = (".stl", ".obj", ".msh", ".dae", ".ply")


def _with_hint(error: ValueError) -> ValueError:
    text = str(error)
    if "Error opening file" in text and any(s in text.lower() for s in _MESH_SUFFIXES):
        return ValueError(text + MESH_HINT)
    return error


def _spec(source):
    import mujoco

    if isinstance(source, mujoco.MjModel):
        raise ValueError(
            "ignore_meshes and end_effector_body edit the model before it compiles: pass "
            "the XML text or the file's path, not an MjModel"
        )
    text, path = text_or_path(source)
    try:
        return (
            mujoco.MjSpec.from_string(text) if path is None else mujoco.MjSpec.from_file(str(path))
        )
    except ValueError as error:
        raise ValueError(f"MuJoCo could not read the model: {error}") from None


def _drop_meshes(spec) -> None:
    """Delete the mesh geoms and mesh assets of ``spec``; refuse (naming them) moving
    bodies whose inertia MuJoCo would compute from those geoms."""
    import mujoco

    kinds = mujoco.mjtInertiaFromGeom
    always = spec.compiler.inertiafromgeom == kinds.mjINERTIAFROMGEOM_TRUE
    auto = spec.compiler.inertiafromgeom == kinds.mjINERTIAFROMGEOM_AUTO
    low, high = (int(g) for g in spec.compiler.inertiagrouprange)
    refused, doomed = [], []
    for body in spec.bodies:
        meshes = [g for g in body.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH]
        doomed += meshes
        if body.name == spec.worldbody.name or not meshes:
            continue
        from_geoms = always or (auto and not body.explicitinertial)
        weighed = [
            g
            for g in meshes
            if low <= g.group <= high and (g.mass > 0 if not math.isnan(g.mass) else g.density > 0)
        ]
        if from_geoms and weighed:
            refused.append(body.name)
    if refused:
        raise ValueError(
            f"ignore_meshes: bodies {refused} take their mass and inertia from mesh geoms "
            "(no <inertial> element): give them <inertial> elements, or the mesh files"
        )
    for geom in doomed:
        spec.delete(geom)
    for mesh in list(spec.meshes):
        spec.delete(mesh)


def _add_site(spec, body: str, offset) -> str:
    """Add a site at ``offset`` (body frame) in ``body``; return its name (the body's,
    unless a site already has it)."""
    found = spec.body(body)
    if found is None or body == spec.worldbody.name:
        names = [b.name for b in spec.bodies if b.name != spec.worldbody.name]
        raise ValueError(f"end_effector_body: unknown body {body!r}; bodies: {names}")
    point = np.asarray(offset, dtype=float)
    if point.shape != (3,) or not np.all(np.isfinite(point)):
        raise ValueError(f"end_effector_offset must be 3 finite numbers [m], got {offset!r}")
    taken = {s.name for s in spec.sites}
    name = body if body not in taken else f"{body}_end_effector"
    found.add_site(name=name, pos=point.tolist())
    return name


def compile_model(
    source, *, ignore_meshes: bool = False, end_effector_body=None, end_effector_offset=None
):
    """``(MjModel, site name or None)``: ``source`` compiled, edited as the module doc says.

    Args:
        source: XML text (MJCF or URDF), a path, or an ``MjModel`` (no edits then).
        ignore_meshes: leave the mesh geoms and assets out.
        end_effector_body: add a site in this body (a URDF link) and name it.
        end_effector_offset: ``(3,)`` the site's position in the body's frame [m]
            (default: its origin).

    Raises:
        ValueError: a file MuJoCo cannot read or compile (a missing mesh file: with the
            remedy), an unknown body, a body whose inertia comes from its meshes.
    """
    if end_effector_offset is not None and end_effector_body is None:
        raise ValueError("end_effector_offset needs end_effector_body")
    if not ignore_meshes and end_effector_body is None:
        try:
            return load_model(source), None
        except ValueError as error:
            raise _with_hint(error) from None
    spec = _spec(source)
    if ignore_meshes:
        _drop_meshes(spec)
    site = None
    if end_effector_body is not None:
        offset = (0.0, 0.0, 0.0) if end_effector_offset is None else end_effector_offset
        site = _add_site(spec, end_effector_body, offset)
    try:
        return spec.compile(), site
    except ValueError as error:
        raise _with_hint(ValueError(f"MuJoCo could not compile the model: {error}")) from None
