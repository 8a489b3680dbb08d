"""Your own robot: mechanisms loaded from MJCF/URDF (``jaxbal.robots.from_mjcf``).

References and tolerances, per test:

* MuJoCo C ``mj_inverse`` on the *user's own file* mounted on six base dofs (the base
  reaction ``−qfrc_inverse[:6]``; connect forces have no base component): 1e-9 of the
  peak reaction (serial: 203 random mechanisms; 3-RRR, spatial RUSR);
* ``jaxbal.mujoco.confirm`` on the tree rebuilt from the parsed structure: 1e-9;
* MuJoCo C ``mj_kinematics`` (``xpos``, ``xmat``) for the forward kinematics: 1e-12;
* the built-in robots' own ``shaking_wrench``, exported with ``export_mjcf`` and
  re-imported: 1e-9 (planar bodies' padded inertias act only off-plane);
* loop closures: ``|Φ| < 1e-12`` m along every move;
* central finite differences for gradients: 1e-6 relative;
* a force-balanced five-bar: shaking force < 1e-9 of the unbalanced one.
"""

import functools
import re

import equinox as eqx
import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from typer.testing import CliRunner

import jaxbal
from jaxbal import robots
from jaxbal._src.momentum import tree_wrench
from jaxbal._src.robots.mjcf_balance import _singular_start
from jaxbal._src.robots.mjcf_solve import pose_equations
from jaxbal.design import peak_force
from jaxbal.mujoco import confirm, export_mjcf
from jaxbal.robots import add_counter_mass, from_mjcf, from_urdf
from jaxbal.robots.mjcf_balancing import closure_samples, pose_samples

HEAD = '<mujoco><compiler angle="radian" autolimits="true"/><option gravity="0 0 0"/>'
MOUNT = (
    '<body name="mount"><inertial pos="0 0 0" mass="1e-14" diaginertia="1e-14 1e-14 1e-14"/>'
    + "".join(
        f'<joint name="base{i}" type="{"slide" if i < 3 else "hinge"}" '
        f'axis="{" ".join(str(v) for v in np.eye(3)[i % 3])}"/>'
        for i in range(6)
    )
)
FIVE_BAR_BODIES = """
  <body name="crank_a" pos="-0.1 0 0" euler="0 0 2.260904">
   <joint name="a" axis="0 0 1" ref="2.260904"/>
   <inertial pos="0.1 0 0" mass="0.5" diaginertia="1e-4 2e-3 2e-3"/>
   <body name="distal_a" pos="0.2 0 0" euler="0 0 -1.549961">
    <joint name="pa" axis="0 0 1" ref="-1.549961"/>
    <inertial pos="0.15 0 0" mass="0.4" diaginertia="1e-4 3e-3 3e-3"/>
    <site name="tip" pos="0.3 0 0"/>
   </body>
  </body>
  <body name="crank_b" pos="0.1 0 0" euler="0 0 0.880688">
   <joint name="b" axis="0 0 1" ref="0.880688"/>
   <inertial pos="0.1 0 0" mass="0.5" diaginertia="1e-4 2e-3 2e-3"/>
   <body name="distal_b" pos="0.2 0 0" euler="0 0 1.549961">
    <joint name="pb" axis="0 0 1" ref="1.549961"/>
    <inertial pos="0.15 0 0" mass="0.4" diaginertia="1e-4 3e-3 3e-3"/>
   </body>
  </body>"""
LOOP = '<equality><connect body1="distal_a" body2="distal_b" anchor="0.3 0 0"/></equality>'
MOTORS = '<actuator><motor joint="a"/><motor joint="b"/></actuator>'
FIVE_BAR = f"{HEAD}<worldbody>{FIVE_BAR_BODIES}</worldbody>{LOOP}{MOTORS}</mujoco>"


def _fmt(values) -> str:
    return " ".join(f"{float(v):.17g}" for v in np.ravel(values))


def _mounted(xml: str) -> str:
    """The same model carried by a massless body on six base dofs."""
    head, rest = xml.split("<worldbody>", 1)
    inner, tail = rest.split("</worldbody>", 1)
    return f"{head}<worldbody>{MOUNT}{inner}</body></worldbody>{tail}"


def _mujoco_reaction(xml: str, q, qd, qdd) -> np.ndarray:
    """``(T, 6)`` force and moment on the base from MuJoCo C (``-qfrc_inverse[:6]``)."""
    model = mujoco.MjModel.from_xml_string(_mounted(xml))
    data = mujoco.MjData(model)
    out = []
    for state in zip(*(np.atleast_2d(a) for a in (q, qd, qdd)), strict=True):
        data.qpos[:], data.qvel[:], data.qacc[:] = (np.r_[np.zeros(6), s] for s in state)
        mujoco.mj_inverse(model, data)
        out.append(-data.qfrc_inverse[:6].copy())
    return np.array(out)


def _relative(ours, reference) -> float:
    """Max error of force and moment, each relative to the peak reference magnitude."""
    ours, reference = np.asarray(ours), np.asarray(reference)
    errors = []
    for part in (slice(0, 3), slice(3, 6)):
        scale = max(float(np.max(np.abs(reference[..., part]))), 1e-300)
        errors.append(float(np.max(np.abs(ours[..., part] - reference[..., part]))) / scale)
    return max(errors)


@jax.jit
def _wrenches(robot, q, qd, qdd):
    """``(T, 6)`` shaking wrenches and the loop-closure residuals ``(Φ, Φ̇, Φ̈)``."""

    def one(a, b, c):
        force, moment = jaxbal.shaking_wrench(robot, a, b, c)
        return jnp.concatenate([force, moment]), jaxbal.loop_closure_residuals(robot, a, b, c)

    return jax.vmap(one)(q, qd, qdd)


# --- random serial mechanisms vs MuJoCo -------------------------------------------------


def _rotation(rng):
    quat = rng.normal(size=4)
    return quat / np.linalg.norm(quat)


def _template(rng, joints: int):
    """Random topology: ``(parent, joint types)`` per body (chains with branches, bodies
    with two joints and welded bodies)."""
    bodies, count = [], 0
    while count < joints:
        chain = not bodies or rng.random() < 0.75
        parent = len(bodies) - 1 if chain else int(rng.integers(-1, len(bodies)))
        k = min(int(rng.choice([0, 1, 1, 1, 2])), joints - count) or (0 if bodies else 1)
        bodies.append((parent, tuple(str(rng.choice(["hinge", "slide"])) for _ in range(k))))
        count += k
    return bodies


