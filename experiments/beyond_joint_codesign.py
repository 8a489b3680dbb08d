"""Beyond the papers: joint counter-mass + trajectory co-design, robust over the payload.

For the 3R, SCARA, DUAL-V and Orthoglide: the paper's design, the sequential design
(counter-masses for the paper's nominal move) and the joint design (counter-masses and
switch times together), minimising the worst-case peak shaking force over a payload grid
under an added-mass budget and a torque limit; then Pareto fronts of the peak force
against added mass, peak moment and RMS torque, end points checked by independent solves.
"""

from __future__ import annotations

import jax.numpy as jnp
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import jaxbal  # noqa: E402
import jaxbal.design as jd  # noqa: E402
from jaxbal.report import Experiment, Result, Table, release_compiled_programs, save_figure  # noqa: E402
from jaxbal.robots import PickAndPlace, ScaraTrajectory  # noqa: E402
from jaxbal.robots import scara_balancing as sb  # noqa: E402

DEG = np.pi / 180
SAMPLES = 24
STEPS = 100
ROUNDS = 6  # shifted-penalty rounds (at most)
NOMINAL = {"u2": 0.25, "ratio": 0.5}  # trapezoid u1 = 0.125, u2 = 0.25 (fractions of T)
THETA_LOWER = {"u2": 0.05, "ratio": 0.05}
THETA_UPPER = {"u2": 0.45, "ratio": 1.0}
FIXED = 1e-9  # half-width of the sequential design's trajectory box
TORQUE_MARGIN = 1.2  # torque limit: 1.2 x the paper design's worst peak torque
#: fronts (metric a, metric b): weights w of b; w = 0 is the joint design's problem
FRONTS = {
    ("peak_force", "added_mass"): (0.0, 0.01, 0.2, 1.0),
    ("peak_force", "peak_moment"): (0.0, 0.5, 1.0),
    ("peak_force", "rms_torque"): (0.0, 0.5, 1.0),
}
METRICS = ("peak_force", "added_mass", "peak_moment", "peak_torque", "rms_torque")
UNITS = {"peak_force": "N", "added_mass": "kg", "peak_moment": "N·m", "rms_torque": "N·m|N"}
MOTION_ONLY = "joint at the paper's added mass (switch times only)"


def scara_lift(robot, line):
    """SCARA path: the paper's pick-and-place with a 25 mm lift along the line."""
    return ScaraTrajectory(robot, PickAndPlace(line.start, line.end, line.duration,
                                               line.profile, lift=0.025))  # fmt: skip


def cases():
    """name -> (paper robot, start, end, cycle time [s], payloads [kg], budget [kg], upper,
    path, label of the paper's design)."""
    scara = sb.force_balanced(jaxbal.robots.scara())
    dual_v = jaxbal.robots.dual_v()
    return {
        # Briot 2012 §3.2: 3R, 5 kg payload nominal; no counterweights (COM planning only)
        "3R": (jaxbal.robots.planar_3r(), [0.225, 0.25, 0.0], [0.225, 0.70, 0.0], 0.5,
               np.linspace(0.0, 5.0, 5), 5.0, {"counter_distance": 0.2}, None,
               "no counterweights"),
        # Arakelian & Briot 2008: force-balanced SCARA, the paper's move
        "SCARA": (scara, [0.15, 0.2, 83 * DEG], [-0.15, 0.2, 157 * DEG], 0.3,
                  np.linspace(0.0, 0.5, 5), float(jaxbal.design.added_mass(scara)),
                  {"counter_distance": 0.3}, scara_lift, "force-balanced (eqs 1-3)"),
        # van der Wijk 2013: DUAL-V with its counter-masses, payload 0-0.5 kg
        "DUAL-V": (dual_v, [0.0, -0.05, 0.0], [0.05, 0.05, 0.0], 0.1,
                   np.linspace(0.0, 0.5, 5), float(jaxbal.design.added_mass(dual_v)),
                   {"counter_distance": 0.1}, None, "Table 1 counter-masses"),
        # Geng 2021 §3: Orthoglide move, payload 0-5 kg; no counter-sliders in the paper
        "Orthoglide": (jaxbal.robots.orthoglide(), [0.0, 0.0, 0.0], [-0.1, 0.07, -0.11], 0.1,
                       np.linspace(0.0, 5.0, 5), 2.0, None, None, "no counter-sliders"),
    }  # fmt: skip


