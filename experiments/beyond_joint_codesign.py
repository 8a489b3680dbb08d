"""Beyond the papers: joint counter-mass + trajectory co-design, robust over the payload.

For the 3R, SCARA, DUAL-V and Orthoglide: the paper's design (its counter-masses, a
nominal trapezoidal move), the sequential design (counter-masses optimised for that
fixed move) and the joint design (counter-masses and switch times together), each
minimising the worst-case (smooth max) peak shaking force over a payload grid, at the
same added-mass budget and under an actuator-torque limit; then the Pareto front
between peak shaking force and added mass (weighted-sum continuation, one compilation).
"""

from __future__ import annotations

import jax.numpy as jnp
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import jaxbal  # noqa: E402
from jaxbal.design import TrapezoidLine, joint_codesign, pareto_front, payload_metrics  # noqa: E402
from jaxbal.report import Experiment, Result, Table, save_figure  # noqa: E402
from jaxbal.robots import PickAndPlace, ScaraTrajectory  # noqa: E402
from jaxbal.robots import scara_balancing as sb  # noqa: E402

DEG = np.pi / 180
SAMPLES = 24
STEPS = 25
ROUNDS = 3  # shifted-penalty rounds
NOMINAL = {"u2": 0.25, "ratio": 0.5}  # trapezoid u1 = 0.125, u2 = 0.25 (fractions of T)
THETA_LOWER = {"u2": 0.05, "ratio": 0.05}
THETA_UPPER = {"u2": 0.45, "ratio": 1.0}
FIXED = 1e-9  # half-width of the trajectory box of the sequential design
TORQUE_MARGIN = 1.2  # torque limit: 1.2 x the paper design's worst peak torque
FRONT_WEIGHTS = (0.0, 0.01, 0.2, 1.0)
METRICS = ("peak_force", "added_mass", "peak_moment", "peak_torque")


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
    fronts = {}
    for name, (robot, start, end, cycle, payloads, budget, upper, path, label) in cases().items():
        ctx.progress(name)
        times = jaxbal.sample_times(cycle, SAMPLES)
        kwargs = {} if path is None else {"path": path}
        move = TrapezoidLine(jnp.asarray(start), jnp.asarray(end), times, **kwargs)
        paper_values = np.asarray(payload_metrics(robot, move, NOMINAL, payloads, METRICS))
        torque_limit = TORQUE_MARGIN * paper_values[:, 3].max()
        options = dict(
            payloads=payloads, robust="max", upper=upper, max_steps=STEPS, rounds=ROUNDS,
            constraints={"added_mass": budget, "peak_torque": torque_limit},
        )  # fmt: skip
        objective = {"peak_force": 1.0, "added_mass": 0.0}
        box = (
            {k: v - FIXED for k, v in NOMINAL.items()},
            {k: v + FIXED for k, v in NOMINAL.items()},
        )
        sequential = joint_codesign(robot, move, NOMINAL, objective, trajectory_lower=box[0],
                                    trajectory_upper=box[1], **options)  # fmt: skip
        joint = joint_codesign(sequential.robot, move, NOMINAL, objective,
                               trajectory_lower=THETA_LOWER, trajectory_upper=THETA_UPPER,
                               **options)  # fmt: skip
        designs = {
            f"paper ({label})": paper_values,
            "sequential": np.asarray(payload_metrics(sequential.robot, move, sequential.trajectory,
                                                     payloads, METRICS)),
            "joint": np.asarray(payload_metrics(joint.robot, move, joint.trajectory, payloads,
                                                METRICS)),
        }  # fmt: skip
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
        front = pareto_front(robot, move, NOMINAL, ("peak_force", "added_mass"), FRONT_WEIGHTS,
                             start={k: joint.design[k] for k in joint.design if k != "payload"},
                             trajectory_lower=THETA_LOWER, trajectory_upper=THETA_UPPER,
                             **options)  # fmt: skip
        table.add(f"{name}: front", "points", len(FRONT_WEIGHTS), "-")
        table.add(f"{name}: front", "non-dominated points", int(front.efficient.sum()), "-")
        table.add(f"{name}: front", "all feasible", bool(front.feasible.all()), "-")
        fronts[name] = (front, designs)
    return Result(tables=[table, per_payload], figures=[_plot(ctx, fronts)], notes=NOTES)


def _plot(ctx, fronts):
    fig, axes = plt.subplots(1, len(fronts), figsize=(4 * len(fronts), 3.5))
    for axis, (name, (front, designs)) in zip(axes, fronts.items(), strict=True):
        values = np.asarray(front.values)[np.asarray(front.efficient)]  # dominated: dropped
        axis.plot(values[:, 1], values[:, 0], "o-", color="k", ms=3, label="joint front")
        for (design, v), marker in zip(designs.items(), ("r*", "bs", "g^"), strict=True):
            axis.plot([v[0, 1]], [v[:, 0].max()], marker, ms=8, label=design)
        axis.set(title=name, xlabel="added mass [kg]", ylabel="worst peak ‖f‖ [N]")
        axis.legend(fontsize=7)
    fig.tight_layout()
    return save_figure(fig, ctx.figure_path("beyond_joint_codesign_fronts"))


NOTES = """
Every design is evaluated at every payload of the grid; the objective is the smooth
maximum (log-sum-exp) over the payloads of the peak shaking force, with the added mass
at most the paper's design's (3R: 5 kg, Orthoglide: 2 kg, where the paper adds none) and
the worst peak actuator torque at most 1.2 x the paper design's. The move is the paper's
end-effector line with a trapezoidal acceleration profile (nominal u1 = 0.125 T,
u2 = 0.25 T); the cycle time is fixed. Sequential: counter-masses for the nominal move;
joint: counter-masses and switch times together, started from the sequential design.
Front: weighted sum of peak force and added mass, warm-started from the joint design.
"""

EXPERIMENT = Experiment(
    name="beyond_joint_codesign",
    title="Beyond the papers — joint counter-mass + trajectory co-design over payloads",
    run=run,
    paper="Briot 2012; Arakelian & Briot 2008; van der Wijk 2013; Geng 2021",
)