def _mechanism(bodies, rng, ball: bool = False) -> str:
    """MJCF body tree with random offsets, axes, anchors, refs, masses, full inertias."""
    children = {i: [] for i in range(-1, len(bodies))}
    for i, (parent, _) in enumerate(bodies):
        children[parent].append(i)
    counter = iter(range(100))

    def emit(i):
        mass = rng.uniform(0.1, 3.0)
        second = rng.uniform(0.05, 1.0, 3) * mass * 0.01  # ∫x², ∫y², ∫z²: realisable
        principal = np.array([second[1] + second[2], second[0] + second[2], second[0] + second[1]])
        rotation = np.zeros(9)
        mujoco.mju_quat2Mat(rotation, _rotation(rng))
        rotation = rotation.reshape(3, 3)
        inertia = rotation @ np.diag(principal) @ rotation.T
        xml = f'<body name="b{i}" pos="{_fmt(rng.uniform(-0.3, 0.3, 3))}" quat="{_fmt(_rotation(rng))}">'  # noqa: E501
        for kind in bodies[i][1]:
            kind = "ball" if ball and i == 1 else kind
            axis = "" if kind == "ball" else f'axis="{_fmt(rng.normal(size=3))}" '
            ref = "" if kind == "ball" else f'ref="{rng.uniform(-1, 1):.17g}" '
            xml += f'<joint name="j{next(counter)}" type="{kind}" {axis}{ref}'
            xml += f'pos="{_fmt(rng.uniform(-0.1, 0.1, 3))}"/>'
        full = inertia[[0, 1, 2, 0, 0, 1], [0, 1, 2, 1, 2, 2]]
        xml += f'<inertial pos="{_fmt(rng.uniform(-0.2, 0.2, 3))}" mass="{mass:.17g}" '
        xml += f'fullinertia="{_fmt(full)}"/>'
        return xml + "".join(emit(c) for c in children[i]) + "</body>"

    inner = "".join(emit(c) for c in children[-1])
    return f"{HEAD}<worldbody>{inner}</worldbody></mujoco>"


@jax.jit
def _batched_wrenches(stacked, q, qd, qdd):
    def one(robot, a, b, c):
        wrench = jax.vmap(lambda x, y, z: jaxbal.shaking_wrench(robot, x, y, z))(a, b, c)
        return jnp.concatenate(wrench, axis=-1)

    return jax.vmap(one)(stacked, q, qd, qdd)


def _random_states(rng, robot, count):
    """Random ``(q, q̇, q̈)``; ball joints get unit quaternions and consistent rates."""
    q, qd, qdd = (rng.uniform(-s, s, (count, robot.dof)) for s in (2.0, 3.0, 10.0))
    for j, kind in enumerate(robot.joint_types):
        if kind != "ball":
            continue
        a = robot.joint_qpos[j]
        for k in range(count):
            quat, omega, omega_d = _rotation(rng), rng.normal(size=3), rng.normal(size=3)
            rate, accel = np.zeros(4), np.zeros(4)
            mujoco.mju_mulQuat(rate, quat, np.r_[0.0, omega])
            rate *= 0.5  # Q̇ = ½ Q ⊗ (0, ω), ω in the body frame (MuJoCo's qvel)
            mujoco.mju_mulQuat(accel, rate, np.r_[0.0, omega])
            extra = np.zeros(4)
            mujoco.mju_mulQuat(extra, quat, np.r_[0.0, omega_d])
            q[k, a : a + 4], qd[k, a : a + 4], qdd[k, a : a + 4] = quat, rate, 0.5 * (accel + extra)
    return q, qd, qdd


def _to_mujoco_rates(robot, q, qd, qdd):
    """MuJoCo ``qvel``/``qacc`` (ball: body angular velocity and its rate)."""
    tree = robot.mujoco_tree()
    states = [jaxbal.mujoco.tree_state(tree, *s) for s in zip(q, qd, qdd, strict=True)]
    return np.array([s[1] for s in states]), np.array([s[2] for s in states])


@pytest.mark.slow
@pytest.mark.parametrize("ball", [False, True], ids=["hinge_slide", "with_ball"])
def test_random_serial_mechanisms_match_mujoco(ball):
    """204 random hinge/slide mechanisms (random topologies of 1, 2, 4 and 7 joints,
    51 parameter draws each: one compilation per topology), 3 random states each:
    shaking wrench = MuJoCo C's base reaction of the user's file to 1e-9. With
    ``ball``: 29 three-joint mechanisms whose second body hangs on a ball joint."""
    rng = np.random.default_rng(7 if ball else 0)
    worst, count, draws = 0.0, 0, 29 if ball else 51
    for joints in (3,) if ball else (1, 2, 4, 7):
        template = _template(rng, joints)
        while ball and len(template) < 2:
            template = _template(rng, joints)
        models, states, references = [], [], []
        for _ in range(draws):
            xml = _mechanism(template, rng, ball)
            robot = from_mjcf(xml)
            q, qd, qdd = _random_states(rng, robot, 3)
            vel, acc = _to_mujoco_rates(robot, q, qd, qdd) if ball else (qd, qdd)
            references.append(_mujoco_reaction(xml, q, vel, acc))
            models.append(robot)
            states.append((q, qd, qdd))
        stacked = jax.tree.map(lambda *leaves: np.stack(leaves), *models)
        arrays = (jnp.asarray(np.stack([s[k] for s in states])) for k in range(3))
        ours = np.asarray(_batched_wrenches(stacked, *arrays))
        for mine, reference in zip(ours, references, strict=True):
            worst = max(worst, _relative(mine, reference))
        count += len(models)
    assert count == (29 if ball else 204)
    assert worst < 1e-9, worst


def test_forward_kinematics_matches_mujoco_and_urdf():
    """Body frames of a URDF arm (through MuJoCo's URDF compiler) equal MuJoCo's
    ``xpos``/``xmat`` at random joint values (1e-12); masses are the URDF's."""
    urdf = """<robot name="arm">
      <link name="base"/>
      <link name="upper"><inertial><origin xyz="0.1 0 0.02"/><mass value="2"/>
        <inertia ixx="0.01" iyy="0.02" izz="0.025" ixy="0.001" ixz="0" iyz="0"/></inertial></link>
      <link name="fore"><inertial><origin xyz="0.1 0 0"/><mass value="1"/>
        <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
      <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
        <origin xyz="0 0 0.1" rpy="0.1 0 0.3"/><axis xyz="0 0 1"/>
        <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
      <joint name="slide" type="prismatic"><parent link="upper"/><child link="fore"/>
        <origin xyz="0.2 0 0" rpy="0 0.2 0"/><axis xyz="1 0 0"/>
        <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
    </robot>"""
    robot = from_urdf(urdf)
    model = mujoco.MjModel.from_xml_string(urdf)
    data = mujoco.MjData(model)
    assert robot.mass_names() == ("upper", "fore")
    np.testing.assert_allclose(robot.mass, [2.0, 1.0])
    frames = jax.jit(lambda x: robot.body_frames(x))
    for q in np.random.default_rng(1).uniform(-1, 1, (4, 2)):
        data.qpos[:] = q
        mujoco.mj_kinematics(model, data)
        origins, rotations = frames(jnp.asarray(q))
        np.testing.assert_allclose(origins, data.xpos[1:], atol=1e-12)
        np.testing.assert_allclose(rotations, data.xmat[1:].reshape(-1, 3, 3), atol=1e-12)
    with pytest.raises(ValueError, match="<robot>"):
        from_urdf("<mujoco/>")


# --- round trip of the built-in robots ----------------------------------------------------

ROUND_TRIP = {
    "planar_2r": robots.planar_2r(),
    "planar_3r": robots.planar_3r(),
    "scara": robots.scara(),
    "dual_v": robots.dual_v(),
    "orthoglide": robots.orthoglide(payload=1.0),
}


