"""The base's vibration (jaxbal.vibration): exact against closed forms of a single
mode (step, ramp at uneven times, overdamped step), the residual amplitude against an
independent Fourier integral of the shaking force, a force-balanced arm leaving the
base still, gradients against finite differences, vmap against a loop, co-design of
the residual vibration, and every bad input refused."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jax.test_util import check_grads

import jaxbal
from jaxbal.planning import com_line
from jaxbal.profiles import BangBang
from jaxbal.robots.planar_arm import force_balanced
from jaxbal.vibration import (
    BaseModes,
    BaseVibration,
    base_response,
    carrying,
    residual_amplitude,
    rigid_base,
)

MASS, FREQUENCY = 200.0, 7.0
OMEGA = 2 * np.pi * FREQUENCY


def _along(axis: int, values):
    """``(t, 3)`` vectors with ``values`` along ``axis``, and zero ``(t, 3)`` moments."""
    force = np.zeros((len(values), 3))
    force[:, axis] = values
    return force, np.zeros_like(force)


def test_step_of_an_undamped_mode_is_one_minus_cosine():
    """x = F/(M ω²)(1 − cos ωt), ẋ = F/(M ω) sin ωt, exact at any step size."""
    times = np.linspace(0.0, 0.5, 41)  # ω h ≈ 0.55: far from a fine grid
    base = rigid_base(MASS, FREQUENCY, 0.0, "x")
    x, v = base_response(base, times, *_along(0, 10.0 + 0 * times))
    scale = 10.0 / (MASS * OMEGA**2)
    expected = scale * (1 - np.cos(OMEGA * times)), scale * OMEGA * np.sin(OMEGA * times)
    np.testing.assert_allclose(x[:, 0], expected[0], rtol=0, atol=1e-13 * scale)
    np.testing.assert_allclose(v[:, 0], expected[1], rtol=0, atol=1e-13 * scale * OMEGA)


def test_ramp_of_a_damped_mode_at_uneven_times():
    """Force b·t on a mode with ζ = 0.05: particular solution plus the decaying
    homogeneous one (closed form), at 50 random instants."""
    zeta, slope = 0.05, 30.0
    times = np.sort(np.r_[0.0, np.random.default_rng(0).uniform(0, 0.3, 50), 0.3])
    x, _ = base_response(rigid_base(MASS, FREQUENCY, zeta, "y"), times, *_along(1, slope * times))
    sigma, damped = zeta * OMEGA, OMEGA * np.sqrt(1 - zeta**2)
    a = slope / MASS
    e0, e0_rate = 2 * zeta * a / OMEGA**3, -a / OMEGA**2  # x(0) − x_p(0), ẋ(0) − ẋ_p(0)
    decay = np.exp(-sigma * times) * (
        e0 * np.cos(damped * times) + (e0_rate + sigma * e0) / damped * np.sin(damped * times)
    )
    exact = a * times / OMEGA**2 - 2 * zeta * a / OMEGA**3 + decay
    np.testing.assert_allclose(x[:, 0], exact, rtol=0, atol=1e-12 * np.max(np.abs(exact)))


def test_step_of_an_overdamped_rotation_mode():
    """ζ = 1.5 about z (a base inertia J): θ = m/(J ω²)(1 + (r₂e^{r₁t} − r₁e^{r₂t})/(r₁ − r₂))."""
    zeta, inertia, torque = 1.5, 40.0, 3.0
    base = rigid_base(MASS, FREQUENCY, zeta, ("rz",), inertia=inertia)
    times = np.linspace(0.0, 0.2, 31)
    moment = np.zeros((31, 3))
    moment[:, 2] = torque
    angle, _ = base_response(base, times, np.zeros((31, 3)), moment)
    r1, r2 = OMEGA * (-zeta + np.sqrt(zeta**2 - 1)), OMEGA * (-zeta - np.sqrt(zeta**2 - 1))
    static = torque / (inertia * OMEGA**2)
    exact = static * (1 + (r2 * np.exp(r1 * times) - r1 * np.exp(r2 * times)) / (r1 - r2))
    np.testing.assert_allclose(angle[:, 0], exact, rtol=0, atol=1e-12 * static)


@pytest.fixture(scope="module")
def move():
    """The 2R's P5→P9 COM bang-bang move (Briot et al. 2012), 401 samples in 0.5 s."""
    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    times = jaxbal.sample_times(0.5, 401)
    motion = jaxbal.design.motion_samples(arm, [com_line(arm, q0, q1, BangBang(), 0.5)], times)
    return arm, np.asarray(times), motion


