"""Reading a mechanism from MuJoCo's compiler: MJCF or URDF -> structure and arrays.

The file is compiled by MuJoCo itself (``mujoco.MjModel.from_xml_string`` /
``from_xml_path``; URDF goes through the same compiler), so every default, unit
(``angle="degree"``), inertia from geoms, ``childclass`` and ``ref`` is resolved exactly
as MuJoCo resolves it. :func:`parse` then reads the compiled arrays: the body tree
(``body_parentid``, ``body_pos``, ``body_quat``), the inertials (``body_mass``,
``body_ipos``, ``body_iquat``, ``body_inertia``), the joints (``jnt_type``, ``jnt_axis``,
``jnt_pos``, ``jnt_bodyid``, ``qpos0``), the ``connect`` equalities (``eq_data`` or their
two sites), the joint equalities (:mod:`~jaxbal._src.robots.mjcf_couplings`) and the
actuated joints (``actuator_trnid``).

Supported: hinge, slide and ball joints on a fixed base (the worldbody), ``connect``
loop closures, joint couplings (gears, URDF mimic joints). Anything else that would
change the dynamics (free joints, tendons, weld and tendon equalities, inactive
equalities, actuators on non-joints or ball joints, mocap bodies,
flexes, gravity compensation, joint armature) raises a ``ValueError`` naming it:
nothing is silently dropped. Joint damping, springs and friction loss do not enter the
base reaction but would change the actuator torques: they are refused too, unless
``ignore_passive`` (then the torques are those without them). Contacts and joint limits
do not enter the inertial dynamics and are ignored (the ranges bound the solved joints).

References:
    MuJoCo XML reference, https://mujoco.readthedocs.io/en/stable/XMLreference.html
    (``body``, ``joint``, ``inertial``, ``equality/connect``, ``actuator``);
    MuJoCo API types, https://mujoco.readthedocs.io/en/stable/APIreference/APItypes.html
    (``mjModel`` fields); URDF in MuJoCo,
    https://mujoco.readthedocs.io/en/stable/modeling.html#urdf-extensions.
"""

from __future__ import annotations

from functools import partial
from pathlib import Path
from typing import NamedTuple

import numpy as np

from jaxbal._src.robots.mjcf_couplings import Couplings, parse_couplings

#: MuJoCo joint type codes (``mjtJoint``) -> jaxbal names.
JOINT_TYPES = {0: "free", 1: "ball", 2: "slide", 3: "hinge"}
#: random configurations used to find the fixed directions of a loop closure.
PROBES = 8
#: an eigenvalue below this fraction of the largest marks a fixed direction.
RANK_RTOL = 1e-10


class Parsed(NamedTuple):
    """A compiled MuJoCo model read into numpy arrays and static tuples.

    Bodies are MuJoCo's non-world bodies (ids ``1 … nbody−1``, parents before
    children); joints and ``qpos`` addresses are MuJoCo's.
    """

    body_names: tuple[str, ...]
    parents: tuple[int, ...]  # index into body_names, -1 = world
    moving: tuple[bool, ...]  # a joint on the path to the world
    body_pos: np.ndarray  # (nb, 3) origin in the parent frame [m]
    body_rot: np.ndarray  # (nb, 3, 3) orientation in the parent frame
    mass: np.ndarray  # (nb,) [kg]
    com: np.ndarray  # (nb, 3) in the body frame [m]
    inertia: np.ndarray  # (nb, 3, 3) about the COM, body frame [kg m^2]
    joint_names: tuple[str, ...]
    joint_types: tuple[str, ...]
    joint_body: tuple[int, ...]
    joint_qpos: tuple[int, ...]
    joint_range: tuple[tuple[float, float], ...]  # limited joints, else (-inf, inf)
    joint_axis: np.ndarray  # (nj, 3) unit, body frame
    joint_pos: np.ndarray  # (nj, 3) anchor, body frame [m]
    qpos0: np.ndarray  # (nq,) reference configuration (``ref``)
    connect_names: tuple[str, ...]
    connect_bodies: tuple[tuple[int, int], ...]  # -1 = world
    anchor1: np.ndarray  # (c, 3) in body 1's frame [m]
    anchor2: np.ndarray  # (c, 3) in body 2's frame [m]
    closure_rows: tuple[tuple[tuple[float, float, float], ...], ...]
    couplings: Couplings  # joint equalities (gears, URDF mimic joints)
    site_names: tuple[str, ...]
    site_body: tuple[int, ...]
    site_pos: np.ndarray  # (s, 3) in the body frame [m]
    motors: tuple[str, ...]  # joints carrying an actuator, in actuator order
    extent: float  # MuJoCo's model extent [m]