@functools.partial(jax.jit, static_argnums=2)
def _both_wrenches(builtin, imported, tree, q, qd, qdd):
    """Wrench of the built-in robot at ``(q, q̇, q̈)`` and of the imported one at the
    same state mapped through the exported tree's coordinates."""

    def velocity(x, xd):
        return jax.jvp(tree.coordinates, (x,), (xd,))

    (p, pd), (_, pdd) = jax.jvp(velocity, (q, qd), (qd, qdd))
    # the bodies' wrench at any state (tree_wrench: the DUAL-V's loops not required)
    original = jnp.concatenate(tree_wrench(builtin, q, qd, qdd))
    return original, jnp.concatenate(tree_wrench(imported, p, pd, pdd))


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(ROUND_TRIP))
def test_builtin_robots_round_trip_through_mjcf(name):
    """``export_mjcf`` then ``from_mjcf``: the same shaking wrench (1e-9 relative) at a
    moving state, mapped through ``robot.mujoco_tree().coordinates`` (the Orthoglide's
    ball joints as quaternions). Any state of the serial arms and of the DUAL-V (whose
    body frames do not need closed loops); the Orthoglide's from its IK (``pose_motion``:
    its bars' rotations need closed legs)."""
    robot = ROUND_TRIP[name]
    imported = from_mjcf(export_mjcf(robot))
    assert set(robot.mass_properties().names) <= set(imported.mass_names())
    if name == "orthoglide":
        rate = jnp.array([0.3, -0.2, 0.4])
        state = jaxbal.pose_motion(robot, jnp.array([-0.1, 0.07, -0.11]), rate, 3.0 * rate)
    else:
        rng = np.random.default_rng(3)
        state = (jnp.asarray(rng.uniform(-s, s, robot.dof)) for s in (1.0, 2.0, 5.0))
    original, again = _both_wrenches(robot, imported, robot.mujoco_tree(), *state)
    assert _relative(again, original) < 1e-9


# --- the five-bar: closed chain, counter-masses, gradients, MuJoCo ---------------------

START, END = jnp.array([-0.05, 0.33]), jnp.array([0.06, 0.40])  # tip positions [m]


@pytest.fixture(scope="module")
def five_bar():
    """The five-bar with a payload body, a counter-mass on each crank and a quintic
    move of its tip (exact joint motion from the differentiated loop and pose
    equations; counter-masses do not change it)."""
    motion = pose_samples(from_mjcf(FIVE_BAR, end_effector_site="tip"), START, END, 0.25, 41)
    robot = from_mjcf(FIVE_BAR, end_effector_site="tip", payload_body="distal_a")
    robot = add_counter_mass(robot, "crank_a", (-0.08, 0.01, 0.0), 0.3)
    robot = add_counter_mass(robot, "crank_b", (-0.06, -0.02, 0.0), 0.2, inertia=1e-4 * np.eye(3))
    return robot, motion