def _force(robot, motion):
    run = jax.vmap(lambda a, b, c: jaxbal.shaking_wrench(robot, a, b, c))
    return [np.asarray(part) for part in run(*motion)]


def test_residual_amplitude_is_the_fourier_integral_of_the_force(move):
    """After a force that ends, an undamped mode from rest rings with amplitude
    |∫ f(τ) e^{iωτ} dτ| / (M ω) (Duhamel): the integral of the sampled shaking force
    (linear between samples) by a 10⁵-point trapezoid rule, for x and y at 5 and 9 Hz.
    The metric is the norm of the two, and ``kind="peak"`` the largest sampled ‖η‖."""
    arm, times, motion = move
    force, moment = _force(arm, motion)
    base = rigid_base(300.0, [5.0, 9.0], 0.0, ("x", "y"))
    ours = np.asarray(residual_amplitude(base, times, force, moment))
    fine = np.linspace(0.0, times[-1], 100_001)
    expected = []
    for axis, frequency in ((0, 5.0), (1, 9.0)):
        omega = 2 * np.pi * frequency
        integrand = np.interp(fine, times, force[:, axis]) * np.exp(1j * omega * fine)
        expected.append(abs(np.trapezoid(integrand, fine)) / (300.0 * omega))
    np.testing.assert_allclose(ours, expected, rtol=1e-8)
    residual = BaseVibration(base, times)(arm, motion)
    assert float(residual) == pytest.approx(np.hypot(*ours), rel=1e-12)
    x, _ = base_response(base, times, force, moment)
    peak = BaseVibration(base, times, "peak")
    assert float(peak(arm, motion)) == pytest.approx(np.max(np.hypot(x[:, 0], x[:, 1])), rel=1e-12)
    assert peak.__name__ == "peak_vibration" and float(peak(arm, motion)) > 0
    assert repr(peak).endswith("samples=401, carries_robot=False)")  # short, in messages


def test_residual_amplitude_of_a_damped_mode_is_its_envelope(move):
    """After the move a mode of damping ζ rings as the exact free response
    ``η(t) = e^{−ζωt}(η_T cos ω_d t + (η̇_T + ζωη_T)/ω_d sin ω_d t)``: its amplitude is
    the largest ``|η(t)| e^{ζωt}`` over a period, sampled densely from the computed
    ``η_T, η̇_T`` (``sqrt(η_T² + (η̇_T/ω)²)`` was 0.3 % low at ζ = 0.02, 10 % at 0.3).
    A damping ratio ≥ 1 (no ringing) is refused."""
    arm, times, motion = move
    force, moment = _force(arm, motion)
    for zeta in (0.0, 0.02, 0.3, 0.9):
        base = rigid_base(300.0, 5.0, zeta, ("y",))
        eta, rate = (float(v[-1, 0]) for v in base_response(base, times, force, moment))
        omega = 2 * np.pi * 5.0
        damped = omega * np.sqrt(1 - zeta**2)
        t = np.linspace(0.0, 2 * np.pi / damped, 200_001)
        ring = eta * np.cos(damped * t) + (rate + zeta * omega * eta) / damped * np.sin(damped * t)
        ours = float(residual_amplitude(base, times, force, moment)[0])
        assert ours == pytest.approx(np.max(np.abs(ring)), rel=1e-9)
        metric = BaseVibration(base, times)(arm, motion)
        assert float(metric) == pytest.approx(ours, rel=1e-12)
    overdamped = rigid_base(300.0, 5.0, 1.0, ("y",))
    with pytest.raises(ValueError, match="underdamped modes, damping ratio < 1"):
        residual_amplitude(overdamped, times, force, moment)
    with pytest.raises(ValueError, match="underdamped modes"):
        BaseVibration(overdamped, times)
    assert BaseVibration(overdamped, times, "peak")(arm, motion) > 0