def text_or_path(source) -> tuple[str | None, Path | None]:
    """``(text, None)`` for XML text (it starts with ``<``), ``(None, path)`` for a file.

    Raises:
        ValueError: a path that is not a file.
    """
    if isinstance(source, str) and source.lstrip().startswith("<"):
        return source, None
    path = Path(source)
    if not path.is_file():
        raise ValueError(f"no such MJCF/URDF file: {str(path)!r}")
    return None, path


def load_model(source):
    """Compile ``source`` with MuJoCo: an ``MjModel``, XML text (MJCF or URDF) or a path.

    Raises:
        ValueError: malformed XML or a model MuJoCo refuses (its message included).
    """
    import mujoco

    if isinstance(source, mujoco.MjModel):
        return source
    text, path = text_or_path(source)
    try:
        if text is not None:
            return mujoco.MjModel.from_xml_string(text)
        return mujoco.MjModel.from_xml_path(str(path))
    except ValueError as error:
        hint = ""
        if "mjMINVAL" in str(error):  # MuJoCo's words for a body without mass
            hint = (" (a moving body has no mass: give it an <inertial> (URDF, MJCF) or "
                    "geoms with a density or mass, or weld it to a body that has one)")  # fmt: skip
        raise ValueError(f"MuJoCo could not compile the model: {error}{hint}") from None


def _name(model, kind, index: int, fallback: str) -> str:
    return getattr(model, kind)(index).name or f"{fallback}{index}"


def _quat_matrix(quat) -> np.ndarray:
    import mujoco

    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(quat, dtype=float))
    return matrix.reshape(3, 3)


def _refuse_passive(model) -> None:
    """``ValueError`` naming the first joint with a passive force MuJoCo applies (joint
    damping, a spring, friction loss; the option flags that disable them are honoured):
    the actuator torques would have to overcome it, jaxbal's leave it out."""
    import mujoco

    def enabled(flag):
        bit = getattr(mujoco.mjtDisableBit, flag, None)
        return bit is None or not model.opt.disableflags & int(bit)

    springs, dampers = enabled("mjDSBL_SPRING"), enabled("mjDSBL_DAMPER")
    friction = enabled("mjDSBL_FRICTIONLOSS")
    for d in range(model.nv):
        j = int(model.dof_jntid[d])
        forces = {
            "damping": model.dof_damping[d] if dampers else 0.0,
            "stiffness": model.jnt_stiffness[j] if springs else 0.0,
            "frictionloss": model.dof_frictionloss[d] if friction else 0.0,
        }
        named = ", ".join(f"{k} {v:g}" for k, v in forces.items() if v != 0)
        if named:
            raise ValueError(
                f"joint {_name(model, 'joint', j, 'joint')!r} has {named}: a passive joint "
                "force, which changes the actuator torques (not the base reaction) and "
                "which jaxbal's torques leave out; remove it, or pass ignore_passive=True "
                "(jaxbal balance: --ignore-passive)"
            )


def _refuse_unsupported(model, ignore_armature: bool, ignore_passive: bool) -> None:
    """``ValueError`` naming the first element jaxbal cannot represent exactly."""
    import mujoco

    if not ignore_passive:
        _refuse_passive(model)

    if model.ntendon:
        names = [_name(model, "tendon", i, "tendon") for i in range(model.ntendon)]
        raise ValueError(f"tendons are not supported: {names}")
    if getattr(model, "nflex", 0):
        raise ValueError(f"flexible bodies (flex) are not supported: {model.nflex} flex(es)")
    for b in range(1, model.nbody):
        name = _name(model, "body", b, "body")
        if model.body_mocapid[b] >= 0:
            raise ValueError(f"mocap body {name!r} is not supported (its motion is not a joint's)")
        if model.body_gravcomp[b] != 0:
            raise ValueError(f"body {name!r}: gravcomp is not supported")
    for j in range(model.njnt):
        if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_FREE):
            name = _name(model, "joint", j, "joint")
            raise ValueError(f"free joint {name!r} is not supported (jaxbal needs a fixed base)")
    for d in range(model.nv):
        if model.dof_armature[d] != 0 and not ignore_armature:
            name = _name(model, "joint", int(model.dof_jntid[d]), "joint")
            raise ValueError(
                f"joint {name!r} has armature {model.dof_armature[d]:g} (a rotor inertia "
                "without a body): model the rotor as a body, or pass ignore_armature=True "
                "(jaxbal balance: --ignore-armature)"
            )
    for e in range(model.neq):
        name = _name(model, "eq", e, "equality")
        if int(model.eq_type[e]) not in (
            int(mujoco.mjtEq.mjEQ_CONNECT),
            int(mujoco.mjtEq.mjEQ_JOINT),
        ):
            kind = mujoco.mjtEq(int(model.eq_type[e])).name.removeprefix("mjEQ_").lower()
            raise ValueError(
                f"equality {name!r} of type {kind!r} is not supported (only connect and joint)"
            )
        if not model.eq_active0[e]:
            raise ValueError(f"equality {name!r} is inactive; remove it or make it active")
    joint_transmissions = (int(mujoco.mjtTrn.mjTRN_JOINT), int(mujoco.mjtTrn.mjTRN_JOINTINPARENT))
    for a in range(model.nu):
        name = _name(model, "actuator", a, "actuator")
        if int(model.actuator_trntype[a]) not in joint_transmissions:
            kind = mujoco.mjtTrn(int(model.actuator_trntype[a])).name.removeprefix("mjTRN_").lower()
            raise ValueError(
                f"actuator {name!r} drives a {kind}; only joint actuators are supported"
            )
        joint = int(model.actuator_trnid[a, 0])
        if int(model.jnt_type[joint]) == int(mujoco.mjtJoint.mjJNT_BALL):
            raise ValueError(f"actuator {name!r} drives a ball joint; only hinges and slides")


