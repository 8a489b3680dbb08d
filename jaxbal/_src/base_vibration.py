"""The vibration of the base excited by the shaking wrench: what balancing is for.

A robot's shaking force and moment excite the frame it stands on; the frame's
vibration, during the move and after it (the *residual* vibration, which sets how long
a pick-and-place cell waits before the next operation), is what balancing reduces in
the end. The base is a linear modal model (:class:`BaseModes`), each mode ``j``::

    η̈_j + 2 ζ_j ω_j η̇_j + ω_j² η_j = b_j · w(t),     ω_j = 2π f_j,

driven by the shaking wrench ``w = (f_sh, m_sh)`` (``(6,)``: force [N], moment about the
base origin [N·m], :func:`jaxbal.shaking_wrench`), with ``b_j`` the mode's
participation (its mode shape at the robot's mounting divided by its modal mass): for a
rigid base of mass ``M`` on springs along x, ``b = (1/M, 0, 0, 0, 0, 0)`` and ``η`` is
its displacement [m] (:func:`rigid_base`). The base starts at rest.

The robot rides on the base: for a translating base ``(M_base + m_robot) ẍ + c ẋ + k x
= f_sh`` exactly (the shaking force on a fixed base, the joint motion prescribed relative
to the base; tested against MuJoCo C's dynamics of the whole system, where ``M_base``
alone is 25 % off). So either give the modes as measured with the robot mounted, or the
base alone and let the robot's mass ride on it: :func:`carrying` (and
``BaseVibration(..., carries_robot=True)``, which adds the robot's total mass at every
evaluation, so that co-designed counter-masses and swept payloads load the base too)
keeps each translation mode's stiffness and damping coefficient and adds the mass. A
rotation mode's inertia changes with the robot's configuration: give it with the robot
mounted (a constant modal inertia is then an approximation, good for a base much
heavier or stiffer than the robot); :func:`carrying` refuses it.

:func:`base_response` is exact for a wrench linear between the samples (first-order
hold): each step is the matrix exponential of the mode's state matrix augmented with
the input and its slope, in the mode's own time ``ω t`` (no cancellation for short
steps; any damping ``ζ ≥ 0``); the samples need not be equally spaced (equal steps
cost one exponential per mode), and the steps are chained by a ``lax.scan`` (as cheap
as the RMS shaking force along the same samples). After the last
sample the robot is at rest (the end of a rest-to-rest move: the wrench drops to zero,
as a bang-bang's deceleration does) and each mode rings freely,
``η(t) = e^{−ζωt}(η_T cos ω_d t + (η̇_T + ζωη_T)/ω_d sin ω_d t)`` (``ω_d = ω√(1 − ζ²)``),
with the amplitude its envelope decays from,
``A_j = sqrt(η_T² + ((η̇_T + ζ_j ω_j η_T)/ω_{d,j})²)`` (:func:`residual_amplitude`; for an
undamped mode ``sqrt(η_T² + (η̇_T/ω)²) = |∫ b_j·w(τ) e^{iωτ} dτ| / ω``, Duhamel). It
needs an underdamped mode, ``ζ < 1`` (an overdamped one does not ring).

:class:`~jaxbal._src.base_vibration_metric.BaseVibration` is the metric ``(robot,
motion) -> scalar`` of co-design, sensitivity and sweeps: ``kind="residual"`` the norm
of the residual amplitudes ``sqrt(Σ_j A_j²)``, ``kind="peak"`` the peak
``max_t sqrt(Σ_j η_j(t)²)`` over the samples (give modes of one unit — displacements
[m] or rotations [rad] — to one metric, or weigh two metrics). It needs the motion's
sample times, so a motion factory of :func:`jaxbal.design.joint_codesign` must sample
at exactly those times: a trajectory variable ``"duration"``, which rescales them, is
refused.

References:
    Briot, Arakelian & Le Baron (2012), §1 (shaking forces excite the base's
    vibrations); Van Loan (1978), "Computing integrals involving the matrix
    exponential", IEEE TAC 23(3) (the augmented exponential).
"""

from __future__ import annotations

from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import safe_sqrt
from jaxbal._src.types import Array, Float, Scalar
from jaxbal._src.validation import guard, is_traced

__all__ = [
    "AXES",
    "BaseModes",
    "base_response",
    "carrying",
    "envelope",
    "residual_amplitude",
    "rigid_base",
]

#: the wrench components a rigid base's mode can follow (:func:`rigid_base`).
AXES = ("x", "y", "z", "rx", "ry", "rz")


