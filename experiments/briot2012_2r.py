"""Briot, Arakelian & Le Baron (2012), Table 1 and Fig 5: the planar 2R arm.

Eight paths across the 0.45 m test square (numbering: :mod:`jaxbal.square_paths`),
0.5 s each, three motion laws:

1. quintic profile on the end-effector straight line;
2. bang-bang profile on the straight line of the total centre of mass (eqs 3-4);
3. trapezoidal acceleration on the COM line, switch times optimised under
   ``|dτ_i/dt| ≤ 3·10⁴ N·m/s`` (eqs 5-6).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import jaxbal  # noqa: E402
from jaxbal.planning import ComLine, EndEffectorLine, com_line, peak_norm, wrench_along  # noqa: E402
from jaxbal.profiles import BangBang, Quintic  # noqa: E402
from jaxbal.rate_limit import plan_rate_limited  # noqa: E402
from jaxbal.report import Experiment, Result, Table, save_figure  # noqa: E402
from jaxbal.square_paths import BRIOT2012_PATHS, path_name, square_points  # noqa: E402

DURATION = 0.5  # s
RATE_LIMIT = 3.0e4  # N·m/s
CENTRE, EDGE = (0.0, 0.475), 0.45  # m, Fig 3
ELBOW = -1  # end-effector IK branch whose COM IK is the "+" mode of eq (10)
COM_MODE = 1
SAMPLES = 2001

# Table 1 of the paper (max shaking force norm, N), in the order of BRIOT2012_PATHS.
PAPER_TABLE1 = {
    "case1": (194.7, 165.3, 178.8, 178.2, 155.3, 218.7, 201.3, 195.4),
    "case2": (121.0, 85.0, 47.5, 41.5, 44.3, 136.3, 121.7, 111.8),
    "case3": (124.0, 86.0, 48.0, 41.8, 44.7, 137.7, 123.2, 113.1),
}


def com_path(profile, data):
    """COM straight line with ``profile`` (``data = (robot, start, end)``)."""
    robot, start, end = data
    return ComLine(robot, jaxbal.StraightLine(start, end, profile, DURATION), mode=COM_MODE)


def cases(robot, start_point, end_point):
    """The three motion laws between two end-effector points: name ↦ trajectory."""
    q_start = robot.inverse_kinematics(start_point, ELBOW)
    q_end = robot.inverse_kinematics(end_point, ELBOW)
    line = jaxbal.StraightLine(start_point, end_point, Quintic(), DURATION)
    case2 = com_line(robot, q_start, q_end, BangBang(), DURATION, mode=COM_MODE)
    plan = plan_rate_limited(
        robot, com_path, (robot, case2.line.start, case2.line.end), DURATION, RATE_LIMIT
    )
    case3 = com_path(plan.profile, (robot, case2.line.start, case2.line.end))
    return {"case1": EndEffectorLine(robot, line, ELBOW), "case2": case2, "case3": case3}, plan


@jax.jit
def _forces(robot, path, times):
    return wrench_along(robot, path, times)[0]


def run(ctx) -> Result:
    robot = jaxbal.robots.planar_2r()
    points = square_points(CENTRE, EDGE)
    times = jaxbal.sample_times(DURATION, SAMPLES)
    table = Table("briot2012_table1", "2R: max shaking force norm", tolerance=0.03)
    plans, curves = {}, {}
    for index, (a, b) in enumerate(BRIOT2012_PATHS):
        name = path_name(a, b)
        ctx.progress(f"2R {name}")
        laws, plan = cases(robot, points[a - 1], points[b - 1])
        plans[name] = plan
        for case, path in laws.items():
            forces = _forces(robot, path, times)
            table.add(name, case, peak_norm(forces), "N", PAPER_TABLE1[case][index])
            if name == "P5P9":
                curves[case] = jnp.linalg.norm(forces, axis=-1)
    fig, ax = plt.subplots(figsize=(6, 3.5))
    styles = {
        "case1": ("k", "-", "case 1 (quintic, end-effector)"),
        "case2": ("k", "--", "case 2 (bang-bang, COM)"),
        "case3": ("0.6", "-", "case 3 (trapezoid, COM, rate-limited)"),
    }
    for case, (color, line, label) in styles.items():
        ax.plot(times, curves[case], color=color, linestyle=line, label=label)
    ax.set(xlabel="time [s]", ylabel="‖f_sh‖ [N]", title="2R, path P5P9 (cf. Fig 5)")
    ax.legend(fontsize=8)
    figure = save_figure(fig, ctx.figure_path("briot2012_fig5_2r_shaking_force"))

    rows = [
        "| path | u1 | u2 | peak accel / bang-bang | peak dτ/dt [N·m/s] |",
        "|---|---:|---:|---:|---:|",
    ]
    for name, plan in plans.items():
        rows.append(
            f"| {name} | {float(plan.profile.u1):.4f} | {float(plan.profile.u2):.4f} | "
            f"{float(plan.peak_acceleration) / 4:.4f} | {float(plan.peak_rate):.4g} |"
        )
    notes = NOTES + "\n\nOptimised trapezoid switch times (fractions of T):\n\n" + "\n".join(rows)
    return Result(tables=[table], figures=[figure], notes=notes)


NOTES = """
Robot: §3.1 parameters, payload 5 kg at the tip, link inertias about their own COM,
horizontal plane. Test square centred at (0, 0.475) m, edge 0.45 m, P1 at the
bottom-left corner and counter-clockwise numbering (see `jaxbal.square_paths`): this is
the only numbering (up to its mirror image) for which the 16 case-2 entries match the
paper (all within 0.3%). End-effector IK branch: the one whose COM inverse kinematics
is the "+" working mode of eq (10) (q2 < 0 on the whole square).
Case 2's shaking force has constant norm m_tot·4·|x_Sf − x_S0|/T² by construction.
Case 3: switch times from a refined vectorised grid search (`jaxbal.rate_limit`), with
the torque rates computed by exact inverse dynamics (Lagrange, autodiff) including the
jerk of the joint motion.
"""

EXPERIMENT = Experiment(
    name="briot2012_2r",
    title="Briot et al. 2012 — planar 2R (Table 1, Fig 5)",
    run=run,
    paper="Briot, Arakelian & Le Baron, Mech. Mach. Theory 57 (2012) 1-12, §3.1",
)
