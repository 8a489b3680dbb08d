"""``from_mjcf`` / ``from_urdf``: build an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot`.

The file is compiled by MuJoCo and read by :mod:`~jaxbal._src.robots.mjcf_parse`; this
module resolves the user's choices (actuated and independent joints, end-effector site,
pose components, payload body) from names to indices, with errors that list the valid
names.

References:
    MuJoCo XML reference, https://mujoco.readthedocs.io/en/stable/XMLreference.html;
    MuJoCo's URDF import, https://mujoco.readthedocs.io/en/stable/modeling.html#urdf-extensions.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from jaxbal._src.robots.mjcf_axes import dependent_axes, pose_axes
from jaxbal._src.robots.mjcf_parse import parse
from jaxbal._src.robots.mjcf_robot import MjcfRobot
from jaxbal._src.robots.mjcf_spec import compile_model

__all__ = ["from_mjcf", "from_urdf"]


def _names(value) -> tuple[str, ...] | None:
    """``None``, a comma-separated string or a sequence of names -> tuple of names."""
    if value is None:
        return None
    if isinstance(value, str):
        return tuple(v.strip() for v in value.split(",") if v.strip())
    return tuple(value)


def _coordinates(parsed, names: Sequence[str], what: str) -> tuple[int, ...]:
    """``qpos`` indices of hinge/slide joints named ``names``."""
    indices = []
    for name in names:
        if name not in parsed.joint_names:
            raise ValueError(f"{what}: unknown joint {name!r}; joints: {list(parsed.joint_names)}")
        j = parsed.joint_names.index(name)
        if parsed.joint_types[j] == "ball":
            raise ValueError(f"{what}: {name!r} is a ball joint; only hinges and slides")
        indices.append(parsed.joint_qpos[j])
    if len(set(indices)) != len(indices):
        raise ValueError(f"{what}: repeated joints in {list(names)}")
    return tuple(indices)


def _reference(model, parsed, keyframe: str | None) -> np.ndarray:
    """``qpos0``, or the ``qpos`` of the model's ``<key>`` named ``keyframe``."""
    if keyframe is None:
        return parsed.qpos0
    import mujoco

    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) for k in range(model.nkey)]
    if keyframe not in names:
        raise ValueError(f"unknown keyframe {keyframe!r}; keyframes: {names}")
    return np.array(model.key_qpos[names.index(keyframe)], dtype=float)


def _moving_index(parsed, moving: tuple[int, ...], name: str, what: str) -> int:
    if name not in parsed.body_names:
        raise ValueError(f"{what}: unknown body {name!r}; bodies: {list(parsed.body_names)}")
    i = parsed.body_names.index(name)
    if i not in moving:
        raise ValueError(f"{what}: body {name!r} is fixed to the base (no joint moves it)")
    return moving.index(i)


