"""The papers' force-balancing conditions, derived by jaxbal from the robots' motions.

``jaxbal.balancing.balancing_conditions`` reads the linear conditions on the bodies'
lumped inertial parameters (mass, first moment, inertia about the frame origin) under
which the shaking force vanishes along a motion; along a generic motion (every
coordinate a sine of its own frequency) they hold for every motion. The papers write
these conditions by hand; here the papers' balanced designs are checked against the
derived ones (residuals in kg·m: zero to rounding when a design meets them):

- Briot et al. (2012), §3.3: the 2R's counterweights (closed form, 0.35 m and 0.2 m);
- Arakelian & Briot (2008), eqs (1)-(3) and the vertical counterweight: the SCARA;
- van der Wijk et al. (2013), eqs (1) and (2): the DUAL-V's counter-masses, along
  platform translations (the paper's "force-balanced for translational motion of a
  non-rotated platform") and with platform rotation (§2: "not perfectly
  force-balanced"; the conditions that contain no counter-mass parameter show why).
No paper value: the papers state conditions, not numbers of this kind.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

import jaxbal
from jaxbal.balancing import balancing_conditions
from jaxbal.design import Motion
from jaxbal.report import Experiment, Result, Table
from jaxbal.robots import dual_v_balancing, planar_arm, scara_balancing

FREQUENCIES = (1.0, 1.7, 2.3, 2.9)  # [Hz] one per coordinate (generic motion)
PHASES = (0.2, 0.9, 1.4, 0.5)  # [rad]
#: balance-mass bodies of the DUAL-V (counter-masses with their tuning masses, rotors)
DUAL_V_BALANCE = ("counter_mass", "tuning_mass", "rotor")


def _sines(amplitudes, samples=400):
    """Each coordinate a sine of its own frequency over 1 s (``(t, n)`` arrays)."""
    n = len(amplitudes)
    t = jnp.linspace(0.0, 1.0, samples)[:, None]
    omega, phase = 2 * jnp.pi * jnp.asarray(FREQUENCIES[:n]), jnp.asarray(PHASES[:n])
    amplitude = jnp.asarray(amplitudes, dtype=float)
    value = amplitude * jnp.sin(omega * t + phase)
    return value, amplitude * omega * jnp.cos(omega * t + phase), -(omega**2) * value


def _platform_motion(robot, rotation):
    """The DUAL-V's joint motion for platform sines (x, y ±0.04 m; θ5 ±``rotation``)."""
    pose = _sines([0.04, 0.04, rotation], samples=200)
    return Motion(*jax.vmap(lambda *u: jaxbal.pose_motion(robot, *u))(*pose))


def _add(table, row, conditions, designs):
    table.add(row, "conditions", conditions.rank, "")
    for label, robot in designs.items():
        table.add(row, f"largest residual, {label}", np.max(np.abs(conditions.residuals(robot))),
                  "kg·m")  # fmt: skip


def run(ctx) -> Result:
    table = Table("beyond_balancing_conditions", "Force-balancing conditions: papers' designs")
    ctx.progress("2R")
    arm = planar_arm.planar_2r()
    conditions = balancing_conditions(arm, Motion(*_sines([1.0, 1.0])))
    balanced = planar_arm.force_balanced(arm, [0.35, 0.2])
    _add(table, "2R, generic joint motion", conditions, {"paper design": balanced, "bare": arm})
    ctx.progress("SCARA")
    scara = jaxbal.robots.scara()
    conditions = balancing_conditions(scara, Motion(*_sines([1.0, 1.0, 1.0, 0.05])))
    balanced = scara_balancing.force_balanced(scara)
    _add(table, "SCARA, generic joint motion", conditions,
         {"paper design": balanced, "bare": scara})  # fmt: skip
    ctx.progress("DUAL-V")
    robot = jaxbal.robots.dual_v()
    designs = {
        f"eq ({k})": dual_v_balancing.with_counter_mass_moments(robot, equation(robot))
        for k, equation in ((1, dual_v_balancing.balance_condition_eq1),
                            (2, dual_v_balancing.balance_condition_eq2))
    }  # fmt: skip
    translation = balancing_conditions(robot, _platform_motion(robot, 0.0))
    _add(table, "DUAL-V, platform translations", translation, designs)
    rotation = balancing_conditions(robot, _platform_motion(robot, 0.2))
    _add(table, "DUAL-V, translations and ±0.2 rad rotation", rotation, designs)
    balance = np.asarray([name.startswith(DUAL_V_BALANCE) for name in rotation.names])
    free_of = [k for k, row in enumerate(rotation.matrix) if not np.any(row[balance])]
    without = len(free_of)
    table.add("DUAL-V, translations and ±0.2 rad rotation",
              "conditions without a balance-mass parameter", without, "")  # fmt: skip
    equations = rotation.equations(4, atol=1e-9)
    lines = "\n".join(f"    {equations[k]}" for k in free_of)
    notes = f"""
Residuals are `C π` of the design's lumped parameters (rows of `C` in reduced
row-echelon form, leading coefficient 1). The 2R's and the SCARA's paper designs meet
their conditions to rounding; the DUAL-V's designs of eq (1) and eq (2) both meet the
{translation.rank} conditions of platform translations (three of them fix the four
counter-mass moments up to one free combination, the two equations' difference). With
platform rotation {without} of the {rotation.rank} conditions contain only the distal
links and the platform, on which the counter-masses of the links connecting the base
have no effect:

{lines}

which is the paper's statement (§2) that motion with a rotated platform is not
perfectly force-balanced, derived here from the mechanism.
"""
    return Result(tables=[table], notes=notes)


EXPERIMENT = Experiment(
    name="beyond_balancing_conditions",
    title="Force-balancing conditions derived from the motion (jaxbal.balancing)",
    run=run,
    paper="Briot et al. (2012) §3.3; Arakelian & Briot (2008) eqs (1)-(3); "
    "van der Wijk et al. (2013) eqs (1)-(2), §2",
)
