"""The 4-DOF SCARA robot of Arakelian & Briot (2008), with counter-masses and an optional
vertical counterweight (the cable-and-pulley of their Fig 5).

======================  ===========  ========  =========================================
parameter               nominal      unit      source
======================  ===========  ========  =========================================
l_O1O2, l_O2O3          0.125, 0.225 m         §2 (printed "mm"; the values are metres)
l_O1S1, l_O2S2, l_O3S3  0.0625,      m         §2; l_O3S3 not printed, taken 0 (eq 1)
                        0.1125, 0
m_1, m_2, m_3           1.2, 2, 0.5  kg        §2
I_1, I_2, I_3           0.014,       kg·m²     §2, axial, about each link's own COM
                        0.036, 0.0126
r_c1, r_c2, r_c3        0.16, 0.16,  m         counter-mass distances behind O1, O2, O3:
                        0.05                   0.16 m reproduces the paper's balanced
                                               m_1, m_2, l_O1S1, l_O2S2 (see below)
======================  ===========  ========  =========================================

Coordinates ``q = (θ1, θ2, θ3, d4)``: the relative joint angles of O1, O2, O3 [rad] and
the vertical translation of the end-effector [m] (+z up). Absolute angles: link 1
``θ1``, link 2 ``θ1 + θ2``, end-effector ``φ = θ1 + θ2 + θ3`` (eq 6). The base origin is
O1; the horizontal links lie in the plane ``z = 0``.

Bodies (rows of :meth:`Scara.mass_properties`):

* ``link1``, ``link2``: COM at the signed distance ``l_OiSi`` along the link (negative:
  behind the joint, "outside" in the paper's words);
* ``end_effector`` (link 3, the quill): turns by θ3 about the O3 axis and translates by
  d4; COM at ``l_O3S3`` from the axis;
* ``payload``: point mass on the O3 axis, moving with the end-effector;
* ``counter_mass1..3``: point counter-masses ``m_ci`` on the prolongation of link i at
  ``r_ci`` behind its joint (counter-mass 3 rides on the end-effector);
* ``vertical_counterweight``: point mass on the O3 axis whose height is ``−d4`` (cable
  over a pulley, Fig 5): it cancels the vertical inertia force when it equals the mass
  that translates with d4. It is carried by link 2, so it takes part in the horizontal
  balance as a mass at O3.

With the counterweight (0.5 kg) and counter-masses of 5.01 kg and 2.81 kg at 0.16 m
behind O1 and O2, conditions (1)-(3) give ``m_1 = 6.21 kg``, ``l_O1S1 = −0.117 m``,
``m_2 = 4.81 kg``, ``l_O2S2 = −0.0468 m``: the paper's printed balanced values to their
rounding (see :mod:`jaxbal.robots.scara_balancing`).

References:
    Arakelian, V., Briot, S. (2008). Dynamic balancing of the SCARA robot. RoManSy 17,
    Tokyo. Section 2, eqs (1)-(8), Figs 3-6.
"""

from __future__ import annotations

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import two_link_ik, unit
from jaxbal._src.mujoco.tree import Coupling, Joint, Tree, TreeBody, Z
from jaxbal._src.profiles import Profile, Quintic, held, normalised_time
from jaxbal._src.robot import Bodies, Robot, concatenate, planar_inertia, point_masses, rot_z
from jaxbal._src.solution_guard import guard_solution
from jaxbal._src.types import Array, Float, ScalarLike
from jaxbal._src.validation import (
    check_nonnegative,
    check_shape,
    is_traced,
)

__all__ = [
    "PickAndPlace",
    "Scara",
    "ScaraTrajectory",
    "check_reachable",
    "joint_trajectory",
    "scara",
]


def _in_plane(points2d, height):
    return jnp.concatenate([points2d, jnp.reshape(height, (1,))])


