"""Which world axes of an end-effector site make its pose: the default and the checks.

The pose of a site is some of its world coordinates (``pose_components``). They must be
independent, else the pose equations are singular wherever they are solved: an arm in
a vertical plane yawed 45° about z has equal x and y, and an arm in the x-z plane never
moves along y. The test is the rank of the site Jacobian's rows at MuJoCo's random
probe configurations (:func:`~jaxbal._src.robots.mjcf_parse._point_jacobians`), per
configuration: the reference ``qpos0`` is often an arm drawn straight, singular for
every choice.

References:
    MuJoCo API, ``mj_jac``; Siciliano et al. (2009), *Robotics*, §3.3 (the rank of the
    geometric Jacobian's rows and kinematic singularities).
"""

from __future__ import annotations

import numpy as np

from jaxbal._src.robots.mjcf_parse import RANK_RTOL, _point_jacobians

__all__ = ["dependent_axes", "moving_components", "pose_axes"]


def _site_jacobians(model, site: int) -> np.ndarray:
    """``(PROBES, 3, nv)`` Jacobians of a site at the random probe configurations."""
    body = int(model.site_bodyid[site])
    return _point_jacobians(model, [(body, np.array(model.site_pos[site]))], seed=1)[:, 0]


def moving_components(model, site: int) -> tuple[int, ...]:
    """World axes (0, 1, 2) along which a site can move (a planar mechanism's site does
    not move along the plane normal)."""
    jac = _site_jacobians(model, site)
    gram = np.einsum("kin,kjn->ij", jac, jac)
    diagonal = np.diag(gram)
    return tuple(
        i for i in range(3) if diagonal[i] > RANK_RTOL * max(float(diagonal.max()), 1e-300)
    )


def _independent(jacobians, axes) -> bool:
    """Are the site's velocity components along the world ``axes`` independent, i.e. do
    its Jacobian's rows ``axes`` have full rank at most of the random configurations?
    Per configuration, not summed: a pendulum's tip moves along x and z, but only along
    one direction at a time."""
    rows = jacobians[:, list(axes)]
    scale = max(float(np.abs(jacobians).max(initial=0.0)), 1e-300)
    smallest = np.linalg.svd(rows, compute_uv=False)[:, -1]
    return int(np.sum(smallest > np.sqrt(RANK_RTOL) * scale)) * 2 > len(jacobians)


def pose_axes(model, site: int, count: int) -> tuple[int, ...]:
    """The default pose components: up to ``count`` world axes, in order, whose site
    coordinates are independent (the rows of the site's Jacobian have full rank at
    random configurations, not at ``qpos0``, where an arm is often drawn straight).
    Taking the first ``count`` moving axes chose ``(x, y)`` for an arm in a vertical
    plane yawed 45° about z, whose x and y are always equal: a singular pose. That arm
    gets ``(x, z)``."""
    jac = _site_jacobians(model, site)
    chosen: list[int] = []
    for axis in range(3):
        if len(chosen) < count and _independent(jac, chosen + [axis]):
            chosen.append(axis)
    return tuple(chosen)


def dependent_axes(model, site: int, axes) -> bool:
    """True when the site's coordinates along the world ``axes`` are not independent (a
    user's ``pose_components`` that no motion of the mechanism can steer apart)."""
    jac = _site_jacobians(model, site)
    return not _independent(jac, list(axes))
