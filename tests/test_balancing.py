"""Balancing conditions from the linear-in-parameters wrench (jaxbal.balancing).

References: :func:`jaxbal.shaking_wrench` (an independent evaluation: the derivative of
the bodies' momentum, against Newton–Euler on the frames here; 1e-12 of the wrench's
gross scale), the classical complete force-balancing conditions of a planar 2R arm
(Berkof & Lowen 1969: the first moment of everything a joint carries cancels about
it; exact), and the wrench of a robot designed to meet the conditions along another,
unrelated motion (zero to 1e-10 of the unbalanced arm's).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from conftest import slow_for
from test_contract import CASES, _motion

import jaxbal
from jaxbal import balancing
from jaxbal.design import Motion, motion_samples

L1, L2, R1, R2 = 0.4, 0.3, 0.5, 0.4


def _arm(counter_masses=(0.0, 0.0)):
    return jaxbal.robots.PlanarArm(
        lengths=np.array([L1, L2]),
        com_ratios=np.array([R1, R2]),
        masses=np.array([2.0, 1.0]),
        inertias=np.array([0.03, 0.01]),
        payload=0.5,
        counter_masses=np.asarray(counter_masses, dtype=float),
        counter_distances=np.array([0.1, 0.1]),
    )


def _sines(frequencies, phases, samples=400):
    """A generic joint motion: each joint a sine of its own frequency [Hz]."""
    t = jnp.linspace(0.0, 1.0, samples)[:, None]
    omega, phase = 2 * jnp.pi * jnp.asarray(frequencies), jnp.asarray(phases)
    q = jnp.sin(omega * t + phase)
    return Motion(q, omega * jnp.cos(omega * t + phase), -(omega**2) * q)


def _gross(y, pi):
    """Largest ``Σ_k |Y_k π_k|`` over samples and components (rounding scale)."""
    return float(np.max(np.abs(np.asarray(y)) @ np.abs(pi)))


# the closed-chain DUAL-V here (the 2R's regressor is checked exactly by its
# Berkof-Lowen conditions below); the others in make test-all
@pytest.mark.parametrize(
    "name", slow_for(sorted(CASES), "orthoglide", "planar_2r", "planar_3r", "scara")
)
def test_linear_wrench_equals_shaking_wrench(name):
    """Newton–Euler on the frames (Y π) equals the momentum derivative of
    shaking_wrench on every robot, closed chains included."""
    robot, path = _motion(name)
    motion = motion_samples(robot, path, jnp.linspace(0.0, 0.2, 50))
    linear = balancing.linear_wrench(robot, motion)
    pi = np.ravel(np.asarray(balancing.lumped_parameters(robot)))
    force, moment = jax.jit(jax.vmap(lambda *s: jaxbal.shaking_wrench(robot, *s)))(*motion)
    for y, direct in ((linear.force, force), (linear.moment, moment)):
        np.testing.assert_allclose(np.asarray(y) @ pi, direct, rtol=0, atol=1e-12 * _gross(y, pi))
    assert len(linear.names) == pi.size == linear.force.shape[-1]


def test_planar_arm_conditions_are_berkof_lowen():
    """Along a generic motion the 2R arm's force conditions are the classical ones, in
    reduced row-echelon form exactly: per joint, the first moment of everything it
    carries (link, counterweight; the payload at the tip) cancels about it."""
    arm = _arm()
    conditions = balancing.balancing_conditions(arm, _sines([2.0, 3.3], [0.1, 0.7]))
    names = list(conditions.names)
    expected = np.zeros((4, len(names)))
    rows = [
        {"link1.h_x": 1, "counterweight1.h_x": 1, "link2.m": L1, "counterweight2.m": L1,
         "payload.m": L1},
        {"link1.h_y": 1, "counterweight1.h_y": 1},
        {"link2.h_x": 1, "counterweight2.h_x": 1, "payload.h_x": 1, "payload.m": L2},
        {"link2.h_y": 1, "counterweight2.h_y": 1, "payload.h_y": 1},
    ]  # fmt: skip
    for row, coefficients in zip(expected, rows, strict=True):
        for name, value in coefficients.items():
            row[names.index(name)] = value
    assert conditions.rank == 4
    np.testing.assert_allclose(conditions.matrix, expected, rtol=0, atol=1e-12)
    assert conditions.equations()[1] == "link1.h_y + counterweight1.h_y = 0"


def test_meeting_the_conditions_balances_every_motion():
    """Counterweights solved from the conditions (found along one motion) cancel the
    shaking force along an unrelated motion, to 1e-10 of the unbalanced arm's."""
    conditions = balancing.balancing_conditions(_arm(), _sines([2.0, 3.3], [0.1, 0.7]))
    m2, mp, d = 1.0, 0.5, 0.1
    cw2 = (m2 * R2 * L2 + mp * L2) / d
    cw1 = (2.0 * R1 * L1 + L1 * (m2 + cw2 + mp)) / d
    balanced = _arm((cw1, cw2))
    np.testing.assert_allclose(conditions.residuals(balanced), 0.0, atol=1e-12)
    assert np.max(np.abs(conditions.residuals(_arm()))) > 0.1
    other = _sines([1.1, 4.7], [2.0, 0.3], samples=300)

    @eqx.filter_jit  # one program for both arms (op by op it took seconds)
    def forces(robot):
        return jax.vmap(lambda *s: jaxbal.shaking_wrench(robot, *s)[0])(*other)

    unbalanced = float(jnp.max(jnp.abs(forces(_arm((cw1 * 0.5, cw2 * 0.5))))))
    assert float(jnp.max(jnp.abs(forces(balanced)))) <= 1e-10 * unbalanced