def test_a_force_balanced_arm_leaves_the_base_still(move):
    """Counterweights by the closed form (Briot et al. 2012, eq 23): zero shaking force,
    so the translational modes neither move nor ring (1e-12 of the unbalanced arm's)."""
    arm, times, motion = move
    balanced = force_balanced(arm, jnp.array([0.2, 0.2]))
    base = rigid_base(300.0, [5.0, 9.0], 0.02, ("x", "y"))
    for kind in ("residual", "peak"):
        metric = BaseVibration(base, times, kind)
        assert float(metric(balanced, motion)) < 1e-12 * float(metric(arm, motion))


def test_gradients_match_finite_differences_and_vmap_is_a_loop(move):
    """d/d(frequency, damping, participation) of the response by check_grads; the
    metric's gradient w.r.t. the counter-masses agrees with central differences
    (sensitivity(check=True)) and is finite; a vmap over base frequencies equals a loop."""
    arm, times, motion = move
    force, moment = _force(arm, motion)
    t, f, m = times[:80], force[:80], moment[:80]

    def response(frequency, damping, participation):
        base = BaseModes(frequency, damping, participation)
        return residual_amplitude(base, t, f, m) + base_response(base, t, f, m)[0][-1]

    base = rigid_base(300.0, [5.0, 9.0], 0.03, ("x", "y"))
    check_grads(response, (base.frequency, base.damping, base.participation), order=1,
                modes=("fwd", "rev"), rtol=1e-5)  # fmt: skip
    metric = BaseVibration(base, times, carries_robot=True)  # the counter-masses ride too
    study = jaxbal.sensitivity.sensitivity(arm, motion, metric, wrt=("counter_mass",), check=True)
    assert np.all(np.isfinite(study.gradient["counter_mass"]))

    def amplitude(frequency):
        modes = rigid_base(300.0, 1.0, 0.03, ("x", "y"))
        modes = eqx.tree_at(lambda b: b.frequency, modes, jnp.stack([frequency, 2 * frequency]))
        return residual_amplitude(modes, times, force, moment)

    frequencies = jnp.array([3.0, 5.5, 11.0])
    swept = jax.jit(jax.vmap(amplitude))(frequencies)
    looped = np.stack([np.asarray(amplitude(fr)) for fr in frequencies])
    np.testing.assert_allclose(swept, looped, rtol=1e-12)
    # traced times take the step-by-step path (one exponential per step), concrete equal
    # steps one exponential per mode: the same response
    traced = jax.jit(lambda t: base_response(base, t, force, moment)[0])(times)
    np.testing.assert_allclose(traced, base_response(base, times, force, moment)[0], rtol=1e-12,
                               atol=1e-12 * float(np.max(np.abs(traced))))  # fmt: skip


def test_codesign_of_the_residual_vibration(move):
    """Counter-masses co-designed against the residual vibration of a 4 Hz base (a
    hashable metric, a key of the objective): it falls by ≥ 10³, and the design variable
    bounds still hold."""
    arm, times, motion = move
    metric = BaseVibration(rigid_base(300.0, 4.0, 0.02, ("x", "y")), times)
    assert metric == BaseVibration(rigid_base(300.0, 4.0, 0.02, ("x", "y")), times)
    best = jaxbal.design.codesign(arm, motion, {metric: 1.0},
                                  upper={"counter_distance": 0.3})  # fmt: skip
    before, after = best.metrics["residual_vibration"]
    assert after < 1e-3 * before
    assert np.all(best.design["counter_mass"] >= 0)


