"""The mass models, checked without `mass_properties()`: total mass and centre of mass
computed by hand from the papers' printed parameters (the MuJoCo check receives the
mass model from `mass_properties()`, so it cannot catch an error there).

References: Briot et al. (2012) §3.1-3.2 (link masses, COM ratios, 5 kg payload);
Geng et al. (2021) eq (6) and §3 (0.396, 0.248, 0.1 kg: 2.032 kg without payload).
Tolerance 1e-12 (exact arithmetic up to rounding).
"""

import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal

BRIOT = {  # §3.1 / §3.2: lengths [m], COM ratios, masses [kg]; payload 5 kg at the tip
    "planar_2r": ([0.5, 0.3], [0.289, 0.098], [24.4, 8.3]),
    "planar_3r": ([0.5, 0.3, 0.1], [0.289, 0.098, 0.5], [24.4, 8.3, 2.0]),
}


@pytest.mark.parametrize("name", sorted(BRIOT))
def test_briot_arms_total_mass_and_com_by_hand(name):
    lengths, ratios, masses = BRIOT[name]
    robot = getattr(jaxbal.robots, name)()
    q = np.array([0.7, -1.1, 0.4][: len(lengths)])
    angles = np.cumsum(q)
    units = np.stack([np.cos(angles), np.sin(angles)], -1)
    joints = np.concatenate([[np.zeros(2)], np.cumsum(np.array(lengths)[:, None] * units, 0)])
    first_moment = sum(m * (joints[k] + r * lengths[k] * units[k])
                       for k, (m, r) in enumerate(zip(masses, ratios, strict=True)))  # fmt: skip
    first_moment = first_moment + 5.0 * joints[-1]
    total = sum(masses) + 5.0
    assert float(jaxbal.total_mass(robot)) == pytest.approx(total, rel=1e-12)
    com = np.asarray(jaxbal.center_of_mass(robot, jnp.asarray(q)))
    np.testing.assert_allclose(com[:2], first_moment / total, rtol=0, atol=1e-12)
    assert com[2] == 0.0


@pytest.mark.parametrize("payload", [0.0, 2.0])
def test_orthoglide_total_mass_from_eq6(payload):
    robot = jaxbal.robots.orthoglide(payload=payload)
    expected = 3 * 0.396 + 3 * 0.248 + 0.1 + payload  # parallelograms, sliders, joint P
    assert float(jaxbal.total_mass(robot)) == pytest.approx(expected, rel=1e-12)


def test_scara_total_mass_and_com_by_hand():
    """Arakelian & Briot (2008) §2: m1 = 1.2, m2 = 2, m3 = 0.5 kg; l_O1O2 = 0.125,
    l_O2O3 = 0.225, l_O1S1 = 0.0625, l_O2S2 = 0.1125 m; link 3 (end-effector) at O3."""
    robot = jaxbal.robots.scara()
    assert float(jaxbal.total_mass(robot)) == pytest.approx(3.7, rel=1e-12)
    q = jnp.array([0.3, -0.7, 0.2, 0.05])
    e1 = np.array([np.cos(0.3), np.sin(0.3)])
    e12 = np.array([np.cos(-0.4), np.sin(-0.4)])
    first = 1.2 * 0.0625 * e1 + 2.0 * (0.125 * e1 + 0.1125 * e12) + 0.5 * (0.125 * e1 + 0.225 * e12)
    com = np.asarray(jaxbal.center_of_mass(robot, q))
    np.testing.assert_allclose(com[:2], first / 3.7, rtol=0, atol=1e-12)


def test_dual_v_total_mass_from_table1():
    """van der Wijk et al. (2013) Table 1: 4 m_i1 + 4 m_i2 + m5 + 4 m_cm,i (the tuning
    masses are included in m_cm,i): 4·1.169 + 4·0.606 + 0.899 + 4·7.983 kg."""
    expected = 4 * 1.169 + 4 * 0.606 + 0.899 + 4 * 7.983
    assert float(jaxbal.total_mass(jaxbal.robots.dual_v())) == pytest.approx(expected, rel=1e-12)
