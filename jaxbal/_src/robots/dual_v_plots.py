"""DUAL-V drawings: the derived layout and the condition-number map of Fig 8.

References:
    van der Wijk, Krut, Pierrot & Herder (2013), Fig 2b-c (layout), Fig 8 (κ map).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.robots.dual_v import OUTWARD, DualV

__all__ = ["condition_number_grid", "plot_condition_number", "plot_layout"]

ARM_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:red")


def plot_layout(robot: DualV, pose=(0.0, 0.0, 0.0), branch=OUTWARD, ax=None, workspace=True):
    """Draw the DUAL-V at ``pose``: base pivots A_i, links, platform, counter-masses.

    Args:
        robot: the robot.
        pose: ``(x5, y5, θ5)`` [m, m, rad].
        branch: elbow signs (see :mod:`jaxbal.robots.dual_v`).
        ax: a matplotlib axis (created if ``None``).
        workspace: also draw the two circles whose intersection is the workspace.

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
