"""Geng, Arakelian, Chablat & Lemoine (2021): the Orthoglide with a varying payload.

§3 kinematic numbers (ρ, COM, designed COM acceleration), §3.1 cases 1-3 and Fig 4,
§3.2 Tables 1-2 (payloads 0…5 kg), §3.3 sensitivity to a payload error Δm (Tables 3-4,
whose values are withheld from us) as curves over Δm and as exact gradients through the
COM planner.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import jaxbal  # noqa: E402
from jaxbal.mujoco import confirm  # noqa: E402
from jaxbal.report import Experiment, Result, Table, save_figure  # noqa: E402
from jaxbal.planning import shaking_peaks  # noqa: E402
from jaxbal.robots import orthoglide  # noqa: E402
from jaxbal.robots.orthoglide_planning import motion_cases, switching_times  # noqa: E402

P_START = (0.0, 0.0, 0.0)  # m, §3
P_END = (-0.1, 0.07, -0.11)  # m, §3
DURATION = 0.1  # s, §3
PAYLOADS = (0.0, 1.0, 2.0, 3.0, 4.0, 5.0)  # kg, §3.2
SAMPLES = 401
MJX_SAMPLES = 51  # per trajectory, for the MJX confirmation tables
# Assumptions that reproduce Table 2 (least-squares fit of the 18 entries, slender-bar
# parallelograms m·L²/12; see NOTES): slider offset l and the moment reference point.
SLIDER_OFFSET = 0.069  # m
MOMENT_REFERENCE = (-0.020, -0.300, 0.010)  # m, base frame
COM_PAYLOAD = 2.0  # kg: the payload for which §3's COM coordinates are reproduced
DELTA_M = 0.1  # kg, payload error of §3.3 (not given in the paper)
DELTA_SWEEP = jnp.linspace(-0.5, 0.5, 21)  # kg, sensitivity curves

PAPER_RHO = {"rho_xi": 0.31, "rho_yi": 0.31, "rho_zi": 0.31}
# §3 prints "ρ_yf = 0.18, ρ_xf = 0.34": the labels are swapped (eq (1) gives ρ_xf = 0.18).
PAPER_RHO_F = {"rho_xf": 0.18, "rho_yf": 0.34, "rho_zf": 0.17}
PAPER_COM = {"x_Si": 0.04, "y_Si": 0.04, "z_Si": 0.04, "x_Sf": -0.04, "y_Sf": 0.09, "z_Sf": -0.05}
PAPER_TABLE1 = {
    "case1": (117.99, 212.08, 306.73, 401.55, 496.43, 591.35),
    "case2": (88.56, 152.82, 218.08, 283.65, 349.36, 415.14),
    "case3": (78.86, 144.57, 210.55, 276.31, 342.22, 408.14),
    "reduction2": (24.9, 27.9, 28.9, 29.3, 29.6, 29.8),
    "reduction3": (33.2, 31.8, 31.3, 31.2, 31.1, 30.9),
}
PAPER_TABLE2 = {
    "case1": (38.19, 64.11, 90.08, 116.06, 142.03, 168.01),
    "case2": (29.11, 47.18, 65.25, 83.33, 101.40, 119.47),
    "case3": (25.35, 43.66, 61.82, 79.93, 98.02, 116.09),
    "reduction2": (23.8, 26.4, 27.6, 28.2, 28.6, 28.9),
    "reduction3": (33.6, 31.9, 31.4, 31.1, 31.0, 30.9),
}


sample_jit = eqx.filter_jit(jaxbal.sample)


def robot_with(payload):
    return orthoglide(payload=payload, slider_offset=SLIDER_OFFSET)


def case_peaks(payload, reference):
    """Peak |F| [N] and |M| [N·m] of cases 1-3 for one payload: arrays (3,), (3,)."""
    robot = robot_with(payload)
    times = switching_times(DURATION, SAMPLES)
    peaks = [
        shaking_peaks(robot, plan, times, reference)
        for plan in motion_cases(robot, P_START, P_END, DURATION).values()
    ]
    return jnp.stack([f for f, _ in peaks]), jnp.stack([m for _, m in peaks])


def sensitivity(payload, delta, reference):
    """Case 3 (planned with payload + Δm) and case 4 (planned with the nominal payload),
    both executed with payload + Δm: peaks ``(F3, F4, M3, M4)``."""
    robot = robot_with(payload + delta)
    plans = motion_cases(robot, P_START, P_END, DURATION, planned_payload=payload)
    times = switching_times(DURATION, SAMPLES)
    f3, m3 = shaking_peaks(robot, plans["case3"], times, reference)
    f4, m4 = shaking_peaks(robot, plans["case4"], times, reference)
    return jnp.stack([f3, f4, m3, m4])


def run(ctx) -> Result:
    reference = jnp.asarray(MOMENT_REFERENCE)
    robot = robot_with(0.0)
    start, end = jnp.asarray(P_START), jnp.asarray(P_END)

    # --- §3: kinematics, COM, designed acceleration -------------------------------------
    ctx.progress("kinematics")
    kin = Table("orthoglide2021_kinematics", "§3: inputs, COM and COM acceleration", tolerance=0.03)
    rho_i, rho_f = robot.inverse_kinematics(start)[:3], robot.inverse_kinematics(end)[:3]
    for k, name in enumerate(PAPER_RHO):
        kin.add(name, "value", rho_i[k], "m", PAPER_RHO[name])
    for k, name in enumerate(PAPER_RHO_F):
        kin.add(name, "value", rho_f[k], "m", PAPER_RHO_F[name])
    # The paper's COM coordinates are those of the robot carrying 2 kg (see NOTES).
    loaded = robot_with(COM_PAYLOAD)
    coms = jnp.concatenate([loaded.com_of_point(start), loaded.com_of_point(end)])
    for k, name in enumerate(PAPER_COM):
        kin.add(name, "value", coms[k], "m", PAPER_COM[name])
        kin.add(name + "_rounded", "value", jnp.round(coms[k], 2), "m", PAPER_COM[name])
    com_i, com_f = robot.com_of_point(start), robot.com_of_point(end)
    for k, name in enumerate(PAPER_COM):
        kin.add(name + "_payload0", "value", jnp.concatenate([com_i, com_f])[k], "m")
    a_com = 4 * jnp.linalg.norm(com_f - com_i) / DURATION**2
    kin.add("a_com", "value", a_com, "m/s^2", 38.7)
    swapped = orthoglide(parallelogram_mass=0.248, slider_mass=0.396)
    d_swapped = swapped.com_of_point(end) - swapped.com_of_point(start)
    kin.add("a_com_swapped_masses", "value", 4 * jnp.linalg.norm(d_swapped) / DURATION**2, "m/s^2")
    quintic_peak, bang_peak = 10 / jnp.sqrt(3.0), 4.0
    kin.add("theoretical_reduction", "value", 100 * (1 - bang_peak / quintic_peak), "%", 30.7)

    # --- §3.2: Tables 1 and 2 (vmap over the payloads) ---------------------------------
    ctx.progress("Tables 1-2")
    payloads = jnp.asarray(PAYLOADS)
    forces, moments = jax.jit(jax.vmap(case_peaks, in_axes=(0, None)))(payloads, reference)
    _, moments_origin = jax.jit(jax.vmap(case_peaks, in_axes=(0, None)))(payloads, jnp.zeros(3))
    table1 = Table(
        "orthoglide2021_table1", "Max shaking force [N] and reduction [%]", tolerance=0.01
    )
    table2 = Table("orthoglide2021_table2", "Max shaking moment [N·m] about c", tolerance=0.01)
    table2o = Table("orthoglide2021_table2_origin", "Max shaking moment [N·m] about O")
    for table, values, paper, unit in (
        (table1, forces, PAPER_TABLE1, "N"),
        (table2, moments, PAPER_TABLE2, "N*m"),
        (table2o, moments_origin, None, "N*m"),
    ):
        for i, payload in enumerate(PAYLOADS):
            row = f"payload{int(payload)}"
            for k in range(3):
                column = f"case{k + 1}"
                table.add(row, column, values[i, k], unit, paper and paper[column][i])
            for k in (1, 2):
                column = f"reduction{k + 1}"
                reduction = 100 * (values[i, 0] - values[i, k]) / values[i, 0]
                table.add(row, column, reduction, "%", paper and paper[column][i])

    # --- MJX confirmation of Tables 1-2: the same 18 trajectories through mjx.inverse --
    ctx.progress("MJX confirmation")
    mjx_tables = [
        Table(f"{table.id}_mjx", f"{table.id}: max relative difference jaxbal vs MJX "
              "(closed chain, tolerance 1e-6; moments about O)")
        for table in (table1, table2)
    ]  # fmt: skip
    mjx_times = switching_times(DURATION, MJX_SAMPLES)
    for payload in PAYLOADS:
        loaded = robot_with(payload)
        for case, plan in motion_cases(loaded, start, end, DURATION).items():
            states = sample_jit(plan, mjx_times)  # compiled once per case structure
            confirmation = confirm(loaded, *states, engine="mjx")
            for table in mjx_tables:
                row = f"payload{int(payload)} {case}"
                table.add(row, "force_rel", confirmation.force_relative, "-")
                table.add(row, "moment_rel", confirmation.moment_relative, "-")

    # --- Fig 4: time histories for payload 0 -------------------------------------------
    ctx.progress("Fig 4")
    times = jaxbal.sample_times(DURATION, SAMPLES)
    plans = motion_cases(robot, start, end, DURATION)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5))
    for (name, plan), style in zip(plans.items(), ("-", "--", ":"), strict=True):
        force, moment = jax.jit(jaxbal.planning.wrench_along)(robot, plan, times)
        moment = moment - jnp.cross(reference, force)
        axes[0].plot(times, jnp.linalg.norm(force, axis=1), "k" + style, label=name)
        axes[1].plot(times, jnp.linalg.norm(moment, axis=1), "k" + style, label=name)
    axes[0].set(xlabel="time [s]", ylabel="|F_sh| [N]", title="shaking force (cf. Fig 4a)")
    axes[1].set(xlabel="time [s]", ylabel="|M_sh| about c [N·m]", title="shaking moment (Fig 4b)")
    axes[0].legend()
    figures = [save_figure(fig, ctx.figure_path("geng2021_fig4_orthoglide_shaking"))]

    # --- §3.3: sensitivity to the payload error ----------------------------------------
    ctx.progress("sensitivity")
    nominal = payloads[1:]
    at_delta = jax.jit(jax.vmap(sensitivity, in_axes=(0, None, None)))
    values = at_delta(nominal, DELTA_M, reference)  # (5, 4)
    # exact derivatives w.r.t. Δm: case 3 through the planner, case 4 with the plan fixed
    slopes = jax.jit(jax.vmap(jax.jacfwd(sensitivity, argnums=1), in_axes=(0, None, None)))(
        nominal, DELTA_M, reference
    )
    table3 = Table("orthoglide2021_table3", f"Max shaking force [N], Δm = {DELTA_M} kg")
    table4 = Table("orthoglide2021_table4", f"Max shaking moment [N·m], Δm = {DELTA_M} kg")
    for table, offset, unit in ((table3, 0, "N"), (table4, 2, "N*m")):
        for i, payload in enumerate(PAYLOADS[1:]):
            row = f"payload{int(payload)}"
            case3, case4 = values[i, offset], values[i, offset + 1]
            table.add(row, "case3", case3, unit)
            table.add(row, "case4", case4, unit)
            table.add(row, "difference", case4 - case3, unit)
            table.add(row, "dcase3_ddm", slopes[i, offset], unit + "/kg")
            table.add(row, "dcase4_ddm", slopes[i, offset + 1], unit + "/kg")

    sweep = jax.jit(
        jax.vmap(jax.vmap(sensitivity, in_axes=(None, 0, None)), in_axes=(0, None, None))
    )(nominal, DELTA_SWEEP, reference)  # (5, d, 4)
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.5))
    for i, payload in enumerate(PAYLOADS[1:]):
        axes[0].plot(DELTA_SWEEP, sweep[i, :, 1] - sweep[i, :, 0], label=f"{payload:g} kg")
        axes[1].plot(DELTA_SWEEP, sweep[i, :, 3] - sweep[i, :, 2], label=f"{payload:g} kg")
    axes[0].set(xlabel="Δm [kg]", ylabel="F case 4 − case 3 [N]", title="force sensitivity")
    axes[1].set(xlabel="Δm [kg]", ylabel="M case 4 − case 3 [N·m]", title="moment sensitivity")
    axes[0].legend(title="nominal payload")
    figures.append(save_figure(fig, ctx.figure_path("geng2021_sensitivity_orthoglide")))

    notes = NOTES.format(
        a_com=float(a_com),
        l=SLIDER_OFFSET,
        c=MOMENT_REFERENCE,
        dm=DELTA_M,
    )
    return Result(
        tables=[kin, table1, table2, table2o, table3, table4, *mjx_tables],
        figures=figures,
        notes=notes,
    )


NOTES = """
**Model.** Three PRPaR legs, L = 0.31 m, s = +1 (§3), no gravity. Masses as eq (6) reads
them: each parallelogram 0.396 kg (COM at mid-BC), each slider 0.248 kg (COM at
(A_i+B_i)/2), joint P 0.1 kg, payload a point mass at P. §3 calls 0.396 kg "sliders": with
that reading the designed COM acceleration is 34.3 m/s² instead of 38.7 (ours:
{a_com:.2f} m/s²), and Table 1 is missed by up to 10 %, so §3 swaps the words, not eq (6).
The prismatic-joint labels of §3 are swapped too (eq (1) gives ρ_xf = 0.18, ρ_yf = 0.34).
The COM plan (case 3) solves eq (6) with eq (1) for P by Newton's method with implicit
differentiation (`jaxbal.implicit`), so every number below is differentiable.

