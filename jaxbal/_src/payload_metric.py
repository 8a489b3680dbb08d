"""A metric aggregated over a payload grid: the objective of a robust co-design as a
metric of its own, for :func:`jaxbal.sensitivity.tolerance` and ``sensitivity``, and
(without a motion factory: hashable) in a sweep or as a term of
:func:`jaxbal.design.codesign`: a counter-mass design robust over the payloads along a
fixed motion.

:func:`jaxbal.design.joint_codesign` optimises a metric aggregated over payloads; the
tolerances of its design (how far a counter-mass may be off) belong to that aggregate,
not to the metric at the nominal payload. :func:`over_payloads` makes it a metric
``(robot, motion) -> scalar`` [the metric's unit]: the metric at every payload of the
grid (one ``vmap``) and their mean, quadratic mean (``"rms"``, as
:mod:`~jaxbal._src.payload_aggregate`) or **hard** maximum (``"max"``: the worst
payload, which a tolerance must hold for; the co-design's smooth maximum lies up to
``s log(n)/k`` below it). With a motion factory and its ``θ`` (a ``JointSolution``'s
``trajectory``) the motion is planned again for each loaded robot, as the co-design
does (a COM plan depends on the payload); the ``motion`` the metric is called with is
then not used. Without one, that motion is used at every payload (an end-effector path:
its joint motion does not depend on the payload).

As an objective, prefer ``"rms"`` for an RMS force or moment: the mean of the payloads'
values has its minimum on a kink (one payload balanced exactly), where a gradient-based
optimiser stalls unconverged (:mod:`~jaxbal._src.payload_aggregate`); likewise the
hard maximum where two payloads tie, as at its minimax optimum (optimise with
:func:`~jaxbal.design.joint_codesign`'s smooth maximum, check with the hard one).

References:
    Geng et al. (2021), §3.3 (sensitivity of the shaking force to payload variation);
    van der Wijk et al. (2013), §7.2 (sensitivity of the balance to counter-masses too
    light, equivalently to a payload on the platform).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import equinox as eqx
import jax.numpy as jnp

from jaxbal._src import design_inputs as inputs
from jaxbal._src.joint_codesign import _per_payload
from jaxbal._src.metrics import Metric, Motion, as_motion, resolve_metric
from jaxbal._src.payload_aggregate import ROBUST, aggregate
from jaxbal._src.robot import Robot
from jaxbal._src.types import Scalar

__all__ = ["OverPayloads", "over_payloads"]


class OverPayloads(eqx.Module):
    """A metric over a payload grid (module doc); build it with :func:`over_payloads`.

    Attributes:
        metric: static, a metric name or a module-level callable ``(robot, motion)``.
        payloads: static, the ``n`` payloads [kg] (floats: without a factory the metric
            is hashable, so it can be a term of :func:`~jaxbal.design.codesign`).
        robust: static, ``"mean"``, ``"rms"`` or ``"max"`` (hard).
        factory: ``None``, or a motion factory ``(robot, θ) -> Motion``.
        trajectory: the factory's ``θ`` (name -> array), or ``None``.
    """

    metric: Any = eqx.field(static=True)
    payloads: tuple[float, ...] = eqx.field(static=True)
    robust: str = eqx.field(static=True)
    factory: Any = None
    trajectory: dict | None = None

    def __call__(self, robot: Robot, motion: Motion) -> Scalar:
        # the co-design's own evaluation (one vmap), the fixed motion as a factory
        fixed = lambda loaded, theta: as_motion(motion)  # noqa: E731
        factory = fixed if self.factory is None else self.factory
        payloads = jnp.asarray(self.payloads, dtype=float)
        values = _per_payload(robot, factory, self.trajectory, payloads, (self.metric,))
        if self.robust == "max":  # hard: the worst payload
            return jnp.max(values)
        return aggregate(values, jnp.ones(1), self.robust, None)[0]


def over_payloads(
    metric: Metric,
    payloads,
    robust: str = "rms",
    factory=None,
    trajectory: Mapping[str, Any] | None = None,
) -> OverPayloads:
    """``metric`` aggregated over ``payloads`` [kg] (module doc), a metric itself.

    Example (the machining tolerances of a robust co-design's counter-masses)::

        solution = joint_codesign(arm, line, θ, "rms_force", payloads=grid, robust="rms", …)
        objective = over_payloads("rms_force", grid, "rms", line, solution.trajectory)
        tol = jaxbal.sensitivity.tolerance(solution.robot, line(solution.robot,
                                           solution.trajectory), objective)

    Raises:
        ValueError: an unknown metric or ``robust``, payloads that are empty, negative
            or not finite, a factory without ``trajectory`` or the reverse.
    """
    resolve_metric(metric)
    if robust not in ROBUST:
        raise ValueError(f"robust must be 'mean', 'rms' or 'max', got {robust!r}")
    if (factory is None) != (trajectory is None):
        raise ValueError("give a motion factory and its trajectory θ together, or neither")
    payloads = tuple(float(p) for p in inputs.check_payloads(payloads))
    theta = None if trajectory is None else {k: jnp.asarray(v) for k, v in trajectory.items()}
    return OverPayloads(metric, payloads, robust, factory, theta)
