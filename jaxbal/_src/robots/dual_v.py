"""The DUAL-V: a redundant planar 4-RRR parallel robot (van der Wijk et al. 2013).

Four RR arms ``A_i B_i C_i`` carry a platform *link* 5 whose two joints coincide pairwise
(``C_1 = C_2``, ``C_3 = C_4``). Links ``i1`` (``A_i B_i``) are driven at the base; a brass
counter-mass (with a lead tuning mass) sits on the prolongation of each link ``i1``.

======================  =========================  ============  ======================
parameter               value                      unit          note
======================  =========================  ============  ======================
l_i1, l_i2              0.2800, 0.2800             m             all arms equal
a = l_i1·√2, b          0.3960, 0.1100             m             l_5 = 2b = 0.22 m
m_i1, I_i1, p_i1        1.169, 0.012967, 0.0737    kg, kg·m², m  COM from A_i
m_i2, I_i2, p_i2        0.606, 0.006417, 0.1279    kg, kg·m², m  COM from B_i
m_5, I_5                0.899, 0.008168            kg, kg·m²     COM at platform centre
m_cm,i, I_cm,i, p_cm,i  7.983, 0.026845, 0.0575    kg, kg·m², m  incl. tuning mass
m_tun,i, p_tun,i        0.188, 0.080               kg, m         lead, point mass
I_act,i                 0.0041                     kg·m²         actuator rotor
======================  =========================  ============  ======================

Source: Table 1 of the paper; inertias are about each body's COM.
Layout (Fig 2c; derived from it and the equations, drawn by ``plot_layout``):

* base frame at the workspace centre; platform pose ``u = (x5, y5, θ5)``. At ``θ5 = 0``
  the platform lies along y: ``C_1 = C_2 = (x5, y5 + b)``, ``C_3 = C_4 = (x5, y5 - b)``,
  i.e. ``C_i = (x5, y5) + s_i·b·(-sin θ5, cos θ5)`` with ``s = (+1, +1, -1, -1)``; these
  signs are the only ones that reproduce the ``∓c(θ_i2 - θ5)·b`` column of eq (7).
* base pivots numbered counter-clockwise from the first quadrant:
  ``A_1 = (a, b)``, ``A_2 = (-a, b)``, ``A_3 = (-a, -b)``, ``A_4 = (a, -b)``; then
  ``A_i - C_i = (±a - x5, -y5)`` and the workspace of a non-rotated platform is the
  intersection of the circles of radius ``l_i1 + l_i2`` about ``(±a, 0)``: widths
  ``2(l_i1 + l_i2 - a) = 0.328 m`` along x and ``2·sqrt((l_i1 + l_i2)² - a²) = 0.792 m``
  along y, as the paper states. (The mirror image x → -x is equally consistent.)
* arms 1, 4 and arms 2, 3 form the parallelograms: with the *elbow branch*
  ``σ_i = sign sin(θ_i2 - θ_i1)`` equal to ``OUTWARD = (+1, -1, +1, -1)`` (elbows away
  from the x axis, the two "V"s) or ``CROSSED = (-1, +1, -1, +1)``, a non-rotated platform
  gives ``θ_41 = θ_12, θ_42 = θ_11, θ_31 = θ_22, θ_32 = θ_21``. Hence the linear
  momentum multiplies the four link directions ``e_11, e_21, e_22 (= e_31), e_12 (= e_41)``
  by exactly the four rows of eq (2). Mixed branches break the parallelograms. Both
  branches give the same shaking force but not the same shaking moment: on the Fig 12
  triangle OUTWARD gives 16.1 / 14.2 / 14.1 N·m (unbalanced / 96.72 % / balanced), the
  paper's values, and CROSSED 10.0 / 27.8 / 28.5 N·m; OUTWARD is the prototype's branch.
* all angles are absolute, from the x axis, counter-clockwise [rad].

Coordinates ``q`` (what :meth:`DualV.inverse_kinematics` returns, 11 entries):
``(θ_11, θ_21, θ_31, θ_41, θ_12, θ_22, θ_32, θ_42, x5, y5, θ5)``.

References:
    van der Wijk, V., Krut, S., Pierrot, F., Herder, J. L. (2013). Design and
    experimental evaluation of a dynamically balanced redundant planar 4-RRR parallel
    manipulator. Int. J. Robotics Research, pp. 743-758, doi:10.1177/0278364913484183.
    Table 1, eqs (1)-(9), Fig 8.
"""

from __future__ import annotations

from collections.abc import Mapping

