"""Test points on a square of the workspace, numbered as in Briot et al. (2012), Figs 3 and 7.

The paper discretises each edge of a square test zone into four segments delimited by
points P1 … P16 but does not say how they are numbered. jaxbal's convention, found by
matching Table 1 of the paper (all 16 case-2 entries of the 2R agree to 0.25% with
this numbering and with no other start point or direction, see
``experiments/briot2012_2r.py``), is:

* P1 is the corner with the smallest x and the smallest y (bottom-left, the base
  being at the origin and the square above it);
* P1 … P16 go **counter-clockwise** in steps of a quarter edge: P1-P5 along the
  bottom edge, P5-P9 up the right edge, P9-P13 along the top edge, P13-P1 down the
  left edge.

The mirror image (P1 bottom-right, clockwise) gives the same numbers with the other
elbow branch; jaxbal uses the convention above with the working mode "+" of eq (10),
for both the 2R and the 3R.
"""

from __future__ import annotations

import jax.numpy as jnp

from jaxbal._src.types import Array, Float

#: The eight paths of Tables 1-3, as (start, end) point numbers.
BRIOT2012_PATHS: tuple[tuple[int, int], ...] = (
    (1, 13),
    (2, 12),
    (3, 11),
    (4, 10),
    (5, 9),
    (15, 7),
    (14, 8),
    (13, 9),
)


def square_points(centre, edge, per_side: int = 4) -> Float[Array, "n 2"]:
    """``(4·per_side, 2)`` points on the square of side ``edge`` [m] centred at ``centre``.

    Row ``k`` is point P_{k+1} in the numbering of the module docstring.
    """
    centre = jnp.asarray(centre, dtype=float)
    half = 0.5 * jnp.asarray(edge, dtype=float)
    corners = centre + half * jnp.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])
    fractions = jnp.arange(per_side) / per_side
    sides = [
        corners[k] + fractions[:, None] * (corners[(k + 1) % 4] - corners[k]) for k in range(4)
    ]
    return jnp.concatenate(sides, axis=0)


def path_name(start: int, end: int) -> str:
    """``"P15P7"`` style name of a path."""
    return f"P{start}P{end}"
