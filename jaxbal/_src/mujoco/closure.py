"""MuJoCo C closes a closed chain's loops: positions, velocities and accelerations.

A :class:`~jaxbal._src.mujoco.tree.Tree` whose ``solved`` names some joints lets MuJoCo,
not jaxbal, decide where those joints are. The other joints are *prescribed* (their
``qpos, qvel, qacc`` come from the tree's ``coordinates``, e.g. the platform pose of a
parallel robot); the solved ones start from the tree's ``guess`` (a geometric rule
that picks the assembly mode, never jaxbal's inverse kinematics) and are found from the
model's own ``connect`` equalities, with MuJoCo's kinematics only:

* positions: Newton on the residual ``r(qpos) = Σ_k x_site1,k − x_site2,k`` (site
  positions from ``mj_kinematics``), Jacobian ``mj_jacSite``, minimum-norm steps over
  the solved dofs, applied with ``mj_integratePos`` (ball joints stay unit quaternions);
  a joint equality (gear, mimic) adds the row ``q1 − q1⁰ − p(q2 − q2⁰)`` of its
  polynomial ``p`` (``eq_data``), Jacobian ``(1, −p')``, ``J̇ v = −p'' v2²``;
* velocities: ``J_s v_s = −J_p v_p`` (minimum norm: a ball joint's spin about a bar's
  own axis, which the loops leave free, is zero);
* accelerations: ``J_s a_s = −J_p a_p − J̇ v`` with ``J̇ v`` from ``mj_jacDot``
  (exact, no finite differences).

So a base reaction computed on the result checks jaxbal's inverse kinematics, its
velocities and accelerations of every passive joint, and the layout of jaxbal's
kinematics against a model built from the geometric parameters.

References:
    MuJoCo API reference, ``mj_jacSite``, ``mj_jacDot``, ``mj_integratePos``,
    https://mujoco.readthedocs.io/en/stable/APIreference/APIfunctions.html
"""

from __future__ import annotations

from typing import NamedTuple

import mujoco
import numpy as np

#: Newton stops when the loop residual is below this times the model's size [m].
CLOSURE_RTOL = 1e-13
MAX_ITERATIONS = 60
_DOFS = {"hinge": 1, "slide": 1, "ball": 3, "free": 6}


class ClosureIndex(NamedTuple):
    """Where the solved joints sit in MuJoCo's vectors.

    Attributes:
        sites: ``(n_loops, 2)`` site ids of the ``connect`` equalities.
        dofs: ``(n_solved_dofs,)`` their indices in ``qvel``/``qacc``.
        qpos: their indices in ``qpos`` (a ball joint's four).
        scalar_qpos: ``qpos`` indices of the solved hinge/slide joints.
        hinge: ``(len(scalar_qpos),)`` True for a hinge (an angle, compared modulo 2π).
        scale: the model's size [m] (for the tolerance).
        couplings: ``(m, 4)`` ``qpos`` and dof addresses of each joint equality's
            joint1 and joint2 (``-1`` without joint2).
        polycoef: ``(m, 5)`` their polynomials; origins: ``(m, 2)`` their ``qpos0``.
    """

    sites: np.ndarray
    dofs: np.ndarray
    qpos: np.ndarray
    scalar_qpos: np.ndarray
    hinge: np.ndarray
    scale: float
    couplings: np.ndarray
    polycoef: np.ndarray
    origins: np.ndarray


