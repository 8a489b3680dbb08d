"""DUAL-V drawings: the derived layout, the condition-number map of Fig 8, and the
histories and trade-offs of :mod:`jaxbal.robots.dual_v_studies` (Figs 12-14, eq 30,
co-design). Every function returns the matplotlib figure (or axis) it drew.

References:
    van der Wijk, Krut, Pierrot & Herder (2013), Fig 2b-c (layout), Fig 8 (κ map),
    Figs 12-14 (shaking wrench, torques, bearing forces), eq (30).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.robots.dual_v import OUTWARD, DualV

__all__ = [
    "condition_number_grid",
    "plot_bearing_forces",
    "plot_codesign_trade",
    "plot_condition_number",
    "plot_layout",
    "plot_sweeps",
    "plot_wrench_and_torques",
]

ARM_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red")


def plot_layout(
    robot: DualV, pose=(0.0, 0.0, 0.0), branch=OUTWARD, ax=None, workspace=True, outline=None
):
    """Draw the DUAL-V at ``pose``: base pivots A_i, links, platform, counter-masses.

    Args:
        robot: the robot.
        pose: ``(x5, y5, θ5)`` [m, m, rad].
        branch: elbow signs (see :mod:`jaxbal.robots.dual_v`).
        ax: a matplotlib axis (created if ``None``).
        workspace: also draw the two circles whose intersection is the workspace.
        outline: optional ``(label, vertices (k, ≥2))``: a closed path of the platform
            centre drawn dashed (e.g. the Fig 12 triangle) [m].

    Returns:
        The matplotlib axis.
    """
    import matplotlib.pyplot as plt

    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6))
    q = robot.inverse_kinematics(jnp.asarray(pose, dtype=float), branch=branch)
    base, elbows, ends = (np.asarray(p) for p in robot.joint_positions(q))
    theta1 = np.asarray(q[:4])
    p_cm = np.asarray(robot.p_cm)
    reach = float(robot.l1[0] + robot.l2[0])
    if workspace:
        for side in (-1.0, 1.0):
            circle = plt.Circle(
                (side * float(robot.a), 0.0), reach, fill=False, ls=":", color="0.6"
            )
            ax.add_patch(circle)
    for i in range(4):
        colour = ARM_COLOURS[i]
        ax.plot(*zip(base[i], elbows[i], ends[i], strict=True), "-o", color=colour, lw=2)
        counter = base[i] - p_cm[i] * np.array([np.cos(theta1[i]), np.sin(theta1[i])])
        ax.plot(*zip(base[i], counter, strict=True), color=colour, lw=4, alpha=0.5)
        ax.plot(*counter, "s", color=colour, ms=10)
        ax.annotate(f"A{i + 1}", base[i], textcoords="offset points", xytext=(6, -12))
        ax.annotate(f"B{i + 1}", elbows[i], textcoords="offset points", xytext=(6, 4))
    top, bottom = ends[0], ends[2]
    ax.plot(*zip(top, bottom, strict=True), "k-", lw=5, label="platform 5")
    ax.annotate("C1=C2", top, textcoords="offset points", xytext=(6, 6))
    ax.annotate("C3=C4", bottom, textcoords="offset points", xytext=(6, -14))
    ax.plot(*np.asarray(pose)[:2], "k+", ms=12)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("DUAL-V layout (squares: counter-masses)")
    if outline is not None:
        label, vertices = outline
        closed = np.vstack([vertices, vertices[:1]])[:, :2]
        ax.plot(*closed.T, "k--", lw=1, label=label)
        ax.legend(loc="lower right")
    return ax


def condition_number_grid(robot: DualV, theta5: float, count: int = 81, branch=OUTWARD):
    """κ = cond(J_h) of Fig 8 on a ``count × count`` grid over the workspace box.

    Returns:
        ``(xs (count,), ys (count,), kappa (count, count))``; NaN outside the workspace.
    """
    half_x = float(robot.l1[0] + robot.l2[0] - robot.a)
    half_y = float(jnp.sqrt((robot.l1[0] + robot.l2[0]) ** 2 - robot.a**2))
    xs = jnp.linspace(-half_x, half_x, count)
    ys = jnp.linspace(-half_y, half_y, count)
    grid = jnp.stack(jnp.meshgrid(xs, ys), -1).reshape(-1, 2)
    poses = jnp.concatenate([grid, jnp.full((grid.shape[0], 1), theta5)], -1)

    def kappa(pose):
        q, valid = robot.inverse_kinematics(pose, branch=branch, return_valid=True)
        return jnp.where(valid, robot.harmonised_condition_number(q), jnp.nan)

    values = jax.jit(jax.vmap(kappa))(poses).reshape(count, count)
    return xs, ys, values


def plot_condition_number(robot: DualV, orientations=(-0.2, 0.0, 0.2), count=81, vmax=5.0):
    """Fig 8: contour maps of κ for several platform orientations [rad]."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(orientations), figsize=(4 * len(orientations), 6))
    for ax, theta5 in zip(np.atleast_1d(axes), orientations, strict=True):
        xs, ys, kappa = condition_number_grid(robot, theta5, count)
        levels = np.linspace(1.0, vmax, 17)
        image = ax.contourf(xs, ys, np.clip(np.asarray(kappa), 1.0, vmax), levels=levels)
        ax.add_patch(plt.Circle((0, 0), 0.1, fill=False, color="w", ls="--"))
        ax.set_aspect("equal")
        ax.set_title(f"θ5 = {np.degrees(theta5):.0f}°")
        ax.set_xlabel("x5 [m]")
    np.atleast_1d(axes)[0].set_ylabel("y5 [m]")
    fig.colorbar(image, ax=axes, label="κ = cond(J_h)")
    return fig


