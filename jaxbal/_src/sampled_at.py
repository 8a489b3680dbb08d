"""Is a concrete motion sampled at the times a metric assumes?

A :class:`~jaxbal.design.Motion` carries no times: a metric that integrates over time
(:class:`~jaxbal.vibration.BaseVibration`) takes them separately, and given the times of
another move with the same sample count it used them silently (a tester's 0.35 s move
under the times of a 0.5 s one: 126 µm of residual vibration for 209 µm). The samples
tell their own time step: between two instants the positions advance by the rates'
Hermite-corrected trapezoid ``Δq ≈ h (q̇₀ + q̇₁)/2 + h² (q̈₀ − q̈₁)/12`` (exact for a
quintic in ``t``; O(h⁵) per step for a smooth motion, O(h³) across a jump of ``q̈``
such as a bang-bang's switch). :func:`check_sampled_at` compares the two.
"""

from __future__ import annotations

import numpy as np

__all__ = ["MISMATCH", "check_sampled_at", "time_mismatch"]

#: largest relative mismatch accepted: ``Σ_k |Δq_k − Hermite_k| / Σ_k |Hermite_k|`` of
#: the worst joint (a correct bang-bang move: 0.048 at 4 samples, 0.007 at 8, 5e-6 at
#: 351; its samples under times 10 % too long: ≈ 0.09, under a 0.5 s move's for 0.35 s: 0.30)
MISMATCH = 0.1


def time_mismatch(q, qd, qdd, times) -> tuple[float, float]:
    """``(mismatch, scale)``: the relative mismatch of the worst moving joint (module
    doc; an error of a whole turn, 2π, counts as none: a wrapped angle), and the factor
    by which the samples' own time steps exceed ``times``' (least squares)."""
    q, qd, qdd = (np.asarray(x, dtype=float) for x in (q, qd, qdd))
    h = np.diff(np.asarray(times, dtype=float))[:, None]
    predicted = h * (qd[:-1] + qd[1:]) / 2.0 + h**2 * (qdd[:-1] - qdd[1:]) / 12.0
    step = np.diff(q, axis=0)
    step = predicted + np.mod(step - predicted + np.pi, 2.0 * np.pi) - np.pi
    path = np.sum(np.abs(predicted), axis=0)
    moving = path > 1e-12 * (1.0 + np.max(np.abs(q), axis=0))
    if not np.any(moving):
        return 0.0, 1.0
    error = np.sum(np.abs(step - predicted), axis=0)[moving] / path[moving]
    p, s = predicted[:, moving], step[:, moving]
    return float(np.max(error)), float(np.sum(p * s) / np.sum(p * p))


def check_sampled_at(motion, times, what: str) -> None:
    """Raise ``ValueError`` if the concrete ``motion`` (its ``q, q̇, q̈``) is not sampled at
    ``times`` (:data:`MISMATCH`), naming the duration its samples suggest."""
    times = np.asarray(times, dtype=float)
    if times.size < 2:
        return
    mismatch, scale = time_mismatch(motion.q, motion.qd, motion.qdd, times)
    if mismatch > MISMATCH:
        span = times[-1] - times[0]
        raise ValueError(
            f"{what}: the motion's rates do not integrate to its positions over the "
            f"metric's times ({span:.6g} s; relative mismatch {mismatch:.2g}): its samples "
            f"move as if over about {scale * span:.3g} s. Sample the motion at the "
            "metric's times (motion_samples(robot, moves, times))"
        )
