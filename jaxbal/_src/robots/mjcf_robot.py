"""Your own robot: a mechanism read from MJCF or URDF, serial or closed-chain.

:class:`MjcfRobot` satisfies the whole robot contract (:class:`jaxbal.Robot`) for any
tree of hinge, slide and ball joints on a fixed base, closed by ``connect`` equalities.
Built by :func:`~jaxbal._src.robots.mjcf_import.from_mjcf` (structure from MuJoCo's
compiler, :mod:`~jaxbal._src.robots.mjcf_parse`).

Coordinates ``q`` are MuJoCo's ``qpos``: hinge angles [rad], slide displacements [m]
and ball quaternions ``(w, x, y, z)``, in MuJoCo's order (``robot.coordinate(name)``
gives a joint's index). Closed chains: the loop closures ``Φ(q)`` stack, per
``connect``, the world difference of its two anchors (only along the directions in
which the anchors can move: a planar mechanism in the x-y plane keeps the x and y rows,
see :func:`~jaxbal._src.robots.mjcf_parse.fixed_directions`), then ``|Q|² − 1`` per
ball joint, then one row per joint coupling (gear, URDF mimic:
:mod:`~jaxbal._src.robots.mjcf_couplings`). The independent coordinates (default: the
actuated joints) fix the others through :meth:`MjcfRobot.closure`, a Newton solve
differentiated implicitly.

The end-effector pose is the position of a named site (the components
``pose_components``, e.g. ``(0, 1)`` for a planar mechanism) followed by the values of
the joints ``ik_free`` when the mechanism has more independent coordinates than pose
components (as the 3R's φ). The site's axes are also the COM components planning steers
(:attr:`MjcfRobot.com_components`, e.g. ``(0, 2)`` for an arm in the x-z plane). The
inverse kinematics is numerical (Newton from the
robot's :attr:`~MjcfRobot.reference` configuration or a ``guess``, which picks the
assembly mode; no sign branches); a solution, or a closed chain's passive joint,
outside a limited joint's ``range`` (``joint_range``) is refused as unreachable.

Every body's mass, COM (body frame) and inertia (about the COM, body frame) is a leaf
addressable by its MJCF name (:meth:`MjcfRobot.body_index`, :meth:`MjcfRobot.with_body`);
so are the geometry (body offsets, joint axes and anchors) and the counter-masses of
:func:`~jaxbal._src.robots.counter_mass.add_counter_mass`. Bodies without a joint on
their path to the world are part of the base and left out.

References:
    MuJoCo XML reference (``joint``, ``equality/connect``, ``site``); Blondel et al.
    (2022), implicit differentiation (:func:`jaxbal.newton_solve`).
"""

from __future__ import annotations

from collections.abc import Mapping

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.robot import Bodies, Robot
from jaxbal._src.robots import mjcf_design
from jaxbal._src.robots.mjcf_couplings import coupling_residuals
from jaxbal._src.robots.mjcf_kinematics import point_in_world, world_frames
from jaxbal._src.robots.mjcf_solve import closure, closure_motion, inverse_kinematics, pose_motion
from jaxbal._src.robots.mjcf_tree import mjcf_tree
from jaxbal._src.types import Array, Coordinates, Float
from jaxbal._src.validation import check_shape

__all__ = ["MjcfRobot"]


