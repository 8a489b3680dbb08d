"""DUAL-V layout constants and its MuJoCo kinematic tree (van der Wijk et al. 2013).

The sign tables fix the layout derived in :mod:`jaxbal._src.robots.dual_v` (base pivots
``A_i = (BASE_SIDE_i·a, PLATFORM_END_i·b)``, platform joints ``C_i`` at
``PLATFORM_END_i·b`` along the platform's y axis) and the two elbow branches.

References:
    van der Wijk, Krut, Pierrot & Herder (2013), Fig 2, eqs (1), (7), (9).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxbal._src.mujoco.tree import Connect, Joint, Tree, TreeBody, Z, vec

OUTWARD = (1, -1, 1, -1)
CROSSED = (-1, 1, -1, 1)
BASE_SIDE = jnp.array([1.0, -1.0, -1.0, 1.0])  # x sign of A_i
PLATFORM_END = jnp.array([1.0, 1.0, -1.0, -1.0])  # s_i: y sign of A_i and end of C_i
N_COORDINATES = 11


def dual_v_tree(robot) -> Tree:
    """MuJoCo tree of a :class:`~jaxbal._src.robots.dual_v.DualV`: four RR arms from the
    base pivots (link i1 on a z-hinge at A_i carrying the brass and tuning counter-masses
    and the rotor, link i2 on a z-hinge at B_i), the platform on x, y slides and a
    z-hinge, and the loops closed by ``connect`` at C_i (arm i's link i2 end = platform
    end ``s_i·b``). MuJoCo's ``qpos`` per arm is ``(θ_i1, θ_i2 − θ_i1)``."""
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
                pos=vec(side[i] * a, end[i] * b, 0.0),
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
        connects.append(Connect(f"link{arm}2", vec(l2[i], 0, 0), "platform", vec(0, end[i] * b, 0)))
    slides = (Joint("x5", "slide", (1.0, 0, 0)), Joint("y5", "slide", (0, 1.0, 0)))
    bodies += [
        TreeBody(
            "platform",
            None,
            joints=slides + (Joint("theta5", "hinge", Z),),
            visual_to=(0, b, 0),
        ),
        TreeBody("payload", "platform"),
    ]
    return Tree(
        bodies=tuple(bodies),
        coordinates=_mujoco_coordinates,
        connects=tuple(connects),
        actuated=tuple(f"theta{i}1" for i in range(1, 5)),
    )


def _mujoco_coordinates(q):
    """MuJoCo's ``qpos``: ``(θ_i1, θ_i2 − θ_i1)`` per arm, then ``(x5, y5, θ5)``."""
    arms = jnp.stack([q[0:4], q[4:8] - q[0:4]], -1).reshape(-1)
    return jnp.concatenate([arms, q[8:11]])
