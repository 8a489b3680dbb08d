"""Machining tolerances and couplings of a design (:func:`jaxbal.sensitivity.tolerance`)
against closed forms on the 2R: along its COM move the shaking force is affine in each
counter-mass and in link 1's static moment ``m₀d₀``, so the squared RMS force is a
parabola in each, whose minimum and level crossings are known exactly."""

import jax.numpy as jnp
import numpy as np
import pytest
from conftest import com_move_2r

import jaxbal
from jaxbal.design import rms_force, rms_moment
from jaxbal.profiles import BangBang
from jaxbal.sensitivity import tolerance

WRT = ("counter_distance", "counter_mass")


@pytest.fixture(scope="module")
def move():
    return com_move_2r(101)


def _designed(robot, m, d):
    return robot.with_design({"counter_mass": jnp.asarray(m), "counter_distance": jnp.asarray(d)})


def _parabola(f):
    """``(a, x*, f(x*)²)`` of ``f(x)² = a (x − x*)² + f(x*)²`` from three samples."""
    q = [f(x) ** 2 for x in (0.0, 1.0, 2.0)]
    a = (q[2] - 2.0 * q[1] + q[0]) / 2.0
    best = -((q[1] - q[0]) - a) / (2.0 * a)
    return a, best, q[0] - a * best**2


def test_the_tolerance_of_a_counter_mass_at_its_optimum_is_the_parabolas(move):
    """Link 2's counter-mass at the RMS optimum (others 0): the metric reaches
    ``1.01 × value`` at ``m* ± √((1.01² − 1) v² / a)``; the coupling of a variable
    with the others is ≥ 1; an entry the metric does not see (a counter-mass at joint 1's
    axis, d₀ = 0, and that axis distance for m₀ = 0) has coupling NaN and an open
    interval up to its bound and the reach."""
    robot, motion = move

    def rms(m):
        return float(rms_force(_designed(robot, [0.0, m], [0.0, 0.1]), motion))

    a, best, floor = _parabola(rms)
    design = _designed(robot, [0.0, best], [0.0, 0.1])
    result = tolerance(design, motion, "rms_force", wrt=WRT)
    value = np.sqrt(floor)
    assert result.value == pytest.approx(value, rel=1e-10)
    expected = np.sqrt((1.01**2 - 1.0) * value**2 / a)
    below, above = result.interval["counter_mass"]
    np.testing.assert_allclose([below[1], above[1]], [expected, expected], rtol=1e-7)
    for end in (best - below[1], best + above[1]):
        assert rms(end) == pytest.approx(result.threshold, rel=1e-8)
    assert not np.any(result.open["counter_mass"][1][1:]) and result.open["counter_mass"][0][0]
    assert result.interval["counter_mass"][0][0] == 0.0  # at its bound, 0 kg
    assert result.interval["counter_mass"][1][0] == pytest.approx(10.0)  # the reach
    assert np.isnan(result.coupling["counter_mass"][0])
    assert np.isnan(result.coupling["counter_distance"][0])
    assert 1.0 <= result.coupling["counter_mass"][1] < 10.0
    # d₁ is not at its optimum (-47.5 N/m): convex, but no stationary point; the
    # counter-masses alone are at a minimum (m₀ unseen, m₁ at its optimum)
    assert result.convex and not result.stationary and not result.minimum
    assert tolerance(design, motion, "rms_force", wrt=("counter_mass",)).minimum
    assert result.labels == (
        "counter_distance[0]",
        "counter_distance[1]",
        "counter_mass[0]",
        "counter_mass[1]",
    )
    assert "counter_mass[1]" in result.table()


def test_the_coupling_is_that_of_a_finite_difference_hessian(move):
    """``√(H_ii (H⁻¹)_ii)`` with H from exact differences of the squared metric. The
    RMS moment is a norm of a moment affine in the counter-masses, which cannot cancel
    it (they add inertia): convex, H positive definite (the RMS force is not: two
    counter-masses balance the 2R, and H is singular along the line to that design)."""
    robot, motion = move
    distances = [0.1, 0.12]
    x0 = np.array([2.0, 4.0])
    result = tolerance(_designed(robot, x0, distances), motion, "rms_moment", wrt=("counter_mass",))

    def q(x):  # the squared RMS moment: exactly quadratic, so differences are exact
        return float(rms_moment(_designed(robot, x, distances), motion)) ** 2

    h, eye = 0.5, np.eye(2) * 0.5
    slope = np.array([(q(x0 + eye[i]) - q(x0 - eye[i])) / (2 * h) for i in range(2)])
    curve = np.array(
        [
            [
                q(x0 + eye[i] + eye[j])
                - q(x0 + eye[i] - eye[j])
                - q(x0 - eye[i] + eye[j])
                + q(x0 - eye[i] - eye[j])
                for j in range(2)
            ]
            for i in range(2)
        ]
    ) / (4 * h * h)
    f = np.sqrt(q(x0))
    hessian = curve / (2 * f) - np.outer(slope, slope) / (4 * f**3)  # of f = √q
    d = 1.0 / np.sqrt(np.diag(hessian))
    assert np.all(np.linalg.eigvalsh(d[:, None] * hessian * d[None, :]) > 1e-3)
    np.testing.assert_allclose(result.hessian, hessian, rtol=1e-8)
    expected = np.sqrt(np.diag(hessian) * np.diag(np.linalg.inv(hessian)))
    assert np.all(expected > 1.01)  # coupled: the test can tell a coupling from 1
    np.testing.assert_allclose(result.coupling["counter_mass"], expected, rtol=1e-6)
    assert 0.0 < result.flattest_curvature < 1.0
    assert result.convex and not result.stationary  # the moment falls with less mass
    assert "curvature only" in result.table()