def _connect(model, e: int, body_index):
    """Bodies ``(b1, b2)`` (indices, -1 = world) and anchors of connect ``e``."""
    import mujoco

    if int(model.eq_objtype[e]) == int(mujoco.mjtObj.mjOBJ_SITE):
        s1, s2 = int(model.eq_obj1id[e]), int(model.eq_obj2id[e])
        bodies = (int(model.site_bodyid[s1]), int(model.site_bodyid[s2]))
        anchors = (model.site_pos[s1], model.site_pos[s2])
    else:
        bodies = (int(model.eq_obj1id[e]), int(model.eq_obj2id[e]))
        anchors = (model.eq_data[e, 0:3], model.eq_data[e, 3:6])
    return tuple(body_index(b) for b in bodies), tuple(np.array(a, dtype=float) for a in anchors)


def _random_qpos(model, rng) -> np.ndarray:
    import mujoco

    qpos = model.qpos0.copy()
    for j in range(model.njnt):
        a = model.jnt_qposadr[j]
        if int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_HINGE):
            qpos[a] = rng.uniform(-np.pi, np.pi)
        elif int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_SLIDE):
            qpos[a] += rng.uniform(-1.0, 1.0) * max(model.stat.extent, 1e-3)
        else:
            quat = rng.normal(size=4)
            qpos[a : a + 4] = quat / np.linalg.norm(quat)
    return qpos


def _point_jacobians(model, points, seed: int = 0):
    """``(PROBES, len(points), 3, nv)`` Jacobians of body-fixed points ``(body id, local
    point)`` at random configurations (MuJoCo's ``mj_jac``)."""
    import mujoco

    rng = np.random.default_rng(seed)
    data = mujoco.MjData(model)
    out = np.zeros((PROBES, len(points), 3, model.nv))
    for k in range(PROBES):
        data.qpos[:] = _random_qpos(model, rng)
        mujoco.mj_kinematics(model, data)
        mujoco.mj_comPos(model, data)
        for i, (body, local) in enumerate(points):
            if body <= 0:
                continue
            world = data.xpos[body] + data.xmat[body].reshape(3, 3) @ local
            mujoco.mj_jac(model, data, out[k, i], None, world, body)
    return out


def fixed_directions(jacobians) -> tuple[np.ndarray, np.ndarray]:
    """Orthonormal ``(moving (3, r), fixed (3, 3 − r))`` directions of a point (or of a
    point difference) from its Jacobians ``(probes, 3, nv)`` at random configurations:
    a fixed direction is one along which it never moves (the normal of a planar
    mechanism's plane)."""
    gram = np.einsum("kin,kjn->ij", jacobians, jacobians)
    values, vectors = np.linalg.eigh(gram)
    free = values > RANK_RTOL * max(float(values[-1]), 1e-300)
    return vectors[:, free], vectors[:, ~free]


def _rows(moving: np.ndarray, fixed: np.ndarray) -> tuple[tuple[float, float, float], ...]:
    """Closure rows: the world axes if the fixed directions are world axes (a planar
    mechanism in a coordinate plane), else the orthonormal moving directions."""
    eye = np.eye(3)
    dropped = [i for i in range(3) if fixed.size and np.max(np.abs(fixed.T @ eye[i])) > 1 - 1e-9]
    if len(dropped) == fixed.shape[1]:
        chosen = [eye[i] for i in range(3) if i not in dropped]
    else:
        chosen = list(moving.T)
    return tuple(tuple(float(v) for v in row) for row in chosen)


