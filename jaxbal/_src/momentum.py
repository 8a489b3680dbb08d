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

import jax
import jax.numpy as jnp

from jaxbal._src.eager import run_compiled
from jaxbal._src.linalg import (
    cross,
    matmul_transposed,
    matvec,
    vee,
    weighted_sum,
    world_inertia_times,
)
from jaxbal._src.loop_checks import loops_faulty, with_closure_excess
from jaxbal._src.merged_guards import merged_guards
from jaxbal._src.planar import PlanarRobot, planar_inertial_wrench
from jaxbal._src.robot import Robot
from jaxbal._src.robot_checks import checked_physics, robot_faulty
from jaxbal._src.state_checks import state_check
from jaxbal._src.straight_line import straight_line
from jaxbal._src.types import Coordinates, Points, Rotations, Scalar, Vec3
from jaxbal._src.validation import (
    _TraceFlag,
    check_shape,
    guard,
    is_traced,
    runtime_checks,
)


def _com_faulty(robot: Robot, q):
    """:func:`robot_faulty` (the eager centre of mass's test, :func:`run_compiled`)."""
    return robot_faulty(robot)


def _wrench_faulty(robot: Robot, q, qd, qdd, gravity):
    """:func:`robot_faulty`, or the state off a closed chain's loops (the eager
    wrench's test, :func:`run_compiled`)."""
    return robot_faulty(robot) | loops_faulty(robot, q, qd, qdd)


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
        return run_compiled(_center_of_mass, _com_faulty, robot, q)
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
            parameter (e.g. a NaN length), a state off a closed chain's loop closures
            (:func:`jaxbal.state_valid`; e.g. a motion held while a length was changed
            with ``eqx.tree_at``) or an overflow to inf. Under ``jit`` the same value
            checks raise at run time (:func:`jaxbal.set_runtime_checks`).

    Performance: under ``jit``/``vmap``/``grad`` the evaluation is replayed as
    straight-line scalar code (:mod:`jaxbal._src.straight_line`): the same operations,
    fused by XLA like a hand-written closed form of the robot.

    References:
        Briot et al. (2012), eq (1); van der Wijk et al. (2013), section 2.
    """
    if not is_traced(robot, q, qd, qdd, gravity):
        return run_compiled(_wrench_of_one_state, _wrench_faulty, robot, q, qd, qdd, gravity)
    return _shaking_wrench(robot, q, qd, qdd, gravity)


def tree_wrench(robot: Robot, q, qd, qdd, gravity=None):
    """:func:`shaking_wrench` of the robot's bodies moving with ``(q, q̇, q̈)``, any state:
    a closed chain's loop closures are not required, every other check is kept (e.g.
    comparing two models of the same bodies at random states, the MJCF export's check)."""
    return _shaking_wrench(robot, q, qd, qdd, gravity, loops=False)


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


def _shaking_wrench(
    robot: Robot, q, qd, qdd, gravity, replay: bool | None = None, loops: bool = True
):
    """The checked wrench; ``replay=False`` evaluates the physics as written, without
    the straight-line replay (the benchmark's "before"); ``None``: as set by
    :func:`replayed`. ``loops=False``: a closed chain's loop closures not required (the
    wrench of its bodies at any state: :func:`tree_wrench`)."""
    q, qd, qdd, check = state_check(robot, q, qd, qdd, loops=loops, gravity=gravity)
    replay = _REPLAY.value if replay is None else replay
    straight = _straight_physics_loops if check.traced_loops else _straight_physics
    physics = straight if replay else straight.as_written
    if not check.traced_loops:
        # Both outputs guarded: a check on the force alone was dropped from compiled
        # code that uses only the moment (peak_moment of a NaN-inertia robot was finite).
        wrench = physics(robot, q, qd, qdd, gravity)
        return merged_guards(
            lambda w: check.loops(checked_physics(_WRENCH, robot, check(w))), wrench
        )

    # A closed chain: its loop residual computed with the wrench and written to memory
    # with it before the checks (merged_guards). Measured, DUAL-V chunked jit(vmap) on the
    # 2-core CPU: +20 % over no loop check; with Φ̇ and Φ̈ too +42 %, and +85 % when the
    # check read them straight from the generated code (computed twice by XLA's fusion).
    def checks(both):
        w, excess = both
        return check.loops(checked_physics(_WRENCH, robot, check(w)), excess), excess

    return merged_guards(checks, physics(robot, q, qd, qdd, gravity))[0]


_WRENCH = "shaking wrench"


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
#: the wrench and the loop excess of a closed chain's state as one program
#: (:mod:`jaxbal._src.loop_checks`: they share their sines and cosines)
_straight_physics_loops = straight_line(with_closure_excess(_physics))