import equinox as eqx
import jax.numpy as jnp

from jaxbal._src.linalg import elbow_angle, unit, wrap
from jaxbal._src.mujoco.tree import Tree
from jaxbal._src.planar import PlanarRobot
from jaxbal._src.robot import Bodies, planar_inertia
from jaxbal._src.robots.dual_v_layout import (
    BASE_SIDE,
    CROSSED,
    N_COORDINATES,
    OUTWARD,
    PLATFORM_END,
    dual_v_tree,
)
from jaxbal._src.solution_guard import guard_solution
from jaxbal._src.types import Array, Float
from jaxbal._src.validation import check_nonnegative, check_shape

__all__ = ["CROSSED", "OUTWARD", "DualV", "dual_v"]


def _per_arm(value):
    """The same value for the four arms, ``(4,)``."""
    return jnp.broadcast_to(jnp.asarray(value, dtype=float), (4,))


class DualV(PlanarRobot):
    """The DUAL-V robot: geometry and mass parameters as differentiable leaves.

    Attributes:
        l1, l2: ``(4,)`` lengths of links i1 and i2 [m].
        a, b: base pivot distances [m]; ``b`` is also the platform half-length.
        m1, p1, inertia1: ``(4,)`` mass [kg], COM distance from A_i [m], inertia about
            the COM [kg·m²] of links i1.
        m2, p2, inertia2: ``(4,)`` same for links i2 (COM distance from B_i).
        m5, inertia5: platform mass [kg] and inertia about its centre [kg·m²].
        payload: point mass at the platform centre [kg].
        m_cm, p_cm, inertia_cm: ``(4,)`` counter-masses *with* their tuning masses
            (Table 1): mass [kg], COM distance behind A_i [m], inertia about COM [kg·m²].
        m_tun, p_tun: ``(4,)`` lead tuning masses [kg] at ``p_tun`` behind A_i [m].
        tuning_scale: ``(4,)`` fraction of each tuning mass mounted (1 = Table 1,
            0 = removed, the "96.72 % balanced" robot).
        inertia_act: ``(4,)`` actuator rotor inertias [kg·m²].
    """

    branch_size = 4
    design_fields = {"payload": "payload"}  # counter-masses: see design()/with_design()
    nonnegative_parameters = ("a", "b", "l1", "l2", "m1", "m2", "m5", "payload", "m_cm", "m_tun",
        "inertia_cm", "inertia1", "inertia2", "inertia5", "inertia_act")  # fmt: skip

    l1: Float[Array, "4"]
    l2: Float[Array, "4"]
    a: Float[Array, ""]
    b: Float[Array, ""]
    m1: Float[Array, "4"]
    p1: Float[Array, "4"]
    inertia1: Float[Array, "4"]
    m2: Float[Array, "4"]
    p2: Float[Array, "4"]
    inertia2: Float[Array, "4"]
    m5: Float[Array, ""]
    inertia5: Float[Array, ""]
    payload: Float[Array, ""]
    m_cm: Float[Array, "4"]
    p_cm: Float[Array, "4"]
    inertia_cm: Float[Array, "4"]
    m_tun: Float[Array, "4"]
    p_tun: Float[Array, "4"]
    tuning_scale: Float[Array, "4"]
    inertia_act: Float[Array, "4"]

    def __check_init__(self):
        for name in ("l1", "l2", "m1", "p1", "inertia1", "m2", "p2", "inertia2"):
            check_shape(name, getattr(self, name), (4,))
        for name in ("m_cm", "p_cm", "inertia_cm", "m_tun", "p_tun", "tuning_scale"):
            check_shape(name, getattr(self, name), (4,))
        check_shape("inertia_act", self.inertia_act, (4,))
        for name in ("a", "b", "m5", "inertia5", "payload"):
            check_shape(name, getattr(self, name), ())
        for name in self.nonnegative_parameters:
            check_nonnegative(f"DualV.{name}", getattr(self, name))
        check_nonnegative("DualV.m_cm - m_tun (brass part)", self.m_cm - self.m_tun)

    @property
    def dof(self) -> int:
        return N_COORDINATES

    @property
    def default_branch(self) -> tuple[int, ...]:
        return OUTWARD

    @property
    def independent(self) -> tuple[int, ...]:
        return (8, 9, 10)  # the platform pose

    @property
    def actuated(self) -> tuple[int, ...]:
        return (0, 1, 2, 3)  # θ_11 … θ_41

    def end_effector(self, q) -> Float[Array, "3"]:
        """The platform pose ``(x5, y5, θ5)`` [m, m, rad] (the last three coordinates)."""
        return jnp.asarray(q, dtype=float)[8:11]

    # --- geometry -------------------------------------------------------------------

    def base_pivots(self) -> Float[Array, "4 2"]:
        """Base pivots ``A_i`` [m]."""
        return jnp.stack([BASE_SIDE * self.a, PLATFORM_END * self.b], -1)

    def platform_joints(self, pose) -> Float[Array, "4 2"]:
        """Platform joints ``C_i`` of arm i [m] for the pose ``(x5, y5, θ5)``."""
        pose = jnp.asarray(pose, dtype=float)
        offset = self.b * jnp.stack([-jnp.sin(pose[2]), jnp.cos(pose[2])])
        return pose[:2] + PLATFORM_END[:, None] * offset

    def joint_positions(self, q) -> tuple[Float[Array, "4 2"], ...]:
        """``(A, B, C)``, each ``(4, 2)`` [m], from the coordinates ``q``."""
        q = jnp.asarray(q, dtype=float)
        base = self.base_pivots()
        elbows = base + self.l1[:, None] * unit(q[0:4])
        return base, elbows, elbows + self.l2[:, None] * unit(q[4:8])

    def constraint(self, q) -> Float[Array, "8"]:
        """Loop-closure residuals ``C_i(arm) - C_i(platform)`` (zero on valid ``q``) [m]."""
        _, _, ends = self.joint_positions(q)
        return (ends - self.platform_joints(q[8:11])).reshape(-1)

    # --- counter-mass bookkeeping ---------------------------------------------------

    def counter_mass_moments(self) -> Float[Array, "4"]:
        """``m_cm,i·p_cm,i`` of the mounted counter-masses (tuning fraction applied) [kg·m]."""
        return self.m_cm * self.p_cm - (1.0 - self.tuning_scale) * self.m_tun * self.p_tun

    def counter_mass_inertia_about_base(self) -> Float[Array, "4"]:
        """``I_cm,i + m_cm,i·p_cm,i²`` of the mounted counter-masses about A_i [kg·m²]."""
        full = self.inertia_cm + self.m_cm * self.p_cm**2
        return full - (1.0 - self.tuning_scale) * self.m_tun * self.p_tun**2

    def without_tuning_masses(self) -> DualV:
        """The robot with the lead tuning masses removed (the 96.72 % balanced robot)."""
        return eqx.tree_at(lambda r: r.tuning_scale, self, jnp.zeros(4))

    def without_counter_masses(self) -> DualV:
        """The unbalanced robot: counter-masses and tuning masses removed."""
        zeros = jnp.zeros(4)
        return eqx.tree_at(lambda r: (r.m_cm, r.inertia_cm, r.m_tun), self, (zeros, zeros, zeros))

    def _brass(self):
        """Mass, COM distance and own inertia of the brass: the counter-mass less its
        tuning mass. The inertia is the parallel-axis difference written without
        cancellation, ``I_cm − m_cm·m_tun·(p_cm − p_tun)² / (m_cm − m_tun)``: as
        ``about_base − mass·distance²`` it rounded to −3.5e-18 kg·m² for a counter-mass
        of no inertia, and the co-designed robot was refused as non-physical."""
        mass = self.m_cm - self.m_tun
        moment = self.m_cm * self.p_cm - self.m_tun * self.p_tun
        safe = jnp.maximum(mass, 1e-12)
        removed = self.m_cm * self.m_tun * (self.p_cm - self.p_tun) ** 2 / safe
        return mass, moment / safe, self.inertia_cm - removed

    def _mounted_inertia(self):
        """Own inertia [kg·m²] of each mounted counter-mass (brass and mounted tuning
        mass) about its COM, a sum of non-negative terms: as ``about_base − m·d²`` it
        was −1.8e-18 under ``jit`` for a counter-mass of no own inertia (refused)."""
        brass_mass, brass_distance, brass_inertia = self._brass()
        tuning = self.tuning_scale * self.m_tun
        mounted = jnp.maximum(brass_mass + tuning, 1e-12)
        offset = brass_distance - self.p_tun
        return brass_inertia + brass_mass * tuning * offset**2 / mounted

    # --- the two methods every robot provides ---------------------------------------

    def mass_properties(self) -> Bodies:
        """22 bodies: links i1, links i2, platform, payload, brass counter-masses,
        tuning masses, actuator rotors (in this order, four of each per arm)."""
        zeros = jnp.zeros(4)
        brass_mass, brass_distance, brass_inertia = self._brass()

        def along(distance):
            return jnp.stack([distance, zeros, zeros], -1)

        mass = jnp.concatenate(
            [self.m1, self.m2, jnp.stack([self.m5, self.payload]), brass_mass,
             self.tuning_scale * self.m_tun, zeros]
        )  # fmt: skip
        com = jnp.concatenate(
            [along(self.p1), along(self.p2), jnp.zeros((2, 3)), along(-brass_distance),
             along(-self.p_tun), jnp.zeros((4, 3))]
        )  # fmt: skip
        izz = jnp.concatenate(
            [self.inertia1, self.inertia2, jnp.stack([self.inertia5, 0.0 * self.m5]),
             brass_inertia, zeros, self.inertia_act]
        )  # fmt: skip
        names = (
            tuple(f"link{i}1" for i in range(1, 5))
            + tuple(f"link{i}2" for i in range(1, 5))
            + ("platform", "payload")
            + tuple(f"counter_mass{i}" for i in range(1, 5))
            + tuple(f"tuning_mass{i}" for i in range(1, 5))
            + tuple(f"rotor{i}" for i in range(1, 5))
        )
        return Bodies(mass=mass, com=com, inertia=planar_inertia(izz), names=names)

    def planar_frames(self, q):
        """Plane origins ``(22, 2)`` and angles ``(22,)`` of the 22 bodies for the 11
        coordinates ``q`` (see the module doc); ``body_frames`` follows from them."""
        q = jnp.asarray(q, dtype=float)
        check_shape("q", q, (N_COORDINATES,))
        base, elbows, _ = self.joint_positions(q)
        centre = q[8:10][None]
        origins = jnp.concatenate([base, elbows, centre, centre, base, base, base])
        angles = jnp.concatenate([q[0:4], q[4:8], q[10:11], q[10:11], q[0:4], q[0:4], q[0:4]])
        return origins, angles

    # --- kinematics -----------------------------------------------------------------

    def inverse_kinematics(self, pose, *, branch=None, return_valid: bool = False):
        """All 11 coordinates from the platform pose, closed form per arm.

        Args:
            pose: ``(3,)`` platform pose ``(x5 [m], y5 [m], θ5 [rad])``.
            branch: four elbow signs ``σ_i = sign sin(θ_i2 - θ_i1)`` (``OUTWARD``, the
                default, ``CROSSED`` or any tuple of ±1).
            return_valid: return ``(q, valid)``, a boolean mask (all arms reach their
                joint), instead of raising; ``q`` is then clipped to the boundary (for
                a non-finite pose: the coordinates of the centred pose ``(0, 0, 0)``).

        Returns:
            ``q`` ``(11,)`` (and the mask). Batch with ``jax.vmap``.

        Raises:
            ValueError: eagerly, when the pose is outside the workspace (unless
                ``return_valid``); under ``jit`` a runtime error.
        """
        pose = pose_given = jnp.asarray(pose, dtype=float)
        check_shape("pose", pose, (3,))
        sigma = jnp.asarray(self.branch(branch), dtype=float)
        finite = jnp.all(jnp.isfinite(pose))
        # A non-finite pose is invalid; solve the centred pose instead so q stays finite
        # (a NaN pose gave NaN coordinates with return_valid=True, against the contract).
        pose = jnp.where(finite, pose, 0.0)
        reach = self.platform_joints(pose) - self.base_pivots()
        distance2 = jnp.sum(reach**2, -1)
        distance = jnp.sqrt(jnp.maximum(distance2, 1e-24))
        cos_alpha = (self.l1**2 + distance2 - self.l2**2) / (2.0 * self.l1 * distance)
        alpha, inside = elbow_angle(cos_alpha)  # the boundary is singular: not valid
        valid = jnp.all(inside) & jnp.all(distance2 > 1e-20) & finite
        # an arm folded onto its pivot (reach 0): arctan2's gradient is NaN, use (1, 0)
        direction = jnp.where((distance2 > 1e-20)[:, None], reach, jnp.array([1.0, 0.0]))
        theta1 = wrap(jnp.arctan2(direction[:, 1], direction[:, 0]) - sigma * alpha)
        to_end = reach - self.l1[:, None] * unit(theta1)
        theta2 = jnp.arctan2(to_end[:, 1], to_end[:, 0])
        q = jnp.concatenate([theta1, theta2, pose])
        if return_valid:
            return q, valid
        message = "DUAL-V platform pose outside the workspace or on its singular boundary"
        return guard_solution(q, ~valid, message, pose_given, robot=self)

    def design(self) -> dict:
        """``counter_mass`` ``(4,)`` [kg]: the mounted counter-masses (tuning fraction
        applied); ``counter_distance`` ``(4,)`` [m]: their COM behind A_i; ``payload``."""
        mounted = self.m_cm - (1.0 - self.tuning_scale) * self.m_tun
        distance = self.counter_mass_moments() / jnp.maximum(mounted, 1e-12)
        return {"counter_mass": mounted, "counter_distance": distance, "payload": self.payload}

    def with_design(self, design: Mapping) -> DualV:
        """The robot with new design variables. A new counter-mass or distance makes
        each counter-mass one body (tuning mass folded in) whose inertia about its own
        COM scales with its mass (same radius of gyration; zero for a robot built
        without counter-masses, whose new counter-masses are then point masses)."""
        current = self.design()
        unknown = set(design) - set(current)
        if unknown:
            raise ValueError(
                f"unknown design variable(s) {sorted(unknown)} of DualV; it has {sorted(current)}"
            )
        robot = super().with_design({k: v for k, v in design.items() if k == "payload"})
        if not {"counter_mass", "counter_distance"} & set(design):
            return robot
        mass = jnp.asarray(design.get("counter_mass", current["counter_mass"]), dtype=float)
        distance = jnp.asarray(
            design.get("counter_distance", current["counter_distance"]), dtype=float
        )
        check_shape("design['counter_mass']", mass, (4,))
        check_shape("design['counter_distance']", distance, (4,))
        old_mass = current["counter_mass"]
        inertia = self._mounted_inertia() * mass / jnp.maximum(old_mass, 1e-12)
        return eqx.tree_at(
            lambda r: (r.m_cm, r.p_cm, r.inertia_cm, r.m_tun, r.tuning_scale),
            robot,
            (mass, distance, inertia, jnp.zeros(4), jnp.ones(4)),
        )

    def mujoco_tree(self) -> Tree:
        """Four RR arms from the base pivots, the platform on a planar joint, and the
        loops closed by ``connect`` at C_i (see :func:`dual_v_tree`)."""
        return dual_v_tree(self)

    def jacobian(self, q) -> Float[Array, "4 3"]:
        """Eq (9): ``q̇_a = J u̇`` with ``q_a = (θ_11..θ_41)``, ``u = (x5, y5, θ5)``."""
        q = jnp.asarray(q, dtype=float)
        theta1, theta2, theta5 = q[0:4], q[4:8], q[10]
        denominator = self.l1 * jnp.sin(theta1 - theta2)
        rows = jnp.stack(
            [-jnp.cos(theta2), -jnp.sin(theta2), PLATFORM_END * self.b * jnp.cos(theta2 - theta5)],
            -1,
        )
        return rows / denominator[:, None]

    def harmonised_condition_number(self, q):
        """``κ = cond(J·diag(1, 1, 1/b))`` of Fig 8 (2-norm) [-]."""
        jh = self.jacobian(q) * jnp.array([1.0, 1.0, 1.0 / self.b])
        singular = jnp.linalg.svd(jh, compute_uv=False)
        return singular[0] / jnp.maximum(singular[-1], 1e-300)


