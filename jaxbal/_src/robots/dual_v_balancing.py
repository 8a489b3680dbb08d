"""DUAL-V force balance: eqs (1)-(2), reduced mass, sensitivity, counter-mass co-design.

For a non-rotated platform the linear momentum of the DUAL-V is a combination of the
rates of the four link directions ``e_11, e_21, e_22 (= e_31), e_12 (= e_41)`` (the two
parallelograms, see :mod:`jaxbal.robots.dual_v`) with coefficients ``μ*_i - m_cm,i·p_cm,i``;
``μ*`` is the left-hand side of eq (2) (or eq (1)). Because ``C_1 = C_2`` ties the four
directions (``l(ė_11 + ė_12) = l(ė_21 + ė_22)`` when all links are equal), the exactly
balanced designs form a *line* ``μ* + c·(-1, +1, +1, -1)``: moving counter-mass moment
from the pair (1, 4) to the pair (2, 3) keeps the force balance. Eqs (1) and (2)
differ precisely along that line (by ``l·(m_eq,32 - m_eq,12)``), so both are exact.

Without counter-masses the shaking force of a non-rotated translation is
``-m_red·a_5`` with ``m_red = 2μ*/l_i1`` (§6); a counter-mass moment short by ``δμ`` on
every arm acts like a payload ``2δμ/l_i1`` at the platform centre, eq (30).

References:
    van der Wijk, Krut, Pierrot & Herder (2013), eqs (1), (2), (30), §6 and §7.2;
    van der Wijk et al. (2011) for eq (1), van der Wijk & Herder (2012b) for eq (2).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import jaxbal
from jaxbal._src.robots.dual_v import DualV
from jaxbal._src.sweep import sweep
from jaxbal._src.sweep_axes import grid
from jaxbal._src.types import Array, Float

__all__ = [
    "BALANCE_NULL_DIRECTION",
    "balance_condition_eq1",
    "balance_condition_eq2",
    "balance_fraction",
    "balance_line_offsets",
    "balance_sweep",
    "codesign_loss",
    "counter_mass_design",
    "payload_sweep",
    "peak_force_x",
    "reduced_mass",
    "shaking_forces",
    "with_balance_fraction",
    "with_counter_mass_moments",
]

BALANCE_NULL_DIRECTION = np.array([-1.0, 1.0, 1.0, -1.0]) / 2.0


def balance_condition_eq1(robot: DualV) -> Float[Array, "4"]:
    """Required ``m_cm,i·p_cm,i`` [kg·m] by eq (1) (first design approach).

    The payload, a point mass at the platform centre, is counted with ``m_5``.
    """
    m1, p1, m2, p2, l1, l2 = robot.m1, robot.p1, robot.m2, robot.p2, robot.l1, robot.l2
    m5 = robot.m5 + robot.payload
    k = m2 * p2 / l2  # equivalent mass of link i2 at C_i
    return jnp.stack(
        [
            m1[0] * p1[0] + m2[0] * l1[0] * (1 - p2[0] / l2[0]) + m2[3] * p2[3]
            + k[2] * l2[3] + m5 * l2[3] / 2,
            m1[1] * p1[1] + m2[1] * l1[1] + k[0] * l1[1] + m5 * l1[1] / 2,
            m1[2] * p1[2] + m2[2] * l1[2] * (1 - p2[2] / l2[2]) + m2[1] * p2[1]
            + k[0] * l2[1] + m5 * l2[1] / 2,
            m1[3] * p1[3] + m2[3] * l1[3] + k[2] * l1[3] + m5 * l1[3] / 2,
        ]
    )  # fmt: skip


def balance_condition_eq2(robot: DualV) -> Float[Array, "4"]:
    """Required ``m_cm,i·p_cm,i`` [kg·m] by eq (2) (pantograph approach)."""
    m1, p1, m2, p2, l1 = robot.m1, robot.p1, robot.m2, robot.p2, robot.l1
    m5 = robot.m5 + robot.payload
    partner = jnp.array([3, 2, 1, 0])  # link j2 parallel to link i1
    return m1 * p1 + m2 * l1 + m2[partner] * p2[partner] + m5 * l1 / 2


def with_counter_mass_moments(robot: DualV, moments) -> DualV:
    """The robot with ``m_cm,i`` rescaled so that ``m_cm,i·p_cm,i = moments`` (tuning
    masses and ``p_cm`` kept; ``I_cm`` scaled with the mass)."""
    moments = jnp.broadcast_to(jnp.asarray(moments, dtype=float), (4,))
    tuning = (1.0 - robot.tuning_scale) * robot.m_tun * robot.p_tun
    m_cm = (moments + tuning) / robot.p_cm
    scale = m_cm / jnp.maximum(robot.m_cm, 1e-12)
    return eqx.tree_at(lambda r: (r.m_cm, r.inertia_cm), robot, (m_cm, robot.inertia_cm * scale))


def reduced_mass(robot: DualV) -> Float[Array, ""]:
    """``m_red = 2(μ* - m_cm·p_cm)/l_i1`` [kg], averaged over the arms (§6, eq 30).

    Exact ratio ``|f_sh|/|a_5|`` for non-rotated translations of a robot whose four
    arms are equal; 3.279 kg for the unbalanced prototype, 0.107 kg of equivalent
    payload for the prototype without tuning masses.
    """
    shortfall = balance_condition_eq2(robot) - robot.counter_mass_moments()
    return jnp.mean(2.0 * shortfall / robot.l1)


def balance_fraction(robot: DualV, reference=None) -> Float[Array, ""]:
    """Mounted ``m_cm·p_cm`` as a fraction of ``reference`` (default: eq 2) [-]."""
    reference = balance_condition_eq2(robot) if reference is None else reference
    return jnp.mean(robot.counter_mass_moments() / reference)


def shaking_forces(robot: DualV, q, qd, qdd) -> Float[Array, "t 2"]:
    """Planar shaking forces ``(t, 2)`` [N] along sampled joint motions ``(t, 11)``."""
    return jax.vmap(lambda a, b, c: jaxbal.shaking_wrench(robot, a, b, c)[0][:2])(q, qd, qdd)


def counter_mass_design(robot: DualV, params) -> DualV:
    """Robot with counter-masses ``params = (log m_cm (4,), log p_cm (4,))`` [log kg,
    log m] (logarithms keep masses and distances positive). Each designed counter-mass is
    one body (tuning masses folded in: ``m_tun = 0``); the radius of gyration
    ``sqrt(I_cm/m_cm)`` of the Table 1 counter-mass is kept (same shape, scaled)."""
    m_cm, p_cm = (jnp.exp(jnp.asarray(v, dtype=float)) for v in params)
    gyration2 = robot.inertia_cm / jnp.maximum(robot.m_cm, 1e-12)
    return eqx.tree_at(
        lambda r: (r.m_cm, r.p_cm, r.inertia_cm, r.m_tun),
        robot,
        (m_cm, p_cm, m_cm * gyration2, jnp.zeros(4)),
    )


def codesign_loss(params, robot: DualV, motion, weight, force_scale=100.0, inertia_scale=0.05):
    """Co-design objective: mean squared shaking force over the sampled motions
    ``motion = (q, q̇, q̈)`` ``(t, 11)`` each, plus ``weight`` times the summed reduced
    counter-mass inertias ``Σ I_cm,i + m_cm,i·p_cm,i²`` (scaled to O(1)) [-]."""
    design = counter_mass_design(robot, params)
    forces = shaking_forces(design, *motion)
    inertia = jnp.sum(design.counter_mass_inertia_about_base())
    return jnp.mean(jnp.sum(forces**2, -1)) / force_scale**2 + weight * inertia / inertia_scale


def balance_line_offsets(moments, reference) -> tuple[Float[Array, ""], Float[Array, ""]]:
    """How far counter-mass moments ``μ`` ``(4,)`` [kg·m] lie from a balance condition
    ``μ*`` ``(4,)`` (e.g. eq 1) [-]: ``(max_i |μ_i - μ*_i| / μ*_i, max_i |d_i| / μ*_i)``
    with ``d`` the part of ``μ - μ*`` off the line ``μ* + c·(-1, 1, 1, -1)`` of exactly
    balanced designs (the first is zero only at ``μ*``, the second on the whole line)."""
    deviation = moments - reference
    direction = BALANCE_NULL_DIRECTION
    along = deviation @ direction / (direction @ direction)
    off_line = jnp.max(jnp.abs(deviation - along * direction) / reference)
    return jnp.max(jnp.abs(deviation / reference)), off_line


def peak_force_x(robot: DualV, states) -> Float[Array, ""]:
    """``max_t |F_x|`` [N] along joint states ``(q, q̇, q̈)`` ``(t, 11)`` each (the metric
    of :func:`balance_sweep` and :func:`payload_sweep`, a :func:`jaxbal.sweep` metric)."""
    force = jax.vmap(lambda q, qd, qdd: jaxbal.shaking_wrench(robot, q, qd, qdd)[0][0])
    return jnp.max(jnp.abs(force(*states)))


def with_balance_fraction(robot: DualV, fraction) -> DualV:
    """The robot with ``m_cm,i·p_cm,i`` set to ``fraction`` of eq (2) (``m_cm`` scaled,
    ``p_cm``, ``I_cm`` and the tuning masses kept)."""
    masses = fraction * balance_condition_eq2(robot) / robot.p_cm
    return eqx.tree_at(lambda r: r.m_cm, robot, masses)


def _peak_force_x_sweep(robot: DualV, states, dim: str, axis):
    """``max_t |F_x|`` over one :func:`jaxbal.sweep` axis, as a labelled DataArray."""
    dataset = sweep(
        peak_force_x, robot, tuple(states), {dim: axis}, units="N",
        chunk_size=axis.size, progress=False,
    )  # fmt: skip
    return dataset["value"].rename("peak_force_x")


def balance_sweep(robot: DualV, states, fractions):
    """``max_t |F_x|`` [N] along joint states ``(q, q̇, q̈)`` ``(t, 11)`` each, with
    ``m_cm,i·p_cm,i`` set to each fraction of eq (2) (:func:`with_balance_fraction`): the
    shortfall acts as a payload ``2δμ/l_i1`` at the platform centre (eq 30).

    Returns:
        An :class:`xarray.DataArray` ``peak_force_x`` [N] over ``balance_fraction`` [-]
        (one :func:`jaxbal.sweep` block).
    """
    axis = grid(fractions, units="-", set=with_balance_fraction)
    return _peak_force_x_sweep(robot, states, "balance_fraction", axis)


def payload_sweep(robot: DualV, states, payloads):
    """``max_t |F_x|`` [N] along joint states ``(q, q̇, q̈)`` with each payload [kg] at the
    platform centre (eq 30: ``|F_x| = (m_red + payload)·|ẍ5|`` for translations).

    Returns:
        An :class:`xarray.DataArray` ``peak_force_x`` [N] over ``payload`` [kg] (the
        design variable, one :func:`jaxbal.sweep` block).
    """
    return _peak_force_x_sweep(robot, states, "payload", grid(payloads, units="kg"))
