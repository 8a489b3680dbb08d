"""Tests of jaxbal.robots.scara_studies (Arakelian & Briot 2008, §3) and of the studies
shared by every robot (jaxbal._src.studies: confirm_cases, agreement_table, mujoco_peaks
in jaxbal.mujoco; plot_histories in jaxbal.report), on the SCARA."""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal.mujoco import agreement_table, confirm_cases, mujoco_peaks
from jaxbal.planning import peak_norm, wrench_along
from jaxbal.report import plot_histories
from jaxbal.robots import PickAndPlace, scara
from jaxbal.robots import scara_balancing as sb
from jaxbal.robots import scara_studies as ss

# Reproduction studies (their numbers are also written by `make reproduce`): make test-all.
pytestmark = pytest.mark.slow

DEG = np.pi / 180
MOVE = PickAndPlace([0.15, 0.2, 83 * DEG], [-0.15, 0.2, 157 * DEG], 0.3, lift=0.025)
TIMES = jaxbal.sample_times(0.3, 31)
L1, L2 = 0.125, 0.225  # m, §2
PRINTED = ss.PRINTED_BALANCED


def test_printed_balance_ratios_closed_form():
    # reference: eqs (2)-(3) by hand with M_3 = m_3 + m_v: the required static moments are
    # m_2|l_O2S2| = M_3 l_O2O3 and m_1|l_O1S1| = (m_2 + M_3) l_O1O2
    for m_v in (0.0, 0.5):
        at_o3 = 0.5 + m_v
        eq2 = PRINTED["m2"] * -PRINTED["l_O2S2"] / (at_o3 * L2)
        eq3 = PRINTED["m1"] * -PRINTED["l_O1S1"] / ((PRINTED["m2"] + at_o3) * L1)
        np.testing.assert_allclose(ss.printed_balance_ratios(m_v), [eq2, eq3], rtol=1e-12)
    # §3: violated by 100 % and 9 % without the counterweight, < 0.3 % with it
    as_printed, with_counterweight = ss.printed_balance_ratios(0.0), ss.printed_balance_ratios(0.5)
    assert float(as_printed[0]) == pytest.approx(2.0, rel=0.01)
    assert float(as_printed[1]) == pytest.approx(1.09, abs=0.01)
    np.testing.assert_allclose(with_counterweight, 1.0, atol=3e-3)


def test_printed_force_balanced_keeps_com_fixed_and_inertia_readings():
    # references: offsets from (2)-(3) by hand (−(m_2 + M_3) l_O1O2/m_1, −M_3 l_O2O3/m_2);
    # the generic total COM stays at O1 (horizontally) in any configuration; the "joints"
    # reading makes I + m l_OiSi² equal to the printed I_i
    robot, offsets = ss.printed_force_balanced()
    expected = [-(PRINTED["m2"] + 1.0) * L1 / PRINTED["m1"], -1.0 * L2 / PRINTED["m2"]]
    np.testing.assert_allclose(offsets, expected, rtol=1e-14)
    assert float(offsets[1]) == -0.046875
    rng = np.random.default_rng(0)
    for q in rng.uniform(-3, 3, (5, 4)):
        com = jaxbal.center_of_mass(robot, jnp.asarray(q))
        np.testing.assert_allclose(com[:2], 0.0, atol=1e-15)
    joints, _ = ss.printed_force_balanced(inertias_about="joints")
    about_joint = joints.inertias[:2] + joints.masses[:2] * offsets**2
    np.testing.assert_allclose(about_joint, [PRINTED["I1"], PRINTED["I2"]], rtol=1e-14)
    with pytest.raises(ValueError, match="inertias_about"):
        ss.printed_force_balanced(inertias_about="tip")


def test_closed_form_vs_printed_rows():
    # references: the merged link 1 (link + counter-mass at r_c = 0.16 m behind O1)
    # satisfies eq (3) by hand; §3's printed values within the summary table's 1 %
    rows = {name: (value, unit, paper) for name, value, unit, paper in ss.closed_form_vs_printed()}
    m1, offset1 = float(rows["m1 (link 1 + counter-mass)"][0]), float(rows["l_O1S1"][0])
    m2 = float(rows["m2 (link 2 + counter-mass)"][0])
    m_v = float(rows["m_v vertical counterweight"][0])
    assert m_v == pytest.approx(0.5)  # = m_3: the vertical axis is balanced
    assert m1 * offset1 + (m2 + 0.5 + m_v) * L1 == pytest.approx(0.0, abs=1e-14)
    m_c1 = float(rows["m_c1 at r_c1 = 0.16 m"][0])
    assert m1 * offset1 == pytest.approx(1.2 * 0.0625 - m_c1 * 0.16, rel=1e-14)
    for name in ("m1 (link 1 + counter-mass)", "l_O1S1", "m2 (link 2 + counter-mass)", "l_O2S2"):
        value, _, paper = rows[name]
        assert float(value) == pytest.approx(paper, rel=0.01)  # the table's tolerance


