"""Studies of Geng et al. (2021) on the Orthoglide: §3 kinematics, Tables 1-2 over the
payloads, the fit of the moment reference point and slider offset, and the payload
error of §3.3 (public face of :mod:`jaxbal._src.robots.orthoglide_studies`)."""

from jaxbal._src.robots.orthoglide_studies import (
    ReferenceFit,
    case_histories,
    fit_moment_reference,
    fit_table,
    kinematic_summary,
    payload_cases,
    payload_error_peaks,
    payload_error_slopes,
    payload_error_table,
    payload_peaks,
    peaks_table,
    reference_errors,
    with_payload,
)

__all__ = [
    "ReferenceFit",
    "case_histories",
    "fit_moment_reference",
    "fit_table",
    "kinematic_summary",
    "payload_cases",
    "payload_error_peaks",
    "payload_error_slopes",
    "payload_error_table",
    "payload_peaks",
    "peaks_table",
    "reference_errors",
    "with_payload",
]