class Scara(Robot):
    """The 4-DOF SCARA (RRR + vertical prismatic) of Arakelian & Briot (2008), Fig 3.

    Attributes:
        lengths: ``(2,)`` ``l_O1O2, l_O2O3`` [m].
        com_offsets: ``(3,)`` signed ``l_O1S1, l_O2S2, l_O3S3`` along each link [m].
        masses: ``(3,)`` link masses ``m_1, m_2, m_3`` [kg].
        inertias: ``(3,)`` axial inertias ``I_1, I_2, I_3`` about each link's COM [kg·m²].
        payload: point payload on the end-effector axis [kg].
        counter_masses: ``(3,)`` counter-masses ``m_c1, m_c2, m_c3`` [kg] (default 0).
        counter_distances: ``(3,)`` their distances ``r_ci`` behind O1, O2, O3 [m].
        vertical_counterweight: mass ``m_v`` moving opposite to the end-effector [kg]
            (default 0: no counterweight).
    """

    com_dims = 2  # COM planning steers the horizontal COM (φ and z follow the pose line)
    design_fields = {
        "counter_mass": "counter_masses",
        "counter_distance": "counter_distances",
        "vertical_counterweight": "vertical_counterweight",
        "payload": "payload",
    }
    nonnegative_parameters = (
        *("lengths", "masses", "inertias", "payload", "counter_masses"),
        "vertical_counterweight",
    )

    lengths: Float[Array, "2"]
    com_offsets: Float[Array, "3"]
    masses: Float[Array, "3"]
    inertias: Float[Array, "3"]
    payload: Float[Array, ""]
    counter_masses: Float[Array, "3"]
    counter_distances: Float[Array, "3"]
    vertical_counterweight: Float[Array, ""]

    def __init__(
        self,
        lengths,
        com_offsets,
        masses,
        inertias,
        payload=0.0,
        counter_masses=(0.0, 0.0, 0.0),
        counter_distances=(0.16, 0.16, 0.05),
        vertical_counterweight=0.0,
    ):
        self.lengths = jnp.asarray(lengths, dtype=float)
        self.com_offsets = jnp.asarray(com_offsets, dtype=float)
        self.masses = jnp.asarray(masses, dtype=float)
        self.inertias = jnp.asarray(inertias, dtype=float)
        self.payload = jnp.asarray(payload, dtype=float)
        self.counter_masses = jnp.asarray(counter_masses, dtype=float)
        self.counter_distances = jnp.asarray(counter_distances, dtype=float)
        self.vertical_counterweight = jnp.asarray(vertical_counterweight, dtype=float)
        check_shape("lengths", self.lengths, (2,))
        for name in ("com_offsets", "masses", "inertias", "counter_masses", "counter_distances"):
            check_shape(name, getattr(self, name), (3,))
        check_shape("payload", self.payload, ())
        check_shape("vertical_counterweight", self.vertical_counterweight, ())
        for name in self.nonnegative_parameters:
            check_nonnegative(f"Scara.{name}", getattr(self, name))

    @property
    def dof(self) -> int:
        return 4

    # --- the two methods every robot provides --------------------------------------

    def mass_properties(self) -> Bodies:
        zeros = jnp.zeros(3)
        links = Bodies(
            mass=self.masses,
            com=jnp.stack([self.com_offsets, zeros, zeros], axis=-1),
            inertia=planar_inertia(self.inertias),
            names=("link1", "link2", "end_effector"),
        )
        counter = Bodies(
            mass=self.counter_masses,
            com=jnp.stack([-self.counter_distances, zeros, zeros], axis=-1),
            inertia=jnp.zeros((3, 3, 3)),
            names=("counter_mass1", "counter_mass2", "counter_mass3"),
        )
        return concatenate(
            links,
            point_masses(self.payload[None], ("payload",)),
            counter,
            point_masses(self.vertical_counterweight[None], ("vertical_counterweight",)),
        )

    def body_frames(self, q):
        check_shape("q", q, (4,))
        q = jnp.asarray(q, dtype=float)
        theta1, theta12 = q[0], q[0] + q[1]
        phi = theta12 + q[2]
        joints = self.joint_positions(q)
        zero = jnp.zeros(())
        o1 = _in_plane(joints[0], zero)
        o2 = _in_plane(joints[1], zero)
        tool = _in_plane(joints[2], q[3])
        counterweight = _in_plane(joints[2], -q[3])
        origins = jnp.stack([o1, o2, tool, tool, o1, o2, tool, counterweight])
        angles = jnp.stack([theta1, theta12, phi, phi, theta1, theta12, phi, theta12])
        return origins, rot_z(angles)

    # --- kinematics ----------------------------------------------------------------

    def joint_positions(self, q) -> Float[Array, "3 2"]:
        """Horizontal positions of O1, O2, O3 [m], shape ``(3, 2)``."""
        q = jnp.asarray(q, dtype=float)
        steps = self.lengths[:, None] * unit(jnp.cumsum(q[:2]))
        return jnp.concatenate([jnp.zeros((1, 2)), jnp.cumsum(steps, axis=0)], axis=0)

    def end_effector(self, q) -> Float[Array, "4"]:
        """End-effector pose ``(x, y, φ, z)`` [m, m, rad, m] (z = d4)."""
        q = jnp.asarray(q, dtype=float)
        return jnp.concatenate([self.joint_positions(q)[2], jnp.sum(q[:3])[None], q[3:]])

    def inverse_kinematics(self, pose, *, branch=None, return_valid: bool = False):
        """Joint coordinates ``(θ1, θ2, θ3, d4)`` of an end-effector pose, eqs (4)-(6).

        Angles are not wrapped, so a continuous pose path gives continuous joints
        (θ3 = φ − θ1 − θ2 keeps the turns of φ).

        Args:
            pose: ``(4,)`` ``(x, y, φ, z)`` [m, m, rad, m].
            branch: ``+1`` or ``−1`` (or ``(±1,)``), the sign of ``sin θ2`` (the "±" of
                eq 4; ``+1`` is the working mode of the paper's move).
            return_valid: return ``(q, valid)`` and never raise (batched code).

        Raises:
            ValueError: eagerly, naming the pose, when (x, y) is out of reach or on
                the boundary (arm stretched or folded: singular; under ``jit`` a
                runtime error).
        """
        pose = pose_given = jnp.asarray(pose, dtype=float)
        check_shape("pose", pose, (4,))
        (mode,) = self.branch(branch)
        finite = jnp.all(jnp.isfinite(pose))
        # A non-finite pose is invalid; solve a finite stand-in so q stays finite (a NaN
        # pose gave NaN joints with return_valid=True, against the contract).
        pose = jnp.where(finite, pose, jnp.zeros_like(pose).at[0].set(self.lengths[0]))
        q1, q2, valid = two_link_ik(pose[:2], self.lengths[0], self.lengths[1], mode)
        valid = valid & finite
        q = jnp.stack([q1, q2, pose[2] - q1 - q2, pose[3]])
        if return_valid:
            return q, valid
        message = "SCARA end-effector pose out of reach or on its singular boundary (x, y, φ, z)"
        return guard_solution(q, ~valid, message, pose_given, robot=self)  # under jit too

    # --- MuJoCo --------------------------------------------------------------------

    def mujoco_tree(self) -> Tree:
        """RRR + prismatic; the vertical counterweight hangs at O3 on its own slide
        (the cable of Fig 5 is the coordinate map ``−d4`` of that slide)."""
        l1, l2 = (float(x) for x in np.asarray(self.lengths))
        bodies = (
            TreeBody("link1", None, joints=(Joint("theta1", "hinge", Z),), visual_to=(l1, 0, 0)),
            TreeBody("counter_mass1", "link1"),
            TreeBody(
                "link2",
                "link1",
                pos=(l1, 0, 0),
                joints=(Joint("theta2", "hinge", Z),),
                visual_to=(l2, 0, 0),
            ),
            TreeBody("counter_mass2", "link2"),
            TreeBody(
                "vertical_counterweight",
                "link2",
                pos=(l2, 0, 0),
                joints=(Joint("cable", "slide", Z),),
            ),
            TreeBody(
                "end_effector",
                "link2",
                pos=(l2, 0, 0),
                joints=(Joint("theta3", "hinge", Z), Joint("d4", "slide", Z)),
                visual_to=(0, 0, -0.1),
            ),
            TreeBody("payload", "end_effector"),
            TreeBody("counter_mass3", "end_effector"),
        )
        return Tree(
            bodies=bodies,
            coordinates=_mujoco_coordinates,
            actuated=("theta1", "theta2", "theta3", "d4"),
            # the cable: a joint equality cable = −d4, so an exported model keeps the
            # counterweight moving (without it, 39 N of vertical shaking force)
            couplings=(Coupling("cable", "d4", (0.0, -1.0, 0.0, 0.0, 0.0)),),
        )