class MjcfRobot(Robot):
    """A mechanism loaded from MJCF/URDF (see the module docstring).

    Attributes (arrays, differentiable leaves; ``nb`` bodies of the MJCF without the
    world, ``n`` of them moving, ``nj`` joints, ``c`` connects, ``k`` counter-masses):
        body_pos, body_rot: ``(nb, 3)``, ``(nb, 3, 3)`` body frames in the parent frame
            at the reference joint values [m].
        mass, com, inertia: ``(n,)`` [kg], ``(n, 3)`` [m], ``(n, 3, 3)`` [kg·m²] of the
            moving bodies (COM and inertia in the body frame, inertia about the COM).
        joint_axis, joint_pos, joint_ref: ``(nj, 3)`` unit axes, ``(nj, 3)`` anchors
            [m] in the body frame, ``(nj,)`` ``ref`` values [rad or m].
        anchor1, anchor2: ``(c, 3)`` connect anchors in their bodies' frames [m].
        coupling_coef: ``(e, 5)`` polynomials of the ``e`` joint couplings.
        site_pos: ``(3,)`` end-effector site in its body frame [m].
        reference: ``(dof,)`` Newton's default start for IK and closure (``qpos0``).
        counter_mass, counter_position, counter_inertia: ``(k,)`` [kg], ``(k, 3)`` in
            the carrying body's frame [m], ``(k, 3, 3)`` about their COM [kg·m²].

    Static structure: names, parents, joint types, ``qpos`` addresses and ranges
    (``(lo, hi)``, ``±inf`` unlimited; a ball's is its angle), which bodies move, the
    loop-closure rows, the site, the pose components, the independent, actuated and
    IK-free coordinates, the counter-masses' bodies, the payload body and the Newton
    ``tolerance`` (on ``|Φ|∞`` and the pose error, default ``1e-13`` m: some hundred
    times the round-off of a model of up to ~100 m; ``dataclasses.replace`` changes it).
    """

    branch_size = 0
    physical_inertias = True  # robot_checks: principal moments obey the triangle inequality
    #: payload (when ``payload_body`` is set) is handled in :meth:`with_design`.
    design_fields = {"counter_mass": "counter_mass", "counter_position": "counter_position"}

    body_pos: Float[Array, "nb 3"]
    body_rot: Float[Array, "nb 3 3"]
    mass: Float[Array, " n"]
    com: Float[Array, "n 3"]
    inertia: Float[Array, "n 3 3"]
    joint_axis: Float[Array, "nj 3"]
    joint_pos: Float[Array, "nj 3"]
    joint_ref: Float[Array, " nj"]
    anchor1: Float[Array, "c 3"]
    anchor2: Float[Array, "c 3"]
    site_pos: Float[Array, "3"]
    reference: Float[Array, " dof"]
    counter_mass: Float[Array, " k"]
    counter_position: Float[Array, "k 3"]
    counter_inertia: Float[Array, "k 3 3"]
    coupling_coef: Float[Array, "e 5"]
    body_names: tuple[str, ...] = eqx.field(static=True)
    parents: tuple[int, ...] = eqx.field(static=True)
    body_joints: tuple[tuple[int, ...], ...] = eqx.field(static=True)
    moving_bodies: tuple[int, ...] = eqx.field(static=True)
    joint_names: tuple[str, ...] = eqx.field(static=True)
    joint_types: tuple[str, ...] = eqx.field(static=True)
    joint_qpos: tuple[int, ...] = eqx.field(static=True)
    connect_names: tuple[str, ...] = eqx.field(static=True)
    connect_bodies: tuple[tuple[int, int], ...] = eqx.field(static=True)
    closure_rows: tuple[tuple[tuple[float, float, float], ...], ...] = eqx.field(static=True)
    coupling_names: tuple[str, ...] = eqx.field(static=True)
    coupling_joints: tuple[tuple[int, int], ...] = eqx.field(static=True)
    site_name: str | None = eqx.field(static=True)
    site_body: int = eqx.field(static=True)
    pose_components: tuple[int, ...] = eqx.field(static=True)
    ik_free: tuple[int, ...] = eqx.field(static=True)
    independent_coordinates: tuple[int, ...] = eqx.field(static=True)
    actuated_coordinates: tuple[int, ...] = eqx.field(static=True)
    counter_bodies: tuple[int, ...] = eqx.field(static=True)
    counter_names: tuple[str, ...] = eqx.field(static=True)
    payload_body: int | None = eqx.field(static=True)
    joint_range: tuple[tuple[float, float], ...] = eqx.field(static=True, default=())
    tolerance: float = eqx.field(static=True, default=1e-13)

    def __check_init__(self):
        nb, n, nj = len(self.body_names), len(self.moving_bodies), len(self.joint_names)
        c, k = len(self.connect_names), len(self.counter_names)
        shapes = {
            "body_pos": (nb, 3),
            "body_rot": (nb, 3, 3),
            "mass": (n,),
            "com": (n, 3),
            "inertia": (n, 3, 3),
            "joint_axis": (nj, 3),
            "joint_pos": (nj, 3),
            "joint_ref": (nj,),
            "anchor1": (c, 3),
            "anchor2": (c, 3),
            "coupling_coef": (len(self.coupling_names), 5),
            "site_pos": (3,),
            "counter_mass": (k,),
            "counter_position": (k, 3),
            "counter_inertia": (k, 3, 3),
        }
        for name, shape in shapes.items():
            check_shape(f"MjcfRobot.{name}", getattr(self, name), shape)
        check_shape("MjcfRobot.reference", self.reference, (None,))
        if len(set(names := self.mass_names())) != len(names):
            raise ValueError(f"body and counter-mass names must be unique, got {names}")

    @property
    def dof(self) -> int:
        return int(self.reference.shape[0])

    @property
    def independent(self) -> tuple[int, ...]:
        return self.independent_coordinates

    @property
    def actuated(self) -> tuple[int, ...]:
        return self.actuated_coordinates

    @property
    def com_components(self) -> tuple[int, ...]:
        """World axes of the COM that planning steers (:mod:`jaxbal._src.com_components`):
        the site's pose axes, the plane the mechanism moves in (``(0, 2)`` for an arm
        drawn in the vertical x-z plane; ``[:2]`` planned its world x, y); all three
        without a site."""
        return self.pose_components if self.site_name is not None else (0, 1, 2)

    @property
    def com_dims(self) -> int:
        return len(self.com_components)

    @property
    def dependent(self) -> tuple[int, ...]:
        """Indices of the coordinates fixed by the loop closures."""
        return tuple(i for i in range(self.dof) if i not in self.independent_coordinates)

    def mass_names(self) -> tuple[str, ...]:
        """Names of :meth:`mass_properties`: moving MJCF bodies, then counter-masses."""
        return tuple(self.body_names[i] for i in self.moving_bodies) + self.counter_names

    def body_index(self, name: str) -> int:
        """Index of a body (or counter-mass) in :meth:`mass_properties`, by its name.

        Raises:
            ValueError: an unknown name, or a body fixed to the base (the message lists
                the moving bodies).
        """
        names = self.mass_names()
        if name not in names:
            fixed = name in self.body_names
            why = "is fixed to the base (no joint moves it)" if fixed else "is not a body"
            raise ValueError(f"{name!r} {why}; moving bodies: {list(names)}")
        return names.index(name)

    def coordinate(self, joint: str) -> int:
        """Index in ``q`` of a hinge or slide joint (its ``qpos`` address)."""
        if joint not in self.joint_names:
            raise ValueError(f"unknown joint {joint!r}; joints: {list(self.joint_names)}")
        j = self.joint_names.index(joint)
        if self.joint_types[j] == "ball":
            raise ValueError(f"joint {joint!r} is a ball joint (4 quaternion coordinates)")
        return self.joint_qpos[j]

    def with_body(self, name: str, *, mass=None, com=None, inertia=None) -> MjcfRobot:
        """The robot with the mass [kg], COM ``(3,)`` [m] and/or inertia ``(3, 3)``
        [kg·m²] (about the COM, body frame) of the MJCF body ``name`` replaced (traced
        values allowed: differentiate through them)."""
        i = self.body_index(name)
        if i >= len(self.moving_bodies):
            raise ValueError(f"{name!r} is a counter-mass: change it with with_design")
        robot = self
        changes = (("mass", mass, ()), ("com", com, (3,)), ("inertia", inertia, (3, 3)))
        for field, value, shape in (c for c in changes if c[1] is not None):
            value = jnp.asarray(value, dtype=float)
            check_shape(f"{field} of {name!r}", value, shape)
            updated = getattr(robot, field).at[i].set(value)
            robot = eqx.tree_at(lambda r, f=field: getattr(r, f), robot, updated)
        return robot

    # --- the two methods every robot provides ---------------------------------------

    def mass_properties(self) -> Bodies:
        """Moving MJCF bodies (MuJoCo order) then the counter-masses."""
        return Bodies(
            mass=jnp.concatenate([self.mass, self.counter_mass]),
            com=jnp.concatenate([self.com, self.counter_position]),
            inertia=jnp.concatenate([self.inertia, self.counter_inertia]),
            names=self.mass_names(),
        )

    def body_frames(self, q: Coordinates):
        q = jnp.asarray(q, dtype=float)
        check_shape("q", q, (self.dof,))
        origins, rotations = world_frames(self, q)
        index = np.array(
            self.moving_bodies + tuple(self.moving_bodies[b] for b in self.counter_bodies),
            dtype=int,
        )
        return origins[index], rotations[index]

    # --- closed chains --------------------------------------------------------------

    def constraint(self, q: Coordinates) -> Float[Array, " k"]:
        """Loop closures ``Φ(q)`` [m, and 1 for the quaternion norms] (module doc)."""
        q = jnp.asarray(q, dtype=float)
        return self.closures_at(q, world_frames(self, q) if self.connect_names else None)

    def closures_at(self, q, frames) -> Float[Array, " k"]:
        """:meth:`constraint` from already computed ``world_frames`` (``None`` without
        connects), so that one pass of forward kinematics serves several quantities."""
        pieces = []
        if self.connect_names:
            origins, rotations = frames
            for c, (b1, b2) in enumerate(self.connect_bodies):
                gap = point_in_world(origins, rotations, b1, self.anchor1[c]) - point_in_world(
                    origins, rotations, b2, self.anchor2[c]
                )
                rows = jnp.asarray(self.closure_rows[c], dtype=float).reshape(-1, 3)
                pieces.append(jnp.sum(rows * gap[None, :], axis=1))
        for j, kind in enumerate(self.joint_types):
            if kind == "ball":
                a = self.joint_qpos[j]
                pieces.append(jnp.sum(q[a : a + 4] ** 2)[None] - 1.0)
        pieces += [coupling_residuals(self, q)] if self.coupling_names else []
        return jnp.concatenate(pieces) if pieces else jnp.zeros((0,))

    def closure_count(self) -> int:
        """Number of loop-closure equations (rows of :meth:`constraint`)."""
        rows = sum(len(r) for r in self.closure_rows) + len(self.coupling_names)
        return rows + self.joint_types.count("ball")

    def assemble(self, independent, dependent) -> Coordinates:
        """``q`` from the independent and the dependent coordinates."""
        order = np.argsort(np.array(self.independent_coordinates + self.dependent, dtype=int))
        return jnp.concatenate([jnp.asarray(independent), jnp.asarray(dependent)])[order]

    def closure(self, q_independent, guess=None, *, return_valid: bool = False):
        """All coordinates ``q (dof,)`` from the independent ones ``(m,)`` (loop
        closure by Newton from ``guess``, default :attr:`reference`; see
        :func:`~jaxbal._src.robots.mjcf_solve.closure`)."""
        return closure(self, q_independent, guess, return_valid=return_valid)

    def closure_motion(self, u, u_d, u_dd, guess=None, *, return_valid: bool = False):
        """``(q, q̇, q̈)`` from the independent ``(u, u̇, ü)`` (see
        :func:`~jaxbal._src.robots.mjcf_solve.closure_motion`)."""
        return closure_motion(self, u, u_d, u_dd, guess, return_valid=return_valid)

    # --- end effector ---------------------------------------------------------------

    def require_site(self) -> None:
        """Raise ``ValueError`` when the robot was built without an end-effector site."""
        if self.site_name is None:
            raise ValueError(
                "this robot has no end-effector site: pass end_effector_site= to from_mjcf"
            )

    def end_effector(self, q: Coordinates) -> Float[Array, " m"]:
        """Site position components ``pose_components`` [m], then the values of the
        ``ik_free`` joints [rad or m]."""
        self.require_site()
        q = jnp.asarray(q, dtype=float)
        return self.pose_at(q, world_frames(self, q))

    def pose_labels(self) -> tuple[str, ...]:
        """Names of the components of :meth:`end_effector`, e.g. ``('tip.x', 'tip.y')``
        or, for a 6-joint arm, ``('hand.x', 'hand.y', 'hand.z', 'wrist_1', …)``: the
        site's world axes, then the ``ik_free`` joints."""
        self.require_site()
        axes = tuple(f"{self.site_name}.{'xyz'[c]}" for c in self.pose_components)
        return axes + tuple(self.joint_names[self.joint_qpos.index(i)] for i in self.ik_free)

    def pose_at(self, q, frames) -> Float[Array, " m"]:
        """:meth:`end_effector` from already computed ``world_frames``."""
        site = point_in_world(*frames, self.site_body, self.site_pos)
        free = q[np.asarray(self.ik_free, dtype=int)]
        return jnp.concatenate([site[np.asarray(self.pose_components, dtype=int)], free])

    def branch(self, branch=None) -> tuple[int, ...]:
        """Numerical IK has no sign branches: ``None``, ``()`` or ``±1`` give ``()``
        (choose the assembly mode with ``guess=``)."""
        if isinstance(branch, int | np.integer) and not isinstance(branch, bool):
            if int(branch) not in (1, -1):
                raise ValueError(f"branch must be None, () or ±1, got {branch!r}")
            return ()
        return super().branch(branch)

    def inverse_kinematics(self, pose, *, branch=None, return_valid: bool = False, guess=None):
        """All coordinates ``q (dof,)`` for an end-effector ``pose`` (as
        :meth:`end_effector` returns it), by Newton from ``guess`` (default
        :attr:`reference`, picks the assembly mode); ``branch`` must be ``None`` (see
        :meth:`branch`). With ``return_valid`` returns ``(q, valid)`` and never raises;
        see :func:`~jaxbal._src.robots.mjcf_solve.inverse_kinematics`."""
        self.branch(branch)
        return inverse_kinematics(self, pose, guess, return_valid=return_valid)

    def pose_motion(self, pose, pose_d, pose_dd, guess=None, *, return_valid: bool = False):
        """``(q, q̇, q̈)`` from an end-effector motion ``(u, u̇, ü)``: the same as
        :func:`jaxbal.pose_motion`, cheaper to compile (see
        :func:`~jaxbal._src.robots.mjcf_solve.pose_motion`)."""
        return pose_motion(self, pose, pose_d, pose_dd, guess, return_valid=return_valid)

    def with_reference(self, q) -> MjcfRobot:
        """The robot whose Newton solves start from ``q (dof,)`` (the assembly mode)."""
        q = jnp.asarray(q, dtype=float)
        check_shape("reference", q, (self.dof,))
        return eqx.tree_at(lambda r: r.reference, self, q)

    # --- design variables (jaxbal._src.robots.mjcf_design) ---------------------------

    def design(self) -> dict[str, Array]:
        """``counter_mass (k,)`` [kg] and ``counter_position (k, 3)`` [m, body frame]
        when counter-masses were added; ``payload`` [kg], the mass of ``payload_body``."""
        return mjcf_design.design(self)

    def with_design(self, design: Mapping) -> MjcfRobot:
        """The robot with some design variables replaced (see :meth:`design`).

        Raises:
            ValueError: an unknown name (``payload`` without a ``payload_body``
                included) or a wrong shape.
        """
        return mjcf_design.with_design(self, design)

    def design_lower_bounds(self) -> dict[str, float]:
        """Masses ≥ 0; counter positions ≥ −:meth:`position_bound` per coordinate."""
        return mjcf_design.design_lower_bounds(self)

    def position_bound(self) -> float:
        """Ten times the mechanism's size (largest body offset, anchor or site
        distance, at least 1 m) [m]: the default bound of counter positions."""
        return mjcf_design.position_bound(self)

    # --- MuJoCo -----------------------------------------------------------------------

    def mujoco_tree(self):
        """The parsed tree rebuilt for MuJoCo, counter-masses welded to their bodies
        (see :func:`~jaxbal._src.robots.mjcf_tree.mjcf_tree`)."""
        return mjcf_tree(self)
