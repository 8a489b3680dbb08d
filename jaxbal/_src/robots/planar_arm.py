"""Planar serial nR arms of Briot, Arakelian & Le Baron (2012), sections 3.1 and 3.2.

================  =========  =========  ==========  ==========================
parameter         2R         3R         unit        source
================  =========  =========  ==========  ==========================
l_OA, l_AB, l_BC  0.5, 0.3   + 0.1      m           §3.1, §3.2
r_1, r_2, r_3     0.289,     + 0.5      --          l_OSi = r_i · l_i
                  0.098
m_1, m_2, m_3     24.4, 8.3  + 2        kg
I_1, I_2, I_3     1.246,     + 0.025    kg·m²       axial, about each link's COM
                  0.057
m_tool            5          5          kg          point payload at the tip
================  =========  =========  ==========  ==========================

Coordinates ``q = (q1, …, qn)`` are the paper's *relative* joint angles [rad]; the
absolute angle of link k is ``θ_k = q1 + … + qk`` (so ``φ = θ_3`` for the 3R). The arm
moves in the horizontal x-y plane (gravity, if given, acts along −z and does not load
the joints). The paper says "axial moment of inertia of element i" without naming the
point: jaxbal takes it about the link's own centre of mass (ADAMS' convention).

Optional counterweights ``m_cw,k`` sit on the prolongation of link k at distance
``d_cw,k`` behind its proximal joint (classical force balancing, §3.3 footnote).

References:
    Briot, S., Arakelian, V., Le Baron, J.-P. (2012). Shaking force minimization of
    high-speed robots via centre of mass acceleration control. Mech. Mach. Theory 57,
    1-12. Eqs (7)-(18).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxbal._src.linalg import cos_sin, two_link_ik, unit, wrap
from jaxbal._src.mujoco.tree import Joint, Tree, TreeBody, Z, identity
from jaxbal._src.planar import PlanarRobot
from jaxbal._src.robot import Bodies, concatenate, planar_inertia, point_masses
from jaxbal._src.solution_guard import guard_solution
from jaxbal._src.types import Array, Float
from jaxbal._src.validation import check_nonnegative, check_shape, raise_if_invalid


def _partial_sums(values):
    """Inclusive prefix sums along axis 0, unrolled (n is small and static): XLA's
    ``cumsum`` becomes a reduce-window that does not fuse under ``vmap``."""
    sums = [values[0]]
    for k in range(1, values.shape[0]):
        sums.append(sums[-1] + values[k])
    return jnp.stack(sums)


class PlanarArm(PlanarRobot):
    """A planar serial arm of ``n`` revolute links with a point payload at the tip.

    Attributes:
        lengths: ``(n,)`` link lengths l_k [m].
        com_ratios: ``(n,)`` r_k, the COM of link k is at r_k·l_k from its joint [-].
        masses: ``(n,)`` link masses m_k [kg].
        inertias: ``(n,)`` axial inertias I_k about the link COM [kg·m²].
        payload: payload (tool) mass at the tip [kg].
        counter_masses: ``(n,)`` counterweight masses m_cw,k [kg] (default 0).
        counter_distances: ``(n,)`` distances d_cw,k behind joint k [m] (default 0).
    """

    design_fields = {
        "counter_mass": "counter_masses",
        "counter_distance": "counter_distances",
        "payload": "payload",
    }
    nonnegative_parameters = ("lengths", "masses", "inertias", "payload", "counter_masses")

    lengths: Float[Array, " n"]
    com_ratios: Float[Array, " n"]
    masses: Float[Array, " n"]
    inertias: Float[Array, " n"]
    payload: Float[Array, ""]
    counter_masses: Float[Array, " n"]
    counter_distances: Float[Array, " n"]

    def __init__(
        self,
        lengths,
        com_ratios,
        masses,
        inertias,
        payload=0.0,
        counter_masses=None,
        counter_distances=None,
    ):
        self.lengths = jnp.asarray(lengths, dtype=float)
        n = self.lengths.shape[0] if self.lengths.ndim == 1 else -1
        if self.lengths.ndim != 1 or n < 2:
            raise ValueError(f"lengths must have shape (n,) with n >= 2, got {self.lengths.shape}")
        self.com_ratios = jnp.asarray(com_ratios, dtype=float)
        self.masses = jnp.asarray(masses, dtype=float)
        self.inertias = jnp.asarray(inertias, dtype=float)
        self.payload = jnp.asarray(payload, dtype=float)
        zeros = jnp.zeros(n)
        self.counter_masses = (
            zeros if counter_masses is None else jnp.asarray(counter_masses, float)
        )
        self.counter_distances = (
            zeros if counter_distances is None else jnp.asarray(counter_distances, float)
        )
        for name in ("com_ratios", "masses", "inertias", "counter_masses", "counter_distances"):
            check_shape(name, getattr(self, name), (n,))
        check_shape("payload", self.payload, ())
        for name in self.nonnegative_parameters:
            check_nonnegative(f"PlanarArm.{name}", getattr(self, name))

    @property
    def n_links(self) -> int:
        return self.lengths.shape[0]

    @property
    def dof(self) -> int:
        return self.n_links

    # --- what every (planar) robot provides ------------------------------------------

    def mass_properties(self) -> Bodies:
        n = self.n_links
        links = Bodies(
            mass=self.masses,
            com=jnp.stack([self.com_ratios * self.lengths, jnp.zeros(n), jnp.zeros(n)], axis=-1),
            inertia=planar_inertia(self.inertias),
            names=tuple(f"link{k + 1}" for k in range(n)),
        )
        counter = Bodies(
            mass=self.counter_masses,
            com=jnp.stack([-self.counter_distances, jnp.zeros(n), jnp.zeros(n)], axis=-1),
            inertia=jnp.zeros((n, 3, 3)),
            names=tuple(f"counterweight{k + 1}" for k in range(n)),
        )
        return concatenate(links, counter, point_masses(self.payload[None], ("payload",)))

    def planar_frames(self, q):
        check_shape("q", q, (self.n_links,))
        theta = _partial_sums(q)
        joints = self._joints(*cos_sin(theta))  # one sine and cosine per link
        origins = jnp.concatenate([joints[:-1], joints[:-1], joints[-1:]], axis=0)
        angles = jnp.concatenate([theta, theta, theta[-1:]])
        return origins, angles

    # --- kinematics ----------------------------------------------------------------

    def joint_positions(self, q) -> Float[Array, "n+1 2"]:
        """Positions of O, A, B, … and the tip in the plane [m], shape ``(n + 1, 2)``."""
        return self._joints(*cos_sin(_partial_sums(jnp.asarray(q, dtype=float))))

    def _joints(self, cos, sin):
        steps = self.lengths[:, None] * jnp.stack([cos, sin], -1)
        return jnp.concatenate([jnp.zeros((1, 2)), _partial_sums(steps)], axis=0)

    def end_effector(self, q) -> Float[Array, " k"]:
        """The pose :meth:`inverse_kinematics` takes: tip ``(x, y)`` [m] for the 2R;
        ``(x, y, φ)`` with φ = Σq [rad] for longer arms."""
        tip = self.joint_positions(q)[-1]
        if self.n_links == 2:
            return tip
        return jnp.concatenate([tip, jnp.sum(jnp.asarray(q, dtype=float))[None]])

    def equivalent_lengths(self) -> Float[Array, " n"]:
        """``l_eq,k`` such that the total COM is ``x_S = Σ_k l_eq,k (cos θ_k, sin θ_k)``.

        References: Briot et al. (2012), eqs (9) and (14).
        """
        masses = self.masses + self.counter_masses
        outboard = jnp.cumsum(masses[::-1])[::-1] - masses + self.payload  # Σ_{j>k} m_j + m_tool
        m_tot = jnp.sum(masses) + self.payload
        numerator = (
            self.masses * self.com_ratios * self.lengths
            - self.counter_masses * self.counter_distances
            + outboard * self.lengths
        )
        return numerator / m_tot

    def inverse_kinematics(self, pose, *, branch=None, return_valid: bool = False):
        """End-effector inverse kinematics.

        Args:
            pose: ``(2,)`` tip position [m] for the 2R; ``(3,)`` tip position and the
                orientation φ of the last link [rad] for the 3R.
            branch: ``+1`` or ``−1`` (or ``(±1,)``), the sign of ``sin q2`` (elbow).
            return_valid: return ``(q, valid)`` and never raise (batched code).

        Raises:
            ValueError: eagerly, when the pose is outside the workspace or on its
                boundary (links 1 and 2 stretched or folded: singular; under ``jit`` a
                runtime error).
        """
        pose = pose_given = jnp.asarray(pose, dtype=float)
        n = self.n_links
        if n > 3:
            raise ValueError(f"closed-form IK is implemented for n <= 3, got n = {n}")
        check_shape("pose", pose, (2 if n == 2 else 3,))
        (mode,) = self.branch(branch)
        finite = jnp.all(jnp.isfinite(pose))
        # A non-finite pose is invalid; solve a finite stand-in so q stays finite.
        pose = jnp.where(finite, pose, jnp.zeros_like(pose).at[0].set(self.lengths[0]))
        target = pose[:2]
        if n == 3:
            target = target - self.lengths[2] * unit(pose[2])
        q1, q2, valid = two_link_ik(target, self.lengths[0], self.lengths[1], mode)
        valid = valid & finite
        q = jnp.stack([wrap(q1), q2])
        if n == 3:
            q = jnp.concatenate([q, closing_angle(pose[2], q[0] + q[1])[None]])
        if return_valid:
            return q, valid
        # under jit too (a clipped, silently wrong q before): see validation.guard
        message = "end-effector pose outside the workspace or on its singular boundary"
        return guard_solution(q, ~valid, message, pose_given, robot=self)

    def com_inverse_kinematics(
        self, com, free=None, *, branch=None, return_valid: bool = False, guess=None
    ):
        """Joint angles that put the total centre of mass at ``com``.

        The 2R is solved by eqs (8)-(12); the 3R by eqs (13)-(18) with the free angle
        ``free = φ`` (absolute angle of link 3). ``mode = +1`` is the "+" sign of
        eqs (10)/(15), the working mode used in the paper. Equation (10) is evaluated
        in the numerically stable of its two equivalent forms.

        Args:
            com: ``(2,)`` or ``(3,)`` target COM [m] (z ignored).
            free: φ [rad] for the 3R (required; shape ``()`` or ``(1,)``), ``None`` for
                the 2R.
            branch: ``+1`` or ``−1`` (or ``(±1,)``).
            return_valid: return ``(q, valid)`` (discriminant > 0: on the boundary of
                the COM workspace, ``Δ = 0``, the configuration is singular) and never
                raise.
            guess: ignored (closed form; kept for the contract's signature).

        Raises:
            ValueError: eagerly, naming the target, when no configuration reaches it
                (under ``jit`` a runtime error).
        """
        com = jnp.asarray(com, dtype=float)
        if com.shape not in ((2,), (3,)):
            raise ValueError(f"com must have shape (2,) or (3,), got {com.shape}")
        (mode,) = self.branch(branch)
        n = self.n_links
        l_eq = self.equivalent_lengths()
        target = com[:2]
        if n == 3:
            if free is None:
                raise ValueError("the 3R COM inverse kinematics needs the free angle φ")
            free = jnp.asarray(free, dtype=float)
            if free.shape not in ((), (1,)):
                raise ValueError(f"free (φ) must have shape () or (1,), got {free.shape}")
            free = jnp.reshape(free, ())
            target = target - l_eq[2] * unit(free)
        elif n != 2:
            raise ValueError(f"COM inverse kinematics is implemented for n = 2, 3, got {n}")
        a = -2.0 * l_eq[0] * target[0]
        b = -2.0 * l_eq[0] * target[1]
        c = jnp.sum(target**2) + l_eq[0] ** 2 - l_eq[1] ** 2
        discriminant = b**2 - c**2 + a**2
        # Δ = 0 is the singular boundary, where the floored root has a zero derivative
        valid = (discriminant > 1e-30) & jnp.all(jnp.isfinite(com))
        root = jnp.sqrt(jnp.maximum(discriminant, 1e-30))
        # eq (10): t = (−b ± √Δ)/(c − a) = (c + a)/(−b ∓ √Δ); use the larger denominator.
        den1 = c - a
        den2 = -b - mode * root
        use_first = jnp.abs(den1) >= jnp.abs(den2)
        t = jnp.where(
            use_first,
            (-b + mode * root) / jnp.where(use_first, den1, 1.0),
            (c + a) / jnp.where(use_first, 1.0, den2),
        )
        q1 = 2.0 * jnp.arctan(t)
        rel = target - l_eq[0] * unit(q1)
        theta2 = jnp.arctan2(rel[1], rel[0])
        q = jnp.stack([q1, wrap(theta2 - q1)])
        if n == 3:
            q = jnp.concatenate([q, closing_angle(free, q[0] + q[1])[None]])
        if return_valid:
            return q, valid
        message = "COM target not reachable by the arm, or on its singular boundary"
        return guard_solution(q, ~valid, message, com, robot=self)

    # --- MuJoCo --------------------------------------------------------------------

    def mujoco_tree(self) -> Tree:
        """Serial chain of z-hinges; MuJoCo joint k is the paper's relative angle ``q_k``.

        Link k's frame has its origin at joint k and its x axis along the link, exactly
        the frame of :meth:`body_frames`; counterweight k shares that frame and the
        payload frame sits at the tip of link n.
        """
        lengths = np.asarray(self.lengths, dtype=float)
        n = lengths.shape[0]
        bodies = []
        for k in range(n):
            parent = None if k == 0 else f"link{k}"
            pos = (0.0, 0.0, 0.0) if k == 0 else (float(lengths[k - 1]), 0.0, 0.0)
            bodies.append(
                TreeBody(
                    name=f"link{k + 1}",
                    parent=parent,
                    pos=pos,
                    joints=(Joint(f"q{k + 1}", "hinge", Z),),
                    visual_to=(float(lengths[k]), 0.0, 0.0),
                )
            )
            bodies.append(TreeBody(name=f"counterweight{k + 1}", parent=f"link{k + 1}"))
        tip = (float(lengths[-1]), 0.0, 0.0)
        bodies.append(TreeBody(name="payload", parent=f"link{n}", pos=tip))
        return Tree(
            bodies=tuple(bodies),
            coordinates=identity,
            actuated=tuple(f"q{k + 1}" for k in range(n)),
        )


def planar_2r(payload: float = 5.0) -> PlanarArm:
    """The 2R arm of Briot et al. (2012), §3.1, with its 5 kg payload."""
    return PlanarArm(
        lengths=[0.5, 0.3],
        com_ratios=[0.289, 0.098],
        masses=[24.4, 8.3],
        inertias=[1.246, 0.057],
        payload=payload,
    )


def planar_3r(payload: float = 5.0) -> PlanarArm:
    """The 3R arm of Briot et al. (2012), §3.2, with its 5 kg payload."""
    return PlanarArm(
        lengths=[0.5, 0.3, 0.1],
        com_ratios=[0.289, 0.098, 0.5],
        masses=[24.4, 8.3, 2.0],
        inertias=[1.246, 0.057, 0.025],
        payload=payload,
    )


def force_balanced(arm: PlanarArm, counter_distances) -> PlanarArm:
    """The arm with counterweights that keep its total COM at the base joint O.

    Classical static (shaking-force) balancing, link by link from the tip: the
    counterweight of link k, at ``d_cw,k`` behind joint k, cancels the first moment of
    link k and of everything it carries about joint k,

        m_cw,k d_cw,k = m_k r_k l_k + (Σ_{j>k} (m_j + m_cw,j) + m_tool) l_k,

    so every ``l_eq,k`` of :meth:`PlanarArm.equivalent_lengths` vanishes.

    Args:
        arm: any planar arm (its current counterweights are replaced).
        counter_distances: ``(n,)`` distances behind each joint [m], positive.

    References:
        Briot et al. (2012), §3.3 and footnote 1 (counterweights at 0.35 m from O and
        0.2 m from A); Arakelian & Smith (2005).
    """
    distances = jnp.asarray(counter_distances, dtype=float)
    check_shape("counter_distances", distances, (arm.n_links,))
    raise_if_invalid(distances > 0, "counterweight distances must be positive", distances)
    carried = arm.payload
    counter = []
    for k in reversed(range(arm.n_links)):
        first_moment = arm.masses[k] * arm.com_ratios[k] * arm.lengths[k] + carried * arm.lengths[k]
        counter_mass = first_moment / distances[k]
        counter.append(counter_mass)
        carried = carried + arm.masses[k] + counter_mass
    return PlanarArm(
        arm.lengths,
        arm.com_ratios,
        arm.masses,
        arm.inertias,
        arm.payload,
        counter_masses=jnp.stack(counter[::-1]),
        counter_distances=distances,
    )


#: |φ| [rad] up to which :func:`closing_angle` keeps φ's whole turns.
TURNS_LIMIT = 2.0**10


def closing_angle(phi, before):
    """The last joint angle ``φ − before`` [rad] of a 3R whose link 3 has the absolute
    angle φ, so that the joint angles sum to φ itself, not to φ ± 2π: the round trip
    ``end_effector(inverse_kinematics(pose))`` gives back the φ asked for (φ = 2.0
    came back as 2.0 − 2π, and a COM plan's default φ law between two such poses turned
    link 3 a full extra turn). φ is wrapped first, since ``φ − before`` would lose
    ``before`` to rounding for a large φ (φ = 1e10 rad put the tip 4e-8 m off, 1e300
    0.15 m); for ``|φ| >`` :data:`TURNS_LIMIT` the whole turns are dropped for the
    same reason (the angle is then in ``(−π, π]``).
    """
    rest = wrap(wrap(phi) - before)
    turns = jnp.round((phi - before - rest) / (2 * jnp.pi))
    return rest + jnp.where(jnp.abs(phi) <= TURNS_LIMIT, 2 * jnp.pi * turns, 0.0)
