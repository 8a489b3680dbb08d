"""Centre of mass, momentum and the shaking wrench -- the physics shared by all robots.

The shaking wrench is computed *exactly* as minus the time derivative of the total
linear momentum ``p`` and of the total angular momentum ``L`` (about the base
origin) of every moving body, obtained by forward-mode automatic differentiation:

    d/dt p(q, q̇) = ∂p/∂q · q̇ + ∂p/∂q̇ · q̈      (one ``jax.jvp``)

No finite differences are involved, and nothing here is robot-specific: a robot only
supplies :meth:`~jaxbal.robot.Robot.mass_properties` and
:meth:`~jaxbal.robot.Robot.body_frames`.

References:
    Briot, Arakelian & Le Baron (2012), eq (1): f_sh = Σ m_i · ẍ_S.
    van der Wijk et al. (2013), eqs (1)-(2) (linear momentum of the DUAL-V).
"""

from __future__ import annotations

import contextlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.eager import run_compiled
from jaxbal._src.linalg import (
    cross,
    matmul_transposed,
    matvec,
    vee,
    weighted_sum,
    world_inertia_times,
)
from jaxbal._src.merged_guards import merged_guards
from jaxbal._src.planar import PlanarRobot, planar_inertial_wrench
from jaxbal._src.robot import Robot
from jaxbal._src.state_checks import state_check
from jaxbal._src.straight_line import straight_line
from jaxbal._src.types import Array, Coordinates, Points, Rotations, Scalar, Vec3
from jaxbal._src.validation import (
    ROUNDING,
    _TraceFlag,
    check_shape,
    guard,
    is_traced,
    runtime_checks,
    runtime_checks_enabled,
)


def _body_faults(robot: Robot):
    """``(bodies, inertia diagonals, bad mass (b,), bad inertia (b,))`` (masks)."""
    bodies = robot.mass_properties()
    diagonal = jnp.diagonal(bodies.inertia, axis1=-2, axis2=-1)
    bad_mass = ~(jnp.isfinite(bodies.mass) & (bodies.mass >= -ROUNDING))
    finite = jnp.all(jnp.isfinite(bodies.inertia), axis=(-2, -1))
    signed = getattr(type(robot), "signed_inertias", False)
    bad_inertia = ~finite if signed else ~finite | jnp.any(diagonal < -ROUNDING, -1)
    return bodies, diagonal, bad_mass, bad_inertia


def robot_faulty(robot: Robot):
    """Scalar bool (traceable, never raises): would :func:`checked_bodies` or
    :func:`checked_parameters` reject ``robot``? For compiled code that must stay free of
    runtime-error callbacks (e.g. to be stored in the persistent compilation cache): it
    returns the mask, and the caller raises the named error eagerly."""
    _, _, bad_mass, bad_inertia = _body_faults(robot)
    faulty = jnp.any(bad_mass) | jnp.any(bad_inertia)
    for invalid in _parameter_faults(robot):
        faulty = faulty | jnp.any(invalid)
    return faulty


@eqx.filter_jit
def _faulty(robot: Robot):
    return robot_faulty(robot)


def check_robot(robot: Robot) -> None:
    """Raise ``ValueError`` naming the values where :func:`checked_bodies` or
    :func:`checked_parameters` would reject ``robot`` (an eager call: the entry points
    check the robot before compiling their program). The test is one small compiled
    mask per robot structure (~0.3 s the first time; the same checks run op by op
    took 1–1.6 s), the checks that name the values run only when it is set. Under a
    trace (``jit``, ``vmap``, ``grad``) it does nothing: the traced physics guards the
    robot itself."""
    faulty = _faulty(robot)
    if isinstance(faulty, jax.core.Tracer):
        return
    if bool(faulty):
        checked_parameters(robot, checked_bodies(robot, None))


def checked_bodies(robot: Robot, value):
    """``value``, guarded by the robot's mass properties as the physics sees them: every
    body mass and inertia diagonal finite and ≥ 0 (derived masses included, e.g. the
    DUAL-V's brass counter-mass ``m_cm − m_tun``), to :data:`ROUNDING` (a derived
    quantity that is zero up to rounding passes). A robot whose class sets
    ``signed_inertias = True`` (an exact equivalent model, e.g. the DUAL-V's split model
    with residual inertias ``I − m·p·(l − p)``) is checked for finite inertias only."""
    if is_traced(robot) and not runtime_checks_enabled():
        return value  # the masks would be traced for nothing
    bodies, diagonal, bad_mass, bad_inertia = _body_faults(robot)
    message = "body masses must be finite and >= 0 [kg]"
    value = guard(value, bad_mass, message, bodies.mass, bodies.names)
    message = "body inertias must be finite with diagonal >= 0 [kg m^2]"
    return guard(value, bad_inertia, message, diagonal, bodies.names)


