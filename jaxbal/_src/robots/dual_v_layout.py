"""DUAL-V layout constants and its MuJoCo kinematic tree (van der Wijk et al. 2013).

The sign tables fix the layout derived in :mod:`jaxbal._src.robots.dual_v` (base pivots
``A_i = (BASE_SIDE_i·a, PLATFORM_END_i·b)``, platform joints ``C_i`` at
``PLATFORM_END_i·b`` along the platform's y axis) and the two elbow branches.

References:
    van der Wijk, Krut, Pierrot & Herder (2013), Fig 2, eqs (1), (7), (9).
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxbal._src.mujoco.tree import Connect, Joint, Tree, TreeBody, Z, vec

OUTWARD = (1, -1, 1, -1)
CROSSED = (-1, 1, -1, 1)
BASE_SIDE = np.array([1.0, -1.0, -1.0, 1.0])  # x sign of A_i
PLATFORM_END = np.array([1.0, 1.0, -1.0, -1.0])  # s_i: y sign of A_i and end of C_i
N_COORDINATES = 11


def dual_v_tree(robot) -> Tree:
    """MuJoCo tree of a :class:`~jaxbal._src.robots.dual_v.DualV`, built from its
    geometric parameters: four RR arms from the base pivots (link i1 on a z-hinge at A_i
    carrying the brass and tuning counter-masses and the rotor, link i2 on a z-hinge at
    B_i), the platform on x, y slides and a z-hinge, and the loops closed by ``connect``
    at C_i (arm i's link i2 end = the platform joint C_i). MuJoCo's ``qpos`` per arm is
    ``(θ_i1, θ_i2 − θ_i1)``.

    The pivots and platform joints are written here from Fig 2c, not from jaxbal's sign
    tables (:func:`_pivots`). MuJoCo C closes the loops itself: the platform pose is
    prescribed, the eight arm angles are ``solved`` from the ``connect`` equalities,
    starting from :class:`ElbowsOutward` (the prototype's two "V"s). MJX takes jaxbal's
    coordinates."""
    b = float(robot.b)
    l1, l2 = np.asarray(robot.l1, dtype=float), np.asarray(robot.l2, dtype=float)
    pivots, ends = _pivots(robot)
    bodies, connects = [], []
    for i in range(4):
        arm = i + 1
        bodies += [
            TreeBody(
                f"link{arm}1",
                None,
                pos=vec(*pivots[i], 0.0),
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
        connects.append(Connect(f"link{arm}2", vec(l2[i], 0, 0), "platform", vec(0, ends[i], 0)))
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
        solved=tuple(f"theta{i}{k}" for i in range(1, 5) for k in (1, 2)),
        guess=ElbowsOutward(pivots, ends, vec(l1)),
    )


def _pivots(robot) -> tuple[tuple[tuple[float, float], ...], tuple[float, ...]]:
    """Base pivots ``A_i`` [m] and the platform joints ``C_i`` along the platform's own
    y axis [m], read from Fig 2c: the pivots at ``(±a, ±b)`` numbered counter-clockwise
    from the first quadrant, the platform (length 2b) along y at θ5 = 0 with arms 1, 2
    joined at its +b end and arms 3, 4 at its −b end."""
    a, b = float(robot.a), float(robot.b)
    return ((a, b), (-a, b), (-a, -b), (a, -b)), (b, b, -b, -b)


class ElbowsOutward(NamedTuple):
    """Initial guess of MuJoCo's loop closure: each elbow B_i half a link length off the
    mid-point of A_i C_i, on the side away from the x axis (the prototype's two "V"s,
    Fig 2). Only the platform pose ``q[8:11]`` is read; returns the tree's ``qpos``."""

    pivots: tuple[tuple[float, float], ...]
    ends: tuple[float, ...]
    l1: tuple[float, ...]

    def __call__(self, q) -> np.ndarray:
        x5, y5, theta5 = (float(v) for v in np.asarray(q, dtype=float)[8:11])
        arms = []
        for pivot, end, length in zip(self.pivots, self.ends, self.l1, strict=True):
            pivot = np.asarray(pivot)
            joint = np.array([x5 - end * np.sin(theta5), y5 + end * np.cos(theta5)])
            along = joint - pivot
            normal = np.array([-along[1], along[0]]) / max(np.linalg.norm(along), 1e-12)
            normal *= np.sign(pivot[1]) * np.sign(normal[1] + (normal[1] == 0))
            elbow = 0.5 * (pivot + joint) + 0.5 * length * normal
            theta1 = np.arctan2(*(elbow - pivot)[::-1])
            theta2 = np.arctan2(*(joint - elbow)[::-1])
            arms += [theta1, theta2 - theta1]
        return np.array(arms + [x5, y5, theta5])


def _mujoco_coordinates(q):
    """MuJoCo's ``qpos``: ``(θ_i1, θ_i2 − θ_i1)`` per arm, then ``(x5, y5, θ5)``."""
    arms = jnp.stack([q[0:4], q[4:8] - q[0:4]], -1).reshape(-1)
    return jnp.concatenate([arms, q[8:11]])