@pytest.mark.slow
def test_five_bar_structure_and_loop_closure(five_bar):
    """Parsed structure (planar loop: x and y rows), the move's loop closures (|Φ| <
    1e-12 m, rates 1e-10) and the tip following the line exactly (1e-12)."""
    robot, motion = five_bar
    assert robot.closure_rows == (((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),)
    assert robot.pose_components == (0, 1) and robot.com_dims == 2
    assert robot.independent == robot.actuated == (robot.coordinate("a"), robot.coordinate("b"))
    assert robot.mass_names()[-2:] == ("counter_crank_a", "counter_crank_b")
    _, (phi, phi_d, phi_dd) = _wrenches(robot, *motion)
    assert float(jnp.max(jnp.abs(phi))) < 1e-12
    assert float(jnp.max(jnp.abs(phi_d))) < 1e-10 and float(jnp.max(jnp.abs(phi_dd))) < 1e-9
    tips = jax.jit(jax.vmap(robot.end_effector))(motion.q)
    np.testing.assert_allclose(tips[0], START, atol=1e-12)
    np.testing.assert_allclose(tips[-1], END, atol=1e-12)
    line = jnp.cross(jnp.append(END - START, 0.0), jnp.pad(tips - START, ((0, 0), (0, 1))))
    assert float(jnp.max(jnp.abs(line))) < 1e-12  # on the straight line


def test_five_bar_ik_closure_and_unreachable(five_bar):
    """IK and closure agree with the move; an unreachable pose gives a False mask and
    finite coordinates (``return_valid``), an eager ValueError naming it otherwise."""
    robot, motion = five_bar
    q = robot.inverse_kinematics(START)
    np.testing.assert_allclose(q, motion.q[0], atol=1e-10)
    u = motion.q[-1, np.asarray(robot.independent)]
    np.testing.assert_allclose(robot.closure(u, guess=motion.q[-1]), motion.q[-1], atol=1e-10)
    far = jnp.array([3.0, 3.0])
    q_far, valid = robot.inverse_kinematics(far, return_valid=True)
    assert not bool(valid) and bool(jnp.all(jnp.isfinite(q_far)))
    with pytest.raises(ValueError, match="not reached"):
        robot.inverse_kinematics(far)
    with pytest.raises(ValueError, match="branch"):
        robot.inverse_kinematics(START, branch=2)


@pytest.mark.slow
def test_five_bar_matches_mujoco(five_bar):
    """``confirm`` on the rebuilt tree (counter-masses welded, connect closing the
    loop, MuJoCo C placing the passive joints and computing their velocities and
    accelerations itself) agrees with jaxbal to 1e-9; so does MuJoCo on the user's own file for the
    robot without counter-masses (payload at the file's value)."""
    robot, motion = five_bar
    result = confirm(robot, *motion)
    assert result.independent and result.relative < 1e-9
    # MuJoCo C re-closed the loop itself: its passive joints equal jaxbal's (1e-12)
    assert result.closed_by_mujoco and result.closure_difference < 1e-12, result
    zeros = (jnp.zeros(2), jnp.zeros((2, 3, 3)))
    bare = eqx.tree_at(lambda r: (r.counter_mass, r.counter_inertia), robot, zeros)
    ours, _ = _wrenches(bare, *motion)
    assert _relative(ours, _mujoco_reaction(FIVE_BAR, *motion)) < 1e-9


@pytest.mark.slow
def test_five_bar_gradients_match_finite_differences(five_bar):
    """d(peak force)/d(counter-mass, its position) (jaxbal.sensitivity, check=True)
    and d(peak force)/d(mass of distal_b) (through ``with_body``) equal central
    finite differences to 1e-6 relative."""
    robot, motion = five_bar
    result = jaxbal.sensitivity.sensitivity(robot, motion, "peak_force", check=True, rtol=1e-6)
    assert set(result.gradient) == {"counter_mass", "counter_position", "payload"}

    def peak(mass):
        return peak_force(robot.with_body("distal_b", mass=mass), motion)

    value = jax.jit(jax.value_and_grad(peak))
    mass = float(robot.mass[robot.body_index("distal_b")])
    _, gradient = value(mass)
    step = 1e-6 * mass
    central = (value(mass + step)[0] - value(mass - step)[0]) / (2 * step)
    assert abs(float(gradient) - float(central)) <= 1e-6 * abs(float(central))


@pytest.mark.slow
def test_five_bar_actuator_torques_balance_the_power(five_bar):
    """``jaxbal.actuator_torques`` (virtual work through the loop closures) delivers
    the rate of change of kinetic energy: ``τ · u̇ = dT/dt`` (1e-10 relative)."""
    robot, motion = five_bar

    @jax.jit
    def powers(q, qd, qdd):
        torques = jaxbal.actuator_torques(robot, q, qd, qdd)
        rate = jax.jvp(lambda a, b: jaxbal.kinetic_energy(robot, a, b), (q, qd), (qd, qdd))[1]
        return torques @ qd[np.asarray(robot.actuated)], rate

    for k in (5, 20, 33):
        delivered, rate = powers(motion.q[k], motion.qd[k], motion.qdd[k])
        assert abs(float(delivered - rate)) <= 1e-10 * abs(float(rate))


# --- a 3-RRR and a spatial RUSR, against MuJoCo on the user's own file -----------------

INERTIAL = '<inertial pos="{x:.17g} 0.004 0" mass="{m:.17g}" fullinertia="{i} {i} {j} 1e-5 0 0"/>'


def _link(length, mass):
    return INERTIAL.format(x=length / 2, m=mass, i=mass * length**2 / 12, j=mass * length**2 / 10)


def _three_rrr() -> str:
    """Planar 3-RRR drawn assembled: base pivots on a 0.3 m circle, 0.2 m links, a
    triangular platform (0.08 m circumradius) carried by leg 1, legs 2, 3 connected to
    its vertices. All joints about z, ``ref = 0`` (q = 0 as drawn)."""
    angles = np.deg2rad([90.0, 210.0, 330.0])
    base = 0.3 * np.stack([np.cos(angles), np.sin(angles)], -1)
    centre, phi, lengths = np.array([0.01, 0.02]), 0.1, (0.2, 0.2)
    vertices = centre + 0.08 * np.stack([np.cos(angles + phi), np.sin(angles + phi)], -1)
    legs, connects = "", ""
    for i in range(3):
        d = vertices[i] - base[i]
        r = np.linalg.norm(d)
        alpha = np.arccos((lengths[0] ** 2 + r**2 - lengths[1] ** 2) / (2 * lengths[0] * r))
        theta1 = np.arctan2(d[1], d[0]) + alpha
        elbow = base[i] + lengths[0] * np.array([np.cos(theta1), np.sin(theta1)])
        theta2 = np.arctan2(*(vertices[i] - elbow)[::-1])
        platform = ""
        if i == 0:
            local = [
                np.array([[np.cos(phi), np.sin(phi)], [-np.sin(phi), np.cos(phi)]])
                @ (vertices[k] - vertices[0])
                for k in range(3)
            ]
            platform = (
                f'<body name="platform" pos="{lengths[1]} 0 0" euler="0 0 {phi - theta2:.17g}">'
                '<joint name="c1" axis="0 0 1"/>'
                '<inertial pos="0.05 0.02 0" mass="0.6" fullinertia="2e-3 2e-3 3e-3 1e-4 0 0"/>'
                f'<site name="centre" pos="{_fmt(np.r_[local[1] + local[2], 0] / 3)}"/></body>'
            )
        else:
            connects += f'<connect body1="distal{i}" body2="platform" anchor="{lengths[1]} 0 0"/>'
        legs += (
            f'<body name="proximal{i}" pos="{_fmt(np.r_[base[i], 0])}" euler="0 0 {theta1:.17g}">'
            f'<joint name="a{i}" axis="0 0 1"/>{_link(lengths[0], 0.4)}'
            f'<body name="distal{i}" pos="{lengths[0]} 0 0" euler="0 0 {theta2 - theta1:.17g}">'
            f'<joint name="b{i}" axis="0 0 1"/>{_link(lengths[1], 0.3)}{platform}</body></body>'
        )
    motors = "".join(f'<motor joint="a{i}"/>' for i in range(3))
    return (
        f"{HEAD}<worldbody>{legs}</worldbody><equality>{connects}</equality>"
        f"<actuator>{motors}</actuator></mujoco>"
    )


def _rusr() -> str:
    """Spatial RUSR: a crank on a z-hinge, a coupler on a universal joint (two hinges)
    at its end, ball-connected to a rocker on an x-hinge."""
    crank_end, pivot = np.array([0.1, 0.0, 0.0]), np.array([0.05, 0.25, 0.12])
    rocker_end = pivot + 0.12 * np.array([0.0, np.cos(-2.0), np.sin(-2.0)])
    along = rocker_end - crank_end
    length = np.linalg.norm(along)
    x = along / length
    y = np.cross([0.0, 0.0, 1.0], x)
    y /= np.linalg.norm(y)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.stack([x, y, np.cross(x, y)], -1).ravel())
    rocker_quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(rocker_quat, np.array([1.0, 0.0, 0.0]), -2.0)
    body = (
        '<body name="crank"><joint name="crank" axis="0 0 1"/>'
        f'{_link(0.1, 0.5)}<body name="coupler" pos="0.1 0 0" quat="{_fmt(quat)}">'
        '<joint name="u1" axis="0 1 0"/><joint name="u2" axis="0 0 1"/>'
        f"{_link(length, 0.3)}</body></body>"
        f'<body name="rocker" pos="{_fmt(pivot)}" quat="{_fmt(rocker_quat)}">'
        '<joint name="rocker" axis="1 0 0"/><inertial pos="0.0 0.06 0.01" mass="0.4" '
        'fullinertia="1e-3 5e-4 1e-3 0 0 1e-5"/></body>'
    )
    loop = f'<connect body1="coupler" body2="rocker" anchor="{length:.17g} 0 0"/>'
    return (
        f"{HEAD}<worldbody>{body}</worldbody><equality>{loop}</equality>"
        '<actuator><motor joint="crank"/></actuator></mujoco>'
    )


CLOSED_CHAINS = {"3rrr": (_three_rrr, (0.25, -0.2, 0.15), 3), "rusr": (_rusr, (0.6,), 3)}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CLOSED_CHAINS))
def test_closed_chains_match_mujoco(name):
    """A quintic move of the actuated joints, loops closed by Newton at every instant:
    |Φ| < 1e-12 m (rates to 1e-10), and the shaking wrench equals MuJoCo C's base
    reaction of the user's file to 1e-9. Out-of-reach inputs: mask False, ValueError."""
    make, step, rows = CLOSED_CHAINS[name]
    xml = make()
    robot = from_mjcf(xml)
    assert robot.closure_count() == len(robot.dependent) and len(robot.closure_rows[0]) in (2, 3)
    u0 = robot.reference[np.asarray(robot.independent)]
    motion = closure_samples(robot, u0, u0 + jnp.asarray(step), 0.2, 21)
    ours, (phi, phi_d, phi_dd) = _wrenches(robot, *motion)
    assert float(jnp.max(jnp.abs(phi))) < 1e-12
    assert float(jnp.max(jnp.abs(phi_d))) < 1e-10 and float(jnp.max(jnp.abs(phi_dd))) < 1e-9
    assert _relative(ours, _mujoco_reaction(xml, *motion)) < 1e-9
    with pytest.raises(ValueError, match="leaves the mechanism's reach"):
        closure_samples(robot, u0, u0 + rows, 0.2, 21)  # the legs cannot follow


