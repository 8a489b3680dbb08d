"""Studies of Arakelian & Briot (2008) on the SCARA: the printed balanced design, the
balancing cases of Figs 4 and 6, and the co-design trade-off front.

**The printed design (§3).** The paper prints the balanced links with their
counter-masses merged in: ``m_1 = 6.2 kg``, ``m_2 = 4.8 kg``, ``l_O1S1 = −0.117 m``,
``l_O2S2 = −0.047 m``, ``I_1 = 0.175 kg·m²``, ``I_2 = 0.112 kg·m²``
(:data:`PRINTED_BALANCED`). :func:`printed_balance_ratios` measures how far they are
from conditions (2)-(3) of :mod:`jaxbal.robots.scara_balancing`;
:func:`printed_force_balanced` makes them exact by recomputing ``l_O1S1, l_O2S2`` from
(2)-(3) with ``M_3 = m_3 + m_v`` (the vertical counterweight of Fig 5 counted at O3),
keeping the printed ``m_i`` and ``I_i`` (about the merged COM, or about the joints).

With ``m_3 = 0.5 kg`` alone, as (2)-(3) are printed, the printed values violate (2) by
100% and (3) by 9%; with the 0.5 kg vertical counterweight counted at O3
(``M_3 = 1.0 kg``) they satisfy both to their 3-digit rounding (< 0.3%): the printed
design includes the counterweight of Fig 5. Its ``m_1, m_2, l_O1S1, l_O2S2`` are exactly
what counter-masses of 5.01 kg and 2.81 kg at 0.16 m behind O1 and O2 give (the nominal
``r_c`` of :func:`~jaxbal.robots.scara`); exact (2)-(3) give ``l_O1S1 = −0.11694 m`` and
``l_O2S2 = −0.046875 m`` (the rounded values leave 0.06 N). The printed
``I_1 = 0.175`` and ``I_2 = 0.112 kg·m²`` are not what point counter-masses give (0.062
and 0.123 about the merged COM): ``I_1`` needs a counter-mass with its own inertia, and
``I_2`` is even *below* the point-mass value (it could be taken about O2 for a link
whose ``I_2 = 0.036`` is about O2). The paper does not say.

**Moment increase.** Force balancing raises the peak ``|m_z|`` by the factor
``(J_1 θ̈1 + J_2 θ̈12 + J_3 φ̈)`` over the unbalanced moment, ``J_i`` the inertias about
the joint axes *including the carried masses* (``m l²`` terms, eq 7): 5.4 with the
printed inertias about the merged COM, 4.3 about the joints, 4.0 with point
counter-masses, where the paper reads "about 3" off its Fig 4 (its ADAMS model, the
counter-mass shapes and the moment point are not given).

**The cases of Figs 4 and 6.** :func:`balancing_cases` returns the paper's move on the
unbalanced robot, on the force-balanced robots (printed, and ours from the closed form
of eqs 1-3) and on the fully balanced ones (force balance plus the end-effector rotation
law of eq 7 integrated exactly; and eq 8 as printed).

**Co-design.** :func:`codesign_samples` samples a set of pick-and-place moves;
:func:`tradeoff_front` traces the residual RMS shaking force against the added mass or
added joint-axis inertia as the penalty weight of
:func:`~jaxbal.robots.scara_balancing.codesign_counter_masses` grows.

References:
    Arakelian, V., Briot, S. (2008). Dynamic balancing of the SCARA robot. RoManSy 17,
    §3, eqs (1)-(3), (7), (8), Figs 4-6.
"""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp
import numpy as np

from jaxbal._src.robots.scara import PickAndPlace, Scara, joint_trajectory, scara
from jaxbal._src.robots.scara_balancing import (
    ReactionlessTrajectory,
    added_inertia,
    added_mass,
    angular_momentum_coefficients,
    balance_residuals,
    codesign_counter_masses,
    eq8_orientation,
    force_balanced,
    merged_links,
    move_samples,
    reactionless_turns,
    residual_force_ratio,
)
from jaxbal._src.types import Array, Float

__all__ = [
    "JOINT_INERTIA_VARIANT",
    "PRINTED_BALANCED",
    "balancing_cases",
    "closed_form_vs_printed",
    "codesign_samples",
    "printed_balance_ratios",
    "printed_force_balanced",
    "printed_scara",
    "rotation_law_summary",
    "tradeoff_front",
]

#: §3: the printed balanced links, counter-masses merged in [kg, m, kg·m²].
PRINTED_BALANCED = {
    "m1": 6.2,
    "m2": 4.8,
    "l_O1S1": -0.117,
    "l_O2S2": -0.047,
    "I1": 0.175,
    "I2": 0.112,
}
#: Name of the case of :func:`balancing_cases` with the printed ``I_i`` about the joints.
JOINT_INERTIA_VARIANT = "force-balanced (printed, I_i about the joints)"
_PRINTED_INERTIAS = (PRINTED_BALANCED["I1"], PRINTED_BALANCED["I2"])


