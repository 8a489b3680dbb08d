"""jaxtyping aliases used in jaxbal's public signatures.

Shapes are written in jaxtyping notation: ``n`` is the number of rigid bodies of a
robot, ``dof`` the length of its coordinate vector ``q`` (for parallel robots this
is the coordinates of *all* bodies, as returned by their inverse kinematics).
"""

from jaxtyping import Array, ArrayLike, Float

Scalar = Float[Array, ""]
ScalarLike = float | Float[ArrayLike, ""]
Vec3 = Float[Array, "3"]
Coordinates = Float[Array, " dof"]
Masses = Float[Array, " n"]
Points = Float[Array, "n 3"]
Rotations = Float[Array, "n 3 3"]
Inertias = Float[Array, "n 3 3"]

__all__ = [
    "Array",
    "ArrayLike",
    "Coordinates",
    "Float",
    "Inertias",
    "Masses",
    "Points",
    "Rotations",
    "Scalar",
    "ScalarLike",
    "Vec3",
]
