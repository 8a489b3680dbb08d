"""The Orthoglide's MuJoCo kinematic tree (Geng et al. 2021, eq (1); Fig 1).

References:
    Geng, Arakelian, Chablat & Lemoine (2021), eq (1) and Fig 1.
"""

from __future__ import annotations

from typing import NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxbal._src.mujoco.tree import Connect, Joint, Tree, TreeBody, minimal_rotation_quat, vec

COUNTER_SLIDERS = ("counter_slider_x", "counter_slider_y", "counter_slider_z")


def orthoglide_tree(robot) -> Tree:
    """Three sliders, each carrying a parallelogram (a slender bar, on a ball joint at
    B_i) whose far end is ``connect``-ed to the translating platform P; the
    counter-sliders on their own slides (coordinate ``−ρ_i``).

    MuJoCo C closes the loops itself: the platform point P is prescribed; the slider
    inputs ρ_i and the bars' ball joints are ``solved`` from the ``connect``
    equalities, starting from :class:`SlidersBeyondPlatform` (configuration indices
    ``s_i = +1``). The counter-sliders take jaxbal's ``−ρ_i``, which the comparison of
    MuJoCo's ρ_i with jaxbal's checks. MJX takes jaxbal's coordinates, where the
    parallelogram's orientation is the minimal rotation taking the home direction
    ``−e_i`` onto ``(P − B_i)/|P − B_i|`` (as :meth:`body_frames`; the bar has no axial
    inertia, so the twist about its axis carries no momentum).
    """
    length = float(robot.length)
    eye = np.eye(3)
    bodies, connects = [], []
    for i, axis in enumerate("xyz"):
        slide = Joint(f"rho_{axis}", "slide", vec(eye[i]))
        bodies += [
            TreeBody(f"slider_{axis}", None, joints=(slide,)),
            TreeBody(
                f"parallelogram_{axis}",
                f"slider_{axis}",
                joints=(Joint(f"leg_{axis}", "ball"),),
                visual_to=vec(-length * eye[i]),
            ),
        ]
        end = vec(-length * eye[i])
        connects.append(Connect(f"parallelogram_{axis}", end, "platform", (0.0, 0.0, 0.0)))
    platform = tuple(Joint(f"p_{a}", "slide", vec(eye[i])) for i, a in enumerate("xyz"))
    bodies += [TreeBody("platform", None, joints=platform), TreeBody("payload", "platform")]
    bodies += [
        TreeBody(name, None, joints=(Joint(f"{name}_slide", "slide", vec(eye[i])),))
        for i, name in enumerate(COUNTER_SLIDERS)
    ]
    return Tree(
        bodies=tuple(bodies),
        coordinates=_mujoco_coordinates,
        connects=tuple(connects),
        actuated=("rho_x", "rho_y", "rho_z"),
        solved=tuple(f"{kind}_{axis}" for axis in "xyz" for kind in ("rho", "leg")),
        guess=SlidersBeyondPlatform(length),
    )


class SlidersBeyondPlatform(NamedTuple):
    """Initial guess of MuJoCo's loop closure: slider i a bar length beyond P along
    axis i (``ρ_i = p_i + L``, configuration index ``s_i = +1`` of eq (1)), each bar
    along its home direction ``−e_i``. Only ``P = q[3:6]`` is read; returns the tree's
    ``qpos`` (counter-sliders at ``−ρ_i``)."""

    length: float

    def __call__(self, q) -> np.ndarray:
        p = np.asarray(q, dtype=float)[3:6]
        rho = p + self.length
        legs = [np.array([rho[i], 1.0, 0.0, 0.0, 0.0]) for i in range(3)]
        return np.concatenate(legs + [p, -rho])


def _mujoco_coordinates(q):
    """MuJoCo's ``qpos = (ρ_i, Q_i per leg, p, −ρ)``, ``Q_i`` the minimal rotation
    ``−e_i → P − B_i`` (quaternion)."""
    rho, p = q[:3], q[3:]
    eye = jnp.eye(3)
    pieces = []
    for i in range(3):
        pieces += [rho[i : i + 1], minimal_rotation_quat(-eye[i], p - rho[i] * eye[i])]
    return jnp.concatenate(pieces + [p, -rho])