def run(ctx) -> Result:
    table = Table("beyond_joint_codesign", "Joint co-design, robust over the payload")
    per_payload = Table("beyond_joint_codesign_payloads", "Peak shaking force at every payload")
    fronts, summary = {}, []
    for name, (robot, start, end, cycle, payloads, budget, upper, path, label) in cases().items():
        ctx.progress(name)
        times = jaxbal.sample_times(cycle, SAMPLES)
        kwargs = {} if path is None else {"path": path}
        move = jd.TrapezoidLine(jnp.asarray(start), jnp.asarray(end), times, **kwargs)
        paper_values = np.asarray(jd.payload_metrics(robot, move, NOMINAL, payloads, METRICS))
        torque_limit = TORQUE_MARGIN * paper_values[:, 3].max()
        options = dict(
            payloads=payloads, robust="max", upper=upper, max_steps=STEPS, rounds=ROUNDS,
            constraints={"added_mass": budget, "peak_torque": torque_limit},
        )  # fmt: skip
        objective = {"peak_force": 1.0, "added_mass": 0.0}
        box = [{k: v + d for k, v in NOMINAL.items()} for d in (-FIXED, FIXED)]
        bounds = {"trajectory_lower": THETA_LOWER, "trajectory_upper": THETA_UPPER}
        sequential = jd.joint_codesign(robot, move, NOMINAL, objective, trajectory_lower=box[0],
                                    trajectory_upper=box[1], **options)  # fmt: skip
        joint = jd.joint_codesign(sequential.robot, move, NOMINAL, objective, **bounds, **options)

        def values_of(s, move=move, payloads=payloads):
            return np.asarray(jd.payload_metrics(s.robot, move, s.trajectory, payloads, METRICS))

        designs = {f"paper ({label})": paper_values, "sequential": values_of(sequential),
                   "joint": values_of(joint)}  # fmt: skip
        solved = [sequential, joint]
        if paper_values[0, 1] < budget:
            # at the paper's added mass: the paper's robot, only the switch times optimised
            solved.append(jd.joint_codesign(robot, move, NOMINAL, objective, free=(), **bounds,
                                         **options))  # fmt: skip
            designs[MOTION_ONLY] = values_of(solved[-1])
        for design, values in designs.items():
            row = f"{name}: {design}"
            table.add(row, "worst peak ‖f‖ over payloads", values[:, 0].max(), "N")
            table.add(row, "mean peak ‖f‖ over payloads", values[:, 0].mean(), "N")
            table.add(row, "worst peak ‖m‖", values[:, 2].max(), "N·m")
            table.add(row, "worst peak ‖τ‖", values[:, 3].max(), "N·m|N")
            table.add(row, "added mass", values[0, 1], "kg")
            for p, force in zip(payloads, values[:, 0], strict=True):
                per_payload.add(f"{name}: {design}", f"payload {p:.3g} kg", force, "N")
        table.add(f"{name}: joint", "switch time u1 / T", joint.trajectory["ratio"]
                  * joint.trajectory["u2"], "-")  # fmt: skip
        table.add(f"{name}: joint", "switch time u2 / T", joint.trajectory["u2"], "-")
        table.add(f"{name}: joint", "feasible (added mass, torque limit)", joint.feasible, "-")
        gain = 1 - designs["joint"][:, 0].max() / designs["sequential"][:, 0].max()
        table.add(f"{name}: joint", "improvement over sequential (worst peak ‖f‖)", gain, "-")
        start_design = {k: joint.design[k] for k in joint.design if k != "payload"}
        fronts[name] = [designs]
        for (a, b), weights in FRONTS.items():
            front = jd.pareto_front(robot, move, joint.trajectory, (a, b), weights,
                                 start=start_design, **bounds, **options)  # fmt: skip
            # single-objective optimum of b found independently, from the sequential design
            # and the nominal move (same compilation as the front; w = 0 is the joint design)
            alone = jd.joint_codesign(sequential.robot, move, NOMINAL, {a: 0.0, b: 1.0},
                                      **bounds, **options)  # fmt: skip
            optima = (float(joint.metrics[a][1]), float(alone.metrics[b][1]))
            _front_rows(table, f"{name}: front {a} vs {b}", front, (a, b), optima)
            solved += front.solutions
            fronts[name].append(front)
        table.add(f"{name}: joint", "largest constraint excess / bound (every solve)",
                  max(jd.constraint_excess(s) for s in solved), "-")  # fmt: skip
        parts = [f"{d} {v[:, 0].max():.4g} N ({v[0, 1]:.3g} kg)" for d, v in designs.items()]
        summary.append(f"* {name}, {payloads[0]:g}-{payloads[-1]:g} kg: {'; '.join(parts)}.")
        release_compiled_programs()  # ~7,000 memory mappings per robot
    notes = NOTES + "\nWorst peak shaking force over the payload grid (added mass):\n\n"
    return Result(tables=[table, per_payload], figures=[_plot(ctx, fronts)],
                  notes=notes + "\n".join(summary) + "\n")  # fmt: skip