# --- bad files, names and values ----------------------------------------------------------

ARM = (
    '<body name="l1"><joint name="j1" axis="0 0 1"/><inertial pos="0.1 0 0" mass="1" '
    'diaginertia="1e-3 1e-2 1e-2"/><site name="s1" pos="0.2 0 0"/>'
    '<body name="l2" pos="0.2 0 0"><joint name="j2" axis="0 0 1" {joint}/>{inside}'
    '<inertial pos="0.1 0 0" mass="1" diaginertia="1e-3 1e-2 1e-2"/></body></body>'
)


def _arm(tail: str = "", joint: str = "", before: str = "", inside: str = "") -> str:
    """A two-link arm; ``joint``: attributes of joint j2, ``inside``: elements of l2,
    ``before``: world elements, ``tail``: elements after the worldbody."""
    arm = ARM.format(joint=joint, inside=inside)
    return f"{HEAD}<worldbody>{before}{arm}</worldbody>{tail}</mujoco>"


BAD_FILES = {
    "malformed XML": ("<mujoco><worldbody><body></worldbody></mujoco>", "could not compile"),
    "missing file": ("/no/such/robot.xml", "no such MJCF/URDF file"),
    "tendon": (
        _arm('<tendon><fixed name="coupling"><joint joint="j1" coef="1"/></fixed></tendon>'),
        "tendons are not supported: \\['coupling'\\]",
    ),
    "free joint": (
        _arm(before='<body name="float"><freejoint name="fly"/><geom size="0.1"/></body>'),
        "free joint 'fly'",
    ),
    "weld": (_arm('<equality><weld name="glue" body1="l1" body2="l2"/></equality>'), "'glue'"),
    "inactive connect": (
        _arm(
            '<equality><connect name="off" body1="l2" anchor="0.2 0 0" active="false"/></equality>'
        ),
        "'off' is inactive",
    ),  # fmt: skip
    "site actuator": (
        _arm('<actuator><motor name="push" site="s1" gear="1 0 0 0 0 0"/></actuator>'),
        "actuator 'push' drives a site",
    ),
    "armature": (_arm(joint='armature="0.1"'), "joint 'j2' has armature"),
    "mocap": (
        _arm(before='<body name="target" mocap="true"><geom size="0.1"/></body>'),
        "mocap body 'target'",
    ),
    "connect off the plane": (
        _arm(
            '<equality><connect name="lift" site1="end" site2="pin"/></equality>',
            inside='<site name="end" pos="0.2 0 0.1"/>',
            before='<site name="pin" pos="0.3 0 0"/>',
        ),
        "connect 'lift' can never close: its anchors are .* apart",
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_FILES))
def test_bad_files_are_refused_with_a_clear_message(case):
    source, message = BAD_FILES[case]
    with pytest.raises(ValueError, match=message):
        from_mjcf(source)


def test_bad_names_and_singular_closures():
    """Unknown or unsuitable names list the valid ones; a closed chain without
    actuators asks for them; closure equations that do not match the dependent
    coordinates are refused; a singular closure (the loop anchored on the axis of a
    dependent joint) gives a False mask and an eager ValueError."""
    with pytest.raises(ValueError, match="unknown joint 'jx'; joints: \\['a', 'pa'"):
        from_mjcf(FIVE_BAR, actuated="a,jx")
    with pytest.raises(ValueError, match="unknown site 'hand'; sites: \\['tip'\\]"):
        from_mjcf(FIVE_BAR, end_effector_site="hand")
    with pytest.raises(ValueError, match="unknown body 'floor'; bodies: \\['crank_a'"):
        from_mjcf(FIVE_BAR, payload_body="floor")
    with pytest.raises(ValueError, match="name the actuated joints"):
        from_mjcf(FIVE_BAR.replace(MOTORS, ""))
    with pytest.raises(ValueError, match="2 equations for 3 unknowns"):
        from_mjcf(FIVE_BAR, actuated="a").closure(jnp.array([2.3]))
    without_site = from_mjcf(FIVE_BAR.replace('<site name="tip" pos="0.3 0 0"/>', ""))
    with pytest.raises(ValueError, match="no end-effector site"):
        without_site.end_effector(jnp.zeros(4))
    # distal_a's end is connected at its own hinge axis: Φ does not depend on pa.
    singular = from_mjcf(FIVE_BAR.replace('anchor="0.3 0 0"', 'anchor="0 0 0"'))
    q, valid = singular.closure(jnp.array([2.3, 0.9]), return_valid=True)
    assert not bool(valid) and q.shape == (4,)
    with pytest.raises(ValueError, match="not converge"):
        singular.closure(jnp.array([2.3, 0.9]))