def _mujoco_coordinates(q):
    """MuJoCo's ``qpos = (θ1, θ2, −d4, θ3, d4)`` (module level: trees compare equal)."""
    return jnp.stack([q[0], q[1], -q[3], q[2], q[3]])


def scara(payload: ScalarLike = 0.0, vertical_counterweight: ScalarLike = 0.0) -> Scara:
    """The unbalanced SCARA of Arakelian & Briot (2008), §2 (lengths in metres)."""
    return Scara(
        lengths=[0.125, 0.225],
        com_offsets=[0.0625, 0.1125, 0.0],
        masses=[1.2, 2.0, 0.5],
        inertias=[0.014, 0.036, 0.0126],
        payload=payload,
        vertical_counterweight=vertical_counterweight,
    )


class PickAndPlace(eqx.Module):
    """A pick-and-place move of the end-effector: ``t ↦ (x, y, φ, z)``.

    The horizontal pose ``(x, y, φ)`` goes straight from ``start`` to ``end`` with
    ``profile``; the height rises by ``lift`` and comes back,
    ``z = lift · 64 u³ (1 − u)³`` (``u = t/T``; zero velocity and acceleration at both
    ends, peak ``lift`` at mid-move).

    Attributes:
        start, end: ``(3,)`` horizontal poses ``(x, y, φ)`` [m, m, rad].
        profile: a :class:`~jaxbal.profiles.Profile` (paper: quintic).
        duration: ``T`` [s].
        lift: peak height of the end-effector above its start height [m].

    References:
        Arakelian & Briot (2008), §2: x 0.15 → −0.15 m, y = 0.2 m, φ 83° → 157°,
        quintic, 0.3 s ("25 × 300 mm" cycle).
    """

    start: Float[Array, "3"]
    end: Float[Array, "3"]
    profile: Profile
    duration: Float[Array, ""]
    lift: Float[Array, ""]

    def __init__(self, start, end, duration, profile: Profile | None = None, lift=0.0):
        self.start = jnp.asarray(start, dtype=float)
        self.end = jnp.asarray(end, dtype=float)
        check_shape("start", self.start, (3,))
        check_shape("end", self.end, (3,))
        self.profile = Quintic() if profile is None else profile
        self.duration = jnp.asarray(duration, dtype=float)
        self.lift = jnp.asarray(lift, dtype=float)

    def __call__(self, t: ScalarLike) -> Float[Array, "4"]:
        u = normalised_time(t, self.duration, "PickAndPlace")
        horizontal = self.start + self.profile(u) * (self.end - self.start)
        height = self.lift * 64.0 * (held(u) * (1.0 - held(u))) ** 3
        return jnp.concatenate([horizontal, height[None]])