def printed_scara(offsets, vertical_counterweight, inertias=_PRINTED_INERTIAS) -> Scara:
    """The SCARA with the printed balanced links 1, 2 (masses ``m_1, m_2`` of §3, no
    separate counter-masses) and the unbalanced end-effector.

    Args:
        offsets: ``(l_O1S1, l_O2S2)`` of the merged links [m].
        vertical_counterweight: ``m_v`` [kg] (Fig 5).
        inertias: ``(I_1, I_2)`` about the merged COMs [kg·m²] (default: printed).
    """
    base = scara()
    return Scara(
        base.lengths,
        [offsets[0], offsets[1], 0.0],
        [PRINTED_BALANCED["m1"], PRINTED_BALANCED["m2"], base.masses[2]],
        [inertias[0], inertias[1], base.inertias[2]],
        vertical_counterweight=vertical_counterweight,
    )


def closed_form_vs_printed(robot: Scara | None = None) -> list[tuple]:
    """The closed-form balanced design (eqs 1-3 and Fig 5) beside the printed one (§3).

    Returns:
        Rows ``(quantity, value, unit, printed value or None)``: the merged link masses,
        COM offsets and inertias about the merged COM (point counter-masses), then the
        counter-masses ``m_c1, m_c2`` and the vertical counterweight ``m_v``.
    """
    balanced = force_balanced(scara() if robot is None else robot)
    mass, offset, inertia = merged_links(balanced)
    distances = [float(r) for r in balanced.counter_distances]
    printed = PRINTED_BALANCED
    return [
        ("m1 (link 1 + counter-mass)", mass[0], "kg", printed["m1"]),
        ("l_O1S1", offset[0], "m", printed["l_O1S1"]),
        ("m2 (link 2 + counter-mass)", mass[1], "kg", printed["m2"]),
        ("l_O2S2", offset[1], "m", printed["l_O2S2"]),
        ("I1 about merged COM (point counter-mass)", inertia[0], "kg·m²", printed["I1"]),
        ("I2 about merged COM (point counter-mass)", inertia[1], "kg·m²", printed["I2"]),
        (f"m_c1 at r_c1 = {distances[0]:g} m", balanced.counter_masses[0], "kg", None),
        (f"m_c2 at r_c2 = {distances[1]:g} m", balanced.counter_masses[1], "kg", None),
        ("m_v vertical counterweight", balanced.vertical_counterweight, "kg", None),
    ]


def printed_balance_ratios(vertical_counterweight) -> Float[Array, "2"]:
    """Printed static moments over those conditions (2) and (3) require [-].

    ``m_i·|l_OiSi| / (m_i·|l_OiSi| + residual_i)`` for (2) (link 2) and (3) (link 1),
    with the printed offsets and ``M_3 = m_3 + m_v``: 1 when the printed design
    satisfies the condition exactly.

    References: Arakelian & Briot (2008), eqs (2)-(3) and §3.
    """
    moments = (
        PRINTED_BALANCED["m2"] * -PRINTED_BALANCED["l_O2S2"],
        PRINTED_BALANCED["m1"] * -PRINTED_BALANCED["l_O1S1"],
    )
    offsets = (PRINTED_BALANCED["l_O1S1"], PRINTED_BALANCED["l_O2S2"])
    residual = balance_residuals(printed_scara(offsets, vertical_counterweight))
    return jnp.stack(
        [moment / (moment + residual[k]) for k, moment in zip((1, 2), moments, strict=True)]
    )


def printed_force_balanced(
    vertical_counterweight=0.5, inertias_about: str = "com"
) -> tuple[Scara, Float[Array, "2"]]:
    """The printed design made exact: ``l_O1S1, l_O2S2`` from conditions (3), (2).

    Args:
        vertical_counterweight: ``m_v`` [kg]; 0.5 kg (= m_3) balances the vertical axis.
        inertias_about: ``"com"``: the printed ``I_1, I_2`` are about the merged COMs;
            ``"joints"``: about the joints O1, O2 (``I_com = I − m l_OiSi²``).

    Returns:
        ``(robot, offsets)``, the offsets ``(l_O1S1, l_O2S2)`` [m].
    """
    if inertias_about not in ("com", "joints"):
        raise ValueError(f"inertias_about must be 'com' or 'joints', got {inertias_about!r}")
    unbalanced = printed_scara((0.0, 0.0), vertical_counterweight)
    offsets = -balance_residuals(unbalanced)[jnp.array([2, 1])] / unbalanced.masses[:2]
    robot = printed_scara(offsets, vertical_counterweight)
    if inertias_about == "joints":
        about_com = jnp.array(_PRINTED_INERTIAS) - robot.masses[:2] * offsets**2
        robot = printed_scara(offsets, vertical_counterweight, inertias=about_com)
    return robot, offsets


