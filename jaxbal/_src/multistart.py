"""Several starts of a joint co-design: the best design kept, and how much the
near-optimal designs differ.

A joint counter-mass + trajectory co-design is not convex (peak metrics, a φ law, the
switch times of a profile): each L-BFGS run ends in the local optimum its start leads
to. On the 3R COM co-design of ``experiments/beyond_com_codesign.py`` one run from the
paper's plan *with* counterweights allowed (a superset of the designs without) ended at
a worst peak moment of 83.46 N·m, above the 82.99 N·m reached without them. Here every
start is solved by :func:`~jaxbal.design.joint_codesign` (one compilation: later starts
reuse its program) with the **same** scales of the objective terms (their mean over
the payloads at the given start), so that the final losses compare; the best feasible
one is kept (the lowest loss when none is feasible).

Starts: the given one (``trajectory``, ``start``); ``extra_starts`` (e.g. the solution
of a smaller problem, so that a larger one cannot end worse); ``starts`` random ones,
reproducible from ``seed``: every trajectory entry uniform inside its bounds (1 % of
the span away from them), every free design variable with an upper bound uniform
between its bounds, the others as given. A random start the model refuses (e.g. a COM
line leaving the workspace for that φ law: ``ValueError``) is recorded with its message
and skipped; the given start is not (its error is raised).

The *near-optimal* starts are the feasible ones whose loss is within ``near_rtol`` of the
best: when they end at different designs, the optimum is flat and the reported design
is one of several equivalent ones (:meth:`MultiStart.spread` gives their range per
variable) — a number to quote with that range, not alone.

References:
    Nocedal & Wright (2006), Numerical Optimization, §2 (local minimisers; starts).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import jax.numpy as jnp
import numpy as np

from jaxbal._src.design_loss import _bounds, _objective_terms
from jaxbal._src.joint_codesign import JointSolution, _floors, joint_codesign, payload_metrics
from jaxbal._src.metrics import check_design_names, metric_name
from jaxbal._src.robot import Robot

__all__ = ["MultiStart", "multistart_joint_codesign"]

#: distance of a random trajectory start from its bounds, as a fraction of the span
INSET = 0.01


class MultiStart(NamedTuple):
    """Result of :func:`multistart_joint_codesign`.

    Attributes:
        best: the kept :class:`~jaxbal.design.JointSolution`.
        solutions: one per start (``None`` where the model refused the start).
        values: ``(K,)`` final losses, common scales (``inf`` where refused).
        feasible: ``(K,)`` whether each solution meets every constraint.
        near: ``(K,)`` feasible and within ``near_rtol`` of the best loss.
        kinds: ``(K,)`` ``"given"``, ``"extra"`` or ``"random"``.
        errors: ``(K,)`` the refusal's message, else ``None``.
    """

    best: JointSolution
    solutions: tuple[JointSolution | None, ...]
    values: np.ndarray
    feasible: np.ndarray
    near: np.ndarray
    kinds: tuple[str, ...]
    errors: tuple[str | None, ...]

    def spread(self) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """``name -> (min, max)`` of every trajectory variable and design variable over
        the near-optimal solutions (elementwise for array variables)."""
        chosen = [s for s, n in zip(self.solutions, self.near, strict=True) if n]
        out = {}
        for part in ("trajectory", "design"):
            for name in getattr(self.best, part):
                values = np.stack([np.asarray(getattr(s, part)[name], float) for s in chosen])
                out[name] = (values.min(axis=0), values.max(axis=0))
        return out


def _random_starts(rng, count, trajectory, t_lower, t_upper, design, free, lows, highs, two):
    starts = []
    for _ in range(count):
        theta = {}
        for name, value in trajectory.items():
            shape = np.shape(value)
            lo = np.broadcast_to(np.asarray(t_lower[name], float), shape)
            hi = np.broadcast_to(np.asarray(t_upper[name], float), shape)
            inset = INSET * (hi - lo)
            theta[name] = rng.uniform(lo + inset, hi - inset, size=shape)
        chosen = {}
        for name, lo, hi, two_sided in zip(free, lows, highs, two, strict=True):
            if two_sided:
                chosen[name] = rng.uniform(np.asarray(lo), np.asarray(hi))
            else:
                chosen[name] = np.asarray(design[name], float)
        starts.append((theta, chosen))
    return starts


def _as_start(extra) -> tuple[dict, dict]:
    """``(θ, design)`` of an extra start: a solution or ``{"trajectory", "design"}``."""
    if isinstance(extra, JointSolution):
        return dict(extra.trajectory), dict(extra.design)
    if isinstance(extra, Mapping) and "trajectory" in extra:
        return dict(extra["trajectory"]), dict(extra.get("design", {}))
    raise ValueError(
        "an extra start must be a JointSolution or a mapping with 'trajectory' (and "
        f"optionally 'design'), got {type(extra).__name__}"
    )


def multistart_joint_codesign(
    robot: Robot,
    motion,
    trajectory: Mapping[str, Any],
    objective="peak_force",
    *,
    trajectory_lower: Mapping[str, Any],
    trajectory_upper: Mapping[str, Any],
    starts: int = 4,
    seed: int = 0,
    extra_starts: Sequence[Any] = (),
    near_rtol: float = 1e-3,
    free=None,
    lower: Mapping[str, Any] | None = None,
    upper: Mapping[str, Any] | None = None,
    start: Mapping[str, Any] | None = None,
    payloads=None,
    scales: Mapping[str, float] | None = None,
    **options,
) -> MultiStart:
    """:func:`~jaxbal.design.joint_codesign` from several starts (module doc).

    Args:
        robot, motion, trajectory, objective, trajectory_lower, trajectory_upper, free,
            lower, upper, start, payloads: as ``joint_codesign`` (the given start).
        starts: number of random starts besides the given and extra ones (≥ 0).
        seed: seed of the random starts (NumPy ``default_rng``).
        extra_starts: further starts, each a ``JointSolution`` or a mapping
            ``{"trajectory": θ, "design": {...}}``; only its *free* design variables are
            taken, the others (and the payload) are the given start's.
        near_rtol: relative loss margin of the near-optimal starts (> 0).
        scales: fixed scales of the objective metrics (default: their mean over the
            payloads at the given start), the same for every start.
        **options: passed to every ``joint_codesign`` call (``robust``,
            ``constraints``, ``max_steps``, ``rounds`` …).

    Returns:
        :class:`MultiStart`. Raises ``ValueError`` for a bad ``starts``, ``near_rtol``
        or extra start, when the given start is invalid, or when every start is refused.
    """
    if isinstance(starts, bool) or not isinstance(starts, int | np.integer) or starts < 0:
        raise ValueError(f"starts must be a non-negative integer, got {starts!r}")
    if not np.isfinite(near_rtol) or near_rtol <= 0:
        raise ValueError(f"near_rtol must be positive and finite, got {near_rtol!r}")
    given = robot.with_design(dict(start or {}))
    design = given.design()
    free = tuple(n for n in design if n != "payload") if free is None else tuple(free)
    free = tuple(dict.fromkeys(check_design_names(given, free)))
    if payloads is None:
        payloads = jnp.atleast_1d(design.get("payload", jnp.zeros(())))
    if scales is None:  # joint_codesign's default scales, fixed at the given start
        terms, _ = _objective_terms(objective)
        values = np.asarray(payload_metrics(given, motion, trajectory, payloads, terms))
        theta = {k: jnp.asarray(v, float) for k, v in trajectory.items()}
        floors = np.asarray(_floors(given, motion, theta, terms))  # as joint_codesign's
        scales = {metric_name(m): float(max(abs(v), f))
                  for m, v, f in zip(terms, values.mean(axis=0), floors, strict=True)}  # fmt: skip
    lows, highs, two = _bounds(given, free, lower, upper)
    rng = np.random.default_rng(seed)
    plan = [("given", (dict(trajectory), {}))]
    # only the free variables of an extra start: the others (e.g. a solution's payload
    # or a variable the smaller problem freed) are the given start's, as for every start
    plan += [("extra", (t, {k: d[k] for k in free if k in d}))
             for t, d in map(_as_start, extra_starts)]  # fmt: skip
    randoms = _random_starts(rng, starts, trajectory, trajectory_lower, trajectory_upper,
                             design, free, lows, highs, two)  # fmt: skip
    plan += [("random", s) for s in randoms]
    common = dict(trajectory_lower=trajectory_lower, trajectory_upper=trajectory_upper,
                  free=free, lower=lower, upper=upper, payloads=payloads, scales=scales,
                  **options)  # fmt: skip
    solutions, errors = [], []
    for kind, (theta, chosen) in plan:
        try:
            solution = joint_codesign(given, motion, theta, objective, start=chosen, **common)
        except ValueError as error:
            if kind == "given":
                raise
            solution, message = None, str(error)
        else:
            message = None
        solutions.append(solution)
        errors.append(message)
    values = np.array([np.inf if s is None else float(s.value) for s in solutions])
    feasible = np.array([s is not None and bool(s.feasible) for s in solutions])
    pool = np.where(feasible, values, np.inf) if feasible.any() else values
    if not np.isfinite(pool).any():
        raise ValueError(f"every start was refused: {errors}")
    k = int(np.argmin(pool))
    near = feasible & (values <= values[k] + near_rtol * abs(values[k]))
    return MultiStart(
        best=solutions[k],
        solutions=tuple(solutions),
        values=values,
        feasible=feasible,
        near=near,
        kinds=tuple(kind for kind, _ in plan),
        errors=tuple(errors),
    )
