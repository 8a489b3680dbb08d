"""Motion factories ``motion(robot, θ) -> Motion``: trajectories whose parameters ``θ``
are optimised with the counter-masses (:func:`jaxbal.design.joint_codesign`).

Two factories, one parametrisation of the profile:

* :class:`TrapezoidLine` -- the end-effector on a straight line;
* :class:`ComTrapezoid` -- the robot's total centre of mass on a straight line (the
  COM planning of Briot et al. 2012 and Geng et al. 2021), the free pose coordinates
  (φ of the 3R) following a boundary polynomial with free coefficients.

``θ`` always holds ``"u2"`` and ``"ratio"`` (the trapezoid's switch times, ``u1 =
ratio·u2``, so that ``0 < u1 ≤ u2 < 1/2`` whenever ``0 < ratio ≤ 1`` and ``0 < u2 <
1/2``). Optional entries:

* ``"duration"`` -- the cycle time ``T`` [s]: the samples are ``times/times[-1]·T``;
  its bounds in ``joint_codesign`` are the cycle-time constraint;
* ``"phi"`` (:class:`ComTrapezoid` only) -- ``(K,)`` free coefficients of the law of
  the free coordinates (degree ``5 + K``; the paper's φ law is degree 8, ``K = 3``,
  eq 20); absent: they follow the end-effector line's profile.

``per_phase = n > 0`` adds ``n`` samples inside each of the trapezoid's three jerk
phases after the ``times`` (the torque rate jumps at the switch times, and a short ramp
``u1·T`` falls between uniform samples); they are weighted like the others in the RMS
metrics, so keep ``per_phase = 0`` for an RMS objective.

With ``order=3`` the factory returns a :class:`~jaxbal.design.JerkMotion` (the jerk
``q⃛`` too), which the torque-rate metric needs (Briot et al. 2012, eqs 5-6).

References:
    Briot, Arakelian & Le Baron (2012), eqs (3), (5)-(6), (19)-(20), §2.2.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.motion_samples import JerkMotion, Motion
from jaxbal._src.planning import (
    JOIN_TOLERANCE,
    EndEffectorLine,
    com_plan,
)
from jaxbal._src.profiles import BoundaryPolynomial, TrapezoidalAcceleration
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import check_robot
from jaxbal._src.trajectory import StraightLine, sample
from jaxbal._src.types import Array
from jaxbal._src.validation import checked_call, guard

__all__ = [
    "JOIN_TOLERANCE", "THETA_DOMAIN", "ComTrapezoid", "TrapezoidLine", "check_planned", "in_domain",
    "check_start", "end_effector_path",
]  # fmt: skip


def end_effector_path(robot: Robot, line):
    """Default path of :class:`TrapezoidLine`: the end-effector on the straight line."""
    return EndEffectorLine(robot, line)


def _profile(theta) -> TrapezoidalAcceleration:
    u2 = theta["u2"]
    return TrapezoidalAcceleration(theta["ratio"] * u2, u2)


def _times(times: Array, theta) -> Array:
    """The sample instants [s]: ``times``, rescaled to ``θ["duration"]`` if given."""
    if "duration" not in theta:
        return times
    duration = jnp.asarray(theta["duration"], dtype=float)
    duration = guard(
        duration,
        ~(jnp.isfinite(duration) & (duration > 0)),
        "trajectory 'duration' (cycle time) must be finite and > 0 [s]",
        duration,
    )
    return times / times[-1] * duration


def _with_phases(times: Array, profile: TrapezoidalAcceleration, per_phase: int) -> Array:
    """``times`` followed by ``per_phase`` instants inside each jerk phase [s]."""
    if per_phase == 0:
        return times
    starts, widths = profile.jerk_phases()
    inner = jnp.linspace(0.0, 1.0 - 1e-9, per_phase)
    dense = (starts[:, None] + widths[:, None] * inner[None, :]).reshape(-1)
    return jnp.concatenate([times, dense * times[-1]])


def _arrays(theta) -> dict:
    """``θ`` as float arrays (Python numbers would be static, one compilation each)."""
    return {k: jnp.asarray(v, dtype=float) for k, v in theta.items()}


def _sampled(path, times, order: int):
    # the factories call it under a trace (checked_call of their module-level functions)
    samples = sample(path, times, order=order)
    return Motion(*samples) if order == 2 else JerkMotion(*samples)


#: the domain of this module's ``θ`` entries: (lowest, highest, highest included).
THETA_DOMAIN = {
    "u2": (0.0, 0.5, False),
    "ratio": (0.0, 1.0, True),
    "duration": (0.0, np.inf, False),
}


def in_domain(name: str, values) -> np.ndarray:
    """Where ``values`` of the ``θ`` entry ``name`` lie in its :data:`THETA_DOMAIN`."""
    least, most, closed = THETA_DOMAIN[name]
    values = np.asarray(values, dtype=float)
    return (values > least) & ((values <= most) if closed else (values < most))


def check_start(robot: Robot, factory, theta, lower, upper, payloads) -> None:
    """Raise ``ValueError`` if a joint co-design's start gives no motion at some payload
    (``(n,)`` [kg]) or if, for this module's factories, the bounds of ``θ`` reach out of
    its domain (:data:`THETA_DOMAIN`: ``0 < u2 < 1/2``, ``0 < ratio ≤ 1``,
    ``duration > 0``). The co-design's compiled programs run with the checks off, so a
    refused start (a duration of 0 s) gave finite metrics (an RMS force of 0 N) and a
    bound out of the domain let the optimiser leave it."""
    if isinstance(factory, TrapezoidLine | ComTrapezoid):
        for name, (least, most, closed) in THETA_DOMAIN.items():
            if name not in theta:
                continue
            lo, hi = np.min(np.asarray(lower[name])), np.max(np.asarray(upper[name]))
            if not np.all(in_domain(name, [lo, hi])):
                raise ValueError(
                    f"trajectory bounds of {name!r} must lie in its domain {least:g} < "
                    f"{name} {'<=' if closed else '<'} {most:g}, got [{lo:g}, {hi:g}]"
                )
    check_planned(robot, factory, theta, payloads, start=True)


def check_planned(robot: Robot, factory, theta, payloads, start: bool = False) -> None:
    """Raise ``ValueError`` unless ``factory(robot, θ)`` gives a motion at every payload
    (``(n,)`` [kg]): a co-design's result (or, ``start``, its start). Its compiled
    programs see a refused motion as NaN only, and a design that nearly balances the
    force makes a COM plan so ill conditioned that a motion the optimiser accepted is
    refused when evaluated again (the 2R's ComTrapezoid with free counter-masses: RMS
    force 47 → 3e-5 N, reported as the move's)."""
    for payload in np.asarray(payloads, dtype=float).reshape(-1):
        try:
            factory(robot.with_design({"payload": payload}), theta)
        except ValueError as error:
            if start:
                raise ValueError(
                    f"the starting robot and trajectory give no valid motion at payload "
                    f"{payload:g} kg: {error}"
                ) from None
            raise ValueError(
                f"the co-designed robot and trajectory give no valid motion at payload "
                f"{payload:g} kg: {error}. A design that (nearly) balances the force fixes "
                "the COM, so no COM plan (ComTrapezoid) moves the robot: bound the "
                "counter-masses (upper=), weigh the added mass, or plan the end-effector "
                "(TrapezoidLine)"
            ) from None


def _check_static(order: int, per_phase: int) -> None:
    if order not in (2, 3):
        raise ValueError(f"order must be 2 (q, q̇, q̈) or 3 (with the jerk), got {order!r}")
    if not isinstance(per_phase, int) or per_phase < 0:
        raise ValueError(f"per_phase must be an int >= 0, got {per_phase!r}")


class TrapezoidLine(eqx.Module):
    """Motion factory: end-effector straight line, trapezoidal acceleration profile.

    ``θ = {"u2", "ratio"[, "duration"]}`` (module doc); bang-bang is ``ratio → 0, u2 →
    1/2``. The cycle time is ``times[-1]`` unless ``θ`` has a ``"duration"``.

    Attributes:
        start, end: end-effector poses (as ``robot.inverse_kinematics`` takes them).
        times: ``(t,)`` sample instants [s], from 0 to the cycle time.
        path: static ``path(robot, StraightLine) -> trajectory`` (default: the
            end-effector line; a module-level function for e.g. a SCARA lift).
        order: static, 2 (a :class:`Motion`) or 3 (a :class:`JerkMotion`).
        per_phase: static, samples added inside each jerk phase (module doc).

    References:
        Briot, Arakelian & Le Baron (2012), §2.2 (trapezoidal profile, switch times).
    """

    start: Array
    end: Array
    times: Array
    path: Callable = eqx.field(static=True, default=end_effector_path)
    order: int = eqx.field(static=True, default=2)
    per_phase: int = eqx.field(static=True, default=0)

    def __check_init__(self):
        _check_static(self.order, self.per_phase)

    def __call__(self, robot: Robot, theta) -> Motion | JerkMotion:
        # eagerly one compiled program (checks raise ValueError), inlined under a trace
        check_robot(robot)  # the IK alone would accept e.g. negative lengths
        return checked_call(_line_motion, self, robot, _arrays(theta), once=True)


class ComTrapezoid(eqx.Module):
    """Motion factory: the total COM on a straight line with a trapezoidal profile.

    The COM goes from ``x_S(q_start)`` to ``x_S(q_end)`` (eq 3), both computed for the
    candidate robot, so the move joins the same two configurations whatever the
    counter-masses. The pose coordinates beyond the COM (φ of the 3R, θ5 of the DUAL-V,
    φ and z of the SCARA) go from their start to their end value with a
    :class:`~jaxbal.profiles.BoundaryPolynomial` of free coefficients ``θ["phi"]``
    (zero velocity and acceleration at both ends for every coefficient, eq 20), or,
    without ``"phi"``, with the COM's profile.

    Attributes:
        q_start, q_end: ``(dof,)`` start and end configurations.
        times: ``(t,)`` sample instants [s], from 0 to the cycle time.
        branch: static working mode of the COM inverse kinematics (default: the
            robot's); it must be the branch of ``q_start`` and ``q_end``, else the move
            would jump: a plan that does not start at ``q_start`` and end at ``q_end``
            (every body's COM within :data:`JOIN_TOLERANCE`) is refused, eagerly by a
            ``ValueError``, under ``jit`` by a runtime error.
        order: static, 2 (a :class:`Motion`) or 3 (a :class:`JerkMotion`).
        per_phase: static, samples added inside each jerk phase (module doc).

    References:
        Briot, Arakelian & Le Baron (2012), eqs (3), (19)-(20);
        Geng et al. (2021) (COM planning of the Orthoglide).
    """

    q_start: Array
    q_end: Array
    times: Array
    branch: tuple[int, ...] | int | None = eqx.field(static=True, default=None)
    order: int = eqx.field(static=True, default=2)
    per_phase: int = eqx.field(static=True, default=0)

    def __check_init__(self):
        _check_static(self.order, self.per_phase)

    def __call__(self, robot: Robot, theta) -> Motion | JerkMotion:
        # eagerly one compiled program (checks raise ValueError), inlined under a trace:
        # op by op, the COM plan's end points and the join check took seconds
        check_robot(robot)
        return checked_call(_com_motion, self, robot, _arrays(theta), once=True)

    def valid(self, robot: Robot, theta) -> Array:
        """``(t,)`` boolean mask, one entry per sample instant (the jerk-phase instants
        included): is the COM target reachable there? Where it is False, calling the
        factory raises (eagerly and under ``jit``); e.g. a payload that moves the COM
        line out of the robot's COM workspace. Called eagerly it runs as one compiled
        program (op by op it took seconds)."""
        return checked_call(_valid_mask, self, robot, _arrays(theta), once=True)

    def _plan(self, robot: Robot, theta):
        """``(times, profile, COM line)`` of the move for ``robot`` and ``θ``."""
        times = _times(self.times, theta)
        duration = times[-1]
        profile = _profile(theta)
        free = None
        if "phi" in theta:
            d = robot.com_dims
            pose = (robot.end_effector(self.q_start)[d:], robot.end_effector(self.q_end)[d:])
            if pose[0].shape[0] == 0:
                raise ValueError(
                    f"θ['phi']: {type(robot).__name__} has no pose coordinate beyond its "
                    f"{d} COM coordinates for a free law to steer"
                )
            free = StraightLine(pose[0], pose[1], BoundaryPolynomial(theta["phi"]), duration)
        path = com_plan(robot, self.q_start, self.q_end, profile, duration, free, self.branch)
        return times, profile, path


def _valid_mask(factory: ComTrapezoid, robot: Robot, theta) -> Array:
    """:meth:`ComTrapezoid.valid` (module level: compiled once per structure)."""
    times, profile, path = factory._plan(robot, theta)
    return path.valid(_with_phases(times, profile, factory.per_phase))


def _line_motion(factory: TrapezoidLine, robot: Robot, theta) -> Motion | JerkMotion:
    """:meth:`TrapezoidLine.__call__` (module level: compiled once per structure)."""
    times = _times(factory.times, theta)
    profile = _profile(theta)
    line = StraightLine(factory.start, factory.end, profile, times[-1])
    times = _with_phases(times, profile, factory.per_phase)
    return _sampled(factory.path(robot, line), times, factory.order)


def _com_motion(factory: ComTrapezoid, robot: Robot, theta) -> Motion | JerkMotion:
    """:meth:`ComTrapezoid.__call__` (module level: compiled once per structure)."""
    times, profile, path = factory._plan(robot, theta)
    # the plan's joins are checked on its samples at t = 0 and T (ComLine.checked_samples)
    return _sampled(path, _with_phases(times, profile, factory.per_phase), factory.order)
