"""The shaking wrench as a linear map of the bodies' inertial parameters, and the
balancing conditions of any robot read from it.

At a given state the shaking wrench is *linear* in the lumped inertial parameters of
each body: its mass ``m``, first moment ``h = m c`` and inertia about the frame origin
``J = I + m (‖c‖² 1 − c cᵀ)``, all in the body frame::

    w(q, q̇, q̈) = Y(q, q̇, q̈) π,    π_b = (m, h_x, h_y, h_z, J_xx, J_yy, J_zz, J_xy, J_xz, J_yz)

With the frame origin ``o``, rotation ``R`` (columns ``r_j``), origin acceleration
``a``, angular velocity ``ω`` and acceleration ``α`` (base frame), a body contributes
(Newton–Euler about the base origin; the terms in the origin's velocity cancel)::

    f = −(m a + α × R h + ω × (ω × R h)),
    m_O = o × f − R h × a − (J_w α + ω × J_w ω),     J_w = R J Rᵀ,

so the columns of ``Y`` are ``∂f/∂m = −a``, ``∂f/∂h_j = −(α × r_j + ω × (ω × r_j))``,
``∂f/∂J = 0``, ``∂m_O/∂m = o × ∂f/∂m``, ``∂m_O/∂h_j = o × ∂f/∂h_j − r_j × a`` and
``∂m_O/∂J_ij = −(E α + ω × E ω)`` with ``E = r_i r_jᵀ + r_j r_iᵀ`` (``r_i r_iᵀ`` on the
diagonal). Only the robot's body frames are differentiated
(:meth:`~jaxbal.robot.Robot.body_frames`, or ``planar_frames``), so this is an
evaluation of the wrench *independent* of :func:`jaxbal.shaking_wrench` (which
differentiates the momentum of the bodies' centres of mass); the tests compare the two
on every robot.

**Balancing conditions.** A robot is force-balanced along a motion when
``Y_f(t) π = 0`` at every instant, i.e. when ``π`` lies in the null space of the
regressor stacked over the samples: the conditions are its row space, a few linear
equations in the lumped parameters (:func:`balancing_conditions`). Along a *generic*
motion (every joint moving independently, e.g. sums of sines of unrelated
frequencies) these are the conditions for balance along every motion -- for a planar
serial arm the classical ones of Berkof & Lowen (the first moment of everything
carried by each joint about that joint cancels); along a particular motion (a straight
line) they are those for that motion only, usually fewer. The rank is decided on the
column-equilibrated regressor (each column scaled to unit norm: the parameters have
different units) with a relative singular-value tolerance.

References:
    Atkeson, An & Hollerbach (1986), Int. J. Robot. Res. 5(3) (the wrench is linear in
    the lumped inertial parameters);
    Gautier & Khalil (1990), IEEE Trans. Robot. Autom. 6(3) (parameters the dynamics
    depends on: the regressor's column space);
    Berkof & Lowen (1969), J. Eng. Ind. 91(1) (complete force balancing conditions);
    Arakelian & Briot (2008), eqs (1)-(3); van der Wijk et al. (2013), §2 (the
    force-balanced SCARA and DUAL-V these conditions describe).
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.along_motion import batched
from jaxbal._src.linalg import cos_sin, matmul_transposed, vee
from jaxbal._src.merged_guards import merged_guards
from jaxbal._src.metrics import Motion
from jaxbal._src.planar import PlanarRobot
from jaxbal._src.robot import Bodies, Robot, rot_z_from
from jaxbal._src.robot_checks import checked_bodies, checked_finite, checked_parameters
from jaxbal._src.state_checks import state_check
from jaxbal._src.types import Array, Coordinates
from jaxbal._src.validation import _under_trace, runtime_checks, runtime_checks_enabled

__all__ = [
    "LUMPED",
    "RANK_RTOL",
    "Conditions",
    "LinearWrench",
    "balancing_conditions",
    "linear_wrench",
    "lumped_parameters",
    "parameter_names",
    "wrench_regressor",
]

#: lumped inertial parameters of one body, in this order (body frame; kg, kg·m, kg·m²).
LUMPED = ("m", "h_x", "h_y", "h_z", "J_xx", "J_yy", "J_zz", "J_xy", "J_xz", "J_yz")
_SYMMETRIC = ((0, 0), (1, 1), (2, 2), (0, 1), (0, 2), (1, 2))
#: default relative tolerance on the singular values of the equilibrated regressor.
RANK_RTOL = 1e-9
#: coefficients of the row-echelon conditions below this fraction of the largest are
#: rounding (the SVD's ~1e-16, amplified by the elimination) and set to zero.
CLEAN_RTOL = 1e-10
#: a regressor column below this fraction of the largest is rounding (a parameter the
#: wrench does not depend on, e.g. ``h_z`` of a link turning about z, gives ~1e-16):
#: zeroed before the equilibration, which would scale it up to a spurious condition.
ZERO_COLUMN_RTOL = 1e-12


def _of_bodies(bodies: Bodies) -> Array:
    m, c, inertia = bodies.mass, bodies.com, bodies.inertia
    h = m[:, None] * c
    # J = I + m (‖c‖² 1 − c cᵀ), entry by entry (:data:`_SYMMETRIC`): the diagonal
    # I_ii + m (‖c‖² − c_i²), the products I_ij − m c_i c_j (no (b, 3, 3) temporaries)
    diagonal = jnp.diagonal(inertia, axis1=1, axis2=2) + (jnp.sum(h * c, -1)[:, None] - h * c)
    products = [inertia[:, i, j] - h[:, i] * c[:, j] for i, j in _SYMMETRIC[3:]]
    return jnp.concatenate([m[:, None], h, diagonal, jnp.stack(products, -1)], axis=-1)


def lumped_parameters(robot: Robot) -> Array:
    """``(b, 10)`` lumped parameters :data:`LUMPED` of the robot's bodies (rows in the
    order of :meth:`~jaxbal.robot.Robot.mass_properties`) [kg, kg·m, kg·m²].

    Raises ``ValueError`` (at run time under ``jit``) for a negative or non-finite body
    mass or inertia, or a non-finite robot parameter, as :func:`jaxbal.center_of_mass`."""
    return checked_parameters(robot, checked_bodies(robot, _of_bodies(robot.mass_properties())))


def parameter_names(robot: Robot) -> tuple[str, ...]:
    """``(10 b,)`` names ``body.parameter`` of the flattened :func:`lumped_parameters`."""
    return tuple(f"{body}.{p}" for body in robot.mass_properties().names for p in LUMPED)


class Frames(NamedTuple):
    """Kinematics of every body frame at one instant (base frame): ``origin (b, 3)``
    [m], ``rotation (b, 3, 3)``, ``acceleration (b, 3)`` of the origin [m/s²], ``omega``
    ``(b, 3)`` [rad/s] and ``alpha (b, 3)`` [rad/s²]."""

    origin: Array
    rotation: Array
    acceleration: Array
    omega: Array
    alpha: Array


def frame_kinematics(robot: Robot, q: Coordinates, qd: Coordinates, qdd: Coordinates) -> Frames:
    """:class:`Frames` of ``robot`` at the state ``(q, q̇, q̈)`` (nested forward mode)."""
    if isinstance(robot, PlanarRobot):

        def rates(q_, qd_):
            return jax.jvp(robot.planar_frames, (q_,), (qd_,))

        ((origins, angles), (_, omega)), (_, (acceleration, alpha)) = jax.jvp(
            rates, (q, qd), (qd, qdd)
        )
        zero = jnp.zeros_like(angles)
        return Frames(
            jnp.concatenate([origins, zero[:, None]], -1),
            rot_z_from(*cos_sin(angles)),
            jnp.concatenate([acceleration, zero[:, None]], -1),
            jnp.stack([zero, zero, omega], -1),
            jnp.stack([zero, zero, alpha], -1),
        )

    def rates3(q_, qd_):
        return jax.jvp(robot.body_frames, (q_,), (qd_,))

    ((origin, rotation), (_, rate)), (_, (acceleration, second)) = jax.jvp(
        rates3, (q, qd), (qd, qdd)
    )
    omega = vee(matmul_transposed(rate, rotation))
    alpha = vee(matmul_transposed(second, rotation) + matmul_transposed(rate, rate))
    return Frames(origin, rotation, acceleration, omega, alpha)


def _cross(u, v):
    """Cross product of two 3-tuples of ``(b,)`` arrays (component-wise)."""
    return (u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0])


def _dot(u, v):
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2]


def _columns(frames: Frames):
    """``(force (3, b, 10), moment (3, b, 10))``: the module doc's columns."""
    o, a, w, alpha = (
        tuple(x[:, i] for i in range(3))
        for x in (frames.origin, frames.acceleration, frames.omega, frames.alpha)
    )
    r = [tuple(frames.rotation[:, i, j] for i in range(3)) for j in range(3)]

    def negated_sum(u, v):
        return tuple(-(x + y) for x, y in zip(u, v, strict=True))

    force_m = tuple(-x for x in a)
    force_h = [negated_sum(_cross(alpha, rj), _cross(w, _cross(w, rj))) for rj in r]
    moment_h = [
        tuple(x - y for x, y in zip(_cross(o, fj), _cross(rj, a), strict=True))
        for fj, rj in zip(force_h, r, strict=True)
    ]

    def spin(i, j):
        def apply(v):  # E v
            if i == j:
                return tuple(x * _dot(r[i], v) for x in r[i])
            first, second = _dot(r[j], v), _dot(r[i], v)
            return tuple(x * first + y * second for x, y in zip(r[i], r[j], strict=True))

        return negated_sum(apply(alpha), _cross(w, apply(w)))

    zero = jnp.zeros_like(a[0])
    force_columns = [force_m, *force_h] + [(zero, zero, zero)] * 6
    moment_columns = [_cross(o, force_m), *moment_h, *(spin(i, j) for i, j in _SYMMETRIC)]

    def assemble(columns):
        return jnp.stack([jnp.stack([c[k] for c in columns], -1) for k in range(3)])

    return assemble(force_columns), assemble(moment_columns)