def closure_index(model: mujoco.MjModel, solved: tuple[str, ...]) -> ClosureIndex:
    """Index the ``solved`` joints, the ``connect`` sites and the joint equalities of
    ``model``.

    Raises:
        ValueError: an unknown joint name, or an equality that is neither a
            site-to-site ``connect`` nor a joint equality (the kinds jaxbal writes).
    """
    dofs, positions, scalar, hinge = [], [], [], []
    for name in solved:
        joint = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        if joint < 0:
            raise ValueError(f"solved joint {name!r} is not a joint of the MuJoCo model")
        kind = mujoco.mjtJoint(model.jnt_type[joint]).name.removeprefix("mjJNT_").lower()
        start = int(model.jnt_dofadr[joint])
        dofs += range(start, start + _DOFS[kind])
        first = int(model.jnt_qposadr[joint])
        positions += range(first, first + (4 if kind == "ball" else _DOFS[kind]))
        if _DOFS[kind] == 1:
            scalar.append(int(model.jnt_qposadr[joint]))
            hinge.append(kind == "hinge")
    sites, couplings, polycoef, origins = [], [], [], []
    for k in range(model.neq):
        if model.eq_type[k] == mujoco.mjtEq.mjEQ_JOINT:
            pair = [int(model.eq_obj1id[k]), int(model.eq_obj2id[k])]
            couplings.append([a for j in pair for a in _addresses(model, j)])
            polycoef.append(np.array(model.eq_data[k, :5], dtype=float))
            origins.append([model.qpos0[model.jnt_qposadr[j]] if j >= 0 else 0.0 for j in pair])
            continue
        if model.eq_type[k] != mujoco.mjtEq.mjEQ_CONNECT or (
            model.eq_objtype[k] != mujoco.mjtObj.mjOBJ_SITE
        ):
            raise ValueError(
                f"equality {k} is not a site-to-site connect or a joint equality; cannot close it"
            )
        sites.append((int(model.eq_obj1id[k]), int(model.eq_obj2id[k])))
    scale = max(float(model.stat.extent), 1e-3)
    return ClosureIndex(
        sites=np.array(sites, dtype=int).reshape(-1, 2),
        dofs=np.array(dofs, dtype=int),
        qpos=np.array(positions, dtype=int),
        scalar_qpos=np.array(scalar, dtype=int),
        hinge=np.array(hinge, dtype=bool),
        scale=scale,
        couplings=np.array(couplings, dtype=int).reshape(-1, 4),
        polycoef=np.array(polycoef, dtype=float).reshape(-1, 5),
        origins=np.array(origins, dtype=float).reshape(-1, 2),
    )


def _addresses(model, joint: int) -> tuple[int, int]:
    """``(qpos, dof)`` address of a hinge or slide joint, ``(-1, -1)`` for none."""
    if joint < 0:
        return -1, -1
    return int(model.jnt_qposadr[joint]), int(model.jnt_dofadr[joint])


def _couplings(model, qpos, index: ClosureIndex):
    """``(r (m,), ∂r/∂v (m, nv), ∂²r/∂x² (m,))`` of the joint equalities at ``qpos``:
    ``r = y − y⁰ − p(x − x⁰)`` (the last: ``−p''`` at joint2, for ``J̇ v``)."""
    residual, jacobian, curvature = [], np.zeros((len(index.couplings), model.nv)), []
    for k, (q1, d1, q2, d2) in enumerate(index.couplings):
        a = index.polycoef[k]
        x = qpos[q2] - index.origins[k, 1] if q2 >= 0 else 0.0
        p = a[0] + x * (a[1] + x * (a[2] + x * (a[3] + x * a[4])))
        slope = a[1] + x * (2 * a[2] + x * (3 * a[3] + x * 4 * a[4]))
        residual.append(qpos[q1] - index.origins[k, 0] - p)
        jacobian[k, d1] += 1.0
        if d2 >= 0:
            jacobian[k, d2] -= slope
        curvature.append(-(2 * a[2] + x * (6 * a[3] + x * 12 * a[4])))
    return np.array(residual), jacobian, np.array(curvature)


def _residual_and_jacobian(model, data, index: ClosureIndex):
    """``r (3·loops + couplings,)`` [m, rad] and ``∂r/∂v`` ``(len(r), nv)`` at
    ``data.qpos``."""
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    residual, jacobian = [], []
    for s1, s2 in index.sites:
        jac1, jac2 = np.zeros((3, model.nv)), np.zeros((3, model.nv))
        mujoco.mj_jacSite(model, data, jac1, None, s1)
        mujoco.mj_jacSite(model, data, jac2, None, s2)
        residual.append(data.site_xpos[s1] - data.site_xpos[s2])
        jacobian.append(jac1 - jac2)
    coupled, rows, _ = _couplings(model, data.qpos, index)
    return np.concatenate([*residual, coupled]), np.concatenate([*jacobian, rows]).reshape(
        -1, model.nv
    )