def balancing_cases(move: PickAndPlace, robot: Scara | None = None) -> dict:
    """The balancing cases of Figs 4 and 6 along ``move``: name ↦ ``(robot, t ↦ q)``.

    ``unbalanced``; ``force-balanced`` and ``fully balanced`` (force balance and the
    exact reactionless rotation law) for the printed design
    (:func:`printed_force_balanced`) and for ours (the closed form ``force_balanced``
    of ``robot``); ``eq (8) as printed`` (the printed
    design with eq 8's rotation law); :data:`JOINT_INERTIA_VARIANT`.

    Args:
        move: the end-effector move, starting at rest.
        robot: the unbalanced SCARA (default: the paper's, :func:`~jaxbal.robots.scara`).
    """
    robot = scara() if robot is None else robot
    printed, _ = printed_force_balanced()
    ours = force_balanced(robot)
    variant, _ = printed_force_balanced(inertias_about="joints")
    return {
        "unbalanced": (robot, joint_trajectory(robot, move)),
        "force-balanced (printed)": (printed, joint_trajectory(printed, move)),
        "fully balanced (printed)": (printed, ReactionlessTrajectory(printed, move)),
        "eq (8) as printed": (printed, ReactionlessTrajectory(printed, move, law=eq8_orientation)),
        "force-balanced (ours)": (ours, joint_trajectory(ours, move)),
        "fully balanced (ours)": (ours, ReactionlessTrajectory(ours, move)),
        JOINT_INERTIA_VARIANT: (variant, joint_trajectory(variant, move)),
    }


def rotation_law_summary(robot: Scara, move: PickAndPlace) -> dict:
    """The exact rotation law of a force-balanced SCARA on a move, as table columns.

    Returns:
        ``column ↦ (value, unit)``: the net turns of φ (absolute) and of θ3 (relative to
        link 2) over the move [turn], and ``J_1, J_2, J_3`` [kg·m²] of
        :func:`~jaxbal.robots.scara_balancing.angular_momentum_coefficients`.

    References: Arakelian & Briot (2008), eqs (7)-(8) and Fig 6.
    """
    turns_phi, turns_theta3 = reactionless_turns(robot, move, move.duration)
    summary = {
        "turns of φ (absolute)": (turns_phi, "turn"),
        "turns of θ3 (relative to link 2)": (turns_theta3, "turn"),
    }
    for k, j in enumerate(angular_momentum_coefficients(robot)):
        summary[f"J_{k + 1}"] = (j, "kg·m²")
    return summary


def codesign_samples(robot: Scara, moves: Sequence[PickAndPlace], count: int = 32):
    """``(q, q̇, q̈)`` at ``count`` instants of each move's joint motion, stacked
    (:func:`~jaxbal.robots.scara_balancing.move_samples`)."""
    paths = [joint_trajectory(robot, move) for move in moves]
    return move_samples(paths, [move.duration for move in moves], count=count)


def tradeoff_front(
    robot: Scara,
    samples,
    weights: Sequence[float],
    penalty: str = "mass",
    start: Float[Array, "4"] | None = None,
) -> np.ndarray:
    """Co-design trade-off front: ``(len(weights), 2)`` rows ``(added, residual)``.

    For every weight, the penalised co-design (variables ``m_c1, m_c2, m_c3, m_v``) is
    solved from ``start`` (default: the closed form of eqs 1-3); ``added`` is its added
    mass [kg] (``penalty="mass"``) or added ``J_1 + J_2 + J_3`` [kg·m²]
    (``penalty="inertia"``), ``residual`` its RMS shaking force over ``samples``
    relative to the robot without counter-masses [-].

    References: Arakelian & Briot (2008), eq (7) (the inertias ``J_i`` that raise the
    shaking moment).
    """
    if penalty not in ("mass", "inertia"):
        raise ValueError(f"penalty must be 'mass' or 'inertia', got {penalty!r}")
    if start is None:
        balanced = force_balanced(robot)
        start = jnp.concatenate([balanced.counter_masses, balanced.vertical_counterweight[None]])
    points = []
    for weight in weights:
        key = "mass_weight" if penalty == "mass" else "inertia_weight"
        design = codesign_counter_masses(robot, samples, start, **{key: weight}).params
        residual = residual_force_ratio(robot, design, samples)
        added = added_mass(design) if penalty == "mass" else added_inertia(robot, design)
        points.append((float(added), float(residual)))
    return np.array(points)
