"""The README's benchmark block, rendered from a ``bench_<backend>.json`` result (no
side effects on import: the tests check that README.md quotes the stored JSON)."""

from __future__ import annotations

from pathlib import Path

from jaxbal.report import atomic_write_text

BENCH_START, BENCH_END = "<!-- bench:start -->", "<!-- bench:end -->"
TARGETS = {
    "generic_over_closed_form_time": 1.5,
    "speedup_vs_mujoco_c_loop_all_devices_2r": 50.0,
    "speedup_vs_before_dual_v_orthoglide": 5.0,
    "grad_over_value": 2.0,
    "first_call_seconds": 1.5,
    "warm_first_call_seconds": 0.5,
    "codesign_speedup_compiled_20_variables": 20.0,
    "sweep_speedup_vs_design_loop": 20.0,
}


#: the Python loops of the sweep benchmark (sweep_bench.py), as the README names them.
SWEEP_LOOPS = {
    "loop": "loop over designs: `jit`, robot and motion as arguments, `vmap` over payloads",
    "loop_closure": "loop over designs: `jit`, robot and motion captured (folded as constants)",
    "loop_points": "loop over designs × payloads: `jit(metric)` at each point",
}


def _yes(flag: bool) -> str:
    return "met" if flag else "not met"


def _memory(m: dict, budget: float) -> str:
    mib = 2**20
    return (
        f"{m['total_bytes'] / mib:.2f} MiB for {m['points_per_device_per_call']:,} points "
        f"(arguments {m['argument_bytes'] / mib:.2f}, of which robot and motion "
        f"{m['argument_bytes_shared_robot_and_motion'] / mib:.2f}; temporaries "
        f"{m['temp_bytes'] / mib:.2f}; outputs {m['output_bytes'] / mib:.2f}; budget "
        f"{budget:.0f})"
    )


def sweep_lines(s: dict) -> list[str]:
    """The README lines of the DUAL-V design sweep against Python loops."""
    mib, budget = 2**20, s["memory_budget_bytes"] / 2**20
    default, direct = s["default_budget"], s["direct"]
    lines = [
        "",
        f"| DUAL-V sweep ({s['metric']}): {s['designs']} counter-mass designs × "
        f"{s['payloads']} payloads × {s['samples']:,} samples | states/s | first call [s] "
        "| its time / sweep's |",
        "|---|---:|---:|---:|",
        f"| `jaxbal.sweep` (default: {s['evaluation']} evaluation), {budget:.0f} MiB budget: "
        f"{s['blocks']} block{'s' * (s['blocks'] != 1)} on {s['devices']} devices | "
        f"{s['sweep_states_per_second']:.3g} | {s['sweep_first_call_seconds']:.1f} | 1 |",
        f"| `jaxbal.sweep(..., linear=False)`, {budget:.0f} MiB budget: {direct['blocks']} "
        f"blocks | {direct['sweep_states_per_second']:.3g} | "
        f"{direct['sweep_first_call_seconds']:.1f} | "
        f"{direct['sweep_seconds'] / s['sweep_seconds']:.2f} |",
        f"| `jaxbal.sweep(..., linear=False)`, default "
        f"{default['memory_budget_bytes'] / mib:.0f} MiB budget: "
        f"{default['blocks']} block{'s' * (default['blocks'] != 1)} | "
        f"{default['sweep_states_per_second']:.3g} | "
        f"{default['first_call_seconds']:.1f} | "
        f"{default['sweep_seconds'] / s['sweep_seconds']:.2f} |",
    ]
    for name, label in SWEEP_LOOPS.items():
        b = s["baselines"][name]
        lines.append(
            f"| {label} | {b['states_per_second']:.3g} | {b['first_call_seconds']:.1f} | "
            f"{b['speedup_of_sweep']:.2f} |"
        )
    lines += [
        "",
        f"Sweep × the loop with arguments = {s['speedup_vs_loop']:.1f} (target ≥ "
        f"{TARGETS['sweep_speedup_vs_design_loop']:.0f}: {_yes(s['speedup_target_met'])}); "
        f"with `linear=False` {direct['speedup_vs_loop']:.1f}; the two agree to "
        f"{direct['max_relative_difference_vs_affine']:.1e} (relative to the largest "
        "value). Memory of one block on one device, XLA's analysis: default "
        f"{_memory(s['block_memory_per_device'], budget)}: "
        f"{_yes(s['memory_within_budget'])}; `linear=False` "
        f"{_memory(direct['block_memory_per_device'], budget)}: "
        f"{_yes(direct['memory_within_budget'])}. Resident memory during a warm sweep: "
        f"+{s['rss_growth_bytes_during_warm_sweep'] / mib:.0f} MiB "
        f"({s['rss_growth_over_budget_times_devices']:.2f} × budget × devices), "
        f"`linear=False` +{direct['rss_growth_bytes_during_warm_sweep'] / mib:.0f} MiB "
        f"({direct['rss_growth_over_budget_times_devices']:.2f}).",
    ]
    return lines