class BaseModes(eqx.Module):
    """Linear modal model of the base (module doc); arrays are differentiable leaves.

    Attributes:
        frequency: ``(k,)`` natural frequencies ``f_j`` [Hz], > 0.
        damping: ``(k,)`` damping ratios ``ζ_j`` [-], ≥ 0.
        participation: ``(k, 6)`` modal force per unit shaking wrench ``b_j``
            [1/kg per N, 1/(kg·m²) per N·m for a rigid base].
    """

    frequency: Float[Array, " k"]
    damping: Float[Array, " k"]
    participation: Float[Array, "k 6"]

    def __init__(self, frequency, damping, participation):
        self.frequency = jnp.atleast_1d(jnp.asarray(frequency, dtype=float))
        if self.frequency.ndim != 1:
            raise ValueError(f"frequency must be a (k,) array, got shape {self.frequency.shape}")
        k = self.frequency.shape[0]
        self.damping = _per_entry("damping", damping, k)
        participation = jnp.asarray(participation, dtype=float)
        if participation.shape != (k, 6):
            raise ValueError(
                f"participation must have shape ({k}, 6) for {k} modes, got {participation.shape}"
            )
        self.participation = participation
        if not is_traced(self):
            _checked(self)


def rigid_base(
    mass: float,
    frequency,
    damping=0.02,
    axes: Sequence[str] = ("x", "y"),
    inertia=None,
) -> BaseModes:
    """A rigid base on springs: one mode per axis of ``axes`` (of :data:`AXES`), whose
    ``η`` is the base's displacement [m] along a translation axis or its rotation [rad]
    about a rotation axis.

    Args:
        mass: the mass ``M`` [kg] moving with the base (module doc: with the robot, or
            alone and then :func:`carrying`; translation axes: ``b = e_axis / M``).
        frequency: natural frequency [Hz] of that mass, one or one per axis.
        damping: damping ratio [-], one or one per axis.
        axes: e.g. ``("x", "y")`` or ``("x", "y", "rz")``.
        inertia: moment of inertia [kg·m²] about each rotation axis (one or one per
            rotation axis), the robot's included, needed if ``axes`` has one.
    """
    axes = (axes,) if isinstance(axes, str) else tuple(axes)
    unknown = [a for a in axes if a not in AXES]
    if unknown or not axes or len(set(axes)) != len(axes):
        raise ValueError(f"axes must be distinct names of {AXES}, got {axes!r}")
    rotations = [a for a in axes if a.startswith("r")]
    if rotations and inertia is None:
        raise ValueError(f"rotation axes {rotations} need the base's inertia [kg·m²]")
    inertias = _per_entry("inertia", inertia if rotations else 1.0, len(rotations))
    mass = jnp.asarray(mass, dtype=float)
    if mass.ndim:
        raise ValueError(f"mass must be one value [kg], got shape {mass.shape}")
    moduli = {"mass": mass, "inertia": inertias}
    mass, inertias = (
        guard(v, ~(jnp.isfinite(v) & (v > 0)), f"the base's {n} must be finite and > 0", v)
        for n, v in moduli.items()
    )
    participation = jnp.zeros((len(axes), 6))
    for j, axis in enumerate(axes):
        modal = inertias[rotations.index(axis)] if axis.startswith("r") else mass
        participation = participation.at[j, AXES.index(axis)].set(1.0 / modal)
    frequency = _per_entry("frequency", frequency, len(axes))
    return BaseModes(frequency, _per_entry("damping", damping, len(axes)), participation)


def _per_entry(name: str, value, count: int) -> Array:
    """``value`` (one, or one per mode or axis) as a ``(count,)`` array."""
    value = jnp.asarray(value, dtype=float)
    if value.ndim > 1 or value.size not in (1, count):
        raise ValueError(f"{name} must be one value or {count} (one each), got {value.shape}")
    return jnp.broadcast_to(value.reshape(-1) if value.ndim else value, (count,))


def carrying(base: BaseModes, mass) -> BaseModes:
    """``base`` with ``mass`` [kg] riding on it (the robot, module doc): each mode's
    modal mass ``M_j = 1/‖b_j‖`` grows to ``M_j + mass``, its stiffness ``ω_j² M_j`` and
    damping coefficient ``2 ζ_j ω_j M_j`` kept. Differentiable in ``mass`` and the base.

    Raises:
        ValueError: a mode with moment participation (a rotation: its inertia depends on
            the robot's configuration), a negative or non-finite mass.
    """
    rotating = jnp.any(base.participation[:, 3:] != 0.0, axis=-1)
    rotating |= ~jnp.any(base.participation[:, :3] != 0.0, axis=-1)  # nor a force: no mass
    base = eqx.tree_at(
        lambda b: b.participation,
        base,
        guard(base.participation, rotating, "carrying() takes translation modes only (a "
              "force participation, no moment): give rotation modes with the robot "
              "mounted", base.participation),
    )  # fmt: skip
    mass = jnp.asarray(mass, dtype=float)
    mass = guard(mass, ~(jnp.isfinite(mass) & (mass >= 0)), "carried mass must be finite "
                 "and >= 0 [kg]", mass)  # fmt: skip
    own = 1.0 / jnp.linalg.norm(base.participation[:, :3], axis=-1)
    ratio = own / (own + mass)
    root = jnp.sqrt(ratio)
    return BaseModes(
        base.frequency * root, base.damping * root, base.participation * ratio[:, None]
    )


