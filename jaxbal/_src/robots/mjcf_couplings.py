"""Joint couplings of an MJCF / URDF mechanism: gears, belts, URDF ``<mimic>`` joints.

MuJoCo's ``<equality><joint joint1="b" joint2="a" polycoef="a0 a1 a2 a3 a4"/>`` (and a
URDF ``<mimic joint="a" multiplier="k" offset="c"/>`` on joint ``b``, which MuJoCo's
URDF compiler turns into one) holds::

    q_b − q_b⁰ = a0 + a1 (q_a − q_a⁰) + a2 (q_a − q_a⁰)² + a3 (q_a − q_a⁰)³ + a4 (q_a − q_a⁰)⁴

with ``q⁰`` the joints' reference values (``ref``, MuJoCo's ``qpos0``); without
``joint2`` it fixes ``q_b = q_b⁰ + a0``. jaxbal treats each coupling as one more
closure equation ``Φ(q) = 0`` of the mechanism, beside the loop closures of its
``connect``\\ s: the coupled joint is a dependent coordinate, solved with the others
(Newton with implicit differentiation), and its rates follow exactly. This is how a
counter-rotating inertia geared to a link (a shaking-moment balancer) is modelled; the
coefficients are array leaves of the robot, so a gear ratio can be differentiated.

References:
    MuJoCo XML reference, ``equality/joint``,
    https://mujoco.readthedocs.io/en/stable/XMLreference.html#equality-joint;
    Arakelian & Smith (2005), J. Mech. Design 127(2), §3 (counter-rotations for
    shaking-moment balancing).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

__all__ = ["Couplings", "coupling_residuals", "parse_couplings"]


class Couplings(NamedTuple):
    """The joint equalities of a model.

    Attributes:
        names: one per coupling (MuJoCo's name, else ``"equality<k>"``).
        joints: ``(joint1, joint2)`` joint indices; ``joint2 = -1`` when absent.
        coef: ``(n, 5)`` the polynomial coefficients ``a0 … a4`` [SI: rad or m per
            rad or m to the power].
    """

    names: tuple[str, ...]
    joints: tuple[tuple[int, int], ...]
    coef: np.ndarray


def parse_couplings(model, name) -> Couplings:
    """The joint equalities of a compiled ``MjModel`` (``name(kind, index, fallback)``
    gives an element's name).

    Raises:
        ValueError: a coupling of a ball joint (named).
    """
    import mujoco

    names, joints, coef = [], [], []
    for e in range(model.neq):
        if int(model.eq_type[e]) != int(mujoco.mjtEq.mjEQ_JOINT):
            continue
        pair = (int(model.eq_obj1id[e]), int(model.eq_obj2id[e]))
        for j in pair:
            if j >= 0 and int(model.jnt_type[j]) == int(mujoco.mjtJoint.mjJNT_BALL):
                raise ValueError(
                    f"joint equality {name('eq', e, 'equality')!r} couples the ball joint "
                    f"{name('joint', j, 'joint')!r}; only hinges and slides can be coupled"
                )
        names.append(name("eq", e, "equality"))
        joints.append(pair)
        coef.append(np.array(model.eq_data[e, :5], dtype=float))
    return Couplings(tuple(names), tuple(joints), np.array(coef, dtype=float).reshape(-1, 5))


def coupling_residuals(robot, q):
    """``(n,)`` residuals of the robot's joint couplings at ``q`` [rad or m] (module doc)."""
    pieces = []
    for k, (j1, j2) in enumerate(robot.coupling_joints):
        coef = robot.coupling_coef[k]
        y = q[robot.joint_qpos[j1]] - robot.joint_ref[j1]
        x = q[robot.joint_qpos[j2]] - robot.joint_ref[j2] if j2 >= 0 else jnp.zeros(())
        polynomial = coef[0] + x * (coef[1] + x * (coef[2] + x * (coef[3] + x * coef[4])))
        pieces.append(y - polynomial)
    return jnp.stack(pieces) if pieces else jnp.zeros((0,))