def dual_v(
    counter_masses: bool = True,
    tuning_masses: bool = True,
    payload: float = 0.0,
) -> DualV:
    """The DUAL-V prototype of Table 1.

    Args:
        counter_masses: mount the counter-masses (``False``: the unbalanced robot).
        tuning_masses: keep the lead tuning masses (``False``: "96.72 % balanced").
        payload: point mass at the platform centre [kg].
    """
    arm = _per_arm
    robot = DualV(  # Table 1, row by row
        l1=arm(0.28), l2=arm(0.28), a=jnp.asarray(0.396), b=jnp.asarray(0.11),
        m1=arm(1.169), p1=arm(0.0737), inertia1=arm(0.012967),
        m2=arm(0.606), p2=arm(0.1279), inertia2=arm(0.006417),
        m5=jnp.asarray(0.899), inertia5=jnp.asarray(0.008168),
        payload=jnp.asarray(payload, dtype=float),
        m_cm=arm(7.983), p_cm=arm(0.0575), inertia_cm=arm(0.026845),
        m_tun=arm(0.188), p_tun=arm(0.080), tuning_scale=arm(1.0), inertia_act=arm(0.0041),
    )  # fmt: skip
    if not tuning_masses:
        robot = robot.without_tuning_masses()
    if not counter_masses:
        robot = robot.without_counter_masses()
    return robot