def _invalid(base: BaseModes):
    """``(invalid (k,), message, offending)`` of each check of a base."""
    return (
        (~(jnp.isfinite(base.frequency) & (base.frequency > 0)), "base frequencies must be "
         "finite and > 0 [Hz]", base.frequency),
        (~(jnp.isfinite(base.damping) & (base.damping >= 0)), "base damping ratios must be "
         "finite and >= 0", base.damping),
        (~jnp.all(jnp.isfinite(base.participation), axis=-1), "base participations must be "
         "finite", base.participation),
    )  # fmt: skip


def _checked(base: BaseModes) -> BaseModes:
    """``base``, checked (eagerly ``ValueError``, under ``jit`` a runtime error)."""
    frequency = base.frequency
    for invalid, message, offending in _invalid(base):
        frequency = guard(frequency, invalid, message, offending)
    return eqx.tree_at(lambda b: b.frequency, base, frequency)


def _checked_times(times) -> Array:
    times = jnp.asarray(times, dtype=float)
    if times.ndim != 1 or times.shape[0] < 2:
        raise ValueError(f"times must be a (t,) array of >= 2 instants, got shape {times.shape}")
    steps = jnp.diff(times)
    invalid = ~(jnp.all(jnp.isfinite(times)) & (steps > 0))
    return guard(times, invalid, "times must be finite and strictly increasing [s]", steps)


def _stacked(force, moment, count: int) -> Array:
    """The ``(t, 6)`` wrench of ``(t, 3)`` force and moment samples."""
    wrench = jnp.concatenate([jnp.asarray(force, float), jnp.asarray(moment, float)], axis=-1)
    if wrench.shape != (count, 6):
        raise ValueError(
            f"force and moment must each have shape ({count}, 3) (one per time), got "
            f"{jnp.shape(force)} and {jnp.shape(moment)}"
        )
    # a NaN sample made the residual amplitude 0 ("at rest"): eagerly a ValueError
    # naming the samples, under jit a runtime error
    bad = ~jnp.all(jnp.isfinite(wrench), axis=-1)
    samples = jnp.arange(count)
    return guard(wrench, bad, "the shaking wrench must be finite; not at samples", samples)


#: Taylor degree and largest number of squarings of :func:`_step_matrix` (its argument
#: scaled to a norm ≤ 1/4: truncation error < 1e-17 relative; 2^48 steps H ≈ 7e13).
TAYLOR_DEGREE, MAX_SQUARINGS = 12, 48


def _step_matrix(zeta: Scalar, span: Scalar) -> Float[Array, "4 4"]:
    """``exp(A H)`` for a step ``H = ω h`` of a mode in its own time ``ω t``, state
    ``(η, η̇/ω, u/ω², u̇/ω³)`` (the input and its slope, first-order hold): scaling and
    squaring of a Taylor polynomial, the squarings selected in a fixed loop (an
    exponential as accurate as ``jax.scipy.linalg.expm``'s, compiled about twice as fast
    with its derivatives)."""
    a = jnp.zeros((4, 4)).at[0, 1].set(1.0).at[1, 0].set(-1.0).at[1, 2].set(1.0)
    a = a.at[1, 1].set(-2.0 * zeta).at[2, 3].set(1.0) * span
    size = jax.lax.stop_gradient(jnp.max(jnp.sum(jnp.abs(a), axis=0)))  # the 1-norm
    squarings = jnp.clip(jnp.ceil(jnp.log2(jnp.maximum(size, 1e-300) / 0.25)), 0, MAX_SQUARINGS)
    scaled = a / 2.0**squarings
    term = total = jnp.eye(4)
    for k in range(1, TAYLOR_DEGREE + 1):
        term = term @ scaled / k
        total = total + term

    def square(k, e):
        return jnp.where(k < squarings, e @ e, e)

    return jax.lax.fori_loop(0, MAX_SQUARINGS, square, total)