SHAPE = "shape \\(2, 6\\)"
BAD = {
    "frequency <= 0": (lambda: BaseModes([5.0, -1.0], 0.0, np.ones((2, 6))), "frequencies"),
    "negative damping": (lambda: BaseModes(5.0, -0.1, np.ones((1, 6))), "damping"),
    "participation shape": (lambda: BaseModes([5.0, 6.0], 0.0, np.ones((2, 3))), SHAPE),
    "non-finite participation": (lambda: BaseModes(5.0, 0.0, np.full((1, 6), np.nan)), "finite"),
    "unknown axis": (lambda: rigid_base(100.0, 5.0, axes=("x", "w")), "axes must be distinct"),
    "rotation without inertia": (lambda: rigid_base(100.0, 5.0, axes="rz"), "the base's inertia"),
    "negative mass": (lambda: rigid_base(-1.0, 5.0), "mass must be finite and > 0"),
    "frequencies per axis": (lambda: rigid_base(1.0, [5.0, 6.0, 7.0]), "frequency must be one"),
    "damping per mode": (lambda: BaseModes([5.0, 6.0], [0.1] * 3, np.ones((2, 6))), "damping must"),
    "times not increasing": (
        lambda: base_response(rigid_base(100.0, 5.0), [0.0, 0.2, 0.1], *_along(0, [1.0, 1, 1])),
        "strictly increasing",
    ),
    "force shape": (
        lambda: base_response(rigid_base(100.0, 5.0), [0.0, 0.1], np.ones((3, 3)), np.ones((3, 3))),
        "shape \\(2, 3\\)",
    ),
    "kind": (lambda: BaseVibration(rigid_base(100.0, 5.0), [0.0, 1.0], "rms"), "kind must be"),
    "carrying a rotation": (
        lambda: carrying(rigid_base(100.0, 5.0, axes=("x", "rz"), inertia=3.0), 10.0),
        "translation modes only",
    ),
    "carried rotation": (
        lambda: BaseVibration(
            rigid_base(100.0, 5.0, axes="rz", inertia=3.0), [0.0, 1.0], carries_robot=True
        ),
        "translation modes only",
    ),
    "negative carried mass": (lambda: carrying(rigid_base(100.0, 5.0), -1.0), "carried mass"),
    "carrying an undriven mode": (
        lambda: carrying(BaseModes(5.0, 0.0, np.zeros((1, 6))), 1.0),
        "translation modes only",
    ),
}  # fmt: skip


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_input_is_refused(case):
    make, message = BAD[case]
    with pytest.raises(ValueError, match=message):
        make()