def test_balancing_cases_cancel_what_they_claim():
    # reference: the generic shaking wrench (not eq 7): force-balanced cases have zero
    # force, fully balanced ones a zero wrench, eq (8) as printed leaves a moment
    cases = ss.balancing_cases(MOVE)
    assert list(cases)[0] == "unbalanced" and ss.JOINT_INERTIA_VARIANT in cases
    force0, moment0 = wrench_along(*cases["unbalanced"], TIMES)
    for name, (robot, path) in cases.items():
        force, moment = wrench_along(robot, path, TIMES)
        if name != "unbalanced":
            assert peak_norm(force) < 1e-12 * peak_norm(force0), name
        if name.startswith("fully balanced"):
            assert peak_norm(moment) < 1e-12 * peak_norm(moment0), name
        if name == "eq (8) as printed":
            assert peak_norm(moment) > 0.1 * peak_norm(moment0)


def test_rotation_law_summary_turns_from_end_points():
    # reference: Δφ = −(J_1 Δθ1 + J_2 Δθ12)/J_3 with Δθ from the inverse kinematics of the
    # move's end points (eq 7 integrated), and θ3 = φ − θ12
    robot = sb.force_balanced(scara())
    summary = ss.rotation_law_summary(robot, MOVE)
    q0 = robot.inverse_kinematics(MOVE(0.0))
    q1 = robot.inverse_kinematics(MOVE(0.3))
    j1, j2, j3 = (float(summary[f"J_{k}"][0]) for k in (1, 2, 3))
    d1, d12 = float(q1[0] - q0[0]), float(q1[0] + q1[1] - q0[0] - q0[1])
    d_phi = -(j1 * d1 + j2 * d12) / j3
    assert float(summary["turns of φ (absolute)"][0]) == pytest.approx(d_phi / (2 * np.pi))
    theta3 = float(summary["turns of θ3 (relative to link 2)"][0])
    assert theta3 == pytest.approx((d_phi - d12) / (2 * np.pi))
    assert summary["J_1"][1] == "kg·m²"


def test_tradeoff_front_is_monotone_and_starts_at_the_closed_form():
    # references: a vanishing penalty gives the closed form (zero residual force); a
    # growing penalty never adds mass nor lowers the residual (a Pareto front)
    robot = scara()
    samples = ss.codesign_samples(robot, [MOVE], count=8)
    assert samples[0].shape == (8, 4)
    closed = sb.counter_mass_design(sb.force_balanced(robot))
    front = ss.tradeoff_front(robot, samples, [1e-10, 1e-2, 1.0], "mass")
    assert front[0, 0] == pytest.approx(float(jnp.sum(closed)), rel=1e-4)
    assert front[0, 1] < 1e-4
    assert np.all(np.diff(front[:, 0]) <= 1e-9) and np.all(np.diff(front[:, 1]) >= -1e-9)
    with pytest.raises(ValueError, match="penalty"):
        ss.tradeoff_front(robot, samples, [1.0], "length")


def test_shared_studies_agree_with_jaxbal_and_draw(tmp_path):
    # reference: MuJoCo C's inverse dynamics on the SCARA tree (independent of jaxbal's
    # momentum code) within 1e-9 of the peak; the table holds the confirmations' numbers
    robot, path = ss.balancing_cases(MOVE)["unbalanced"]
    force, moment = wrench_along(robot, path, TIMES)
    mj_force, mj_moment = mujoco_peaks(robot, path, TIMES)
    assert mj_force == pytest.approx(float(peak_norm(force)), rel=1e-9)
    assert mj_moment == pytest.approx(float(peak_norm(moment)), rel=1e-9)
    confirmations = confirm_cases({"unbalanced": (robot, path)}, TIMES, engine="mujoco")
    assert confirmations["unbalanced"].relative < 1e-9
    table = agreement_table("t", "title", confirmations)
    assert [(e.row, e.column) for e in table.entries] == [
        ("unbalanced", "force_rel"),
        ("unbalanced", "moment_rel"),
    ]
    assert table.entries[1].value == confirmations["unbalanced"].moment_relative
    panels = [("f_x [N]", {"unbalanced": force[:, 0]}, "a"), ("m_z [N·m]", {"x": moment[:, 2]})]
    figure = plot_histories(tmp_path / "f.png", TIMES, panels, {"x": {"color": "k"}})
    assert figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
