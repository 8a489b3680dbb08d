"""Small fixed-size linear algebra written as broadcast-multiply-and-sum.

Under ``vmap`` on CPU, ``einsum``/``matmul`` of 3×3 blocks become batched
``dot_general`` calls that XLA does not fuse and that run far slower than the few
multiply-adds they contain. Written elementwise, XLA fuses them into one loop; the
results are identical. Private helpers of :mod:`jaxbal.momentum` and
:mod:`jaxbal.dynamics`.
"""

import jax
import jax.numpy as jnp


def matvec(matrix, vector):
    """``(..., 3, 3) @ (..., 3) -> (..., 3)``."""
    return jnp.sum(matrix * vector[..., None, :], axis=-1)


def rmatvec(matrix, vector):
    """``matrixᵀ @ vector``: ``(..., 3, 3), (..., 3) -> (..., 3)``."""
    return jnp.sum(matrix * vector[..., :, None], axis=-2)


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