def wrench_regressor(robot: Robot, q: Coordinates, qd: Coordinates, qdd: Coordinates):
    """The regressor of the inertial shaking wrench at one state.

    Args:
        robot: any :class:`~jaxbal.robot.Robot`.
        q, qd, qdd: ``(dof,)`` state (SI units of the robot's coordinates).

    Returns:
        ``(Y_force (3, 10 b), Y_moment (3, 10 b))`` [N, N·m per unit parameter]: with
        ``π = lumped_parameters(robot).ravel()``, ``Y_force @ π`` and ``Y_moment @ π``
        are :func:`jaxbal.shaking_wrench` (no gravity; moment about the base origin).
        The columns are independent of the robot's masses. Batch with ``jax.vmap``.

    Raises:
        ValueError: a wrong shape; eagerly, a non-finite state or robot parameter (e.g.
            a NaN length set with ``eqx.tree_at``) or an overflow; under ``jit`` the
            same value checks at run time (:func:`jaxbal.set_runtime_checks`).
    """
    q, qd, qdd, check = state_check(robot, q, qd, qdd)
    force, moment = _columns(frame_kinematics(robot, q, qd, qdd))
    columns = (force.reshape(3, -1), moment.reshape(3, -1))

    def checks(columns):
        return checked_finite("wrench regressor", robot, checked_parameters(robot, check(columns)))

    return merged_guards(checks, columns)


