"""The base's vibration as a metric of co-design, sensitivity and sweeps.

:class:`BaseVibration` evaluates the residual or peak vibration of a base
(:class:`~jaxbal._src.base_vibration.BaseModes`, model and discretisation in
:mod:`jaxbal._src.base_vibration`) along a motion sampled at fixed times, the robot's
mass riding on the base if asked. A ``Motion`` carries no times, so a motion factory
whose trajectory variable ``"duration"`` rescales them is refused
(:func:`refuse_rescaled_times`, called by :func:`jaxbal.design.joint_codesign`), and a
concrete motion whose samples are not at the metric's times
(:func:`~jaxbal._src.sampled_at.check_sampled_at`).

References:
    Briot, Arakelian & Le Baron (2012), §1 (shaking forces excite the base's vibrations).
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.base_vibration import (
    BaseModes,
    _checked,
    _checked_times,
    _norm,
    _response,
    _uniform,
    carrying,
    envelope,
)
from jaxbal._src.metrics import _wrench, as_motion
from jaxbal._src.momentum import total_mass
from jaxbal._src.sampled_at import check_sampled_at
from jaxbal._src.types import Scalar
from jaxbal._src.validation import is_traced

__all__ = ["BaseVibration", "refuse_rescaled_times"]


class BaseVibration(eqx.Module):
    """The base's residual (``kind="residual"``) or peak (``"peak"``) vibration along a
    motion sampled at ``times``, a metric ``(robot, motion) -> scalar`` (module doc), in
    the unit of the modes' ``η`` (m for :func:`rigid_base`'s translations);
    ``carries_robot``: ``base`` is the base alone, the robot's total mass (counter-masses
    and payload included) rides on it (:func:`carrying`).

    Its fields are static (it is hashable, a key of an objective dict; equal metrics
    share one compilation); :func:`base_response` differentiates the base itself.
    """

    frequency: tuple[float, ...] = eqx.field(static=True)
    damping: tuple[float, ...] = eqx.field(static=True)
    participation: tuple[tuple[float, ...], ...] = eqx.field(static=True)
    times: tuple[float, ...] = eqx.field(static=True)
    kind: str = eqx.field(static=True)
    carries_robot: bool = eqx.field(static=True)

    def __init__(self, base: BaseModes, times, kind: str = "residual", carries_robot=False):
        if kind not in ("residual", "peak"):
            raise ValueError(f"kind must be 'residual' or 'peak', got {kind!r}")
        if is_traced(base, times):
            raise ValueError("BaseVibration needs concrete base and times (build it outside jit)")
        base, times = _checked(base), np.asarray(_checked_times(times))
        self.frequency = tuple(float(f) for f in np.asarray(base.frequency))
        self.damping = tuple(float(z) for z in np.asarray(base.damping))
        self.participation = tuple(tuple(float(b) for b in row) for row in base.participation)
        self.times, self.kind = tuple(float(t) for t in times), kind
        self.carries_robot = bool(carries_robot)
        if self.carries_robot:
            carrying(base, 0.0)  # a rotation mode is refused here, not at the first call
        if kind == "residual":
            envelope(base, jnp.zeros(len(self.damping)), jnp.zeros(len(self.damping)))

    @property
    def __name__(self) -> str:
        return f"{self.kind}_vibration"

    def __repr__(self) -> str:  # short: it names the metric in messages
        return (
            f"BaseVibration(kind={self.kind!r}, frequency={self.frequency} Hz, "
            f"samples={len(self.times)}, carries_robot={self.carries_robot})"
        )

    @property
    def units(self) -> str:
        """``η``'s unit for a rigid base: m (translation modes), rad (rotation modes)."""
        moments = [any(row[3:]) for row in self.participation]
        return "rad" if all(moments) else "m" if not any(moments) else "m or rad"

    @property
    def base(self) -> BaseModes:
        """The base, as a :class:`BaseModes`."""
        return BaseModes(self.frequency, self.damping, self.participation)

    def __call__(self, robot, motion) -> Scalar:
        motion = as_motion(motion)
        if motion.q.shape[0] != len(self.times):
            raise ValueError(
                f"the motion has {motion.q.shape[0]} samples but this {self.__name__} metric "
                f"{len(self.times)} times: sample the motion at its times"
            )
        if not is_traced(motion):
            check_sampled_at(motion, self.times, repr(self))
        force, moment = _wrench(robot, motion)
        base = carrying(self.base, total_mass(robot)) if self.carries_robot else self.base
        wrench = jnp.concatenate([force, moment], axis=-1)
        x, y = _response(base, jnp.asarray(self.times), wrench, _uniform(self.times))
        if self.kind == "peak":
            return jnp.max(_norm(x))
        return _norm(envelope(base, x[-1], y[-1]))


def refuse_rescaled_times(metrics, trajectory) -> None:
    """Refuse a :class:`BaseVibration` with a trajectory variable ``"duration"`` (module
    doc): the factory's samples would no longer be at the metric's times."""
    if "duration" in trajectory and any(isinstance(m, BaseVibration) for m in metrics):
        raise ValueError(
            "a BaseVibration metric needs the motion at its fixed times, but the trajectory "
            "variable 'duration' rescales them: optimise at a fixed cycle time (one "
            "joint_codesign per duration)"
        )
