"""The Orthoglide, a 3-DOF translational parallel robot (Geng, Arakelian, Chablat & Lemoine 2021).

Three identical PRPaR legs: an actuated slider moving along base axis i (input ρ_i),
a revolute joint, a parallelogram of length L and a revolute joint to the platform
point P = (p_x, p_y, p_z), which carries the payload. The platform only translates.

=====================  ============  =====  ==============================================
parameter              nominal       unit   source / note
=====================  ============  =====  ==============================================
L (parallelogram)      0.31          m      §3
s_x = s_y = s_z        +1            --     §3, eq (1) configuration indices
m_par  (each of 3)     0.396         kg     §3 "m_1"; eq (6) mass of the parallelograms
m_sl   (each of 3)     0.248         kg     §3 "m_2"; eq (6) mass of the sliders
m_P    (platform P)    0.1           kg     §3 "m_3"
l (slider offset)      0.0           m      not given; S(t) and F_sh do not depend on it
I_par  (transverse)    m_par·L²/12   kg·m²  slender-bar assumption (not given)
payload                0 … 5         kg     §3.2, point mass at P
=====================  ============  =====  ==============================================

**Which mass is which.** Eq (6) multiplies the parallelogram term ``0.5(ρ+3p)`` by
``m_1`` and the slider term ``(ρ+l)`` by ``m_2``, while §3 calls 0.396 kg the slider
and 0.248 kg the parallelogram. Only the assignment *parallelogram = 0.396 kg,
slider = 0.248 kg* reproduces the paper's own designed COM acceleration (38.72 vs
38.7 m/s²; the other assignment gives 34.3 m/s²) and Table 1 (within 0.4 %). So eq
(6) is right and §3 swaps the words; jaxbal uses the eq (6) meaning.

**The offset l.** The COM displacement D, hence a_com and the shaking force, do not
depend on l (it adds the constant m_sl·l/M to every component of S). l only moves the
absolute COM and the sliders' lever arms in the shaking moment about a fixed point.
The default l = 0 puts the slider COM on its axis. The paper's COM coordinates of §3
(which turn out to be those of the robot carrying 2 kg) are reproduced for
0.067 m ≤ l ≤ 0.169 m, and the fit of Table 2 gives l ≈ 0.069 m (see the experiment
``geng2021_orthoglide``).

Coordinates: ``q = (ρ_x, ρ_y, ρ_z, p_x, p_y, p_z)`` [m], the inputs followed by the
platform point, as returned by :meth:`Orthoglide.inverse_kinematics`. Bodies (in
order): 3 sliders (translate along axis i; frame at B_i, COM at (A_i+B_i)/2), 3
parallelograms (slender bars B_iC_i, frame at B_i rotated by the minimal rotation
taking the home direction −e_i onto (P−B_i)/L, COM at the mid-point), the platform
joint P (point mass m_P) and the payload (point mass at P).

References:
    Geng, J., Arakelian, V., Chablat, D., Lemoine, P. (2021). Balancing of the
    Orthoglide taking into account its varying payload. Robotics 10(1), 30.
    Eqs (1), (4)-(7) and §3. Pashkevich, Chablat & Wenger (2006), Robotica 24(1),
    direct kinematics.
"""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.implicit import newton_solve
from jaxbal._src.linalg import skew
from jaxbal._src.momentum import center_of_mass
from jaxbal._src.mujoco.tree import Tree
from jaxbal._src.planning import EndEffectorLine, com_line
from jaxbal._src.profiles import BangBang, Quintic
from jaxbal._src.robot import Bodies, Robot, concatenate, point_masses
from jaxbal._src.robots.orthoglide_layout import COUNTER_SLIDERS, orthoglide_tree
from jaxbal._src.solution_guard import guard_solution
from jaxbal._src.trajectory import StraightLine
from jaxbal._src.types import Array, Float
from jaxbal._src.validation import (
    check_nonnegative,
    check_shape,
)