class LinearWrench(NamedTuple):
    """The shaking wrench along a motion as a linear map (:func:`linear_wrench`).

    Attributes:
        force: ``(t, 3, p)`` regressor of the shaking force.
        moment: ``(t, 3, p)`` regressor of the shaking moment about the base origin.
        names: ``(p,)`` parameter names (:func:`parameter_names`).
    """

    force: Array
    moment: Array
    names: tuple[str, ...]


@eqx.filter_jit
def _along(robot: Robot, motion: Motion, checks: bool):
    """:func:`wrench_regressor` at every sample (``checks``: static, the runtime value
    checks on or off while tracing, so that each setting has its own program)."""
    with runtime_checks(checks):
        return jax.vmap(lambda *state: wrench_regressor(robot, *state))(*motion)


def _compiled(evaluate, robot: Robot, motion: Motion):
    return _along(robot, motion, runtime_checks_enabled())


def linear_wrench(robot: Robot, motion) -> LinearWrench:
    """:func:`wrench_regressor` at every sample of ``motion`` (a
    :class:`~jaxbal.design.Motion` or ``(q, q̇, q̈)`` of ``(t, dof)``), compiled once
    per robot structure and motion length; eagerly the robot and motion are checked by
    name first, as the metrics' (a NaN length, a negative mass, a non-finite state)."""
    force, moment = batched(wrench_regressor, robot, motion, "wrench regressor", run=_compiled)
    return LinearWrench(force, moment, parameter_names(robot))


class Conditions(NamedTuple):
    """Linear conditions ``matrix @ π = 0`` on the lumped parameters for a vanishing
    shaking force or moment along a motion (:func:`balancing_conditions`).

    Attributes:
        matrix: ``(k, p)`` conditions in reduced row-echelon form (each row's leading
            parameter has coefficient 1 and appears in no other row) [SI units of the
            parameters: a row mixes kg, kg·m and kg·m² with coefficients in m, m²].
        names: ``(p,)`` parameter names (:func:`parameter_names`).
        singular_values: of the column-equilibrated regressor, descending.
        rank: ``k``, the number of independent conditions.
    """

    matrix: np.ndarray
    names: tuple[str, ...]
    singular_values: np.ndarray
    rank: int

    def residuals(self, robot: Robot) -> np.ndarray:
        """``(k,)`` ``matrix @ π`` of ``robot`` (zero when it meets the conditions)
        [kg, kg·m, kg·m² as the rows mix them].

        Raises:
            ValueError: ``robot``'s bodies are not those the conditions were derived for.
        """
        names = parameter_names(robot)
        if names != self.names:
            raise ValueError(
                f"the conditions are for the parameters {self.names[:3]}… "
                f"({len(self.names)}), this robot has {names[:3]}… ({len(names)})"
            )
        return self.matrix @ np.ravel(np.asarray(lumped_parameters(robot)))

    def equations(self, digits: int = 6, atol: float = 1e-12) -> list[str]:
        """The conditions as readable equations, e.g. ``link1.h_x + 0.3 link2.m + … = 0``
        (coefficients below ``atol`` omitted)."""
        lines = []
        for row in self.matrix:
            text = ""
            for c, name in zip(row, self.names, strict=True):
                if abs(c) <= atol:
                    continue
                size = "" if np.isclose(abs(c), 1.0, rtol=0, atol=atol) else f"{abs(c):.{digits}g} "
                sign = ("- " if c < 0 else "+ ") if text else ("-" if c < 0 else "")
                text += f"{' ' if text else ''}{sign}{size}{name}"
            lines.append(text + " = 0")
        return lines