def bench_block(result: dict) -> str:
    """The README table (between the bench markers) rendered from a result dict."""
    machine = result["machine"]
    lines = [
        BENCH_START,
        f"Measured by `make bench` on {len(machine['devices'])}× {machine['devices'][0]} "
        f"({machine['platform']}), jax {machine['jax']}, mujoco {machine['mujoco']}; "
        "full numbers in `benchmarks/results/`.",
        "",
        "| robot | generic wrench [states/s], 1 device | all devices | × before "
        "| × MuJoCo C loop (all devices) | × MJX | grad/value | first grad [s] | "
        "memory [B/state] |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for name, r in result["robots"].items():
        lines.append(
            f"| {name} | {r['generic_states_per_second']:.3g} | "
            f"{r['generic_all_devices_states_per_second']:.3g} | {r['speedup_vs_before']:.1f} | "
            f"{r['speedup_vs_mujoco_c_loop_all_devices']:.0f} | {r['speedup_vs_mjx']:.0f} | "
            f"{r['gradient']['grad_over_value']:.2f} | "
            f"{r['gradient']['first_call_grad_seconds']:.2f} | "
            f"{r['memory_bytes_per_state_chunked']:.0f} |"
        )
    two = result["robots"].get("planar_2r")
    if two:
        lines += [
            "",
            f"2R: generic / hand-written closed form time = "
            f"{two['generic_over_closed_form_time']:.2f} (target ≤ "
            f"{TARGETS['generic_over_closed_form_time']}); agreement with MuJoCo C "
            f"{two['max_relative_difference_vs_mujoco']:.1e} (relative).",
        ]
    torques = {n: r["torques"] for n, r in result["robots"].items() if "torques" in r}
    if torques:
        lines += [
            "",
            "| robot | actuator torques [states/s], 1 device | × before (Lagrange) "
            "| first call [s] | before [s] | rel. diff. vs before | vs MuJoCo C |",
            "|---|---:|---:|---:|---:|---:|---:|",
        ]
        for name, t in torques.items():
            mujoco = t.get("max_relative_difference_vs_mujoco")
            lines.append(
                f"| {name} | {t['generic_states_per_second']:.3g} | "
                f"{t['speedup_vs_before']:.1f} | {t['compile_seconds_first_call']:.2f} | "
                f"{t['before_compile_seconds_first_call']:.2f} | "
                f"{t['max_relative_difference_vs_before']:.1e} | "
                f"{'—' if mujoco is None else f'{mujoco:.1e}'} |"
            )
    lines += [
        "",
        "| first call in a fresh process [s] | grad, cold | grad, warm cache | co-design, cold "
        "| co-design, warm | move, cold | move, warm | `checked_jit` grad, warm |",
        "|---|---:|---:|---:|---:|---:|---:|---:|",
    ]

    def seconds(run, key):
        return "—" if key not in run else f"{run[key]:.2f}"

    for name, modes in result["first_call"].items():
        for mode, runs in modes.items():
            cold, warm = runs["cold"], runs["warm"]
            lines.append(
                f"| {name}, runtime checks {mode.split('_')[1]} | "
                f"{cold['first_grad_seconds']:.2f} | {warm['first_grad_seconds']:.2f} | "
                f"{cold['first_codesign_seconds']:.2f} | {warm['first_codesign_seconds']:.2f} | "
                f"{cold['motion_seconds']:.2f} | {warm['motion_seconds']:.2f} | "
                f"{seconds(warm, 'first_checked_jit_grad_seconds')} |"
            )
    lines += [
        "",
        "| co-design vs SciPy SLSQP + finite differences | variables | × with compile "
        "| × with compile, fresh processes | × compiled | objective rel. diff. |",
        "|---|---:|---:|---:|---:|---:|",
    ]
    for name, c in result["codesign"].items():
        diff = abs(c["objective_jaxbal"] - c["objective_scipy"]) / abs(c["objective_scipy"])
        fresh = c.get("speedup_with_compile_fresh_processes")
        fresh = "—" if fresh is None else f"{fresh:.2f}"
        lines.append(
            f"| {name} | {c['variables']} | {c['speedup_with_compile']:.2f} | {fresh} | "
            f"{c['speedup_compiled']:.2f} | {diff:.1e} |"
        )
    if "sweep" in result:
        lines += sweep_lines(result["sweep"])
    lines.append(BENCH_END)
    return "\n".join(lines)


def update_readme(readme: Path, result: dict) -> None:
    """Write :func:`bench_block` between the bench markers of ``readme``."""
    text = readme.read_text()
    start, end = text.find(BENCH_START), text.find(BENCH_END)
    if start < 0 or end < 0:
        return
    atomic_write_text(readme, text[:start] + bench_block(result) + text[end + len(BENCH_END) :])