__all__ = ["COUNTER_SLIDERS", "Orthoglide", "motion_cases", "orthoglide", "switching_times"]

_EYE = np.eye(3)
# A_i - B_i = l * _SLIDER_DIRECTIONS[i]  (§2.2: A_1 = (ρ_x + l, 0, l), …)
_SLIDER_DIRECTIONS = np.array([[1.0, 0.0, 1.0], [1.0, 1.0, 0.0], [0.0, 1.0, 1.0]])


def _minimal_rotation(e0, d):
    """``(..., 3, 3)`` rotation taking unit ``e0`` onto unit ``d`` about ``e0 × d``.

    Smooth for ``e0·d > −1`` (the parallelograms never turn by 180° in the workspace).
    """
    v = jnp.cross(e0, d)
    c = jnp.sum(e0 * d, -1)[..., None, None]
    k = skew(v)
    return _EYE + k + (k @ k) / jnp.maximum(1.0 + c, 1e-12)


def _com_residual(p, params):
    """Eq (6) with eq (1): ``S(ρ(p), p) − S_target`` for the Newton solve of the COM IK."""
    robot, target, signs = params
    root = jnp.sqrt(jnp.maximum(robot._radicands(p), 1e-30))
    q = jnp.concatenate([p + signs * root, p])
    return center_of_mass(robot, q) - target