def _row_echelon(rows: np.ndarray, atol: float) -> np.ndarray:
    """Reduced row-echelon form of ``rows`` (Gauss-Jordan, partial pivoting)."""
    rows = rows.copy()
    pivot_row = 0
    for col in range(rows.shape[1]):
        if pivot_row == rows.shape[0]:
            break
        best = pivot_row + int(np.argmax(np.abs(rows[pivot_row:, col])))
        if abs(rows[best, col]) <= atol:
            continue
        rows[[pivot_row, best]] = rows[[best, pivot_row]]
        rows[pivot_row] /= rows[pivot_row, col]
        others = np.arange(rows.shape[0]) != pivot_row
        rows[others] -= np.outer(rows[others, col], rows[pivot_row])
        pivot_row += 1
    rows[np.abs(rows) <= atol] = 0.0
    return rows


def balancing_conditions(
    robot: Robot, motion, part: str = "force", rtol: float = RANK_RTOL
) -> Conditions:
    """Linear conditions on the lumped parameters under which the shaking force (or
    moment, or both) vanishes at every sample of ``motion`` (module doc).

    Args:
        robot: any :class:`~jaxbal.robot.Robot` (the conditions do not depend on its
            masses: only on its frames and the list of its bodies).
        motion: a :class:`~jaxbal.design.Motion` or ``(q, q̇, q̈)`` of ``(t, dof)``;
            use a generic one (every joint moving independently) for the conditions
            of balance along every motion.
        part: ``"force"``, ``"moment"`` (about the base origin) or ``"both"``.
        rtol: singular values below ``rtol`` times the largest count as zero.

    Returns:
        :class:`Conditions`; ``conditions.residuals(robot)`` is zero (to rounding) for a
        robot balanced along the motion.

    Raises:
        ValueError: an unknown ``part``, a ``rtol`` outside ``(0, 1)``, (as
            :func:`linear_wrench`) an invalid robot or motion, or a call inside
            ``jit``/``vmap``/``grad`` (a host-side analysis; it raised a
            ``TracerArrayConversionError``).
    """
    if _under_trace():
        raise ValueError(
            "balancing_conditions is a host-side analysis (a NumPy SVD giving named "
            "conditions): call it outside jit/vmap/grad; traced code can use linear_wrench"
        )
    if part not in ("force", "moment", "both"):
        raise ValueError(f"part must be 'force', 'moment' or 'both', got {part!r}")
    if not 0.0 < float(rtol) < 1.0:
        raise ValueError(f"rtol must lie in (0, 1), got {rtol!r}")
    linear = linear_wrench(robot, motion)
    chosen = {"force": (linear.force,), "moment": (linear.moment,)}.get(
        part, (linear.force, linear.moment)
    )
    stacked = np.concatenate([np.asarray(y).reshape(-1, y.shape[-1]) for y in chosen])
    norms = np.linalg.norm(stacked, axis=0)
    rounding = norms <= ZERO_COLUMN_RTOL * np.max(norms, initial=0.0)
    stacked, norms = np.where(rounding, 0.0, stacked), np.where(rounding, 0.0, norms)
    scale = np.where(norms > 0.0, norms, 1.0)
    _, singular, vt = np.linalg.svd(stacked / scale, full_matrices=False)
    rank = int(np.sum(singular > rtol * singular[0])) if singular[0] > 0 else 0
    # Y π = (Y / s)(s π): a condition v on the scaled parameters is v s on π; the
    # parameters whose column is zero are unconstrained (exact zeros, not rounding)
    rows = np.where(norms > 0.0, vt[:rank] * scale, 0.0)
    atol = CLEAN_RTOL * max(float(np.max(np.abs(rows), initial=0.0)), 1e-300)
    matrix = _row_echelon(rows, atol)
    return Conditions(matrix, linear.names, singular, rank)
