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
=================  ===========================================  ======================

References:
    Briot, Arakelian & Le Baron (2012), §3.1-3.2 (planar 2R and 3R arms).
"""

from __future__ import annotations

import numpy as np

from jaxbal.mjcf import Joint, Tree, TreeBody, register_tree
from jaxbal.robots.planar_arm import PlanarArm


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
        coordinates=lambda q: q,
        actuated=tuple(f"q{k + 1}" for k in range(n)),
    )