class Orthoglide(Robot):
    """The Orthoglide with a point payload at P (see the module docstring).

    Attributes:
        length: parallelogram length L [m].
        slider_offset: offset l of the slider point A_i [m].
        parallelogram_mass: mass of each parallelogram [kg] (eq (6) ``m_1``).
        slider_mass: mass of each slider [kg] (eq (6) ``m_2``).
        platform_mass: mass of the joint P [kg] (``m_3``).
        parallelogram_inertia: transverse inertia of each parallelogram about its COM
            (slender bar, no axial inertia) [kg·m²].
        payload: payload mass at P [kg].
        counter_masses: ``(3,)`` counter-sliders [kg] (default 0): point masses driven
            opposite to slider i along axis i (at ``−ρ_i e_i``, e.g. by a rack and
            pinion), the classical balancing of a linear axis. Not in the paper: a
            design variable of :mod:`jaxbal.design`.
    """

    branch_size = 3
    design_fields = {"counter_mass": "counter_masses", "payload": "payload"}
    nonnegative_parameters = (
        *("length", "parallelogram_mass", "slider_mass", "platform_mass"),
        *("parallelogram_inertia", "payload", "counter_masses"),
    )

    length: Float[Array, ""]
    slider_offset: Float[Array, ""]
    parallelogram_mass: Float[Array, ""]
    slider_mass: Float[Array, ""]
    platform_mass: Float[Array, ""]
    parallelogram_inertia: Float[Array, ""]
    payload: Float[Array, ""]
    counter_masses: Float[Array, "3"]

    def __init__(
        self,
        length=0.31,
        slider_offset=0.0,
        parallelogram_mass=0.396,
        slider_mass=0.248,
        platform_mass=0.1,
        parallelogram_inertia=None,
        payload=0.0,
        counter_masses=(0.0, 0.0, 0.0),
    ):
        self.length = jnp.asarray(length, dtype=float)
        self.slider_offset = jnp.asarray(slider_offset, dtype=float)
        self.parallelogram_mass = jnp.asarray(parallelogram_mass, dtype=float)
        self.slider_mass = jnp.asarray(slider_mass, dtype=float)
        self.platform_mass = jnp.asarray(platform_mass, dtype=float)
        if parallelogram_inertia is None:
            parallelogram_inertia = self.parallelogram_mass * self.length**2 / 12.0
        self.parallelogram_inertia = jnp.asarray(parallelogram_inertia, dtype=float)
        self.payload = jnp.asarray(payload, dtype=float)
        self.counter_masses = jnp.asarray(counter_masses, dtype=float)
        check_shape("counter_masses", self.counter_masses, (3,))
        for name in (
            "length",
            "slider_offset",
            "parallelogram_mass",
            "slider_mass",
            "platform_mass",
            "parallelogram_inertia",
            "payload",
        ):
            check_shape(name, getattr(self, name), ())
        for name in self.nonnegative_parameters:
            check_nonnegative(f"Orthoglide.{name}", getattr(self, name))

    @property
    def dof(self) -> int:
        return 6

    @property
    def independent(self) -> tuple[int, ...]:
        return (3, 4, 5)  # the platform point P

    @property
    def actuated(self) -> tuple[int, ...]:
        return (0, 1, 2)  # the slider inputs ρ

    def end_effector(self, q) -> Float[Array, "3"]:
        """The platform point ``P`` [m] (the last three coordinates)."""
        return jnp.asarray(q, dtype=float)[3:]

    def constraint(self, q) -> Float[Array, "3"]:
        """Leg closures ``|P − B_i| − L`` [m], eq (1) (zero for consistent ``q``)."""
        q = jnp.asarray(q, dtype=float)
        legs = q[3:][None, :] - q[:3, None] * _EYE
        return jnp.sqrt(jnp.sum(legs**2, axis=-1)) - self.length

    # --- the two methods every robot provides --------------------------------------

    def mass_properties(self) -> Bodies:
        ones = jnp.ones(3)
        sliders = Bodies(
            mass=self.slider_mass * ones,
            com=0.5 * self.slider_offset * _SLIDER_DIRECTIONS,
            inertia=jnp.zeros((3, 3, 3)),  # pure translation: no spin moment
            names=("slider_x", "slider_y", "slider_z"),
        )
        home = -_EYE  # home direction of B_i -> C_i
        parallelograms = Bodies(
            mass=self.parallelogram_mass * ones,
            com=0.5 * self.length * home,
            inertia=self.parallelogram_inertia * (_EYE[None] - home[:, :, None] * home[:, None]),
            names=("parallelogram_x", "parallelogram_y", "parallelogram_z"),
        )
        points = point_masses(
            jnp.stack([self.platform_mass, self.payload]), ("platform", "payload")
        )
        counter = point_masses(self.counter_masses, COUNTER_SLIDERS)
        return concatenate(sliders, parallelograms, points, counter)

    def body_frames(self, q):
        check_shape("q", q, (6,))
        q = jnp.asarray(q, dtype=float)
        rho, p = q[:3], q[3:]
        b = rho[:, None] * _EYE  # B_i = ρ_i e_i
        d = (p[None, :] - b) / self.length
        rotations = _minimal_rotation(-_EYE, d)
        origins = jnp.concatenate([b, b, jnp.stack([p, p]), -b], axis=0)
        rot = jnp.concatenate(
            [
                jnp.broadcast_to(_EYE, (3, 3, 3)),
                rotations,
                _EYE[None],
                _EYE[None],
                jnp.broadcast_to(_EYE, (3, 3, 3)),
            ]
        )
        return origins, rot

    # --- kinematics ------------------------------------------------------------------

    def _radicands(self, p):
        """``L² − p_j² − p_k²`` for the three legs (must be > 0), eq (1)."""
        sq = p**2
        return self.length**2 - (jnp.sum(sq) - sq)

    def inverse_kinematics(self, pose, *, branch=None, return_valid: bool = False):
        """Inputs ρ and all coordinates ``q = (ρ, p)`` for the platform point ``p``, eq (1).

        Args:
            pose: ``(3,)`` position of P [m].
            branch: the configuration indices ``(s_x, s_y, s_z)`` of eq (1); ``+1`` (all
                legs, the paper's, §3, and the default) or any tuple of ±1.
            return_valid: return ``(q, valid)`` (all radicands > 0) and never raise.

        Returns:
            ``q (6,)`` [m] (and ``valid``; where it is False, ``q`` is the home
            configuration ``p = 0``, finite).

        Raises:
            ValueError: when ``p`` is out of reach of a leg (‖p_⊥‖ ≥ L); under jit at run time.
        """
        p = jnp.asarray(pose, dtype=float)
        check_shape("pose", p, (3,))
        signs = jnp.asarray(self.branch(branch), dtype=float)
        radicand = self._radicands(p)
        valid = jnp.all(radicand > 0.0) & jnp.all(jnp.isfinite(p))
        # an invalid point gives the home configuration p = 0, so q stays finite
        given, p = p, jnp.where(valid, p, 0.0)
        radicand = jnp.where(valid, radicand, self.length**2)
        rho = p + signs * jnp.sqrt(jnp.maximum(radicand, 1e-30))
        q = jnp.concatenate([rho, p])
        text = "platform point (pose) out of reach of the Orthoglide legs"
        return (q, valid) if return_valid else guard_solution(q, ~valid, text, given, robot=self)

    def forward_kinematics(self, rho, return_valid: bool = False):
        """Platform point ``p (3,)`` [m] from the inputs ``ρ (3,)`` [m], closed form.

        Subtracting the leg constraints ``(ρ_i − p_i)² + Σ_{j≠i} p_j² = L²`` gives
        ``p_y, p_z`` affine in ``p_x``; the remaining quadratic has two roots (two
        assembly modes); the smaller ``p_x`` is the working mode (``p = 0`` at ``ρ = L``).

        Raises:
            ValueError: eagerly (under ``jit`` at run time), when ρ is not assemblable
                (negative discriminant) or an input is not positive.
        """
        rho = jnp.asarray(rho, dtype=float)
        check_shape("rho", rho, (3,))
        rx, ry, rz = rho
        by, bz = rx / ry, rx / rz
        ay, az = (ry**2 - rx**2) / (2.0 * ry), (rz**2 - rx**2) / (2.0 * rz)
        qa = 1.0 + by**2 + bz**2
        qb = -2.0 * rx + 2.0 * (ay * by + az * bz)
        qc = rx**2 + ay**2 + az**2 - self.length**2
        disc = qb**2 - 4.0 * qa * qc
        valid = (disc >= 0.0) & jnp.all(rho > 0.0)
        root = jnp.sqrt(jnp.maximum(disc, 1e-30))
        # smaller root (−qb − √Δ)/(2qa), in the cancellation-free form 2qc/(−qb + √Δ)
        # (qb < 0 in the workspace).
        px = 2.0 * qc / (-qb + root)
        p = jnp.stack([px, ay + by * px, az + bz * px])
        text = "inputs rho not assemblable by the Orthoglide"
        return (p, valid) if return_valid else guard_solution(p, ~valid, text, rho, robot=self)

    # --- centre of mass ---------------------------------------------------------------

    def com_of_point(self, p):
        """Total COM ``S (3,)`` [m] for the platform point ``p``: eq (6) (payload included)."""
        return center_of_mass(self, self.inverse_kinematics(p))

    def com_inverse_kinematics(
        self, com, free=None, *, branch=None, return_valid: bool = False, guess=None
    ):
        """All coordinates ``q = (ρ, p)`` that put the total COM at ``com``.

        Solves eq (6) with eq (1) for ``p`` by Newton's method
        (:func:`jaxbal.implicit.newton_solve`); the result is differentiable with
        respect to ``com`` and to every parameter of the robot (masses, payload,
        lengths) by implicit differentiation, to any order.

        Args:
            com: ``(3,)`` target centre of mass [m].
            free: must be ``None`` (the Orthoglide has no free coordinate; the argument
                keeps the signature of :class:`jaxbal.planning.ComLine`).
            branch: configuration indices of eq (1) (see :meth:`inverse_kinematics`).
            return_valid: return ``(q, valid)`` (converged, reachable) and never raise.
            guess: ``(3,)`` initial platform point [m] (default: home, 0).

        Raises:
            ValueError: when the target is not a COM of the robot (under jit at run time).
        """
        com = jnp.asarray(com, dtype=float)
        check_shape("com", com, (3,))
        signs = jnp.asarray(self.branch(branch), dtype=float)
        if free is not None:
            raise ValueError("the Orthoglide has no free coordinate: pass free=None")
        x0 = jnp.zeros(3) if guess is None else jnp.asarray(guess, dtype=float)

        solution = newton_solve(
            _com_residual,
            x0,
            (self, com, signs),
            throw=False,
            what="Orthoglide COM inverse kinematics",
        )
        p = solution.value
        reachable = jnp.all(self._radicands(p) > 0.0)
        valid = solution.converged & reachable
        rho = p + signs * jnp.sqrt(jnp.maximum(self._radicands(p), 1e-30))
        q = jnp.concatenate([rho, p])
        text = "COM target not reachable by the Orthoglide"
        return (q, valid) if return_valid else guard_solution(q, ~valid, text, com, robot=self)

    def mujoco_tree(self) -> Tree:
        """Sliders, parallelograms on ball joints closed by ``connect`` at P, the
        platform and the counter-sliders (see :func:`orthoglide_tree`)."""
        return orthoglide_tree(self)