**Table 1** (force) depends only on masses and kinematics; it is reproduced without
gravity (with gravity along any axis the errors grow to 7-19 %). Differences ≤ 0.45 %:
case 1 is 0.07-0.14 % low, case 3 0.23-0.35 % low (our designed COM acceleration is
38.72 m/s², the paper's 78.86 N / 2.032 kg would need 38.81), and case 2 at 0 kg is
0.43 % high because our maximum is the exact supremum, reached just before the
bang-bang switch at T/2 (sampling on a grid without that instant gives +0.3 %). The
reduction columns are percentages: their "rel. diff" is relative to the percentage
(payload 0, case 2: 24.57 vs 24.9 %, i.e. 0.33 percentage points).

**Table 2** (moment). About the intersection O of the prismatic axes the payload adds
no moment at all (it moves on a straight line through O), while the paper's moment grows
by 26 N·m per kg in case 1: the ADAMS moment is taken about another point. Its
perpendicular distance to the path is 25.97/94.87 = 0.274 m (case 1) and
18.07/65.73 = 0.275 m (case 2). A least-squares fit of the 18 entries, with slender-bar
parallelograms (I = m L²/12 about transverse axes) and the free slider offset l, gives
the reference point c = {c} m and l = {l} m (rms 0.08 %, max 0.13 %). The fit is not
unique (another minimum, c ≈ (−0.26, −0.11, −0.32) m with l ≈ 0.64 m, fits as well but
is not physical; with l = 0 the best c ≈ (−0.01, −0.31, 0.01) m gives max 1 %); these
are modelling assumptions, not data from the paper. The moments about O are given in
`orthoglide2021_table2_origin` for reference.

**MJX confirmation.** `orthoglide2021_table1_mjx` and `orthoglide2021_table2_mjx` give,
for each of the 18 trajectories of Tables 1-2 (51 samples each, the switch at T/2
included), the maximum difference between jaxbal's shaking force/moment and the base
reaction of `mjx.inverse` (sliders, ball-jointed parallelograms and platform as a MuJoCo
tree closed by `connect` constraints), relative to the peak gross inertial force/moment
(`jaxbal.mjx.confirm`); the tolerance for this closed chain is 1e-6. Moments are compared
about O (the two tables hold the same numbers); about c the difference changes by at most
|c|·|Δf| (|c| = 0.30 m).

**COM coordinates of §3.** S_i = (0.04, 0.04, 0.04), S_f = (−0.04, 0.09, −0.05) m are
not those of the unloaded robot (their difference would give 58 m/s², not 38.7, for
any l). They are those of the robot carrying **2 kg**: the COM displacement is then
(−0.081, 0.050, −0.093) m, and the six rounded values are all reproduced for any
0.067 m ≤ l ≤ 0.169 m, which contains the l = {l} m found independently from Table 2.
The table gives them for 2 kg (exact, and rounded to the paper's 0.01 m) and for 0 kg
(`_payload0`); the
38.7 m/s² is the unloaded value (2 kg would give 53.4 m/s²). ρ_zf = 0.1750 m is
printed as 0.17 (0.17496 rounds down).

**Reductions.** The theoretical 30.7 % (1 − 4/(10/√3)) is the reduction of the peak COM
acceleration; with growing payload the COM tends to P and our case-3 reduction tends to
it, as in the paper.

**Sensitivity (§3.3).** Δm = {dm} kg (not given in the paper). Case 3: COM plan made
for the true payload m + Δm; case 4: plan made for m, run with m + Δm. `dcase3_ddm` is
the exact derivative through the planner (implicit differentiation of the COM inverse
kinematics); `dcase4_ddm` the derivative with the plan fixed. The case-3 force has a
constant norm (the bang-bang COM plan is optimal for the true payload), so the force
difference case 4 − case 3 is ≥ 0 for both signs of Δm and has a kink at Δm = 0 (see the
figure): to first order it is |Δm| times the one-sided slope difference. As in the
paper, the difference is small (≤ 0.4 N, ≤ 0.25 N·m at Δm = 0.1 kg) and decreases as
the payload grows.
"""

EXPERIMENT = Experiment(
    name="geng2021_orthoglide",
    title="Geng et al. 2021 — Orthoglide with varying payload (Tables 1-4, Fig 4)",
    run=run,
    paper="Geng, Arakelian, Chablat & Lemoine, Robotics 10(1) 30 (2021), §3",
)
