"""Complete balancing of the SCARA: counter-masses (closed form and optax co-design) and
the end-effector rotation law that cancels the shaking moment.

**Force balancing.** The total COM is stationary at O1 when (Arakelian & Briot 2008,
eqs 1-3, written with signed COM offsets and with the counter-masses ``m_ci`` at ``r_ci``
behind joint i)::

    (1)  m_3 l_O3S3 − m_c3 r_c3                      = 0   end-effector COM on the O3 axis
    (2)  m_2 l_O2S2 − m_c2 r_c2 + M_3 l_O2O3         = 0   COM of links 2, 3 at O2
    (3)  m_1 l_O1S1 − m_c1 r_c1 + (m_2 + m_c2 + M_3) l_O1O2 = 0   COM of links 1-3 at O1
    (v)  m_3 + m_c3 + m_payload − m_v                 = 0   vertical counterweight (Fig 5)

where ``M_3 = m_3 + m_c3 + m_payload + m_v`` is everything carried at O3. The paper
writes (2) and (3) with ``m_3`` alone; its printed balanced parameters satisfy them only
with ``M_3 = m_3 + m_v = 1.0 kg``, i.e. with the vertical counterweight counted at O3.

**Shaking moment.** For a force-balanced SCARA the angular momentum about the vertical
axis is exactly (no configuration-dependent cross terms, because each sub-chain's COM
sits on its proximal joint axis)::

    L_z = J_1 θ̇1 + J_2 (θ̇1 + θ̇2) + J_3 (θ̇1 + θ̇2 + θ̇3)

with ``J_1`` the inertia of link 1 (and its counter-mass) about O1 plus
``(m_2 + m_c2 + M_3) l_O1O2²``, ``J_2`` that of link 2 about O2 plus ``M_3 l_O2O3²``, and
``J_3`` that of the end-effector about O3. Eq (7) is this with ``J_i`` in place of the
paper's ``I_i``; eq (8) as printed, with the links' own axial inertias, does not cancel
the moment. Since the ``J_i`` are constant, ``L_z = 0`` integrates *exactly*::

    φ(t) = φ(0) − [J_1 (θ1(t) − θ1(0)) + J_2 (θ12(t) − θ12(0))] / J_3

so the rotation law is a closed form in the joint angles: no quadrature, no drift, and
the end-effector's net rotation depends only on the move's end points.

References:
    Arakelian, V., Briot, S. (2008). Dynamic balancing of the SCARA robot. RoManSy 17,
    eqs (1)-(3), (7), (8), Figs 4-6.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxbal._src.momentum import shaking_wrench
from jaxbal._src.optimize import Solution, minimize
from jaxbal._src.robots.scara import Scara
from jaxbal._src.trajectory import sample, sample_times
from jaxbal._src.types import Array, Float, Scalar, ScalarLike
from jaxbal._src.validation import guard

__all__ = [
    "ReactionlessTrajectory",
    "added_inertia",
    "added_mass",
    "angular_momentum_coefficients",
    "balance_residuals",
    "codesign_counter_masses",
    "codesign_loss",
    "counter_mass_design",
    "eq8_orientation",
    "force_balanced",
    "merged_links",
    "move_samples",
    "reactionless_orientation",
    "reactionless_turns",
    "residual_force_ratio",
    "with_counter_mass_design",
]


def _carried(robot: Scara):
    """Vertically moving mass, mass carried at O3 (M_3) and outboard of O2 (link 2 + M_3)."""
    vertical = robot.masses[2] + robot.counter_masses[2] + robot.payload
    at_o3 = vertical + robot.vertical_counterweight
    outboard_o2 = robot.masses[1] + robot.counter_masses[1] + at_o3
    return vertical, at_o3, outboard_o2


def balance_residuals(robot: Scara) -> Float[Array, "4"]:
    """Residuals of conditions (1), (2), (3) [kg·m] and of the vertical condition [kg].

    All four vanish for a completely force-balanced SCARA (see the module docstring).

    References: Arakelian & Briot (2008), eqs (1)-(3) and Fig 5.
    """
    vertical, at_o3, outboard_o2 = _carried(robot)
    moments = robot.masses * robot.com_offsets - robot.counter_masses * robot.counter_distances
    return jnp.stack(
        [
            moments[2],
            moments[1] + at_o3 * robot.lengths[1],
            moments[0] + outboard_o2 * robot.lengths[0],
            vertical - robot.vertical_counterweight,
        ]
    )


def force_balanced(robot: Scara, solve_for: str = "masses", vertical: bool = True) -> Scara:
    """The force-balanced design of any SCARA, in closed form (eqs 1-3 and Fig 5).

    Args:
        robot: the SCARA to balance (its links, payload and, depending on
            ``solve_for``, its counter-mass distances or masses are kept).
        solve_for: ``"masses"``: counter-mass sizes ``m_ci`` at the robot's distances
            ``r_ci``; ``"distances"``: positions ``r_ci`` for the robot's masses ``m_ci``
            (each must be > 0 where a static moment is needed).
        vertical: add the vertical counterweight (cable and pulley, Fig 5); without it
            the vertical inertia force and the moments about x and y remain.

    Returns:
        The balanced :class:`Scara` (differentiable in the robot's parameters).

    Raises:
        ValueError: eagerly, when balancing needs a negative counter-mass (the link's
            COM already lies behind its joint) or a counter-mass of zero size.
    """
    if solve_for not in ("masses", "distances"):
        raise ValueError(f"solve_for must be 'masses' or 'distances', got {solve_for!r}")
    solve_masses = solve_for == "masses"
    m, s, lengths = robot.masses, robot.com_offsets, robot.lengths
    given_name = "distances" if solve_masses else "masses"  # kept; the others solved
    given_values = robot.counter_distances if solve_masses else robot.counter_masses
    given = jnp.maximum(given_values, 1e-300)
    # Condition (1), then (v), (2), (3): each needs the mass carried by the next joint.
    moment3 = m[2] * s[2]
    mc3 = moment3 / given[2] if solve_masses else robot.counter_masses[2]
    vertical_mass = m[2] + mc3 + robot.payload
    m_v = vertical_mass if vertical else jnp.zeros(())
    at_o3 = vertical_mass + m_v
    moment2 = m[1] * s[1] + at_o3 * lengths[1]
    mc2 = moment2 / given[1] if solve_masses else robot.counter_masses[1]
    moment1 = m[0] * s[0] + (m[1] + mc2 + at_o3) * lengths[0]
    moments = jnp.stack([moment1, moment2, moment3])
    # a given counter-mass (distance) of zero is fine where no static moment is needed
    # (the nominal SCARA's link 3, l_O3S3 = 0: it was refused eagerly, while jit gave
    # 3.8e298 kg for l_O3S3 = 0.02); the message names the kept quantity (it named the
    # solved one)
    needed = ~((given_values > 0) | (moments == 0))
    given = guard(
        given,
        needed,
        f"force balancing needs positive given counter-{given_name} where a static "
        "moment must be balanced",
        given_values,
    )
    solved = moments / given
    solved = guard(
        solved,
        ~(solved >= 0),
        "force balancing needs a counter-mass in front of its joint (negative m_c or r_c)",
        solved,
    )
    if solve_masses:
        masses, distances = solved, robot.counter_distances
    else:
        masses, distances = robot.counter_masses, solved
    return eqx.tree_at(
        lambda r: (r.counter_masses, r.counter_distances, r.vertical_counterweight),
        robot,
        (masses, distances, m_v),
    )


def merged_links(robot: Scara) -> tuple[Float[Array, "3"], Float[Array, "3"], Float[Array, "3"]]:
    """Each link merged with its counter-mass: masses [kg], signed COM offsets [m] and
    axial inertias about the merged COM [kg·m²] (the form the paper prints, §3)."""
    mass = robot.masses + robot.counter_masses
    moment = robot.masses * robot.com_offsets - robot.counter_masses * robot.counter_distances
    offset = moment / jnp.maximum(mass, 1e-300)
    about_joint = (
        robot.inertias
        + robot.masses * robot.com_offsets**2
        + robot.counter_masses * robot.counter_distances**2
    )
    return mass, offset, about_joint - mass * offset**2


def angular_momentum_coefficients(robot: Scara) -> Float[Array, "3"]:
    """``(J_1, J_2, J_3)`` [kg·m²]: ``L_z = J_1 θ̇1 + J_2 θ̇12 + J_3 φ̇`` when force-balanced.

    ``J_1``: link 1 and counter-mass 1 about O1 plus everything outboard as a point mass
    at O2; ``J_2``: link 2 and counter-mass 2 about O2 plus ``M_3`` at O3; ``J_3``: the
    end-effector and counter-mass 3 about O3. Exact only when :func:`balance_residuals`
    vanish (otherwise ``L_z`` has configuration-dependent cross terms).

    References: Arakelian & Briot (2008), eq (7), with inertias about the joint axes.
    """
    _, at_o3, outboard_o2 = _carried(robot)
    own = (
        robot.inertias
        + robot.masses * robot.com_offsets**2
        + robot.counter_masses * robot.counter_distances**2
    )
    carried = jnp.stack([outboard_o2 * robot.lengths[0] ** 2, at_o3 * robot.lengths[1] ** 2, 0.0])
    return own + carried


def reactionless_orientation(
    robot: Scara, theta: Float[Array, "2"], theta_start: Float[Array, "2"], phi_start: ScalarLike
) -> Scalar:
    """End-effector orientation φ [rad] that keeps ``L_z = 0`` (exact integral of eq 8).

    Args:
        robot: a force-balanced SCARA.
        theta: ``(2,)`` current ``(θ1, θ2)`` [rad].
        theta_start: ``(2,)`` ``(θ1, θ2)`` at rest at the start of the move [rad].
        phi_start: φ at the start [rad].

    Raises:
        ValueError: ``J_3 <= 0`` (an end-effector of no axial inertia about O3 cannot
            absorb the links' angular momentum; it gave φ = ±inf silently), eagerly or
            under ``jit`` as a runtime error. The robot's force balance is not checked
            (the paper's printed, rounded design is evaluated with this law): on an
            unbalanced robot the move is not reactionless.
    """
    j1, j2, j3 = angular_momentum_coefficients(robot)
    message = "the rotation law needs J3 > 0, the end-effector's axial inertia about O3"
    j3 = guard(j3, ~(j3 > 0), message, j3)
    d1 = theta[0] - theta_start[0]
    d12 = theta[0] + theta[1] - theta_start[0] - theta_start[1]
    return phi_start - (j1 * d1 + j2 * d12) / jnp.where(j3 > 0, j3, jnp.nan)


def eq8_orientation(
    robot: Scara, theta: Float[Array, "2"], theta_start: Float[Array, "2"], phi_start: ScalarLike
) -> Scalar:
    """Eq (8) as printed, integrated twice from rest: the links' own axial inertias
    ``I_i`` instead of the joint-axis inertias ``J_i`` (does not cancel the moment)."""
    i1, i2, i3 = robot.inertias
    d1 = theta[0] - theta_start[0]
    d12 = theta[0] + theta[1] - theta_start[0] - theta_start[1]
    return phi_start - (i1 * d1 + i2 * d12) / i3


class ReactionlessTrajectory(eqx.Module):
    """Joint motion ``t ↦ q`` whose horizontal path and height follow ``move`` while the
    end-effector turns by the rotation law (the move's own φ is ignored but φ(0)).

    Attributes:
        robot: a force-balanced :class:`Scara`.
        move: ``t ↦ (x, y, φ, z)``, e.g. a :class:`~jaxbal.robots.scara.PickAndPlace`,
            starting at rest at ``t = 0``.
        branch: elbow branch of the inverse kinematics (default: the robot's).
        law: :func:`reactionless_orientation` (default) or :func:`eq8_orientation`.
    """

    robot: Scara
    move: Callable
    branch: tuple[int, ...] | int | None = eqx.field(static=True, default=None)
    law: Callable = eqx.field(static=True, default=reactionless_orientation)

    def __call__(self, t: ScalarLike) -> Float[Array, "4"]:
        start = self.robot.inverse_kinematics(self.move(0.0), branch=self.branch)
        q = self.robot.inverse_kinematics(self.move(t), branch=self.branch)
        phi = self.law(self.robot, q[:2], start[:2], self.move(0.0)[2])
        return q.at[2].set(phi - q[0] - q[1])


def reactionless_turns(robot: Scara, move: Callable, duration: ScalarLike, branch=None):
    """Net turns of the end-effector over a move: ``((φ(T) − φ(0))/2π, θ3(T) − θ3(0))/2π)``."""
    path = ReactionlessTrajectory(robot, move, branch)
    q0, q1 = path(0.0), path(duration)
    phi = lambda q: jnp.sum(q[:3])  # noqa: E731
    return (phi(q1) - phi(q0)) / (2 * jnp.pi), (q1[2] - q0[2]) / (2 * jnp.pi)


# --- co-design with optax ------------------------------------------------------------


def counter_mass_design(robot: Scara) -> Float[Array, "4"]:
    """The co-design variables ``(m_c1, m_c2, m_c3, m_v)`` [kg] of a SCARA."""
    return jnp.concatenate([robot.counter_masses, robot.vertical_counterweight[None]])


def with_counter_mass_design(robot: Scara, design: Float[Array, "4"]) -> Scara:
    """``robot`` with counter-masses and vertical counterweight from ``design``."""
    return eqx.tree_at(
        lambda r: (r.counter_masses, r.vertical_counterweight), robot, (design[:3], design[3])
    )


def added_mass(design: Float[Array, "4"]) -> Scalar:
    """Total mass added by a counter-mass design [kg]."""
    return jnp.sum(design)


def added_inertia(robot: Scara, design: Float[Array, "4"]) -> Scalar:
    """Increase of ``J_1 + J_2 + J_3`` due to the design [kg·m²] (what raises the moment)."""
    bare = with_counter_mass_design(robot, jnp.zeros(4))
    return jnp.sum(
        angular_momentum_coefficients(with_counter_mass_design(robot, design))
        - angular_momentum_coefficients(bare)
    )


def move_samples(trajectories: Sequence[Callable], durations: Sequence, count: int = 64):
    """Exact ``(q, q̇, q̈)`` at ``count`` instants of each trajectory ``t ↦ q`` on
    ``[0, T]``, stacked: each ``(len(trajectories)·count, 4)`` (jit-compiled)."""
    return _move_samples(list(trajectories), [jnp.asarray(T, float) for T in durations], count)


@eqx.filter_jit
def _move_samples(trajectories, durations, count):
    pairs = zip(trajectories, durations, strict=True)
    parts = [sample(path, sample_times(duration, count)) for path, duration in pairs]
    return tuple(jnp.concatenate([p[k] for p in parts]) for k in range(3))


def _mean_square_force(robot: Scara, samples) -> Scalar:
    forces = jax.vmap(lambda q, qd, qdd: shaking_wrench(robot, q, qd, qdd)[0])(*samples)
    return jnp.mean(jnp.sum(forces**2, axis=-1))


@eqx.filter_jit
def residual_force_ratio(robot: Scara, design: Float[Array, "4"], samples) -> Scalar:
    """RMS shaking force of ``design`` over the samples, relative to the bare robot [-]."""
    bare = with_counter_mass_design(robot, jnp.zeros(4))
    balanced = with_counter_mass_design(robot, design)
    return jnp.sqrt(_mean_square_force(balanced, samples) / _mean_square_force(bare, samples))


def codesign_loss(roots, robot: Scara, samples, weights) -> Scalar:
    """Mean squared shaking force relative to the bare robot, plus penalties.

    The variables are ``roots = √design`` (so every counter-mass stays ≥ 0):
    ``loss = ⟨|f|²⟩/⟨|f_0|²⟩ + w_m (Δm/m_links)² + w_J (ΔJ/J_0)²`` with ``f_0`` the force
    of the robot without counter-masses, ``Δm`` the added mass and ``ΔJ`` the added
    joint-axis inertia (:func:`added_inertia`). ``weights = (w_m, w_J)``.
    """
    design = roots**2
    bare = with_counter_mass_design(robot, jnp.zeros(4))
    scale = jax.lax.stop_gradient(_mean_square_force(bare, samples))
    residual = _mean_square_force(with_counter_mass_design(robot, design), samples) / scale
    j_bare = jnp.sum(angular_momentum_coefficients(bare))
    mass_term = (added_mass(design) / jnp.sum(robot.masses)) ** 2
    inertia_term = (added_inertia(robot, design) / j_bare) ** 2
    return residual + weights[0] * mass_term + weights[1] * inertia_term


def codesign_counter_masses(
    robot: Scara,
    samples,
    start: Float[Array, "4"],
    mass_weight: ScalarLike = 0.0,
    inertia_weight: ScalarLike = 0.0,
    max_steps: int = 200,
) -> Solution:
    """Optimal ``(m_c1, m_c2, m_c3, m_v)`` by optax L-BFGS (:func:`jaxbal.optimize.minimize`).

    The optimiser works on ``√m`` so that the masses stay non-negative; the returned
    ``Solution.params`` are the masses themselves [kg].

    With zero weights the loss is a least-squares problem whose zero is the closed form
    of :func:`force_balanced`; positive weights trade residual force for added mass or
    inertia. The counter-mass distances stay those of ``robot``.

    Args:
        robot: the SCARA (its counter-masses are ignored).
        samples: ``(q, q̇, q̈)`` from :func:`move_samples`.
        start: ``(4,)`` starting design [kg].
        mass_weight, inertia_weight: penalty weights (dimensionless).
        max_steps: L-BFGS iteration cap.
    """
    weights = jnp.asarray([mass_weight, inertia_weight], dtype=float)
    solution = minimize(
        codesign_loss,
        jnp.sqrt(jnp.asarray(start, dtype=float)),
        max_steps=max_steps,
        gtol=1e-14,
        args=(robot, samples, weights),
    )
    return solution._replace(params=solution.params**2)