def orthoglide(payload: float = 0.0, **overrides) -> Orthoglide:
    """The Orthoglide prototype of LS2N as modelled by Geng et al. (2021), §3.

    Args:
        payload: payload mass at P [kg] (the paper uses 0 … 5).
        **overrides: any other :class:`Orthoglide` field (e.g. ``slider_offset``).
    """
    return Orthoglide(payload=payload, **overrides)


# --- evaluation along the plans of §3.1 -----------------------------------------------


def motion_cases(robot: Orthoglide, start, end, duration, planned_payload=None) -> dict:
    """The motion laws of §3.1 and §3.3 between two platform points: name ↦ ``t -> q``.

    * ``case1``: P on the straight line, quintic profile;
    * ``case2``: P on the straight line, bang-bang profile;
    * ``case3``: total COM on the straight line, bang-bang (eqs (4), (7)), planned with
      the robot's true payload;
    * ``case4`` (only if ``planned_payload`` is given): the same COM plan made by a
      planner that believes the payload is ``planned_payload`` [kg] (§3.3: the mass
      error Δm = ``robot.payload − planned_payload`` is not taken into account).

    Every plan is a pytree: ``jax.grad`` flows through it to the robot's parameters and
    to ``planned_payload`` (through the implicit-differentiated COM inverse kinematics).
    """
    start = jnp.asarray(start, dtype=float)
    end = jnp.asarray(end, dtype=float)
    q_start, q_end = robot.inverse_kinematics(start), robot.inverse_kinematics(end)
    cases = {
        "case1": EndEffectorLine(robot, StraightLine(start, end, Quintic(), duration)),
        "case2": EndEffectorLine(robot, StraightLine(start, end, BangBang(), duration)),
        "case3": com_line(robot, q_start, q_end, BangBang(), duration, dims=3),
    }
    if planned_payload is not None:
        planner = eqx.tree_at(lambda r: r.payload, robot, jnp.asarray(planned_payload, float))
        cases["case4"] = com_line(planner, q_start, q_end, BangBang(), duration, dims=3)
    return cases


def switching_times(duration, count: int = 401) -> Float[Array, " t"]:
    """``count`` equally spaced instants on ``[0, T]`` [s] plus the left limit at ``T/2``.

    Profiles are right-continuous at the bang-bang switch ``T/2``; adding the instant
    just before it makes the sampled maximum the true supremum of |F| and |M|.
    """
    duration = jnp.asarray(duration, dtype=float)
    grid = jnp.linspace(0.0, 1.0, count)
    return jnp.concatenate([grid, jnp.array([0.5 - 1e-9])]) * duration