def plot_wrench_and_torques(times, histories):
    """Fig 12 analogue: shaking force x, y, shaking moment (every robot) and the torques
    (dotted: unbalanced, solid: balanced) against time.

    Args:
        times: ``(t,)`` [s].
        histories: label ↦ :class:`~jaxbal.robots.dual_v_dynamics.MotionSample` history
            (from :func:`~jaxbal.robots.dual_v_studies.evaluate_motion`); the torques of
            the labels ``"unbalanced"`` and ``"balanced"`` are drawn.
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 2, figsize=(11, 7), sharex=True)
    for label, out in histories.items():
        axes[0, 0].plot(times, out.shaking_force[:, 0], label=label)
        axes[0, 1].plot(times, out.shaking_force[:, 1], label=label)
        axes[1, 0].plot(times, out.shaking_moment, label=label)
    for label, style in (("unbalanced", ":"), ("balanced", "-")):
        for i in range(4):
            axes[1, 1].plot(
                times,
                histories[label].torques[:, i],
                style,
                color=f"C{i}",
                label=f"τ{i + 1} {label}",
            )
    titles = ("ShF_x [N]", "ShF_y [N]", "ShM [N·m]", "τ [N·m]")
    for ax, title in zip(axes.flat, titles, strict=True):
        ax.set_title(title)
        ax.grid(alpha=0.3)
    axes[0, 0].legend()
    axes[1, 1].legend(fontsize=6, ncol=2)
    axes[1, 0].set_xlabel("t [s]")
    axes[1, 1].set_xlabel("t [s]")
    return fig


def plot_bearing_forces(times, histories, labels=("unbalanced", "balanced")):
    """Fig 14 analogue: ``‖F_A,i‖`` [N] of the four base bearings against time [s]."""
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 4, figsize=(14, 3.5), sharey=True)
    for i, ax in enumerate(axes):
        for label in labels:
            ax.plot(times, np.linalg.norm(histories[label].bearing[:, i], axis=-1), label=label)
        ax.set_title(f"‖F_A{i + 1}‖ [N]")
        ax.set_xlabel("t [s]")
    axes[0].legend()
    return fig


def plot_sweeps(balance, payload, marks=(96.72, 0.107)):
    """Eq (30): peak ``|F_x|`` [N] against the counter-mass moment (fraction of eq 2)
    and against a payload [kg]; dashed lines at ``marks`` (the 96.72 % robot, 0.107 kg).

    Args:
        balance, payload: the labelled sweeps of
            :func:`~jaxbal.robots.dual_v_balancing.balance_sweep` (over
            ``balance_fraction``) and :func:`~jaxbal.robots.dual_v_balancing.payload_sweep`
            (over ``payload``).
    """
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    units = balance.attrs.get("units", "N")
    axes[0].plot(100 * balance["balance_fraction"].values, balance.values)
    axes[0].axvline(marks[0], ls="--", color="0.5")
    axes[0].set_xlabel("m_cm·p_cm [% of eq (2)]")
    axes[0].set_ylabel(f"max |ShF_x| on the triangle [{units}]")
    axes[1].plot(payload["payload"].values, payload.values)
    axes[1].axvline(marks[1], ls="--", color="0.5")
    axes[1].set_xlabel(f"payload at the platform centre [{payload['payload'].attrs['units']}]")
    for ax in axes:
        ax.grid(alpha=0.3)
    return fig


def plot_codesign_trade(points, references=None):
    """Peak shaking force against peak torque of the co-designed robots (one point per
    weight of :func:`~jaxbal.robots.dual_v_studies.codesign_trade`), with optional
    ``references`` ``label ↦`` :class:`~jaxbal.robots.dual_v_studies.Peaks` of other
    robots on the same motion (drawn as red squares, green triangles, ...)."""
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4))
    forces = [float(p.peak_force) for p in points]
    torques = [float(p.peak_torque) for p in points]
    ax.plot(forces, torques, "o-")
    for point, force, torque in zip(points, forces, torques, strict=True):
        ax.annotate(
            f"w={point.weight:g}", (force, torque), textcoords="offset points", xytext=(4, 4),
            fontsize=7,
        )  # fmt: skip
    styles = ("rs", "g^", "bv", "kD")
    for (label, peaks), style in zip((references or {}).items(), styles, strict=False):
        ax.plot(float(peaks.force_norm), float(np.max(peaks.torques)), style, label=label)
    ax.set_xlabel("max ‖ShF‖ on the triangle [N]")
    ax.set_ylabel("max ‖τ_i‖ [N·m]")
    ax.legend()
    ax.grid(alpha=0.3)
    return fig