def _parameters(robot: Robot) -> list[tuple[str, Array]]:
    """``(name, leaf)`` of every floating-point array leaf of the robot (its lengths,
    masses, inertias, ...), named ``Class.field``."""
    flat, _ = jax.tree_util.tree_flatten_with_path(robot)
    prefix = type(robot).__name__
    return [(prefix + jax.tree_util.keystr(p), x) for p, x in flat if eqx.is_inexact_array(x)]


def _signed_parameters(robot: Robot) -> list[tuple[str, Array]]:
    """``(name, value)`` of the fields in the class's ``nonnegative_parameters``."""
    prefix = type(robot).__name__ + "."
    names = getattr(type(robot), "nonnegative_parameters", ())
    return [(prefix + name, jnp.asarray(getattr(robot, name))) for name in names]


def _parameter_faults(robot: Robot) -> tuple:
    """Masks of :func:`checked_parameters`: a non-finite parameter ``(p,)``, and a
    negative one ``(s,)`` when the class names ``nonnegative_parameters``."""
    parameters, signed = _parameters(robot), _signed_parameters(robot)
    faults = ()
    if parameters:
        faults += (jnp.stack([~jnp.all(jnp.isfinite(x)) for _, x in parameters]),)
        if signed:
            faults += (jnp.stack([jnp.any(x < -ROUNDING) for _, x in signed]),)
    return faults


def checked_parameters(robot: Robot, value):
    """``value``, guarded by every floating-point parameter of the robot being finite,
    and the fields in the class's ``nonnegative_parameters`` (lengths, masses,
    inertias) being ``>= 0`` to :data:`ROUNDING` (so that a subnormal ``-1e-309``,
    flushed to zero in compiled code, is judged alike eagerly and under ``jit``).

    The body checks (:func:`checked_bodies`) see masses and inertias only; a NaN length
    set with ``eqx.tree_at`` gave a silent NaN wrench, centre of mass or torque, and a
    negative one a mirrored link. Eagerly a ``ValueError`` naming the parameters
    (``PlanarArm.lengths``) and their values; under ``jit`` a runtime error
    (:func:`jaxbal.set_runtime_checks`).
    """
    parameters, signed = _parameters(robot), _signed_parameters(robot)
    if not parameters:
        return value
    message = "robot parameters must be finite"
    negative = "robot parameters must be >= 0"
    if not is_traced([x for _, x in parameters], [x for _, x in signed]):
        bad = {n: np.asarray(x).tolist() for n, x in parameters if not np.all(np.isfinite(x))}
        if bad:
            raise ValueError(f"{message}: {bad}")
        bad = {n: np.asarray(x).tolist() for n, x in signed if np.any(np.asarray(x) < -ROUNDING)}
        if bad:
            raise ValueError(f"{negative}: {bad}")
        return value
    if not runtime_checks_enabled():
        return value
    for invalid, text in zip(_parameter_faults(robot), (message, negative), strict=False):
        value = guard(value, invalid, text, invalid)
    return value


def checked_finite(what: str, robot: Robot, value):
    """``value`` (a pytree of arrays), guarded by being finite: the result of finite
    inputs overflows when a parameter or the state is too large (a 1e300 m link).
    Eagerly the ``ValueError`` names the largest robot parameter."""
    leaves = jax.tree_util.tree_leaves(value)
    message = f"{what} is not finite (overflow: robot parameters or state too large)"
    if not is_traced(leaves):  # in NumPy: no small JAX operations dispatched eagerly
        arrays = [np.asarray(x) for x in leaves]
        if all(np.all(np.isfinite(x)) for x in arrays):
            return value
        parameters = [(n, np.max(np.abs(x), initial=0.0)) for n, x in _parameters(robot)]
        if parameters:
            name, size = max(parameters, key=lambda item: item[1])
            message += f"; largest robot parameter: {name} with |x| = {size:.3g}"
        raise ValueError(f"{message}: {np.concatenate([np.ravel(x) for x in arrays])!r}")
    if not runtime_checks_enabled():
        return value
    invalid = ~jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in leaves]))
    return guard(value, invalid, message, jnp.concatenate([jnp.ravel(x) for x in leaves]))


def checked_physics(what: str, robot: Robot, value):
    """``value`` guarded by :func:`checked_bodies`, :func:`checked_parameters` and
    :func:`checked_finite` (the checks of every physics output; under a trace, call it
    in :func:`~jaxbal._src.merged_guards.merged_guards`)."""
    return checked_finite(what, robot, checked_parameters(robot, checked_bodies(robot, value)))


def total_mass(robot: Robot) -> Scalar:
    """Total mass of all moving bodies (payload, counter-masses included) [kg]."""
    return jnp.sum(robot.mass_properties().mass)