def _link1_only(robot, motion):
    """The RMS force with link 2's counter-mass removed: a metric of m₀ and d₀ alone
    (callable metrics are the user's own objectives)."""
    design = robot.design()
    removed = {k: design[k].at[1].set(0.0) for k in ("counter_mass", "counter_distance")}
    return rms_force(robot.with_design(removed), motion)


def test_a_counter_mass_and_its_distance_at_the_base_are_one_flat_direction(move):
    """Link 1 turns about the fixed base: its counter-mass acts through ``s = m₀d₀``
    alone. At the optimum of ``s`` the metric is flat along ``(δm₀, δd₀) ∝ (m₀, −d₀)``:
    the design is a minimum, both couplings are ``inf``, the flattest direction is
    that one and the Hessian maps it to zero; the tolerance of m₀ alone is the
    parabola's in ``s`` divided by d₀. With link 2's counter-mass in the metric (the
    plain RMS force, m₁ = d₁ = 0) the same design is no minimum: a cross term of d₁,
    which alone the metric does not see, is indefinite; the couplings are NaN."""
    robot, motion = move
    mass = 2.0

    def rms(s):
        return float(rms_force(_designed(robot, [mass, 0.0], [s / mass, 0.0]), motion))

    a, best, floor = _parabola(rms)
    assert best > 0
    design = _designed(robot, [mass, 0.0], [best / mass, 0.0])
    result = tolerance(design, motion, _link1_only, wrt=WRT)
    assert result.minimum and abs(result.flattest_curvature) < 1e-6
    assert np.isinf(result.coupling["counter_mass"][0])
    assert np.isinf(result.coupling["counter_distance"][0])
    assert np.isnan(result.coupling["counter_mass"][1])  # not seen by this metric
    direction = np.array([-best / mass, 0.0, mass, 0.0])  # (d0, d1, m0, m1) offsets
    image = result.hessian @ direction
    assert np.max(np.abs(image)) <= 1e-7 * np.abs(result.hessian).max() * np.abs(direction).max()
    flattest = np.concatenate(
        [result.flattest["counter_distance"], result.flattest["counter_mass"]]
    )
    cosine = flattest @ direction / np.linalg.norm(flattest) / np.linalg.norm(direction)
    assert abs(cosine) == pytest.approx(1.0, abs=1e-6)
    value = np.sqrt(floor)
    expected = np.sqrt((1.01**2 - 1.0) * value**2 / a) / (best / mass)
    np.testing.assert_allclose(result.interval["counter_mass"][1][0], expected, rtol=1e-7)
    plain = tolerance(design, motion, "rms_force", wrt=WRT)
    assert not plain.minimum and np.all(np.isnan(plain.coupling["counter_mass"]))
    assert "no minimum" in plain.table()


def test_bad_inputs_are_named(move):
    robot, motion = move
    design = _designed(robot, [0.0, 2.0], [0.0, 0.1])
    for kwargs, match in [
        ({"rise": 0.0}, "rise must be a finite number > 0"),
        ({"rise": float("nan")}, "rise must be a finite number > 0"),
        ({"rise": "0.01"}, "rise must be a finite number > 0"),
        ({"allowed": -1.0}, "allowed must be a finite number > 0"),
        ({"rise": 0.02, "allowed": 1.0}, "not both"),
        ({"xtol": 0.0}, "xtol must be a finite number > 0"),
        ({"wrt": ("counter_masses",)}, "unknown design variable"),
        ({"wrt": ()}, "wrt names no design variable"),
    ]:
        with pytest.raises(ValueError, match=match):
            tolerance(design, motion, "rms_force", **kwargs)
    with pytest.raises(ValueError, match="unknown metric"):
        tolerance(design, motion, "rms_forces")