def test_refused_under_jit_and_in_a_motion_of_other_times(move):
    """A frequency made negative by ``eqx.tree_at`` inside ``jit`` raises at run time; a
    motion sampled at other times, and a joint co-design that rescales them, are refused."""
    arm, times, motion = move
    base = rigid_base(300.0, 5.0)
    force, moment = _force(arm, motion)

    @jax.jit
    def spoiled(scale):
        modes = eqx.tree_at(lambda b: b.frequency, base, base.frequency * scale)
        return residual_amplitude(modes, times, force, moment)

    assert np.all(np.isfinite(spoiled(1.0)))
    with pytest.raises(Exception, match="base frequencies must be finite and > 0"):
        spoiled(-1.0).block_until_ready()
    with pytest.raises(ValueError, match="the motion has 401 samples but"):
        BaseVibration(base, times[:100])(arm, motion)
    # the same count at another move's times (it used them silently: 126 for 209 µm)
    with pytest.raises(ValueError, match=r"as if over about 0\.5 s"):
        BaseVibration(base, jaxbal.sample_times(0.7, 401))(arm, motion)
    # a joint angle wrapped by a whole turn between two samples is no mismatch
    wrapped = motion._replace(q=motion.q.at[200:, 0].add(2 * np.pi))
    residual = BaseVibration(base, times)
    assert float(residual(arm, wrapped)) == pytest.approx(float(residual(arm, motion)), rel=1e-9)
    factory = jaxbal.design.TrapezoidLine(
        jnp.array([0.225, 0.25]), jnp.array([0.225, 0.70]), jaxbal.sample_times(1.0, 401)
    )
    theta = {"u2": jnp.asarray(0.3), "ratio": jnp.asarray(0.5), "duration": jnp.asarray(0.5)}
    with pytest.raises(ValueError, match="'duration' rescales them"):
        jaxbal.design.joint_codesign(
            arm, factory, theta, BaseVibration(base, times),
            trajectory_lower={k: 0.5 * v for k, v in theta.items()},
            trajectory_upper={k: 1.5 * v for k, v in theta.items()},
        )  # fmt: skip


def test_a_base_on_springs_in_mujoco_moves_as_predicted():
    """Independent check by MuJoCo C: the 2R (quintic end-effector line) on a 250 kg base
    on x and y slide joints with stiffness and damping. The base's acceleration comes
    from MuJoCo's own dynamics of the whole system (``mj_inverse`` with the joint motion
    prescribed and the base's generalised force zero), integrated by RK4. For a
    translating base the model is exact when its mass includes the robot's (the robot
    rides on it): the displacements agree to 1e-5 (the first-order hold of the sampled
    force); the base's mass alone would be 25 % off."""
    import mujoco

    from jaxbal.mujoco import export_mjcf
    from jaxbal.profiles import Quintic

    arm = jaxbal.robots.planar_2r()
    q0 = arm.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = arm.inverse_kinematics(jnp.array([0.3, 0.70]), branch=-1)
    line = jaxbal.StraightLine(arm.end_effector(q0), arm.end_effector(q1), Quintic(), 0.5)
    fine = jaxbal.sample_times(0.5, 4001)  # RK4 evaluates at every second sample's midpoint
    motion = jaxbal.design.motion_samples(arm, [jaxbal.planning.EndEffectorLine(arm, line)], fine)
    q, qd, qdd = (np.asarray(part) for part in motion)
    spec = mujoco.MjSpec.from_string(export_mjcf(arm))
    mass, stiffness, damping = 250.0, 4.0e5, 300.0
    carrier = spec.body("base")
    carrier.mass, carrier.inertia = mass, [1.0, 1.0, 1.0]
    for axis in ([1.0, 0, 0], [0, 1.0, 0]):
        joint = carrier.add_joint()
        joint.type, joint.axis = mujoco.mjtJoint.mjJNT_SLIDE, axis
        joint.stiffness, joint.damping = [stiffness, 0, 0], [damping, 0, 0]
    model = spec.compile()
    data = mujoco.MjData(model)
    full = np.zeros((model.nv, model.nv))

    def rate(k, state):
        data.qpos[:], data.qvel[:] = np.r_[state[:2], q[k]], np.r_[state[2:], qd[k]]
        data.qacc[:] = np.r_[0.0, 0.0, qdd[k]]
        mujoco.mj_inverse(model, data)
        mujoco.mj_fullM(model, data, full)
        return np.r_[state[2:], -np.linalg.solve(full[:2, :2], data.qfrc_inverse[:2])]

    state, path, h = np.zeros(4), [np.zeros(2)], float(fine[2] - fine[0])
    for k in range(0, len(fine) - 1, 2):
        k1 = rate(k, state)
        k2 = rate(k + 1, state + h / 2 * k1)
        k3 = rate(k + 1, state + h / 2 * k2)
        state = state + h / 6 * (k1 + 2 * k2 + 2 * k3 + rate(k + 2, state + h * k3))
        path.append(state[:2])
    path = np.asarray(path)
    force, moment = _force(arm, (q[::2], qd[::2], qdd[::2]))

    omega = np.sqrt(stiffness / mass)
    alone = rigid_base(mass, omega / (2 * np.pi), damping / (2 * mass * omega), ("x", "y"))

    def displacement(base):
        return np.asarray(base_response(base, np.asarray(fine[::2]), force, moment)[0])

    scale = np.max(np.abs(path))
    assert scale > 1e-4  # m: the move shakes the base
    riding = carrying(alone, jaxbal.total_mass(arm))
    assert np.max(np.abs(displacement(riding) - path)) < 1e-5 * scale
    assert np.max(np.abs(displacement(alone) - path)) > 0.1 * scale
    motion = (q[::2], qd[::2], qdd[::2])
    for kind in ("residual", "peak"):
        metric = BaseVibration(alone, fine[::2], kind, carries_robot=True)
        ours = BaseVibration(riding, fine[::2], kind)(arm, motion)
        assert float(metric(arm, motion)) == pytest.approx(float(ours), rel=1e-13)


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_payload_sweep_loads_the_base(move):
    """``jaxbal.sweep`` of the residual vibration over the payload (riding on the base,
    ``carries_robot=True``): each point equals the metric of that robot, in metres."""
    arm, times, motion = move
    metric = BaseVibration(rigid_base(300.0, 5.0, 0.02, ("x", "y")), times, carries_robot=True)
    payloads = np.array([0.0, 2.0, 5.0])
    ds = jaxbal.sweep(metric, arm, motion, {"payload": payloads}, progress=False)
    looped = [float(metric(arm.with_design({"payload": jnp.asarray(p)}), motion)) for p in payloads]
    np.testing.assert_allclose(ds["value"].values, looped, rtol=1e-12)
    assert ds["value"].attrs["units"] == "m" and ds.attrs["metric"] == "residual_vibration"
    assert len(set(np.round(looped, 12))) == 3  # the payload changes it