def from_mjcf(
    source,
    *,
    actuated=None,
    independent=None,
    end_effector_site: str | None = None,
    pose_components: Sequence[int] | None = None,
    ik_free=None,
    payload_body: str | None = None,
    ignore_armature: bool = False,
    ignore_passive: bool = False,
    keyframe: str | None = None,
    end_effector_body: str | None = None,
    end_effector_offset=None,
    ignore_meshes: bool = False,
) -> MjcfRobot:
    """A jaxbal robot from an MJCF (or URDF) mechanism: XML text, a path or an ``MjModel``.

    Args:
        source: the model (see :func:`~jaxbal._src.robots.mjcf_parse.load_model`).
        actuated: the actuated joints (names, or ``"j1,j2"``); default: the joints that
            carry ``<actuator>`` elements, or every hinge/slide of a serial mechanism
            but the coupled ones (``joint1`` of a joint equality, a URDF mimic joint).
        independent: the independent joints; default: ``actuated`` for a closed chain
            (connects), every hinge/slide but the coupled ones for a serial mechanism. A
            redundantly actuated mechanism (the DUAL-V) names fewer independent than
            actuated joints.
        end_effector_site: the site whose position is the end-effector pose (default:
            the model's only site on a moving body, if it has exactly one: a marker on
            the base is never picked).
        pose_components: world axes of the site position in the pose (default: the
            first axes along which it moves independently, at most as many as
            independent joints: ``(0, 1)`` for a planar mechanism in the x-y plane,
            ``(0, 2)`` in the x-z plane or in a vertical plane yawed about z, whose x
            and y are proportional). Axes it cannot move along independently are
            refused. They are also the COM components planning steers
            (``robot.com_components``).
        ik_free: independent joints whose values complete the pose when there are more
            independent joints than pose components (default: the last independent
            ones). Given (or with ``pose_components`` given), the pose must have as
            many coordinates as the mechanism has freedoms.
        payload_body: a moving body whose mass is the design variable ``payload``.
        ignore_armature: accept joint armature (MuJoCo's rotor inertia, which has no
            base reaction) and leave it out; by default it is refused.
        ignore_passive: accept joint damping, springs and friction loss (passive joint
            forces: no base reaction, but the motors would overcome them) and leave them
            out of the actuator torques; by default they are refused.
        keyframe: a ``<key>`` of the model whose ``qpos`` is the robot's ``reference``,
            the start of its Newton solves (picks the assembly mode; default: the
            model's ``qpos0``, often an arm drawn straight, a singular configuration).
        end_effector_body: instead of a site, a body (a URDF link, fused or not) whose
            origin, plus ``end_effector_offset`` ``(3,)`` [m] in its frame, is the
            end-effector point (a site of that name is added).
        ignore_meshes: leave mesh geoms and assets out (mesh files not at hand): the
            inertias come from the ``<inertial>`` elements
            (:mod:`~jaxbal._src.robots.mjcf_spec`).

    Returns:
        An :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot`.

    Raises:
        ValueError: a file MuJoCo cannot compile, an unsupported element (named), a
            model without moving bodies, an unknown or unsuitable name (the message
            lists the valid ones), ``pose_components`` / ``ik_free`` that cannot make
            a regular pose (dependent axes, a dependent joint, a count other than the
            mechanism's freedoms; the message names the option).
    """
    if end_effector_body is not None and end_effector_site is not None:
        raise ValueError("give end_effector_site or end_effector_body, not both")
    model, added = compile_model(
        source,
        ignore_meshes=ignore_meshes,
        end_effector_body=end_effector_body,
        end_effector_offset=end_effector_offset,
    )
    end_effector_site = added or end_effector_site
    parsed = parse(model, ignore_armature=ignore_armature, ignore_passive=ignore_passive)
    moving = tuple(i for i, m in enumerate(parsed.moving) if m)
    kinds = zip(parsed.joint_names, parsed.joint_types, strict=True)
    hinges = tuple(name for name, kind in kinds if kind != "ball")
    closed = bool(parsed.connect_names)
    coupled = {parsed.joint_names[j1] for j1, _ in parsed.couplings.joints}
    if coupled:  # a coupled joint (gear, mimic) follows another: not independent
        hinges = tuple(name for name in hinges if name not in coupled)
    actuated = _names(actuated)
    if actuated is None:
        actuated = parsed.motors or (None if closed else hinges)
        if actuated is None:
            raise ValueError(
                "closed chain without actuators: name the actuated joints (actuated=...); "
                f"joints: {list(parsed.joint_names)}"
            )
    actuated_q = _coordinates(parsed, actuated, "actuated")
    independent = _names(independent)
    if independent is None:
        independent = actuated if closed else hinges
    independent_q = _coordinates(parsed, independent, "independent")

    site_body, site_pos, components, free = -1, np.zeros(3), (), ()
    if end_effector_site is None:
        end_effector_site = _only_moving_site(parsed, moving)
    if end_effector_site is not None:
        if end_effector_site not in parsed.site_names:
            raise ValueError(
                f"unknown site {end_effector_site!r}; sites: {list(parsed.site_names)}"
            )
        s = parsed.site_names.index(end_effector_site)
        site_body, site_pos = parsed.site_body[s], parsed.site_pos[s]
        if site_body not in moving:
            raise ValueError(f"site {end_effector_site!r} is on a body fixed to the base")
        if pose_components is None:
            components = pose_axes(model, s, len(independent_q))
        else:
            components = _given_components(model, s, pose_components, end_effector_site)
        free_names = _names(ik_free)
        if free_names is None:
            extra = max(len(independent_q) - len(components), 0)
            free = independent_q[len(independent_q) - extra :]
        else:
            free = _coordinates(parsed, free_names, "ik_free")
            _check_free(parsed, free, independent_q)
        if pose_components is not None or free_names is not None:
            _check_pose_count(parsed, components, free)
    payload = None
    if payload_body is not None:
        payload = _moving_index(parsed, moving, payload_body, "payload_body")
    moving_array = np.asarray(moving, dtype=int)
    refs = np.array(
        [
            parsed.qpos0[a] if t != "ball" else 0.0
            for a, t in zip(parsed.joint_qpos, parsed.joint_types, strict=True)
        ]
    )
    body_joints = tuple(
        tuple(j for j, b in enumerate(parsed.joint_body) if b == i)
        for i in range(len(parsed.body_names))
    )
    return MjcfRobot(
        body_pos=jnp.asarray(parsed.body_pos),
        body_rot=jnp.asarray(parsed.body_rot),
        mass=jnp.asarray(parsed.mass[moving_array]),
        com=jnp.asarray(parsed.com[moving_array]).reshape(-1, 3),
        inertia=jnp.asarray(parsed.inertia[moving_array]).reshape(-1, 3, 3),
        joint_axis=jnp.asarray(parsed.joint_axis),
        joint_pos=jnp.asarray(parsed.joint_pos),
        joint_ref=jnp.asarray(refs, dtype=float).reshape(-1),
        anchor1=jnp.asarray(parsed.anchor1),
        anchor2=jnp.asarray(parsed.anchor2),
        site_pos=jnp.asarray(site_pos, dtype=float),
        reference=jnp.asarray(_reference(model, parsed, keyframe)),
        counter_mass=jnp.zeros(0),
        counter_position=jnp.zeros((0, 3)),
        counter_inertia=jnp.zeros((0, 3, 3)),
        coupling_coef=jnp.asarray(parsed.couplings.coef),
        body_names=parsed.body_names,
        parents=parsed.parents,
        body_joints=body_joints,
        moving_bodies=moving,
        joint_names=parsed.joint_names,
        joint_types=parsed.joint_types,
        joint_qpos=parsed.joint_qpos,
        joint_range=parsed.joint_range,
        connect_names=parsed.connect_names,
        connect_bodies=parsed.connect_bodies,
        closure_rows=parsed.closure_rows,
        coupling_names=parsed.couplings.names,
        coupling_joints=parsed.couplings.joints,
        site_name=end_effector_site,
        site_body=site_body,
        pose_components=components,
        ik_free=free,
        independent_coordinates=independent_q,
        actuated_coordinates=actuated_q,
        counter_bodies=(),
        counter_names=(),
        payload_body=payload,
    )