@pytest.mark.slow
def test_the_readmes_dual_v_tolerances(capsys):
    """The README's co-designed DUAL-V block, then its tolerance block: the numbers the
    README quotes (counter-mass 1: −24 g / +451 g; its distance −0.58 / +10.7 mm)."""
    import re
    from pathlib import Path

    text = (Path(__file__).resolve().parent.parent / "README.md").read_text()
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    codesign = next(b for b in blocks if "dual_v(counter_masses=False)" in b)
    scope = {"jnp": jnp, "jaxbal": __import__("jaxbal")}
    exec(compile(codesign, "README.md", "exec"), scope)
    exec(
        compile(next(b for b in blocks if "sensitivity.tolerance" in b), "README.md", "exec"), scope
    )
    tol = scope["tol"]
    np.testing.assert_allclose(
        [tol.interval["counter_mass"][0][0], tol.interval["counter_mass"][1][0]],
        [0.024, 0.451],
        rtol=0.03,
    )
    np.testing.assert_allclose(
        [tol.interval["counter_distance"][0][0], tol.interval["counter_distance"][1][0]],
        [0.00058, 0.0107],
        rtol=0.03,
    )
    assert not tol.minimum and "counter_mass[0]" in capsys.readouterr().out


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_a_negative_metric_rises_by_its_magnitude_and_a_zero_one_is_refused(move):
    """``rms_force − 100`` (negative): the threshold was ``1.01 × value``, below the
    value, and every interval 0 (helper, session 38); now ``value + rise·|value|``, the
    intervals of the metric plus a constant. A metric zero up to rounding (a
    force-balanced 2R's RMS force, ~1e-11 N, gave tolerances of 1e-13 kg) is refused
    without ``allowed=``; with it the couplings are NaN (a norm at its zero)."""
    robot, motion = move
    design = _designed(robot, [2.0, 1.0], [0.35, 0.2])
    plain = tolerance(design, motion, "rms_force", wrt=("counter_mass",))
    shifted = tolerance(
        design,
        motion,
        lambda r, m: rms_force(r, m) - 100.0,
        wrt=("counter_mass",),
        allowed=plain.threshold - plain.value,
    )
    assert shifted.value < 0 and shifted.threshold > shifted.value
    for a, b in zip(plain.interval["counter_mass"], shifted.interval["counter_mass"], strict=True):
        np.testing.assert_allclose(a, b, rtol=1e-6)
    negative = tolerance(
        design, motion, lambda r, m: rms_force(r, m) - 100.0, wrt=("counter_mass",)
    )
    assert negative.threshold == pytest.approx(negative.value + 0.01 * abs(negative.value))
    assert np.all(np.concatenate(negative.interval["counter_mass"]) > 0)

    def tiny(r, m):  # zero up to rounding, as a force-balanced arm's force
        return 1e-12 * rms_force(r, m)

    with pytest.raises(ValueError, match="zero up to rounding"):
        tolerance(design, motion, tiny, wrt=("counter_mass",))
    given = tolerance(design, motion, tiny, wrt=("counter_mass",), allowed=1e-12)
    assert np.all(np.isnan(given.coupling["counter_mass"])) and "vanishes" in given.table()


@pytest.mark.slow
def test_an_end_where_the_replanned_motion_fails_is_marked_invalid(move):
    """A COM plan re-planned with the design: beyond d₁ ≈ 1.73 m the COM line leaves
    the workspace. With the checks off the metric there was finite, and the interval
    ran past it as if the metric had risen 1 % (it was 0.42 × the threshold; helper,
    session 38). Now the end is the last valid design, marked ``"invalid"``."""
    robot, _ = move
    design = _designed(robot, [2.0, 1.0], [0.1, 0.1])
    q0 = robot.inverse_kinematics(jnp.array([0.225, 0.25]), branch=-1)
    q1 = robot.inverse_kinematics(jnp.array([0.225, 0.70]), branch=-1)
    times = jaxbal.sample_times(0.5, 11)

    def replanned(r):
        plan = jaxbal.planning.com_line(r, q0, q1, BangBang(), 0.5)
        return jaxbal.design.motion_samples(r, [plan], times)

    result = tolerance(design, replanned, "rms_force", wrt=("counter_distance",))
    assert (
        result.ends["counter_distance"][1][1] == "invalid" and result.open["counter_distance"][1][1]
    )
    end = 0.1 + result.interval["counter_distance"][1][1]

    def at(d1):
        moved = design.with_design({"counter_distance": jnp.array([0.1, d1])})
        return float(rms_force(moved, replanned(moved)))

    # valid and below the threshold up to the end (at the end itself the COM is on the
    # workspace's boundary, where the joint rates, ∝ 1/√0, are all rounding)
    assert at(end - 1e-4) < result.threshold and at(end - 0.5) < result.threshold
    with pytest.raises(ValueError, match="not reachable"):
        at(end + 1e-6)
    assert "x" in result.table()