def body_com_poses(robot: Robot, q: Coordinates) -> tuple[Points, Rotations]:
    """Positions ``(n, 3)`` of every body's centre of mass [m] and the body rotations
    ``(n, 3, 3)``, base frame."""
    bodies = robot.mass_properties()
    origins, rotations = robot.body_frames(q)
    return origins + matvec(rotations, bodies.com), rotations


def body_com_positions(robot: Robot, q: Coordinates) -> Points:
    """``(n, 3)`` positions of every body's centre of mass in the base frame [m]."""
    return body_com_poses(robot, q)[0]


def body_velocities(robot: Robot, q: Coordinates, qd: Coordinates):
    """COM positions, rotations, COM velocities ``(n, 3)`` [m/s] and angular velocities
    ``(n, 3)`` [rad/s] of every body, base frame (one forward-mode pass)."""
    (positions, rotations), (velocities, rotation_rates) = jax.jvp(
        lambda q_: body_com_poses(robot, q_), (q,), (qd,)
    )
    omega = vee(matmul_transposed(rotation_rates, rotations))
    return positions, rotations, velocities, omega


def center_of_mass(robot: Robot, q: Coordinates) -> Vec3:
    """Total centre of mass x_S of the moving bodies, base frame [m].

    References:
        Briot et al. (2012), eq (7).

    Raises:
        ValueError: eagerly, a non-finite ``q``, a negative or non-finite body mass or
            inertia, a non-finite robot parameter (a robot changed with ``eqx.tree_at``
            included), or an overflow; under ``jit`` a runtime error
            (:func:`jaxbal.set_runtime_checks`). Before, these gave a silent NaN or a
            wrong centre of mass (negative masses).
    """
    if not is_traced(robot, q):
        return run_compiled(_center_of_mass, robot_faulty, robot, q)
    return _center_of_mass(robot, q)


def _center_of_mass(robot: Robot, q: Coordinates) -> Vec3:
    q = jnp.asarray(q, dtype=float)
    bodies = robot.mass_properties()
    positions = body_com_positions(robot, q)
    mass = jnp.sum(bodies.mass)
    com = weighted_sum(bodies.mass, positions) / jnp.maximum(mass, 1e-300)

    def checks(com):
        checked = guard(com, ~jnp.isfinite(q), "non-finite coordinates q", q)
        return checked_physics("centre of mass", robot, checked)

    return merged_guards(checks, com)


def momentum(robot: Robot, q: Coordinates, qd: Coordinates) -> tuple[Vec3, Vec3]:
    """Total linear momentum ``p`` [kg·m/s] and angular momentum ``L`` about the base
    origin [kg·m²/s] of all moving bodies, base frame.

    ``L = Σ m_i c_i × v_i + R_i I_i R_iᵀ ω_i`` with ``ω_i = vee(Ṙ_i R_iᵀ)``.
    """
    bodies = robot.mass_properties()
    positions, rotations, velocities, omega = body_velocities(robot, q, qd)
    linear = weighted_sum(bodies.mass, velocities)
    spin = world_inertia_times(rotations, bodies.inertia, omega)  # R I Rᵀ ω
    orbital = weighted_sum(bodies.mass, cross(positions, velocities))
    return linear, orbital + jnp.sum(spin, axis=0)


def inertial_wrench(robot: Robot, q: Coordinates, qd: Coordinates, qdd: Coordinates):
    """``(−dp/dt, −dL/dt)`` of any robot, by forward-mode differentiation of
    :func:`momentum` (the general 3-D evaluation behind :func:`shaking_wrench`)."""
    _, (dp, dl) = jax.jvp(lambda q_, qd_: momentum(robot, q_, qd_), (q, qd), (qd, qdd))
    return -dp, -dl