def test_serial_arm_moment_needs_more_than_counter_masses():
    """The 2R arm's moment condition led by link1.J_zz adds l1² times every mass the
    elbow carries: all coefficients positive, so no counter-mass design of physical
    (positive) masses and inertias cancels the shaking moment (the classical reason
    for counter-rotations)."""
    conditions = balancing.balancing_conditions(_arm(), _sines([2.0, 3.3], [0.1, 0.7]), "moment")
    names = list(conditions.names)
    (index,) = np.flatnonzero(conditions.matrix[:, names.index("link1.J_zz")] == 1.0)
    row = conditions.matrix[index]
    for name in ("link2.m", "counterweight2.m", "payload.m"):
        np.testing.assert_allclose(row[names.index(name)], L1**2, rtol=1e-12)
    assert np.all(row >= 0.0)
    assert conditions.residuals(_arm())[index] > 0


def test_regressor_vmap_equals_loop_and_ignores_masses():
    arm, motion = _arm(), _sines([2.0, 3.3], [0.1, 0.7], samples=6)
    batched = jax.jit(jax.vmap(balancing.wrench_regressor, (None, 0, 0, 0)))(arm, *motion)
    heavier = eqx.tree_at(lambda r: r.masses, arm, arm.masses * 3.0)
    single = jax.jit(balancing.wrench_regressor)  # one program for both robots
    for k in range(6):
        state = [x[k] for x in motion]
        for a, b, c in zip(batched, single(arm, *state), single(heavier, *state), strict=True):
            np.testing.assert_allclose(a[k], b, rtol=1e-14, atol=1e-12)
            np.testing.assert_allclose(c, b, rtol=1e-14, atol=1e-12)


def test_regressor_gradient_in_a_length_is_finite_and_matches_fd():
    motion = _sines([2.0, 3.3], [0.1, 0.7], samples=3)
    state = [x[1] for x in motion]

    def first_force(length):
        arm = eqx.tree_at(lambda r: r.lengths, _arm(), jnp.asarray([length, L2]))
        pi = jnp.ravel(balancing.lumped_parameters(_arm()))
        return (balancing.wrench_regressor(arm, *state)[0] @ pi)[0]

    grad = jax.grad(first_force)(L1)
    step = 1e-6
    fd = (first_force(L1 + step) - first_force(L1 - step)) / (2 * step)
    assert np.isfinite(grad)
    np.testing.assert_allclose(grad, fd, rtol=1e-6)


