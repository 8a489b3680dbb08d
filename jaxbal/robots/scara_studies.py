"""Studies of Arakelian & Briot (2008) on the SCARA: the printed balanced design, the
balancing cases of Figs 4 and 6 and the co-design trade-off front (public face of
:mod:`jaxbal._src.robots.scara_studies`)."""

from jaxbal._src.robots.scara_studies import (
    JOINT_INERTIA_VARIANT,
    PRINTED_BALANCED,
    balancing_cases,
    closed_form_vs_printed,
    codesign_samples,
    printed_balance_ratios,
    printed_force_balanced,
    printed_scara,
    rotation_law_summary,
    tradeoff_front,
)

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
