"""Eager checks of a co-design's inputs, shared by ``codesign`` and ``joint_codesign`` (and
of the numeric options of ``sensitivity`` and ``tolerance``: :func:`check_positive_number`).

Each raises ``ValueError`` naming the offending input *before* anything compiles or
optimises. Without them a bad input ran a whole optimisation and came back as a number:
a negative lower bound on a counter-mass gave a −9 kg body with an "added mass" of 0,
a negative penalty rewarded breaking the constraint, a NaN budget gave ``value = nan``,
a start outside the bounds was silently clipped while "before" reported the unclipped
design, and a non-positive ``sharpness`` turned the smooth worst case into a best case.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from jaxbal._src.metrics import metric_name, resolve_metric
from jaxbal._src.payload_aggregate import ROBUST
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_robot

__all__ = [
    "BOUND_RTOL",
    "check_constraints",
    "check_lower_bounds",
    "check_payloads",
    "check_penalty",
    "check_robust",
    "check_positive_number",
    "check_rounds",
    "check_scales",
    "start_inside",
    "starts_inside",
]

# A design read back from a robot (e.g. a solution's, as the next start) may sit this
# relative rounding error outside a bound it reached: accepted, and clipped onto it.
BOUND_RTOL = 1e-12


def check_constraints(constraints: Mapping[Any, float] | None):
    """``(names, bounds (c,))`` of ``{metric: upper bound}``: every metric known, every
    bound finite, and a named metric's (a norm or a mass, ``>= 0``) bound ``>= 0``."""
    constraints = dict(constraints or {})
    constrained = tuple(constraints)
    for metric in constrained:
        resolve_metric(metric)
    bounds = np.array([float(b) for b in constraints.values()], dtype=float)
    if not np.all(np.isfinite(bounds)):
        raise ValueError(f"constraint bounds must be finite, got {constraints}")
    for metric, bound in zip(constrained, bounds, strict=True):
        if isinstance(metric, str) and bound < 0:
            raise ValueError(
                f"constraints[{metric!r}] = {float(bound)!r} is negative: the metric is >= 0, "
                "so the budget cannot be met"
            )
    return constrained, bounds


def check_positive_number(name: str, value) -> None:
    """Raise ``ValueError`` naming ``value`` unless it is a real number (or a 0-d real
    array; not a bool), finite and > 0: a step, a tolerance, a scale given as an option."""
    number = np.asarray(value)  # a bool, string, None or sequence: not of kind i, u, f
    real = number.ndim == 0 and number.dtype.kind in "iuf"
    if not (real and np.isfinite(number) and number > 0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")


def check_scales(scales: Mapping[str, float] | None, terms) -> dict[str, float]:
    """``scales`` as a dict, each a finite number > 0 naming an objective metric (a scale
    of 0 or −1 was silently replaced by the metric's floor)."""
    names = {metric_name(m) for m in terms}
    for name, scale in dict(scales or {}).items():
        if name not in names:
            raise ValueError(f"scales names {name!r}, not an objective metric of {sorted(names)}")
        check_positive_number(f"scales[{name!r}]", scale)
    return dict(scales or {})


def check_penalty(penalty) -> None:
    """A negative penalty rewards breaking the constraints; NaN makes every loss NaN."""
    if not (np.isfinite(float(penalty)) and float(penalty) >= 0):
        raise ValueError(f"penalty must be finite and >= 0, got {penalty!r}")


def check_robust(robust: str, sharpness) -> None:
    """``robust`` is ``"mean"``, ``"rms"`` or ``"max"``; the smooth maximum's ``sharpness`` is a
    finite number ``> 0`` (a negative one is a smooth *minimum*, zero gives NaN)."""
    if robust not in ROBUST:
        raise ValueError(f"robust must be one of {ROBUST}, got {robust!r}")
    value = float(np.asarray(sharpness))
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"sharpness must be finite and > 0, got {sharpness!r}")


def check_rounds(rounds) -> None:
    """The number of penalty rounds: an integer ``>= 1``."""
    integral = isinstance(rounds, int | np.integer) and not isinstance(rounds, bool)
    if not (integral and rounds >= 1):
        raise ValueError(f"rounds must be an integer >= 1, got {rounds!r}")


def check_payloads(payloads) -> np.ndarray:
    """``(n,)`` payloads [kg]: at least one, each finite and ``>= 0``."""
    values = np.asarray(payloads, dtype=float).reshape(-1)
    if values.size == 0:
        raise ValueError("payloads must hold at least one payload [kg], got none")
    bad = ~(np.isfinite(values) & (values >= 0))
    if np.any(bad):
        raise ValueError(f"payloads must be finite and >= 0 kg, got {values[bad].tolist()}")
    return values


def check_lower_bounds(robot: Robot, free, lows) -> None:
    """A lower bound below the robot's own (:meth:`~jaxbal.Robot.design_lower_bounds`)
    is allowed only where the robot stays a robot there: a negative counter-mass
    distance puts the mass on the other side, a negative counter-*mass* is no body."""
    own = robot.design_lower_bounds()
    for name, lo in zip(free, lows, strict=True):
        if name not in own or not np.any(lo < own[name]):
            continue
        try:
            check_robot(robot.with_design({name: lo}))
        except ValueError as error:
            raise ValueError(
                f"lower[{name!r}] = {np.asarray(lo).tolist()} gives an invalid robot "
                f"({error}); {type(robot).__name__}'s own lower bound of {name!r} is "
                f"{own[name]}"
            ) from None


def start_inside(name: str, x0: np.ndarray, lo, hi) -> np.ndarray:
    """``x0`` clipped onto ``[lo, hi]`` within :data:`BOUND_RTOL`; raise ``ValueError``
    listing the entries (up to 4) further outside."""
    lo, hi = np.asarray(lo, dtype=float), np.asarray(hi, dtype=float)
    slack = BOUND_RTOL * np.maximum(1.0, np.abs(x0))
    outside = (x0 < lo - slack) | (x0 > hi + slack)
    if np.any(outside):
        where = [tuple(int(i) for i in k) for k in np.argwhere(outside)][:4]
        listed = ", ".join(
            f"[{', '.join(map(str, k))}] = {float(np.asarray(x0)[k]):.6g} not in "
            f"[{float(np.broadcast_to(lo, outside.shape)[k]):.6g}, "
            f"{float(np.broadcast_to(hi, outside.shape)[k]):.6g}]"
            for k in where
        )
        raise ValueError(
            f"start of {name!r} lies outside its bounds ({int(outside.sum())} entries): "
            f"{listed}; pass start= inside lower=/upper="
        )
    return np.clip(x0, lo, hi)


def starts_inside(x0: Mapping[str, Any], lows, highs, two_sided) -> dict[str, np.ndarray]:
    """:func:`start_inside` of every free variable (``x0`` in the bounds' order; an upper
    bound applies where ``two_sided``)."""
    return {
        name: start_inside(name, np.asarray(x, dtype=float), lo, hi if two else np.inf)
        for (name, x), lo, hi, two in zip(x0.items(), lows, highs, two_sided, strict=True)
    }