def test_counter_masses_and_design_variables():
    """add_counter_mass registers design variables; with_design/with_body change the
    right leaves; bounds; the MuJoCo tree welds counter-masses; errors name the body."""
    robot = from_mjcf(FIVE_BAR, end_effector_site="tip", payload_body="distal_a")
    assert set(robot.design()) == {"payload"}
    robot = add_counter_mass(robot, "crank_a", (-0.1, 0.0, 0.0), 0.5)
    robot = add_counter_mass(robot, "crank_a", (0.0, 0.1, 0.0), 0.1, name="extra")
    design = robot.design()
    assert design["counter_mass"].shape == (2,) and design["counter_position"].shape == (2, 3)
    assert robot.mass_names()[-2:] == ("counter_crank_a", "extra")
    lower = robot.design_lower_bounds()
    assert lower["counter_mass"] == 0.0 and lower["counter_position"] <= -10.0
    changed = robot.with_design({"payload": 1.5, "counter_mass": jnp.array([0.2, 0.3])})
    assert float(changed.mass[changed.body_index("distal_a")]) == 1.5
    np.testing.assert_allclose(changed.mass_properties().mass[-2:], [0.2, 0.3])
    heavier = robot.with_body("crank_b", mass=2.0, com=jnp.array([0.05, 0.0, 0.0]))
    assert float(heavier.mass_properties().mass[heavier.body_index("crank_b")]) == 2.0
    tree = robot.mujoco_tree()
    names = [b.name for b in tree.bodies]
    assert names[:3] == ["crank_a", "counter_crank_a", "extra"]
    assert tree.actuated == ("a", "b") and tree.connects[0].body1 == "distal_a"
    with pytest.raises(ValueError, match="'world' is fixed to the base|'world' is not a body"):
        add_counter_mass(robot, "world", (0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="already taken"):
        add_counter_mass(robot, "crank_b", (0, 0, 0), 1.0, name="extra")
    with pytest.raises(ValueError, match="non-negative"):
        add_counter_mass(robot, "crank_b", (0, 0, 0), -1.0)
    with pytest.raises(ValueError, match="is a counter-mass"):
        robot.with_body("extra", mass=1.0)


def test_a_move_between_two_configurations_is_the_move_between_their_poses(five_bar):
    """configuration_samples between the five-bar's first and last configurations of
    the fixture's move (given by the independent cranks, or by every coordinate) is that
    move (the same line between the same poses: q, q̇, q̈ to 1e-9); a configuration of
    the wrong length names the independent joints, one off its loops is refused."""
    from jaxbal.robots.mjcf_balancing import configuration_samples

    robot, motion = five_bar
    cranks = np.asarray(robot.independent_coordinates)
    for first, last in ((motion.q[0][cranks], motion.q[-1][cranks]), (motion.q[0], motion.q[-1])):
        again = configuration_samples(robot, first, last, 0.25, 41)
        for ours, theirs in zip(again, motion, strict=True):
            np.testing.assert_allclose(ours, theirs, atol=1e-9)
    with pytest.raises(
        ValueError, match=r"start must be 4 finite .* 2 independent ones, \['a', 'b'\]"
    ):
        configuration_samples(robot, [0.1, 0.2, 0.3], motion.q[-1][cranks], 0.25, 5)
    with pytest.raises(ValueError, match="end does not close the loops"):
        configuration_samples(robot, motion.q[0], motion.q[-1] + 0.1, 0.25, 5)


def test_counter_masses_written_into_the_users_own_file(five_bar, tmp_path):
    """export_balanced writes the five-bar's two counter-masses (one with an inertia)
    into the user's MJCF text: MuJoCo C's base reaction on that file (mj_inverse, no
    jaxbal kinematics) equals jaxbal's wrench of the robot (1e-9); the text keeps the
    file's own elements; a robot changed besides its counter-masses is refused and no
    file is left behind."""
    from jaxbal.robots import export_balanced

    robot, motion = five_bar
    path = tmp_path / "five_bar_balanced.xml"
    text = export_balanced(FIVE_BAR, robot, path)
    assert (
        path.read_text() == text and text.count("<body name=") == FIVE_BAR.count("<body name=") + 2
    )
    ours, _ = _wrenches(robot, *motion)
    assert _relative(ours, _mujoco_reaction(text, *motion)) < 1e-9
    changed = robot.with_body("distal_b", mass=1.0)
    with pytest.raises(ValueError, match="changed besides its counter-masses"):
        export_balanced(FIVE_BAR, changed, tmp_path / "refused.xml")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["five_bar_balanced.xml"]


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_balance_reports_the_bounds_it_reached(five_bar):
    """Counter positions boxed in ±2 cm (the start, outside, moved onto the box): the
    cranks' counter-masses need 0.5-1 m arms (unboxed optimum, interior: at_bound all
    0), so the optimum sits on the box in x and y (-1/+1 marks, values exactly on it)
    and z, on which the planar force does not depend, stays inside; the boxed peak
    force stays well above the unboxed one (> 10x)."""
    from jaxbal._src.robots.mjcf_balance import balance

    robot, motion = five_bar
    box = {"lower": {"counter_position": -0.02}, "upper": {"counter_position": 0.02}}
    boxed, free = balance(robot, motion, **box), balance(robot, motion)
    assert not np.any(free.solution.at_bound["counter_position"])
    assert np.all(np.abs(free.robot.design()["counter_position"][:, 0]) > 0.5)
    sides = boxed.solution.at_bound["counter_position"]
    position = np.asarray(boxed.robot.design()["counter_position"])
    assert np.all(sides[:, :2] != 0) and np.all(sides[:, 2] == 0)
    np.testing.assert_array_equal(position[:, :2], 0.02 * sides[:, :2])
    assert boxed.peak_force[1] > 10 * free.peak_force[1]


# --- command line ------------------------------------------------------------------------


@pytest.mark.slow
def test_cli_balance_force_balances_the_five_bar(tmp_path):
    """``jaxbal balance`` prints the peaks of a quintic move and a counter-mass design
    whose peak shaking force is below 1e-9 of the unbalanced one (``--conditions``: and
    the six force-balancing conditions, which the design meets); bad input exits 2."""
    from jaxbal._src.cli import app

    path = tmp_path / "five_bar.xml"
    path.write_text(FIVE_BAR)
    runner = CliRunner()
    options = ["--actuated", "a,b", "--site", "tip", "--duration", "0.25", "--samples", "41"]
    poses = ["--start", "-0.05,0.33", "--end", "0.06,0.40"]
    result = runner.invoke(app, ["balance", str(path), *options, *poses])
    assert result.exit_code == 0, result.output
    values = {}
    for line in result.output.splitlines():
        for key in ("peak shaking force", "balanced peak shaking force"):
            if line.startswith(key + " "):
                values[key] = float(line.split()[-2])
    assert values["peak shaking force"] > 1.0
    assert values["balanced peak shaking force"] < 1e-9 * values["peak shaking force"]
    assert all(body in result.output for body in ("crank_a", "distal_a", "crank_b", "distal_b"))
    assert "force-balancing conditions" not in result.output
    with_conditions = runner.invoke(app, ["balance", str(path), *options, *poses, "--conditions"])
    assert with_conditions.exit_code == 0, with_conditions.output
    lines = with_conditions.output.splitlines()
    assert "force-balancing conditions along the move (6):" in lines
    assert float(lines[-1].split()[-1]) < 1e-9  # the co-designed design meets them
    assert "[!]" not in result.output  # nothing on a bound, no worse than unbalanced
    boxed = runner.invoke(app, ["balance", str(path), *options, *poses, "--position-bound", "0.02"])
    assert boxed.exit_code == 0, boxed.output
    assert boxed.output.count("xy on a bound") == 4 and "widen --position-bound" in boxed.output
    assert "exceeds the robot's without counter-masses" in boxed.output  # fixed masses
    bad = runner.invoke(app, ["balance", str(path), "--actuated", "a,zz", *poses])
    assert bad.exit_code == 2 and "unknown joint 'zz'" in bad.output


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_armature_is_refused_unless_ignored_also_by_the_cli(tmp_path):
    """Joint armature (MuJoCo Menagerie's arms have it) is refused by default, by
    ``from_mjcf`` and by ``jaxbal balance``; ignored on request, the robot's shaking
    wrench is that of the same file without armature (a rotor inertia without a body
    adds nothing to the base reaction jaxbal models), and the command runs from the
    arm drawn straight (a singular start of its inverse kinematics). A pose of the wrong
    length names its components."""
    from jaxbal._src.cli import app

    tip = '<site name="tip" pos="0.2 0 0"/>'
    with_armature = _arm(joint='armature="0.1"', inside=tip)
    robot = from_mjcf(with_armature, ignore_armature=True, end_effector_site="tip")
    plain = from_mjcf(_arm(inside=tip), end_effector_site="tip")
    state = (jnp.array([0.3, 1.1]), jnp.array([1.5, -2.0]), jnp.array([4.0, 3.0]))
    for ours, reference in zip(
        jaxbal.shaking_wrench(robot, *state), jaxbal.shaking_wrench(plain, *state), strict=True
    ):
        np.testing.assert_array_equal(ours, reference)
    assert robot.pose_labels() == ("tip.x", "tip.y")
    with pytest.raises(
        ValueError, match=r"shape \(2,\), got \(3,\): the components are tip.x, tip.y"
    ):
        robot.inverse_kinematics(jnp.array([0.3, 0.2, 0.0]))
    path = tmp_path / "arm.xml"
    path.write_text(with_armature)
    runner = CliRunner()
    move = ["balance", str(path), "--site", "tip", "--start", "0.3,0.2", "--end", "0.25,0.25"]
    refused = runner.invoke(app, [*move, "--samples", "11"])
    assert refused.exit_code == 2 and "--ignore-armature" in refused.output
    result = runner.invoke(app, [*move, "--samples", "11", "--ignore-armature"])
    assert result.exit_code == 0, result.output
    assert "balanced peak shaking force" in result.output


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_cli_balance_prints_the_frames_residual_vibration(tmp_path):
    """``--base-mass``/``--base-frequency``: the frame's residual vibration printed for
    the arm's move equals ``jaxbal.vibration``'s of the same motion of the arm without
    counter-masses (a 300 kg frame at 5 Hz on x, y, z springs carrying the arm; 6
    significant figures printed), and balancing lowers it; one without the other, or a
    frequency ≤ 0, exits 2 naming it."""
    from jaxbal._src.cli import app
    from jaxbal.vibration import BaseVibration, rigid_base

    tip = '<site name="tip" pos="0.2 0 0"/>'
    path = tmp_path / "arm.xml"
    path.write_text(_arm(inside=tip))
    move = ["balance", str(path), "--site", "tip", "--start", "0.3,0.2", "--end", "0.25,0.25"]
    move += ["--samples", "11", "--duration", "0.2"]
    runner = CliRunner()
    result = runner.invoke(app, [*move, "--base-mass", "300", "--base-frequency", "5"])
    assert result.exit_code == 0, result.output
    line = next(x for x in result.output.splitlines() if x.startswith("residual vibration"))
    printed = [float(v) for v in re.findall(r"([-+\d.e]+) µm", line)]
    robot = from_mjcf(_arm(inside=tip), end_effector_site="tip")
    motion = pose_samples(robot, jnp.array([0.3, 0.2]), jnp.array([0.25, 0.25]), 0.2, 11)
    frame = rigid_base(300.0, 5.0, 0.02, axes=("x", "y", "z"))
    metric = BaseVibration(frame, jaxbal.sample_times(0.2, 11), carries_robot=True)
    expected = float(metric(robot, motion)) * 1e6
    assert printed[0] == pytest.approx(expected, rel=1e-5) and expected > 0.1
    assert printed[1] < printed[0]
    half = runner.invoke(app, [*move, "--base-mass", "300"])
    assert half.exit_code == 2 and "--base-mass and --base-frequency go together" in half.output
    bad = runner.invoke(app, [*move, "--base-mass", "300", "--base-frequency", "-5"])
    assert bad.exit_code == 2 and "base frequencies must be finite and > 0" in bad.output


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_keyframe_reference_and_a_singular_start_named_with_its_remedies():
    """``keyframe=`` starts the Newton solves from a ``<key>`` (unknown names listed).
    A move whose pose equations are singular at the start (two coaxial hinges: the
    tip depends on their sum only) is refused with the reason and the remedies."""
    tip = '<site name="tip" pos="0.2 0 0"/>'
    key = '<keyframe><key name="bent" qpos="0.4 0.9"/></keyframe>'
    robot = from_mjcf(_arm(key, inside=tip), keyframe="bent")
    np.testing.assert_array_equal(np.asarray(robot.reference), [0.4, 0.9])
    with pytest.raises(ValueError, match=r"unknown keyframe 'home'; keyframes: \['bent'\]"):
        from_mjcf(_arm(key, inside=tip), keyframe="home")
    coaxial = _arm(inside=tip).replace('<body name="l2" pos="0.2 0 0">', '<body name="l2">')
    # the tip's x and y move together (only q1 + q2 counts): the default pose is x and
    # the joint j2, a regular choice, and the singular (x, y) is refused at load
    assert from_mjcf(coaxial, end_effector_site="tip").pose_labels() == ("tip.x", "j2")
    with pytest.raises(ValueError, match="pose_components"):
        from_mjcf(coaxial, end_effector_site="tip", pose_components=(0, 1))
    # singular at the start: three joints, the first two coaxial, j3 held as ik_free
    third = (
        '<body name="l3" pos="0.2 0 0"><joint name="j3" axis="0 0 1"/>'
        '<inertial pos="0.1 0 0" mass="1" diaginertia="1e-3 1e-2 1e-2"/>'
        '<site name="tip" pos="0.2 0 0"/></body>'
    )
    xml = _arm(key, inside=third).replace('<body name="l2" pos="0.2 0 0">', '<body name="l2">')
    robot = from_mjcf(xml, end_effector_site="tip", keyframe="bent")
    start = robot.end_effector(robot.reference)
    with pytest.raises(ValueError, match="singular configuration of the pose tip.x, tip.y, j3"):
        pose_samples(robot, start, start + 0.01, 0.1, 5)


def test_a_singular_start_names_a_regular_ik_free_choice():
    """A planar 3-joint arm whose first two hinges are coaxial, its pose the tip and
    (default) j3: with j3 given, j1 and j2 only move the tip through their sum, so the
    pose equations are singular at every configuration; the error names a regular
    choice (j2; j1 would do too), under which the pose equations are well conditioned."""
    third = (
        '<body name="l3" pos="0.2 0 0"><joint name="j3" axis="0 0 1"/>'
        '<inertial pos="0.1 0 0" mass="1" diaginertia="1e-3 1e-2 1e-2"/>'
        '<site name="tip" pos="0.2 0 0"/></body>'
    )
    key = '<keyframe><key name="bent" qpos="0.3 0.2 0.5"/></keyframe>'
    xml = _arm(key, inside=third).replace('<body name="l2" pos="0.2 0 0">', '<body name="l2">')
    robot = from_mjcf(xml, end_effector_site="tip", keyframe="bent")
    assert robot.pose_labels() == ("tip.x", "tip.y", "j3")
    # the hint of the move's error (its path is the keyframe test's); no Newton compiled
    hint = _singular_start(robot)
    assert "singular configuration of the pose tip.x, tip.y, j3" in hint
    assert "e.g. ik_free=('j2',) (--ik-free j2)" in hint
    regular = from_mjcf(xml, end_effector_site="tip", keyframe="bent", ik_free=["j2"])
    jacobian = jax.jacfwd(lambda q: pose_equations(regular, q))(regular.reference)
    singular = np.linalg.svd(np.asarray(jacobian), compute_uv=False)
    assert singular[-1] > 0.01 * singular[0]  # well conditioned, not only regular


def test_four_bar_tree_on_a_fixed_frame_with_a_world_connect():
    """A four-bar written as a serial 3R on a fixed, rotated frame body, its tip
    connected to a world point. Its MuJoCo tree hangs the crank from the base at its
    world pose and closes the loop on the base: MuJoCo's ``xpos``/``xmat`` of the
    exported model equal jaxbal's body frames (1e-12) and the connect residual
    (``efc_pos``) vanishes at the drawn configuration."""
    xml = (
        f'{HEAD}<worldbody><body name="frame" pos="0.05 -0.02 0.1" euler="0 0 0.3">'
        '<body name="crank" pos="0.02 0 0"><joint name="crank" axis="0 0 1"/>'
        f'{_link(0.1, 0.3)}<body name="coupler" pos="0.1 0 0" euler="0 0 1.2">'
        f'<joint name="coupler" axis="0 0 1"/>{_link(0.3, 0.5)}'
        '<body name="rocker" pos="0.3 0 0" euler="0 0 -2.1"><joint name="rocker" axis="0 0 1"/>'
        f"{_link(0.25, 0.4)}</body></body></body></body></worldbody>"
        '<equality><connect body1="rocker" anchor="0.25 0 0"/></equality>'
        '<actuator><motor joint="crank"/></actuator></mujoco>'
    )
    robot = from_mjcf(xml)
    assert robot.mass_names() == ("crank", "coupler", "rocker") and robot.closure_count() == 2
    tree = robot.mujoco_tree()
    assert tree.bodies[0].parent is None and tree.connects[0].body2 is None
    model = mujoco.MjModel.from_xml_string(export_mjcf(robot))
    data = mujoco.MjData(model)
    frames = jax.jit(lambda x: robot.body_frames(x))
    for q in (robot.reference, robot.reference + jnp.array([0.4, -0.3, 0.2])):
        data.qpos[:] = tree.coordinates(q)
        mujoco.mj_forward(model, data)
        origins, rotations = frames(q)
        for k, name in enumerate(robot.mass_names()):
            np.testing.assert_allclose(origins[k], data.body(name).xpos, atol=1e-12)
            np.testing.assert_allclose(rotations[k].ravel(), data.body(name).xmat, atol=1e-12)
        if q is robot.reference:
            assert data.nefc == 3 and np.max(np.abs(data.efc_pos)) < 1e-12


def test_ik_from_a_far_reference_does_not_pass_through_the_base():
    """A revolute–slide arm (tip at radius 0.3 + s, angle j1) asked for a tip straight
    up from its reference q = 0 (tip along x). A full Newton step lands the tip near the
    base (radius ~ 1e-6), a near-singularity from which plain Newton threw j1 to
    ~ -3e16 rad or ~ 5e4 rad; with step halving the inverse kinematics converges to the
    closed form j1 = atan2(y, x), s = |p| - 0.3."""
    xml = (
        '<mujoco><worldbody><body name="l1"><joint name="j1" axis="0 0 1"/>'
        f"{_link(0.1, 1.0)}"
        '<body name="l2" pos="0.2 0 0"><joint name="s2" type="slide" axis="1 0 0"/>'
        f'{_link(0.05, 1.0)}<site name="tip" pos="0.1 0 0"/></body></body>'
        "</worldbody></mujoco>"
    )
    robot = from_mjcf(xml)
    for target in ([0.0, 0.35], [2.95518e-06, 0.349996552]):
        q, valid = robot.inverse_kinematics(jnp.array(target), return_valid=True)
        assert bool(valid)
        expected = [np.arctan2(target[1], target[0]), np.hypot(*target) - 0.3]
        np.testing.assert_allclose(np.asarray(q), expected, atol=1e-10)


@pytest.mark.parametrize(
    "attributes, named",
    [
        ('damping="2"', "damping 2"),
        ('stiffness="30" springref="0.5"', "stiffness 30"),
        ('frictionloss="1.5"', "frictionloss 1.5"),
    ],
)
def test_passive_joint_forces_are_refused_unless_ignored(attributes, named, tmp_path):
    """Joint damping, a spring or friction loss change the torques the motors must give
    (MuJoCo's ``qfrc_inverse`` differs from the inertial torques by them) but not the
    base reaction. jaxbal's torques leave them out, so a file with them is refused by
    ``from_mjcf`` and ``jaxbal balance``, unless ignored: the wrench is then that of the
    file without them. Disabled by the option flags, they are not refused."""
    from jaxbal._src.cli import app

    tip = '<site name="tip" pos="0.2 0 0"/>'
    xml = _arm(joint=attributes, inside=tip)
    with pytest.raises(ValueError, match=f"joint 'j2' has {named}: a passive joint force"):
        from_mjcf(xml, end_effector_site="tip")
    robot = from_mjcf(xml, ignore_passive=True, end_effector_site="tip")
    plain = from_mjcf(_arm(inside=tip), end_effector_site="tip")
    q, qd, qdd = jnp.array([0.3, 1.1]), jnp.array([1.5, -2.0]), jnp.array([4.0, 3.0])
    for ours, reference in zip(
        jaxbal.shaking_wrench(robot, q, qd, qdd), jaxbal.shaking_wrench(plain, q, qd, qdd),
        strict=True,
    ):  # fmt: skip
        np.testing.assert_array_equal(ours, reference)
    # what was left out: MuJoCo's inverse dynamics of the file has the passive force
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    data.qpos[:], data.qvel[:], data.qacc[:] = q, qd, qdd
    mujoco.mj_inverse(model, data)
    torques = jaxbal.actuator_torques(robot, q, qd, qdd)
    assert abs(data.qfrc_inverse[1] - float(torques[1])) > 0.5
    flags = '<flag damper="disable" spring="disable" frictionloss="disable"/></option>'
    disabled = xml.replace('<option gravity="0 0 0"/>', f'<option gravity="0 0 0">{flags}', 1)
    from_mjcf(disabled, end_effector_site="tip")
    path = tmp_path / "arm.xml"
    path.write_text(xml)
    refused = CliRunner().invoke(app, ["balance", str(path), "--site", "tip", "--start",
                                       "0.3,0.2", "--end", "0.25,0.25"])  # fmt: skip
    assert refused.exit_code == 2 and "--ignore-passive" in refused.output


SLIDER_CRANK = """
<mujoco><compiler angle="radian"/><option gravity="0 0 0"/><worldbody>
<body name="crank" euler="0 0 1.0471975511965976"><joint name="a" axis="0 0 1"/>
 <inertial pos="0.03 0.005 0" mass="0.5" diaginertia="1e-4 1e-3 1e-3"/>
 <body name="rod" pos="0.1 0 0" euler="0 0 -1.3400403229251732"><joint name="p" axis="0 0 1"/>
  <inertial pos="0.12 0 0.01" mass="0.3" diaginertia="1e-5 2e-3 2e-3"/></body></body>
<body name="slider" pos="0.3372281323269014 0 0"><joint name="s" type="slide" axis="1 0 0"/>
 <inertial pos="0 0 0" mass="1.2" diaginertia="1e-3 1e-3 1e-3"/><site name="tip"/></body>
</worldbody><equality><connect body1="slider" body2="rod" anchor="0 0 0"/></equality>
<actuator><motor joint="a"/></actuator></mujoco>
"""


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_closed_chains_end_is_closed_from_its_start(tmp_path):
    """A slider-crank's crank from 120 to 175 degrees (one assembly mode, no dead centre):
    the end's independent coordinate was closed from the model's reference, landed in
    the other assembly mode, and the move was refused as leaving the reach."""
    from jaxbal.robots.mjcf_balancing import configuration_samples

    path = tmp_path / "slider_crank.xml"
    path.write_text(SLIDER_CRANK)
    robot = jaxbal.robots.from_mjcf(path)
    motion = configuration_samples(robot, [1.0472], [2.0], 0.1, 21)
    start = robot.closure(jnp.array([1.0472]))
    end = robot.closure(jnp.array([2.0]), guess=start)
    np.testing.assert_allclose(motion.q[-1], end, atol=1e-9)
    np.testing.assert_allclose(motion.q[0], start, atol=1e-9)