def _scaled_response(base: BaseModes, times, wrench, uniform: bool = False):
    """``(x (t, k), y (t, k))``: ``η`` and ``η̇/ω``; ``uniform``: equal steps (one
    matrix exponential per mode instead of one per step and mode)."""
    omega = 2.0 * jnp.pi * base.frequency
    p = (wrench @ base.participation.T) / omega**2
    spans = jnp.diff(times)[:, None] * omega  # (t - 1, k)
    per_mode = jax.vmap(_step_matrix)
    steps = per_mode(base.damping, spans[0])[None] if uniform else jax.vmap(per_mode, (None, 0))(
        base.damping, spans
    )  # fmt: skip
    slopes = jnp.diff(p, axis=0) / spans
    drive = steps[..., :2, 2] * p[:-1, :, None] + steps[..., :2, 3] * slopes[..., None]
    transitions = jnp.broadcast_to(steps[..., :2, :2], (*drive.shape, 2))

    def advance(state, step):  # s_{n+1} = A_n s_n + b_n, from rest
        transition, push = step
        state = jnp.einsum("kij,kj->ki", transition, state) + push
        return state, state

    _, states = jax.lax.scan(advance, jnp.zeros_like(drive[0]), (transitions, drive))
    states = jnp.concatenate([jnp.zeros_like(states[:1]), states])
    return states[..., 0], states[..., 1]


#: :func:`_scaled_response` as one compiled program (eagerly, each of its operations
#: would be a dispatch and a compilation of its own); inlined when traced.
_response = jax.jit(_scaled_response, static_argnames="uniform")


def _uniform(times) -> bool:
    """Whether concrete ``times`` are equally spaced (to 1e-12 of the step)."""
    if is_traced(times):
        return False
    steps = np.diff(np.asarray(times, dtype=float))
    return bool(np.all(np.abs(steps - steps[0]) <= 1e-12 * abs(steps[0])))


def _prepared(base: BaseModes, times, force, moment):
    times = _checked_times(times)
    return _checked(base), times, _stacked(force, moment, times.shape[0])


def base_response(
    base: BaseModes, times: Float[Array, " t"], force: Float[Array, "t 3"], moment
) -> tuple[Float[Array, "t k"], Float[Array, "t k"]]:
    """The base's modal displacements ``η`` and velocities ``η̇`` at ``times`` (module
    doc), from rest, driven by the shaking wrench sampled at ``times``.

    Args:
        base: a :class:`BaseModes`.
        times: ``(t,)`` strictly increasing instants [s].
        force, moment: ``(t, 3)`` shaking force [N] and moment [N·m] at ``times``,
            without gravity (``shaking_wrench(..., gravity=None)``): the base starts
            at rest at ``η = 0`` and the wrench is 0 after the last sample, so a
            constant weight would ring it (a SCARA at rest: 3e-5 m) instead of giving
            its static sag, which is a separate ``weight / stiffness``.

    Raises:
        ValueError: a non-positive or non-finite frequency, a negative damping ratio,
            times not strictly increasing, wrong shapes, a non-finite wrench sample
            (under ``jit``: a runtime error).
    """
    base, times, wrench = _prepared(base, times, force, moment)
    x, y = _response(base, times, wrench, _uniform(times))
    return x, y * (2.0 * jnp.pi * base.frequency)


def residual_amplitude(
    base: BaseModes, times: Float[Array, " t"], force: Float[Array, "t 3"], moment
) -> Float[Array, " k"]:
    """Each mode's amplitude after the last sample, the robot then at rest: the
    amplitude its envelope decays from, ``sqrt(η_T² + ((η̇_T + ζωη_T)/ω_d)²)`` [unit of
    ``η``] (module doc; before, ``sqrt(η_T² + (η̇_T/ω)²)``, 0.3 % low at ζ = 0.02 and
    10 % at 0.3). Same arguments and errors as :func:`base_response`, and a damping
    ratio ``≥ 1`` (no ringing) is refused."""
    base, times, wrench = _prepared(base, times, force, moment)
    x, y = _response(base, times, wrench, _uniform(times))
    return envelope(base, x[-1], y[-1])


def envelope(base: BaseModes, x, y):
    """``(k,)`` envelope amplitudes of free modes at ``η = x``, ``η̇/ω = y`` ``(k,)``
    (:func:`residual_amplitude`), ``ζ < 1`` guarded (eagerly ``ValueError``, under
    ``jit`` a runtime error)."""
    damping = guard(
        base.damping,
        ~(base.damping < 1.0),
        "a residual vibration amplitude needs underdamped modes, damping ratio < 1",
        base.damping,
    )
    scale = jnp.sqrt(1.0 - jnp.where(damping < 1.0, damping, 0.0) ** 2)
    return _norm(jnp.stack([x, (y + damping * x) / scale], axis=-1))


def _norm(vectors):
    """``‖v‖`` over the last axis with a zero (not NaN) gradient at ``v = 0``."""
    return safe_sqrt(jnp.sum(vectors**2, axis=-1))
