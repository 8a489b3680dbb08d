"""Small fixed-size linear algebra written as broadcast-multiply-and-sum.

Under ``vmap`` on CPU, ``einsum``/``matmul`` of 3×3 blocks become batched
``dot_general`` calls that XLA does not fuse and that run far slower than the few
multiply-adds they contain. Written elementwise, XLA fuses them into one loop; the
results are identical. Private helpers of :mod:`jaxbal.momentum` and
:mod:`jaxbal.dynamics`.
"""

import jax
import jax.numpy as jnp


def safe_sqrt(square):
    """``sqrt(x)`` of ``x ≥ 0`` with a zero (not NaN, not inf) gradient at ``x = 0``
    (the double ``where``): the zero-safe norms of the metrics and of the base vibration.
    A NaN stays NaN (it was 0: a NaN wrench sample read as perfectly balanced)."""
    positive = square > 0.0
    rest = jnp.where(jnp.isnan(square), square, 0.0)
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, square, 1.0)), rest)


def matvec(matrix, vector):
    """``(..., 3, 3) @ (..., 3) -> (..., 3)``."""
    return jnp.sum(matrix * vector[..., None, :], axis=-1)


def rmatvec(matrix, vector):
    """``matrixᵀ @ vector``: ``(..., 3, 3), (..., 3) -> (..., 3)``."""
    return jnp.sum(matrix * vector[..., :, None], axis=-2)


def world_inertia_times(rotations, inertia, vectors):
    """``R_i I_i R_iᵀ v_i`` for every body ``i`` (body-frame inertias ``(n, 3, 3)``
    rotated to the base frame), as three matrix-vector products."""
    return matvec(rotations, matvec(inertia, rmatvec(rotations, vectors)))


def matmul_transposed(a, b):
    """``a @ bᵀ`` for ``(..., 3, 3)`` blocks."""
    return jnp.sum(a[..., :, None, :] * b[..., None, :, :], axis=-1)


def cross(a, b):
    """Cross product of ``(..., 3)`` vectors."""
    return jnp.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def vee(skew):
    """The vector of a skew-symmetric ``(..., 3, 3)`` matrix."""
    return jnp.stack([skew[..., 2, 1], skew[..., 0, 2], skew[..., 1, 0]], -1)


def weighted_sum(weights, vectors):
    """``Σ_n w_n v_n`` for ``(n,)`` weights and ``(n, 3)`` vectors."""
    return jnp.sum(weights[:, None] * vectors, axis=0)


@jax.custom_jvp
def cos_sin(angle):
    """``(cos θ, sin θ)`` whose derivatives reuse the two values instead of calling the
    transcendental functions again (``d cos = −sin dθ``, ``d sin = cos dθ``). Nested
    forward-mode differentiation (the shaking wrench is second order in time) then
    evaluates each sine and cosine once."""
    return jnp.cos(angle), jnp.sin(angle)


@cos_sin.defjvp
def _cos_sin_jvp(primals, tangents):
    (angle,), (dangle,) = primals, tangents
    c, s = cos_sin(angle)
    return (c, s), (-s * dangle, c * dangle)


def unit(angle):
    """``(..., 2)`` unit vectors ``(cos θ, sin θ)`` of planar angles [rad]."""
    return jnp.stack(cos_sin(angle), -1)


def wrap(angle):
    """Angles wrapped to ``(−π, π]`` [rad]."""
    return jnp.arctan2(jnp.sin(angle), jnp.cos(angle))


def skew(v):
    """``(..., 3, 3)`` cross-product matrices ``[v]×`` of ``(..., 3)`` vectors."""
    zero = jnp.zeros_like(v[..., 0])
    return jnp.stack(
        [
            jnp.stack([zero, -v[..., 2], v[..., 1]], -1),
            jnp.stack([v[..., 2], zero, -v[..., 0]], -1),
            jnp.stack([-v[..., 1], v[..., 0], zero], -1),
        ],
        -2,
    )


#: how close to ±1 a cosine may be for :func:`elbow_angle` (its ``arccos`` is clipped
#: there: a zero derivative where the true one is infinite).
SINGULAR_COSINE = 1e-15


def elbow_angle(cosine):
    """``(arccos(cosine), valid)``: the angle in ``[0, π]`` and whether ``cosine`` is
    strictly inside ``(−1, 1)`` by :data:`SINGULAR_COSINE` (finite). Outside — out of
    reach, or on the singular boundary where ``d arccos`` is infinite — the angle is
    that of the nearest boundary (finite, zero derivative) and ``valid`` is False."""
    valid = jnp.abs(cosine) < 1.0 - SINGULAR_COSINE
    safe = jnp.where(jnp.isfinite(cosine), cosine, 0.0)
    limit = 1.0 - SINGULAR_COSINE
    return jnp.arccos(jnp.clip(safe, -limit, limit)), valid


def two_link_ik(target, l1, l2, sign):
    """Closed-form inverse kinematics of a planar two-link chain from the origin.

    Args:
        target: ``(2,)`` position of the chain's tip [m].
        l1, l2: link lengths [m].
        sign: ``±1``, the sign of ``sin q2`` (elbow branch).

    Returns:
        ``(q1, q2, valid)``: the absolute angle of link 1 and the relative angle of
        link 2 [rad] (finite even when ``valid`` is False: the target is then out of
        reach, or on the boundary of the workspace, and the angles are those of the
        nearest boundary configuration).

    A target on the boundary (the chain stretched or folded, ``|cos q2| ≥ 1 − 1e-15``)
    is not valid: the configuration is singular (the joint rates of a motion through it
    are unbounded) and the clipped ``arccos`` there has a zero derivative, so the joint
    velocities derived from it would be silently wrong.
    """
    x, y = target[0], target[1]
    cos_q2 = (x**2 + y**2 - l1**2 - l2**2) / (2.0 * l1 * l2)
    cos_q2 = jnp.where(jnp.isfinite(cos_q2), cos_q2, jnp.inf)
    q2, valid = elbow_angle(cos_q2)
    q2 = sign * q2
    # At a target on the origin (folded with l1 = l2, else unreachable) arctan2's
    # gradient is NaN: take the direction from the stand-in (1, 0) there instead.
    apart = x**2 + y**2 > 0.0
    x, y = jnp.where(apart, x, 1.0), jnp.where(apart, y, 0.0)
    q1 = jnp.arctan2(y, x) - jnp.arctan2(l2 * jnp.sin(q2), l1 + l2 * jnp.cos(q2))
    return q1, q2, valid
