"""Tests of jaxbal.robots.orthoglide_studies (Geng et al. 2021, §3)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.planning import wrench_along
from jaxbal.robots import orthoglide
from jaxbal.robots import orthoglide_studies as og
from jaxbal.robots.orthoglide_planning import motion_cases, switching_times

# Reproduction studies (their numbers are also written by `make reproduce`): make test-all.
pytestmark = pytest.mark.slow

P_START = (0.0, 0.0, 0.0)
P_END = (-0.1, 0.07, -0.11)  # §3
DURATION = 0.1
MOVE = (P_START, P_END, DURATION)
SAMPLES = 41  # coarse: the tests check identities, not the paper's numbers
PAYLOADS = jnp.array([1.0, 4.0])  # one shape everywhere: payload_peaks compiles once
L = 0.31


def _eq6(robot, p):
    """Eq (6) with eq (1), written out by hand (independent of the body frames)."""
    p = jnp.asarray(p)
    sq = p**2
    rho = p + jnp.sqrt(L**2 - (jnp.sum(sq) - sq))
    m1, m2, m3 = robot.parallelogram_mass, robot.slider_mass, robot.platform_mass + robot.payload
    total = 3 * (m1 + m2) + m3
    return (0.5 * m1 * (rho + 3 * p) + m2 * (rho + robot.slider_offset) + m3 * p) / total


def test_kinematic_summary_matches_eq1_eq6_and_closed_forms():
    # reference: eq (1) ρ_i = p_i + sqrt(L² − p_j² − p_k²); eq (6) by hand; a_com = 4|ΔS|/T²;
    # theoretical reduction 1 − 4/(10/√3) = 30.72 %; the paper's swapped reading 34.3 m/s²
    robot = orthoglide(slider_offset=0.069)
    rows = og.kinematic_summary(robot, *MOVE, loaded_payload=2.0)
    p = jnp.asarray(P_END)
    rho_f = p + jnp.sqrt(L**2 - (jnp.sum(p**2) - p**2))
    for k, axis in enumerate("xyz"):
        assert rows[f"rho_{axis}i"][0] == pytest.approx(L, abs=1e-14)
        assert rows[f"rho_{axis}f"][0] == pytest.approx(float(rho_f[k]), abs=1e-14)
    loaded = og.with_payload(robot, 2.0)
    com = jnp.concatenate([_eq6(loaded, P_START), _eq6(loaded, P_END)])
    for k, name in enumerate(["x_Si", "y_Si", "z_Si", "x_Sf", "y_Sf", "z_Sf"]):
        assert rows[name][0] == pytest.approx(float(com[k]), abs=1e-14)
        assert rows[name + "_rounded"][0] == pytest.approx(round(float(com[k]), 2), abs=1e-15)
    displacement = _eq6(robot, P_END) - _eq6(robot, P_START)
    expected = 4 * float(jnp.linalg.norm(displacement)) / DURATION**2
    assert rows["a_com"][0] == pytest.approx(expected, rel=1e-12)
    assert rows["a_com"][0] == pytest.approx(38.7, rel=0.01)  # §3
    assert rows["a_com_swapped_masses"][0] == pytest.approx(34.3, rel=0.01)
    assert rows["theoretical_reduction"][0] == pytest.approx(100 * (1 - 4 * np.sqrt(3) / 10))


def test_payload_peaks_closed_form_case3_reference_point_and_loop():
    # references: case 3 (bang-bang COM line) has constant |F| = M·4|ΔS|/T² (eq 2);
    # the moment about c is |M_O − c × F| from the wrench about O; vmap equals a loop
    robot = orthoglide(slider_offset=0.05)
    c = jnp.array([0.01, -0.2, 0.03])
    forces, moments = og.payload_peaks(robot, PAYLOADS, *MOVE, c, SAMPLES)
    times = switching_times(DURATION, SAMPLES)
    for i, payload in enumerate(PAYLOADS):
        loaded = og.with_payload(robot, payload)
        displacement = _eq6(loaded, P_END) - _eq6(loaded, P_START)
        closed = jaxbal.total_mass(loaded) * 4 * jnp.linalg.norm(displacement) / DURATION**2
        assert forces[i, 2] == pytest.approx(float(closed), rel=1e-9)
    # the histories of Fig 4 (wrench about O, moved to c here) have the same maxima
    forces_t, moments_t = og.case_histories(og.with_payload(robot, PAYLOADS[1]), *MOVE, times, c)
    for k, case in enumerate(("case1", "case2", "case3")):
        assert float(jnp.max(forces_t[case])) == pytest.approx(float(forces[1, k]), rel=1e-12)
        assert float(jnp.max(moments_t[case])) == pytest.approx(float(moments[1, k]), rel=1e-12)
    plan = motion_cases(og.with_payload(robot, PAYLOADS[1]), *MOVE)["case2"]
    force, moment = wrench_along(og.with_payload(robot, PAYLOADS[1]), plan, times)
    about_c = np.asarray(moment) - np.cross(np.asarray(c), np.asarray(force))
    assert float(moments[1, 1]) == pytest.approx(np.linalg.norm(about_c, axis=1).max(), rel=1e-12)


def test_moment_is_affine_in_the_slider_offset():
    # reference: the assumption of fit_moment_reference, checked directly: M_O(l) is
    # affine in l (slider COMs ride rigidly on the sliders; F and the plans do not move)
    times = switching_times(DURATION, SAMPLES)

    def wrench(offset):
        robot = orthoglide(payload=1.0, slider_offset=offset)
        plan = motion_cases(robot, *MOVE)["case3"]
        return wrench_along(robot, plan, times)

    (f0, m0), (_, m1), (f3, m3) = wrench(0.0), wrench(0.1), wrench(0.3)
    np.testing.assert_allclose(f3, f0, atol=1e-9)
    np.testing.assert_allclose(m3, m0 + 3 * (m1 - m0), atol=1e-9)


@pytest.mark.slow
def test_fit_recovers_a_known_reference_point_and_offset():
    # reference: synthetic table made with known (l, c); the fit recovers them and the
    # recomputed relative errors vanish
    robot = orthoglide()
    payloads = PAYLOADS
    truth_l, truth_c = 0.05, jnp.array([-0.01, -0.28, 0.02])
    table_robot = orthoglide(slider_offset=truth_l)
    _, table = og.payload_peaks(table_robot, payloads, *MOVE, truth_c, SAMPLES)
    fit = og.fit_moment_reference(
        robot, payloads, table, *MOVE, guess=(0.03, 0.0, -0.25, 0.0), samples=SAMPLES
    )
    assert float(fit.slider_offset) == pytest.approx(truth_l, abs=1e-6)
    np.testing.assert_allclose(fit.reference, truth_c, atol=1e-6)
    assert float(fit.max_error) < 1e-7
    # with the offset held at the truth only c is fitted
    held = og.fit_moment_reference(
        robot, payloads, table, *MOVE, guess=(0.0, 0.0, -0.25, 0.0), fixed_offset=truth_l,
        samples=SAMPLES,
    )  # fmt: skip
    np.testing.assert_allclose(held.reference, truth_c, atol=1e-6)
    errors = og.reference_errors(robot, payloads, table, *MOVE, truth_l, truth_c, SAMPLES)
    np.testing.assert_allclose(errors, 0.0, atol=1e-12)


@pytest.mark.slow
def test_payload_error_slopes_match_finite_differences_and_shapes():
    # references: central differences in Δm (away from the kink at Δm = 0); Δm = 0 gives
    # identical case-3 and case-4 peaks (same plan)
    robot = orthoglide()
    payloads = PAYLOADS[:1]
    delta, h = 0.1, 1e-4
    slopes = og.payload_error_slopes(robot, payloads, jnp.asarray(delta), *MOVE, None, SAMPLES)
    deltas = jnp.array([delta - h, delta + h, 0.0])
    grid = og.payload_error_peaks(robot, payloads, deltas, *MOVE, None, SAMPLES)
    assert grid.shape == (1, 3, 4)  # a labelled jaxbal.sweep: payload × payload_error × peak
    assert grid.dims == ("payload", "payload_error", "peak")
    np.testing.assert_array_equal(grid["payload_error"].values, deltas)
    peaks = [f"{q}_case{k}" for q in ("force", "moment") for k in (3, 4)]
    assert list(grid["peak"].values) == peaks
    assert list(grid["units"].values) == ["N", "N", "N·m", "N·m"]
    at_zero = og.payload_error_peaks(robot, payloads, jnp.asarray(0.0), *MOVE, None, SAMPLES)
    assert at_zero.dims == ("payload", "peak") and float(at_zero["payload_error"]) == 0.0
    np.testing.assert_allclose(at_zero, grid[:, 2], rtol=1e-12)
    np.testing.assert_allclose(slopes, (grid[:, 1] - grid[:, 0]) / (2 * h), rtol=1e-6, atol=1e-8)
    np.testing.assert_allclose(grid[:, 2, 0], grid[:, 2, 1], rtol=1e-12)
    np.testing.assert_allclose(grid[:, 2, 2], grid[:, 2, 3], rtol=1e-12)


def test_tables_layout_and_reductions():
    # reference: reduction_k = 100 (case1 − case_k)/case1, by hand
    peaks = np.array([[10.0, 8.0, 5.0], [20.0, 15.0, 14.0]])
    table = og.peaks_table("t", "title", (0.0, 1.0), peaks, "N", {"case1": (9.0, 21.0),
                           "case2": (1, 1), "case3": (1, 1), "reduction2": (1, 1),
                           "reduction3": (1, 1)})  # fmt: skip
    values = {(e.row, e.column): e.value for e in table.entries}
    assert values[("payload0", "reduction2")] == pytest.approx(20.0)
    assert values[("payload1", "reduction3")] == pytest.approx(30.0)
    assert table.entries[0].paper == 9.0
    errors = og.payload_error_table("e", "t", (1.0,), np.array([[3.0, 3.5]]), np.ones((1, 2)), "N")
    values = {(e.row, e.column): (e.value, e.unit) for e in errors.entries}
    assert values[("payload1", "difference")] == (0.5, "N")
    assert values[("payload1", "dcase4_ddm")] == (1.0, "N/kg")


def test_payload_cases_carry_their_payloads():
    cases = og.payload_cases(orthoglide(), (0.0, 2.0), *MOVE)
    assert list(cases)[:3] == ["payload0 case1", "payload0 case2", "payload0 case3"]
    robot, plan = cases["payload2 case3"]
    assert float(robot.payload) == 2.0
    np.testing.assert_allclose(plan(DURATION)[3:], P_END, atol=1e-12)
    assert jax.tree_util.tree_structure(cases["payload0 case1"][0]) == jax.tree_util.tree_structure(
        robot
    )
