"""Kinematic trees of the jaxbal robots for MuJoCo (see :mod:`jaxbal.mjcf`).

Each builder describes a robot's joints *from its geometric parameters* (link
lengths, joint axes), independently of the robot's own ``body_frames``; only the
mass properties are shared. Every MuJoCo body frame is the frame of the jaxbal body
of the same name, so mass leaves flow into the model unchanged.

=================  ===========================================  ======================
robot              MuJoCo tree                                  qpos from jaxbal q
=================  ===========================================  ======================
``PlanarArm``      link k on a z-hinge at the tip of link k-1;  ``qpos = q`` (relative
(2R, 3R)           counterweight k welded to link k; payload    joint angles [rad])
                   welded at the tip of link n
``Scara``          link1, link2 on z-hinges; at O3 the          ``(θ1, θ2, −d4, θ3,
                   vertical counterweight on a z-slide and the  d4)``
                   end-effector on a z-hinge + z-slide
                   (payload, counter-mass 3 welded to it)
``DualV``          per arm: link i1 on a z-hinge at A_i (brass  ``(θ_i1, θ_i2 − θ_i1)``
(closed chain)     and tuning counter-masses, rotor welded),    per arm, then
                   link i2 on a z-hinge at B_i; the platform    ``(x5, y5, θ5)``
                   on x, y slides + z-hinge; ``connect`` C_i
``Orthoglide``     slider i on a slide along e_i; its           ``(ρ, Q_1..Q_3, p)``,
(closed chain)     parallelogram on a ball joint at B_i; the    Q_i the minimal
                   platform P on x, y, z slides; ``connect``    rotation −e_i → P−B_i
                   parallelogram end = P                        (quaternion)
=================  ===========================================  ======================

Any other robot can use :func:`prescribed_tree` (less independent: kinematics from
jaxbal's own ``body_frames``).

The closed chains are opened at the platform joints and closed again by ``connect``
equality constraints; jaxbal's inverse kinematics supplies every coordinate.

References:
    Briot, Arakelian & Le Baron (2012), §3.1-3.2 (planar 2R and 3R arms).
    Arakelian & Briot (2008), Fig 3, eqs (4)-(6) (SCARA).
    van der Wijk, Krut, Pierrot & Herder (2013), Fig 2, eqs (1), (9) (DUAL-V).
    Geng, Arakelian, Chablat & Lemoine (2021), eq (1) (Orthoglide).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._linalg import vee
from jaxbal.mjcf import Connect, Joint, Tree, TreeBody, _matrix_to_quat, register_tree
from jaxbal.robot import Robot
from jaxbal.robots.planar_arm import PlanarArm

Z = (0.0, 0.0, 1.0)


def _vec(*values) -> tuple[float, ...]:
    """Plain Python floats (tree fields are static: no numpy scalars)."""
    return tuple(float(v) for v in np.ravel(np.asarray(values, dtype=float)))


# Coordinate maps are module-level functions (not closures), so equal trees compare
# equal and jitted state maps are reused across calls (see jaxbal.mjx).


def _identity(q):
    return q


def _scara_coordinates(q):
    return jnp.stack([q[0], q[1], -q[3], q[2], q[3]])


def _dual_v_coordinates(q):
    arms = jnp.stack([q[0:4], q[4:8] - q[0:4]], -1).reshape(-1)
    return jnp.concatenate([arms, q[8:11]])


def _orthoglide_coordinates(q):
    rho, p = q[:3], q[3:]
    eye = jnp.eye(3)
    pieces = []
    for i in range(3):
        pieces += [rho[i : i + 1], _minimal_rotation_quat(-eye[i], p - rho[i] * eye[i])]
    return jnp.concatenate(pieces + [p])


@register_tree(PlanarArm)
def planar_arm_tree(robot: PlanarArm) -> Tree:
    """Serial chain of z-hinges; MuJoCo joint k is the paper's relative angle ``q_k``.

    Link k's frame has its origin at joint k and its x axis along the link, exactly
    the frame of :meth:`PlanarArm.body_frames`; counterweight k shares that frame and
    the payload frame sits at the tip of link n.
    """
    lengths = np.asarray(robot.lengths, dtype=float)
    n = lengths.shape[0]
    bodies = []
    for k in range(n):
        parent = None if k == 0 else f"link{k}"
        pos = (0.0, 0.0, 0.0) if k == 0 else (float(lengths[k - 1]), 0.0, 0.0)
        bodies.append(
            TreeBody(
                name=f"link{k + 1}",
                parent=parent,
                pos=pos,
                joints=(Joint(f"q{k + 1}", "hinge", (0.0, 0.0, 1.0)),),
                visual_to=(float(lengths[k]), 0.0, 0.0),
            )
        )
        bodies.append(TreeBody(name=f"counterweight{k + 1}", parent=f"link{k + 1}"))
    bodies.append(TreeBody(name="payload", parent=f"link{n}", pos=(float(lengths[-1]), 0.0, 0.0)))
    return Tree(
        bodies=tuple(bodies),
        coordinates=_identity,
        actuated=tuple(f"q{k + 1}" for k in range(n)),
    )


def scara_tree(robot) -> Tree:
    """SCARA: RRR + prismatic; the vertical counterweight hangs at O3 on its own slide.

    The cable of Arakelian & Briot's Fig 5 is the coordinate map ``−d4`` of that slide.
    """
    l1, l2 = (float(x) for x in np.asarray(robot.lengths))
    bodies = (
        TreeBody("link1", None, joints=(Joint("theta1", "hinge", Z),), visual_to=(l1, 0, 0)),
        TreeBody("counter_mass1", "link1"),
        TreeBody(
            "link2",
            "link1",
            pos=(l1, 0, 0),
            joints=(Joint("theta2", "hinge", Z),),
            visual_to=(l2, 0, 0),
        ),
        TreeBody("counter_mass2", "link2"),
        TreeBody(
            "vertical_counterweight", "link2", pos=(l2, 0, 0), joints=(Joint("cable", "slide", Z),)
        ),
        TreeBody(
            "end_effector",
            "link2",
            pos=(l2, 0, 0),
            joints=(Joint("theta3", "hinge", Z), Joint("d4", "slide", Z)),
            visual_to=(0, 0, -0.1),
        ),
        TreeBody("payload", "end_effector"),
        TreeBody("counter_mass3", "end_effector"),
    )
    return Tree(
        bodies=bodies,
        coordinates=_scara_coordinates,
        actuated=("theta1", "theta2", "theta3", "d4"),
    )


def dual_v_tree(robot) -> Tree:
    """DUAL-V: four RR arms from the base pivots, the platform on a planar joint, and
    the loops closed by ``connect`` at C_i (arm i's link i2 end = platform end s_i·b).

    Base pivots ``A_i = (±a, ±b)`` and platform ends ``s_i b`` along the platform's
    y axis, with the sign tables of :mod:`jaxbal.robots.dual_v` (the robot's layout).
    """
    from jaxbal.robots.dual_v import BASE_SIDE, PLATFORM_END

    a, b = float(robot.a), float(robot.b)
    l1, l2 = np.asarray(robot.l1, dtype=float), np.asarray(robot.l2, dtype=float)
    side, end = np.asarray(BASE_SIDE), np.asarray(PLATFORM_END)
    bodies, connects = [], []
    for i in range(4):
        arm = i + 1
        bodies += [
            TreeBody(
                f"link{arm}1",
                None,
                pos=_vec(side[i] * a, end[i] * b, 0.0),
                joints=(Joint(f"theta{arm}1", "hinge", Z),),
                visual_to=(float(l1[i]), 0, 0),
            ),
            TreeBody(f"counter_mass{arm}", f"link{arm}1"),
            TreeBody(f"tuning_mass{arm}", f"link{arm}1"),
            TreeBody(f"rotor{arm}", f"link{arm}1"),
            TreeBody(
                f"link{arm}2",
                f"link{arm}1",
                pos=(float(l1[i]), 0, 0),
                joints=(Joint(f"theta{arm}2", "hinge", Z),),
                visual_to=(float(l2[i]), 0, 0),
            ),
        ]
        connects.append(
            Connect(f"link{arm}2", _vec(l2[i], 0, 0), "platform", _vec(0, end[i] * b, 0))
        )
    bodies += [
        TreeBody(
            "platform",
            None,
            joints=(
                Joint("x5", "slide", (1.0, 0, 0)),
                Joint("y5", "slide", (0, 1.0, 0)),
                Joint("theta5", "hinge", Z),
            ),
            visual_to=(0, b, 0),
        ),
        TreeBody("payload", "platform"),
    ]

    return Tree(
        bodies=tuple(bodies),
        coordinates=_dual_v_coordinates,
        connects=tuple(connects),
        actuated=tuple(f"theta{i}1" for i in range(1, 5)),
    )


def _minimal_rotation_quat(a, d):
    """Unit quaternion of the rotation about ``a × d`` taking unit ``a`` onto ``d``."""
    d = d / jnp.linalg.norm(d)
    quat = jnp.concatenate([(1.0 + a @ d)[None], jnp.cross(a, d)])
    return quat / jnp.linalg.norm(quat)


def orthoglide_tree(robot) -> Tree:
    """Orthoglide: three sliders, each carrying a parallelogram (a slender bar, on a ball
    joint at B_i) whose far end is ``connect``-ed to the translating platform P.

    The parallelogram's orientation is the minimal rotation taking the home direction
    ``−e_i`` onto ``(P − B_i)/|P − B_i|`` (the convention of
    :meth:`Orthoglide.body_frames`; the bar has no axial inertia, so the twist about
    its axis, which the real parallelogram fixes differently, carries no momentum).
    """
    length = float(robot.length)
    eye = np.eye(3)
    bodies, connects = [], []
    for i, axis in enumerate("xyz"):
        bodies += [
            TreeBody(f"slider_{axis}", None, joints=(Joint(f"rho_{axis}", "slide", _vec(eye[i])),)),
            TreeBody(
                f"parallelogram_{axis}",
                f"slider_{axis}",
                joints=(Joint(f"leg_{axis}", "ball"),),
                visual_to=_vec(-length * eye[i]),
            ),
        ]
        connects.append(
            Connect(f"parallelogram_{axis}", _vec(-length * eye[i]), "platform", (0.0, 0.0, 0.0))
        )
    bodies += [
        TreeBody(
            "platform",
            None,
            joints=tuple(Joint(f"p_{axis}", "slide", _vec(eye[i])) for i, axis in enumerate("xyz")),
        ),
        TreeBody("payload", "platform"),
    ]
    return Tree(
        bodies=tuple(bodies),
        coordinates=_orthoglide_coordinates,
        connects=tuple(connects),
        actuated=("rho_x", "rho_y", "rho_z"),
    )


# --- generic fallback ---------------------------------------------------------------


def prescribed_tree(robot: Robot) -> Tree:
    """Generic tree: every jaxbal body on 3 world slides + a ball joint under the base.

    Less independent than a registered tree: the kinematics (poses, velocities,
    accelerations) are jaxbal's own ``body_frames`` and its derivatives; MuJoCo then
    checks the Newton-Euler sum of the bodies' momenta about the base origin. Valid
    for closed chains too. The joints sit on massless helper bodies (mass
    :data:`BASE_MASS`, a relative error ~1e-15) carrying the welded jaxbal bodies.
    Its ``state`` gives slide positions and ball quaternions, the velocities and
    accelerations in MuJoCo's convention (a ball joint's velocity is the angular
    velocity in the body frame, not the derivative of its quaternion).
    """
    bodies = ()
    for name in robot.mass_properties().names:
        slides = tuple(
            Joint(f"{name}_{a}", "slide", tuple(float(x) for x in ax))
            for a, ax in zip("xyz", np.eye(3), strict=True)
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
            omega_local = vee(jnp.einsum("nji,njk->nik", rotations, rates))
            return velocities, omega_local

        (velocities, omega), (accelerations, omega_dot) = jax.jvp(twist, (q, qd), (qd, qdd))
        qvel = jnp.concatenate([velocities, omega], axis=-1).reshape(-1)
        qacc = jnp.concatenate([accelerations, omega_dot], axis=-1).reshape(-1)
        return coordinates(q), qvel, qacc

    return Tree(bodies=bodies, coordinates=coordinates, independent=False, state=state)


def _register(module: str, name: str, builder) -> None:
    """Register ``builder`` for ``module.name`` if that robot is available."""
    import importlib

    try:
        cls = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError):
        return
    register_tree(cls)(builder)


_register("jaxbal.robots.scara", "Scara", scara_tree)
_register("jaxbal.robots.dual_v", "DualV", dual_v_tree)
_register("jaxbal.robots.orthoglide", "Orthoglide", orthoglide_tree)