def _front_rows(table, row, front, metrics, optima):
    """A front's points, dominance, and end points against the independent optima
    ``optima`` (of metric a at w = 0, of b at w = 1), relative."""
    values = np.asarray(front.values)
    for w, point in zip(np.asarray(front.weights), values, strict=True):
        for metric, value in zip(metrics, point, strict=True):
            table.add(row, f"w = {w:g}: {metric} (smooth max)", value, UNITS[metric])
    table.add(row, "points", len(values), "-")
    table.add(row, "non-dominated points", int(front.efficient.sum()), "-")
    table.add(row, "all feasible", bool(front.feasible.all()), "-")
    for k, (end, optimum) in enumerate(zip((values[0, 0], values[-1, 1]), optima, strict=True)):
        # relative to the optimum, or to the front's range where the optimum is ~0
        scale = max(abs(optimum), float(np.ptp(values[:, k])), 1e-300)
        table.add(row, f"w = {k}: end point / independent optimum of {metrics[k]} − 1",
                  (end - optimum) / scale, "-")  # fmt: skip


def _plot(ctx, fronts):
    """One column per robot, one row per front; designs marked at their worst payload."""
    fig, axes = plt.subplots(len(FRONTS), len(fronts), figsize=(4 * len(fronts), 9.6),
                             squeeze=False)  # fmt: skip
    for column, (name, (designs, *robot_fronts)) in enumerate(fronts.items()):
        for axis, front, (a, b) in zip(axes[:, column], robot_fronts, FRONTS, strict=True):
            marks = {
                d[:28]: (v[:, METRICS.index(b)].max(), v[:, 0].max()) for d, v in designs.items()
            }
            jd.plot_front(axis, front, (f"worst {a} [{UNITS[a]}]", f"{b} [{UNITS[b]}]"), marks)
            axis.set_title(name)
    fig.tight_layout()
    return save_figure(fig, ctx.figure_path("beyond_joint_codesign_fronts"))


NOTES = """
Every design is evaluated at every payload of the grid; the objective is the smooth
maximum (log-mean-exp) over the payloads of the peak shaking force, with the added mass
at most the paper's design's (3R: 5 kg, Orthoglide: 2 kg, where the paper adds none) and
the worst peak actuator torque at most 1.2 x the paper design's, both to 1e-6 of the
bound. Move: the paper's end-effector line, trapezoidal acceleration (nominal u1 =
0.125 T, u2 = 0.25 T), fixed cycle time. Sequential: counter-masses for the nominal move;
joint: counter-masses and switch times together, started from the sequential design.
Fronts: weighted sums of the peak force and one other metric, warm-started from the joint
design, dominated points (beyond 1e-6) re-solved from the point dominating them. End
points vs single-objective optima found independently (w = 0: the joint design; w = 1:
metric b alone from the sequential design and nominal move): peaks are maxima over the
samples, a non-smooth objective at whose kinks L-BFGS stops, so they agree to the
relative difference shown (to the front's range where the optimum is zero), not to
rounding.
"""

EXPERIMENT = Experiment(
    name="beyond_joint_codesign",
    title="Beyond the papers — joint counter-mass + trajectory co-design over payloads",
    run=run,
    paper="Briot 2012; Arakelian & Briot 2008; van der Wijk 2013; Geng 2021",
)