@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_wrench_sample_is_refused_not_read_as_rest(bad):
    """One NaN (or inf) force sample gave a residual amplitude of exactly 0 — "the base
    is at rest" — eagerly and under ``jit`` (the zero-safe square root mapped NaN to 0);
    ``peak_norm`` skipped the NaN row and returned the finite peak. Now a ValueError
    naming the sample (eagerly), a runtime error under ``jit`` (``peak_norm`` too), and a
    NaN peak under ``jit`` with the runtime checks off (never a finite number)."""
    from jaxbal.planning import peak_norm
    from jaxbal.vibration import base_response, residual_amplitude, rigid_base

    times = jnp.linspace(0.0, 0.4, 41)
    force = jnp.stack([40 * jnp.sin(30 * times), 25 * jnp.cos(17 * times), 0 * times], -1)
    moment = jnp.zeros((41, 3))
    base = rigid_base(300.0, 5.0, 0.02, ("x", "y"))
    assert np.all(np.asarray(residual_amplitude(base, times, force, moment)) > 1e-6)
    broken = force.at[20, 0].set(bad)
    for call in (residual_amplitude, base_response):
        with pytest.raises(ValueError, match=r"must be finite; not at samples.*20"):
            call(base, times, broken, moment)
    with pytest.raises(Exception, match="must be finite"):
        jax.block_until_ready(jax.jit(lambda f: residual_amplitude(base, times, f, moment))(broken))
    with pytest.raises(ValueError, match=r"non-finite rows \[20\]"):
        peak_norm(broken)
    with pytest.raises(Exception, match="peak_norm: vectors must be finite"):
        jax.block_until_ready(jax.jit(peak_norm)(broken))
    with jaxbal.runtime_checks(False):
        assert np.isnan(float(jax.jit(peak_norm)(broken)))
    assert float(peak_norm(force)) > 0