def parse(model, ignore_armature: bool = False, ignore_passive: bool = False) -> Parsed:
    """Read a compiled ``MjModel`` (see the module docstring).

    Raises:
        ValueError: an unsupported element (named), a model without moving bodies (no
            bodies, or no joints), or a connect whose anchors are offset along a
            direction in which they can never move (it cannot close).
    """
    import mujoco

    _refuse_unsupported(model, ignore_armature, ignore_passive)
    nb = model.nbody - 1

    def body_index(b: int) -> int:
        return int(b) - 1  # world -> -1

    names = tuple(_name(model, "body", b, "body") for b in range(1, model.nbody))
    parents = tuple(body_index(model.body_parentid[b]) for b in range(1, model.nbody))
    has_joint = [model.body_jntnum[b] > 0 for b in range(1, model.nbody)]
    moving = []
    for i in range(nb):
        moving.append(has_joint[i] or (parents[i] >= 0 and moving[parents[i]]))
    if not any(moving):  # nothing to balance; numpy's einsum below failed on zero bodies
        what = "no bodies below the worldbody" if nb == 0 else f"no joints (bodies {list(names)})"
        raise ValueError(
            f"no moving bodies: the model has {what}; a mechanism needs a body moved by a "
            "hinge, slide or ball joint"
        )
    body_rot = np.array([_quat_matrix(model.body_quat[b]) for b in range(1, model.nbody)])
    inertial_rot = np.array([_quat_matrix(model.body_iquat[b]) for b in range(1, model.nbody)])
    inertia = np.einsum("nij,nj,nkj->nik", inertial_rot, model.body_inertia[1:], inertial_rot)

    connects = [
        e for e in range(model.neq) if int(model.eq_type[e]) == int(mujoco.mjtEq.mjEQ_CONNECT)
    ]
    connect_bodies, anchors1, anchors2, rows = [], [], [], []
    for e in connects:
        (b1, b2), (a1, a2) = _connect(model, e, body_index)
        connect_bodies.append((b1, b2))
        anchors1.append(a1)
        anchors2.append(a2)
        jac = _point_jacobians(model, [(b1 + 1, a1), (b2 + 1, a2)])
        moving_dirs, fixed = fixed_directions(jac[:, 0] - jac[:, 1])
        if fixed.size:
            data = mujoco.MjData(model)
            mujoco.mj_kinematics(model, data)
            ends = []
            for b, a in ((b1, a1), (b2, a2)):
                frame = (data.xpos[b + 1], data.xmat[b + 1].reshape(3, 3))
                ends.append(frame[0] + frame[1] @ a)
            gap = fixed.T @ (ends[0] - ends[1])
            if np.max(np.abs(gap)) > 1e-9 * max(model.stat.extent, 1.0):
                name = _name(model, "eq", e, "connect")
                raise ValueError(
                    f"connect {name!r} can never close: its anchors are {gap} m apart along "
                    f"the direction(s) {fixed.T.tolist()} in which they cannot move"
                )
        rows.append(_rows(moving_dirs, fixed))

    motors = []
    for a in range(model.nu):
        joint = _name(model, "joint", int(model.actuator_trnid[a, 0]), "joint")
        if joint not in motors:
            motors.append(joint)
    return Parsed(
        body_names=names,
        parents=parents,
        moving=tuple(bool(m) for m in moving),
        body_pos=np.array(model.body_pos[1:], dtype=float),
        body_rot=body_rot,
        mass=np.array(model.body_mass[1:], dtype=float),
        com=np.array(model.body_ipos[1:], dtype=float),
        inertia=inertia,
        joint_names=tuple(_name(model, "joint", j, "joint") for j in range(model.njnt)),
        joint_types=tuple(JOINT_TYPES[int(t)] for t in model.jnt_type),
        joint_body=tuple(body_index(b) for b in model.jnt_bodyid),
        joint_qpos=tuple(int(a) for a in model.jnt_qposadr),
        joint_range=tuple(
            (float(r[0]), float(r[1])) if limited else (-np.inf, np.inf)
            for limited, r in zip(model.jnt_limited, model.jnt_range, strict=True)
        ),
        joint_axis=np.array(model.jnt_axis, dtype=float).reshape(-1, 3),
        joint_pos=np.array(model.jnt_pos, dtype=float).reshape(-1, 3),
        qpos0=np.array(model.qpos0, dtype=float),
        connect_names=tuple(_name(model, "eq", e, "connect") for e in connects),
        connect_bodies=tuple(connect_bodies),
        anchor1=np.array(anchors1, dtype=float).reshape(-1, 3),
        anchor2=np.array(anchors2, dtype=float).reshape(-1, 3),
        closure_rows=tuple(rows),
        couplings=parse_couplings(model, partial(_name, model)),
        site_names=tuple(_name(model, "site", s, "site") for s in range(model.nsite)),
        site_body=tuple(body_index(b) for b in model.site_bodyid),
        site_pos=np.array(model.site_pos, dtype=float).reshape(-1, 3),
        motors=tuple(motors),
        extent=float(model.stat.extent),
    )