class ScaraTrajectory(eqx.Module):
    """Joint motion ``t ↦ q`` following an end-effector move by inverse kinematics."""

    robot: Scara
    move: Callable
    branch: tuple[int, ...] | int | None = eqx.field(static=True, default=None)

    def __call__(self, t: ScalarLike) -> Float[Array, "4"]:
        return self.robot.inverse_kinematics(self.move(t), branch=self.branch)


def check_reachable(robot: Scara, move: Callable, duration, count: int = 201) -> None:
    """Raise ``ValueError`` if ``move`` leaves the workspace at any of ``count`` instants.

    A straight line between two reachable points may cross the unreachable disc of
    radius ``|l_O1O2 − l_O2O3|`` around O1.
    """
    if is_traced(robot, move, duration):
        return
    times = np.linspace(0.0, float(duration), count)
    poses = jax.vmap(move)(jnp.asarray(times))
    _, valid = jax.vmap(lambda p: robot.inverse_kinematics(p, branch=1, return_valid=True))(poses)
    valid = np.asarray(valid)
    if not np.all(valid):
        first = int(np.argmin(valid))
        raise ValueError(
            f"pick-and-place target out of reach: at t = {times[first]:.4g} s the "
            f"end-effector would be at (x, y) = {np.asarray(poses[first, :2])!r} m, outside "
            f"the annulus {float(abs(robot.lengths[0] - robot.lengths[1])):.4g} m <= r <= "
            f"{float(robot.lengths[0] + robot.lengths[1]):.4g} m"
        )


def joint_trajectory(robot: Scara, move: PickAndPlace, branch=None) -> ScaraTrajectory:
    """The joint motion of a pick-and-place move, checked eagerly for reachability.

    Raises:
        ValueError: when the move's start, end or any intermediate point is out of reach.
    """
    check_reachable(robot, move, move.duration)
    return ScaraTrajectory(robot, move, branch)
