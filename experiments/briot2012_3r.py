"""Briot, Arakelian & Le Baron (2012), Tables 2-3 and Figs 9-10: the planar 3R arm.

Eight paths across the 0.3 m test square (numbering: :mod:`jaxbal.robots.planar_arm`),
0.5 s each, end-effector orientation φ from 0 to 120°, three motion laws
(:func:`jaxbal.robots.planar_arm_studies.motion_laws`):

1. quintic profile on the end-effector position and on φ;
2. bang-bang profile on the COM line; φ(t) a degree-8 polynomial meeting eqs (20),
   its three free coefficients optimised (optax L-BFGS on a smoothed maximum, with
   continuation in the smoothing) to minimise the maximal shaking moment, eq (19);
3. trapezoidal COM profile under ``|dτ_i/dt| ≤ 3·10⁴ N·m/s`` with case 2's φ law.

The paper's values of Tables 2 and 3 are withheld from us: the CSVs carry ours only.
"""

from __future__ import annotations

import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")

import jaxbal  # noqa: E402
from jaxbal.mujoco import confirm_cases  # noqa: E402
from jaxbal.planning import peak_norm, wrench_along  # noqa: E402
from jaxbal.report import Experiment, Result, Table, plot_histories  # noqa: E402
from jaxbal.robots.planar_arm import BRIOT2012_PATHS, path_name, square_points  # noqa: E402
from jaxbal.robots.planar_arm_studies import motion_laws  # noqa: E402

DURATION = 0.5  # s
RATE_LIMIT = 3.0e4  # N·m/s
CENTRE, EDGE = (0.0, 0.487), 0.3  # m, Fig 7
PHI_START, PHI_END = 0.0, 2.0 * jnp.pi / 3.0  # rad
ELBOW = -1  # end-effector IK branch whose COM IK is the "+" mode of eq (15)
COM_MODE = 1
SAMPLES = 2001
MJX_SAMPLES = 51  # samples per trajectory for the MJX confirmation
FIG_PATH = "P15P7"  # the path of Figs 9 and 10
STYLES = {
    "case1": {"color": "k", "label": "case 1 (quintic, end-effector)"},
    "case2": {"color": "k", "linestyle": "--", "label": "case 2 (bang-bang COM, optimal φ)"},
    "case3": {"color": "0.6", "label": "case 3 (trapezoid COM, rate-limited)"},
}
FIGURES = (
    ("‖f_sh‖", "N", "briot2012_fig9_3r_shaking_force"),
    ("m_sh,z", "N·m", "briot2012_fig10_3r_shaking_moment"),
)


def run(ctx) -> Result:
    robot = jaxbal.robots.planar_3r()
    points = square_points(CENTRE, EDGE)
    times = jaxbal.sample_times(DURATION, SAMPLES)
    force_table = Table("briot2012_table2", "3R: max shaking force norm")
    moment_table = Table("briot2012_table3", "3R: max shaking moment")
    mjx_force = Table("briot2012_table2_mjx", "3R: force, max relative difference vs MJX")
    mjx_moment = Table("briot2012_table3_mjx", "3R: moment, max relative difference vs MJX")
    mjx_times = jaxbal.sample_times(DURATION, MJX_SAMPLES)
    curves, details = ({}, {}), []
    for a, b in BRIOT2012_PATHS:
        name = path_name(a, b)
        ctx.progress(f"3R {name}")
        laws = motion_laws(
            robot, points[a - 1], points[b - 1], DURATION, RATE_LIMIT, (PHI_START, PHI_END),
            elbow=ELBOW, com_branch=COM_MODE, check_samples=SAMPLES,
        )  # fmt: skip
        cases = {case: (robot, path) for case, path in laws.trajectories.items()}
        for case, agreement in confirm_cases(cases, mjx_times).items():
            forces, moments = wrench_along(robot, laws.trajectories[case], times)
            force_table.add(name, case, peak_norm(forces), "N")
            moment_table.add(name, case, jnp.max(jnp.abs(moments[:, 2])), "N·m")
            mjx_force.add(name, case, agreement.force_relative, "-")
            mjx_moment.add(name, case, agreement.moment_relative, "-")
            if name == FIG_PATH:
                curves[0][case], curves[1][case] = jnp.linalg.norm(forces, axis=-1), moments[:, 2]
        details.append(
            f"| {name} | {', '.join(f'{float(c):.4g}' for c in laws.coefficients)} | "
            f"{float(laws.plan.profile.u1):.4f} | {float(laws.plan.profile.u2):.4f} |"
        )
    figures = [
        plot_histories(
            ctx.figure_path(file),
            times,
            [(f"{quantity} [{unit}]", values)],
            STYLES,
            title=f"3R, path {FIG_PATH}",
            figsize=(6, 3.5),
        )  # fmt: skip
        for (quantity, unit, file), values in zip(FIGURES, curves, strict=True)
    ]
    notes = (
        NOTES
        + "\n\nOptimised φ-law coefficients c (φ = φ0 + (φf−φ0)·[10u³−15u⁴+6u⁵ + "
        + "u³(1−u)³(c0 + c1 u + c2 u²)]) and trapezoid switch times:\n\n"
        + "| path | c0, c1, c2 | u1 | u2 |\n|---|---|---:|---:|\n"
        + "\n".join(details)
    )
    return Result(
        tables=[force_table, moment_table, mjx_force, mjx_moment], figures=figures, notes=notes
    )


NOTES = """
Robot: §3.2 parameters, payload 5 kg, link inertias about their COM, horizontal
plane. Test square centred at (0, 0.487) m, edge 0.3 m, same point numbering as the
2R. The published Tables 2-3 are withheld from this project; they are compared
independently. Case 2's shaking force does not depend on φ (its norm is
m_tot·4·|Δx_S|/T²); only the moment is optimised. The maximum over time is smoothed
by τ·logsumexp(|m|/τ) with τ decreasing from 3 to 0.03 N·m; the reported values are
the true maxima on 2001 samples. The `_mjx` tables give the largest relative
difference between jaxbal and MuJoCo MJX's base reaction on each trajectory (51 samples;
tolerance 1e-9).
"""

EXPERIMENT = Experiment(
    name="briot2012_3r",
    title="Briot et al. 2012 — planar 3R (Tables 2-3, Figs 9-10)",
    run=run,
    paper="Briot, Arakelian & Le Baron, Mech. Mach. Theory 57 (2012) 1-12, §3.2",
)