def test_bad_input_raises():
    arm, motion = _arm(), _sines([2.0, 3.3], [0.1, 0.7], samples=5)
    with pytest.raises(ValueError, match="part must be"):
        balancing.balancing_conditions(arm, motion, "torque")
    with pytest.raises(ValueError, match="rtol must lie"):
        balancing.balancing_conditions(arm, motion, rtol=0.0)
    with pytest.raises(ValueError, match="non-finite state"):
        balancing.linear_wrench(arm, Motion(motion.q.at[2, 0].set(jnp.nan), *motion[1:]))
    with pytest.raises(ValueError, match="q must have shape"):
        balancing.wrench_regressor(arm, jnp.zeros(3), jnp.zeros(2), jnp.zeros(2))
    broken = eqx.tree_at(lambda r: r.lengths, arm, jnp.asarray([jnp.nan, L2]))
    with pytest.raises(ValueError, match="PlanarArm.lengths"):
        balancing.wrench_regressor(broken, *(x[0] for x in motion))
    with pytest.raises(ValueError, match="PlanarArm.lengths"):
        balancing.balancing_conditions(broken, motion)
    with pytest.raises(Exception, match="robot parameters must be finite"):  # under jit
        jax.block_until_ready(
            eqx.filter_jit(balancing.wrench_regressor)(broken, *(x[0] for x in motion))
        )
    negative = eqx.tree_at(lambda r: r.masses, arm, jnp.asarray([-1.0, 1.0]))
    with pytest.raises(ValueError, match="body masses"):
        balancing.lumped_parameters(negative)
    conditions = balancing.balancing_conditions(arm, motion)
    with pytest.raises(ValueError, match="conditions are for"):
        conditions.residuals(jaxbal.robots.scara())


def test_scara_conditions_are_arakelian_briot():
    """Along a generic motion of all four joints the SCARA's force conditions are the
    paper's eqs (1)-(3) and the vertical counterweight's (v), met by the closed-form
    balanced SCARA (robots.scara_balancing.force_balanced) to rounding."""
    from jaxbal.robots import scara_balancing

    scara = jaxbal.robots.scara()
    amplitudes = jnp.asarray([1.0, 1.0, 1.0, 0.05])
    motion = _sines([1.0, 1.7, 2.9, 3.7], [0.1, 0.5, 0.9, 1.3])
    motion = Motion(*(x * amplitudes for x in motion))
    conditions = balancing.balancing_conditions(scara, motion)
    assert conditions.rank == 7
    assert (
        "end_effector.m + payload.m + counter_mass3.m - vertical_counterweight.m = 0"
        in conditions.equations()
    )
    balanced = scara_balancing.force_balanced(scara)
    np.testing.assert_allclose(conditions.residuals(balanced), 0.0, atol=1e-12)
    assert np.max(np.abs(conditions.residuals(scara))) > 0.1


def _dual_v_motion(robot, rotation):
    """A generic platform motion: x, y (and θ5 when ``rotation`` > 0) sines."""
    t = jnp.linspace(0.0, 1.0, 200)[:, None]
    omega = 2 * jnp.pi * jnp.asarray([1.0, 1.7, 2.3])
    phase, amplitude = jnp.asarray([0.2, 0.9, 1.4]), jnp.asarray([0.04, 0.04, rotation])
    u = amplitude * jnp.sin(omega * t + phase)
    ud = amplitude * omega * jnp.cos(omega * t + phase)
    udd = -amplitude * omega**2 * jnp.sin(omega * t + phase)
    # one program (eagerly, the vmapped inverse kinematics ran op by op)
    return Motion(*jax.jit(jax.vmap(lambda *p: jaxbal.pose_motion(robot, *p)))(u, ud, udd))


def test_dual_v_conditions_match_the_paper():
    """van der Wijk et al. (2013), §2: with a non-rotated platform both counter-mass
    designs, eq (1) and eq (2), meet the force conditions (a one-parameter family:
    3 conditions on the 4 counter-mass moments); with platform rotation four more
    conditions involve only the distal links and the platform -- no counter-mass design
    balances it ("motion with a rotated platform is not perfectly force-balanced")."""
    from jaxbal.robots import dual_v_balancing

    robot = jaxbal.robots.dual_v()
    designs = [
        dual_v_balancing.with_counter_mass_moments(robot, equation(robot))
        for equation in (dual_v_balancing.balance_condition_eq1,
                         dual_v_balancing.balance_condition_eq2)
    ]  # fmt: skip
    translation = balancing.balancing_conditions(robot, _dual_v_motion(robot, 0.0))
    assert translation.rank == 6
    for design in designs:
        np.testing.assert_allclose(translation.residuals(design), 0.0, atol=1e-12)
    rotation = balancing.balancing_conditions(robot, _dual_v_motion(robot, 0.2))
    assert rotation.rank == 12
    prefixes = ("counter_mass", "tuning_mass", "rotor")
    balance_masses = np.asarray([name.startswith(prefixes) for name in rotation.names])
    without = [row for row in rotation.matrix if not np.any(row[balance_masses])]
    assert len(without) == 4
    assert np.max(np.abs(rotation.residuals(designs[0]))) > 0.1