def _bias(model, data, index: ClosureIndex) -> np.ndarray:
    """``J̇ v`` of the loop and coupling residuals at ``data.qpos, data.qvel`` [m/s²,
    rad/s²]."""
    mujoco.mj_comVel(model, data)
    rows = []
    for s1, s2 in index.sites:
        rates = []
        for site in (s1, s2):
            jac_dot = np.zeros((3, model.nv))
            body = int(model.site_bodyid[site])
            mujoco.mj_jacDot(model, data, jac_dot, None, data.site_xpos[site].copy(), body)
            rates.append(jac_dot @ data.qvel)
        rows.append(rates[0] - rates[1])
    _, _, curvature = _couplings(model, data.qpos, index)
    followed = np.array([data.qvel[d2] if d2 >= 0 else 0.0 for *_, d2 in index.couplings])
    return np.concatenate([*rows, curvature * followed**2])


def _solve(matrix, rhs, what: str) -> np.ndarray:
    solution = np.linalg.lstsq(matrix, rhs, rcond=None)[0]
    miss = np.max(np.abs(matrix @ solution - rhs), initial=0.0)
    if miss > 1e-8 * np.max(np.abs(rhs), initial=0.0):
        raise ValueError(
            f"MuJoCo cannot close the loops ({what}): the solved joints cannot follow the "
            f"prescribed ones (a singular configuration?); residual {miss:.3g}"
        )
    return solution


def close_loops(model, data, index: ClosureIndex, qpos, qvel, qacc):
    """MuJoCo's ``(qpos, qvel, qacc)`` with the solved joints closing every loop.

    Args:
        model, data: a compiled model and a work ``MjData``.
        index: from :func:`closure_index`.
        qpos: ``(nq,)`` prescribed joints exact, solved joints at their initial guess.
        qvel, qacc: ``(nv,)`` prescribed entries exact (solved entries are ignored).

    Raises:
        ValueError: Newton does not reach :data:`CLOSURE_RTOL`, or the loops are
            singular for the solved joints.
    """
    qpos, qvel, qacc = (np.array(a, dtype=float) for a in (qpos, qvel, qacc))
    solved = index.dofs
    tolerance = CLOSURE_RTOL * index.scale
    residual = np.inf
    for _ in range(MAX_ITERATIONS):
        data.qpos[:] = qpos
        residual_vector, jacobian = _residual_and_jacobian(model, data, index)
        residual = np.max(np.abs(residual_vector), initial=0.0)
        if residual <= tolerance:
            break
        step = np.zeros(model.nv)
        step[solved] = np.linalg.lstsq(jacobian[:, solved], -residual_vector, rcond=None)[0]
        mujoco.mj_integratePos(model, qpos, step, 1.0)
    else:
        raise ValueError(
            f"MuJoCo could not close the loops from the guess: residual {residual:.3g} m after "
            f"{MAX_ITERATIONS} Newton steps (an unreachable pose?)"
        )
    qvel[solved], qacc[solved] = 0.0, 0.0
    qvel[solved] = _solve(jacobian[:, solved], -jacobian @ qvel, "velocities")
    data.qvel[:] = qvel
    bias = _bias(model, data, index)
    qacc[solved] = _solve(jacobian[:, solved], -(jacobian @ qacc + bias), "accelerations")
    return qpos, qvel, qacc


def position_gap(index: ClosureIndex, qpos, reference) -> float:
    """Largest ``|qpos − reference|`` over the solved hinge (modulo 2π) [rad] and slide
    [m] joints."""
    gap = np.asarray(qpos)[index.scalar_qpos] - np.asarray(reference)[index.scalar_qpos]
    gap = np.where(index.hinge, np.angle(np.exp(1j * gap)), gap)
    return float(np.max(np.abs(gap), initial=0.0))