def shaking_wrench(
    robot: Robot,
    q: Coordinates,
    qd: Coordinates,
    qdd: Coordinates,
    gravity: Vec3 | None = None,
) -> tuple[Vec3, Vec3]:
    """Force and moment the moving robot exerts on its base (the shaking wrench).

    Sign convention: this is the wrench applied *by the robot on the base*, about the
    base origin, in the base frame:

        f_sh = -dp/dt + m_tot·g,     m_sh = -dL/dt + Σ m_i c_i × g

    where ``p`` and ``L`` are from :func:`momentum`. With the default ``gravity=None``
    only the inertial (dynamic) part is returned, as in the papers; e.g. f_sh =
    -m_tot·ẍ_S. Planar robots give ``f[2] = 0`` and a moment along z; for a
    :class:`~jaxbal.planar.PlanarRobot` the same quantity is evaluated with scalar
    planar kinematics (:func:`~jaxbal.planar.planar_inertial_wrench`), otherwise by
    :func:`inertial_wrench`.

    Args:
        robot: any :class:`~jaxbal.robot.Robot`.
        q, qd, qdd: ``(dof,)`` coordinates and their first two time derivatives
            (SI units of the robot's coordinates: rad or m, per s, per s²).
        gravity: optional ``(3,)`` gravitational acceleration [m/s²], e.g.
            ``(0, 0, -9.81)``.

    Returns:
        ``(force (3,) [N], moment (3,) [N·m])``. One sample; batch with ``jax.vmap``.

    Raises:
        ValueError: a wrong shape of ``q``, ``qd``, ``qdd`` or ``gravity`` (at trace
            time); eagerly, a non-finite state or a negative/non-finite body mass or
            inertia (a robot changed with ``eqx.tree_at`` included), a non-finite robot
            parameter (e.g. a NaN length) or an overflow to inf. Under ``jit`` the
            same value checks raise at run time (:func:`jaxbal.set_runtime_checks`).

    Performance: under ``jit``/``vmap``/``grad`` the evaluation is replayed as
    straight-line scalar code (:mod:`jaxbal._src.straight_line`): the same operations,
    fused by XLA like a hand-written closed form of the robot.

    References:
        Briot et al. (2012), eq (1); van der Wijk et al. (2013), section 2.
    """
    if not is_traced(robot, q, qd, qdd, gravity):
        return run_compiled(_wrench_of_one_state, robot_faulty, robot, q, qd, qdd, gravity)
    return _shaking_wrench(robot, q, qd, qdd, gravity)


def _wrench_of_one_state(robot: Robot, q, qd, qdd, gravity):
    # one state: evaluated as written (the replay's gain is fusing its scalar code across
    # a batch; for one state it compiles to more kernels than the array code)
    return _shaking_wrench(robot, q, qd, qdd, gravity, replay=False)


#: whether traced evaluations of the wrench are replayed as straight-line code
#: (:func:`replayed`); in JAX's trace keys, so a nested compiled function traced one
#: way is not reused the other way.
_REPLAY = _TraceFlag(True)


@contextlib.contextmanager
def replayed(enabled: bool):
    """Context manager: whether :func:`shaking_wrench` and the generalised forces of
    :func:`jaxbal.inverse_dynamics` (so :func:`jaxbal.actuator_torques`) traced inside
    the block are replayed as straight-line code (:mod:`jaxbal._src.straight_line`;
    default on).

    The replay makes the compiled wrench about as fast as a hand-written closed form
    (sweeps, throughput), but generating it adds trace time and its many scalar
    operations add compile time. A program that runs a few hundred times, such as the
    co-design's value and gradient, starts sooner without it (measured on the 2-core
    CPU: the first DUAL-V co-design 1.47 s → 1.10 s, each later evaluation
    ~1.5–2× slower)."""
    with _REPLAY(enabled):
        yield


def _shaking_wrench(robot: Robot, q, qd, qdd, gravity, replay: bool | None = None):
    """The checked wrench; ``replay=False`` evaluates the physics as written, without
    the straight-line replay (the benchmark's "before"); ``None``: as set by
    :func:`replayed`."""
    q, qd, qdd, check = state_check(robot, q, qd, qdd)
    replay = _REPLAY.value if replay is None else replay
    physics = _straight_physics if replay else _straight_physics.as_written
    wrench = physics(robot, q, qd, qdd, gravity)
    # Both outputs guarded: a check on the force alone was dropped from compiled code
    # that uses only the moment (peak_moment of a NaN-inertia robot was finite).
    return merged_guards(lambda w: checked_physics("shaking wrench", robot, check(w)), wrench)


def _physics(robot: Robot, q, qd, qdd, gravity):
    """The unchecked wrench (:func:`shaking_wrench` wraps it in the value checks)."""
    with runtime_checks(False):  # none inside; the code generated is keyed without it
        if isinstance(robot, PlanarRobot):
            force, moment = planar_inertial_wrench(robot, q, qd, qdd)
        else:
            force, moment = inertial_wrench(robot, q, qd, qdd)
        if gravity is not None:
            g = jnp.asarray(gravity, dtype=float)
            check_shape("gravity", g, (3,))
            bodies = robot.mass_properties()
            positions = body_com_positions(robot, q)
            force = force + jnp.sum(bodies.mass) * g
            moment = moment + weighted_sum(
                bodies.mass, cross(positions, jnp.broadcast_to(g, positions.shape))
            )
    return force, moment


# The checks stay outside the generated straight-line code, so that one program serves
# checked and unchecked evaluations alike (e.g. a gradient's value over every sample and
# its re-evaluation at the peak sample, which skips the checks).
_straight_physics = straight_line(_physics)
