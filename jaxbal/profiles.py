"""Motion profiles ``s(u)`` on ``u ∈ [0, 1]`` (quintic, bang-bang, trapezoidal, polynomial)."""

from jaxbal._src.profiles import (
    BangBang,
    BoundaryPolynomial,
    Profile,
    Quintic,
    TrapezoidalAcceleration,
    polynomial_of_degree,
)

__all__ = [
    "BangBang",
    "BoundaryPolynomial",
    "Profile",
    "Quintic",
    "TrapezoidalAcceleration",
    "polynomial_of_degree",
]