def _only_moving_site(parsed, moving: tuple[int, ...]) -> str | None:
    """The default end-effector site: the model's only site on a moving body, if there
    is exactly one. A site on the base (a ground marker) is never the end effector:
    auto-picked, it made the model impossible to load."""
    names = [n for n, b in zip(parsed.site_names, parsed.site_body, strict=True) if b in moving]
    return names[0] if len(names) == 1 else None


def _given_components(model, site: int, given, site_name: str) -> tuple[int, ...]:
    """A user's ``pose_components``: distinct world axes along which the site moves
    independently (else every solve of the pose is singular; refused here, at load,
    rather than as a Newton failure at the first move)."""
    components = tuple(int(c) for c in given)
    axes = set(components)
    if not components or not axes <= {0, 1, 2} or len(axes) != len(components):
        raise ValueError(f"pose_components must be distinct axes 0, 1, 2; got {components}")
    if dependent_axes(model, site, components):
        names = ", ".join("xyz"[c] for c in components)
        choice = pose_axes(model, site, len(components))
        raise ValueError(
            f"pose_components {components}: the site {site_name!r} cannot move along the "
            f"world axes ({names}) independently (it never moves along one, or they are "
            f"proportional), so every solve of the pose is singular; independent axes: "
            f"pose_components={choice}"
        )
    return components


def _check_free(parsed, free: tuple[int, ...], independent_q: tuple[int, ...]) -> None:
    """``ik_free`` joints must be independent coordinates: a closed chain's dependent
    joint is fixed by the loop closures, so its value cannot complete the pose."""
    for i in free:
        if i not in independent_q:
            name = parsed.joint_names[parsed.joint_qpos.index(i)]
            independent = [parsed.joint_names[parsed.joint_qpos.index(j)] for j in independent_q]
            raise ValueError(
                f"ik_free: {name!r} is not an independent joint (the loop closures fix "
                f"it); name independent joints: {independent}"
            )


def _check_pose_count(parsed, components: tuple[int, ...], free: tuple[int, ...]) -> None:
    """The pose (``pose_components`` then ``ik_free``) must have as many coordinates as
    the mechanism has freedoms (``dof`` minus the loop-closure equations): the
    inverse kinematics is a square Newton solve. Checked at load, naming both options,
    instead of a count mismatch worded for the loop closures at the first solve."""
    closures = sum(len(rows) for rows in parsed.closure_rows) + len(parsed.couplings.names)
    closures += parsed.joint_types.count("ball")
    freedoms = len(parsed.qpos0) - closures
    count = len(components) + len(free)
    if count != freedoms:
        free_names = [parsed.joint_names[parsed.joint_qpos.index(i)] for i in free]
        fix = "fewer" if count > freedoms else "more"
        raise ValueError(
            f"pose_components {components} and ik_free {free_names} give {count} pose "
            f"coordinates, but the mechanism has {freedoms} freedoms ({len(parsed.qpos0)} "
            f"coordinates, {closures} loop-closure equations): give {fix} "
            "pose_components or ik_free joints"
        )


def from_urdf(source, **options) -> MjcfRobot:
    """A jaxbal robot from a URDF (text or path), through MuJoCo's URDF compiler.

    MuJoCo fuses links joined by fixed joints (its ``fusestatic`` default for URDF) and
    fixes the root link to the world; ``options`` are those of :func:`from_mjcf`. A URDF
    has no sites: name the end-effector link with ``end_effector_body`` (e.g. a tool
    link on a fixed joint; ``end_effector_offset`` for a point off its origin), and a
    URDF whose mesh files are not at hand loads with ``ignore_meshes=True``.

    Raises:
        ValueError: text that is not a ``<robot>`` document, or as :func:`from_mjcf`.
    """
    if isinstance(source, str) and source.lstrip().startswith("<"):
        if "<robot" not in source:
            raise ValueError("URDF text must have a <robot> root element")
    return from_mjcf(source, **options)
