"""Studies that every robot shares: jaxbal vs MuJoCo along a list of trajectories, and
time histories of named cases as a figure.

An experiment that reproduces a paper's table usually evaluates several named motions
(``name ↦ (robot, trajectory t ↦ q)``) and confirms each of them independently with
MuJoCo C or MJX. This module does that once for every robot:

* :func:`confirm_cases`: :func:`jaxbal.mujoco.confirm` along every named trajectory,
  the states sampled exactly by one compiled sampler (compiled once per trajectory
  structure, not once per trajectory as :func:`jaxbal.mujoco.confirm_path`);
* :func:`agreement_table`: those confirmations as a :class:`jaxbal.report.Table` with
  the columns ``force_rel`` and ``moment_rel``;
* :func:`mujoco_peaks`: the peak force and moment of MuJoCo C's base reaction along a
  trajectory (an independent number beside jaxbal's peak);
* :func:`plot_histories`: panels of curves (one per named case) against time, saved
  as a PNG (the papers' time-history figures).

The relative differences are those of :class:`jaxbal.mujoco.Confirmation`: the largest
difference over the samples divided by the peak gross inertial force (moment).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import equinox as eqx
import numpy as np

from jaxbal._src.report import Table, save_figure
from jaxbal._src.robot import Robot
from jaxbal._src.trajectory import sample
from jaxbal._src.types import Array, Float

if TYPE_CHECKING:  # MuJoCo is imported on first use (slow to import)
    from jaxbal._src.mujoco.confirm import Confirmation

__all__ = [
    "AGREEMENT_COLUMNS",
    "agreement_table",
    "confirm_cases",
    "mujoco_peaks",
    "plot_histories",
    "sample_states",
]

#: Table column ↦ :class:`~jaxbal.mujoco.Confirmation` attribute of :func:`agreement_table`.
AGREEMENT_COLUMNS = {"force_rel": "force_relative", "moment_rel": "moment_relative"}


@eqx.filter_jit
def sample_states(trajectory: Callable, times: Float[Array, " t"]) -> tuple:
    """``(q, q̇, q̈)``, each ``(t, dof)``, of ``trajectory`` at ``times`` [s] (exact, by
    nested ``jvp``; compiled once per trajectory structure)."""
    return sample(trajectory, times)


def confirm_cases(
    cases: Mapping[str, tuple[Robot, Callable]],
    times: Float[Array, " t"],
    *,
    engine: str = "mjx",
    gravity=None,
) -> dict[str, Confirmation]:
    """:func:`jaxbal.mujoco.confirm` along every named trajectory.

    Args:
        cases: ``name ↦ (robot, trajectory)``, the trajectory a callable ``t ↦ q``.
        times: ``(t,)`` sampling instants [s], the same for every case.
        engine: ``"mjx"`` (``mjx.inverse``, jitted) or ``"mujoco"`` (C ``mj_inverse``).
        gravity: optional ``(3,)`` gravity [m/s²].

    Returns:
        ``name ↦`` :class:`~jaxbal.mujoco.Confirmation`, in the order of ``cases``.
    """
    from jaxbal._src.mujoco.confirm import confirm

    return {
        name: confirm(robot, *sample_states(path, times), gravity=gravity, engine=engine)
        for name, (robot, path) in cases.items()
    }


def agreement_table(
    table_id: str,
    title: str,
    confirmations: Mapping[str, Confirmation],
    columns: Mapping[str, str] = AGREEMENT_COLUMNS,
    tolerance: float | None = None,
) -> Table:
    """A table with one row per confirmation and one column per attribute (default:
    ``force_rel`` and ``moment_rel``, dimensionless)."""
    table = Table(table_id, title, tolerance)
    for row, confirmation in confirmations.items():
        for column, attribute in columns.items():
            table.add(row, column, getattr(confirmation, attribute), "-")
    return table


def mujoco_peaks(
    robot: Robot, trajectory: Callable, times: Float[Array, " t"], gravity=None
) -> tuple[float, float]:
    """``(max_t ‖f‖ [N], max_t ‖m‖ [N·m])`` of MuJoCo C's base reaction (``mj_inverse``
    on the robot's kinematic tree) along ``trajectory`` sampled at ``times``."""
    from jaxbal._src.mujoco.inverse import mujoco_base_reaction

    force, moment = mujoco_base_reaction(robot, *sample_states(trajectory, times), gravity=gravity)
    return (
        float(np.max(np.linalg.norm(force, axis=-1))),
        float(np.max(np.linalg.norm(moment, axis=-1))),
    )


def plot_histories(
    path: Path,
    x: Float[Array, " t"],
    panels: Sequence[tuple],
    styles: Mapping[str, Mapping] | None = None,
    *,
    title: str = "",
    xlabel: str = "time [s]",
    shape: tuple[int, int] | None = None,
    figsize: tuple[float, float] | None = None,
    legend: Mapping | None = None,
) -> Path:
    """Save a figure of panels of named curves against ``x`` (default: time) as PNG.

    Args:
        path: the PNG file (written atomically).
        x: ``(t,)`` abscissa shared by every curve.
        panels: ``(ylabel, curves)`` or ``(ylabel, curves, panel_title)`` per panel,
            ``curves`` a mapping ``name ↦ (t,)`` values.
        styles: ``name ↦`` matplotlib line keywords (``color``, ``linestyle``,
            ``label``; the label defaults to the name). Curves without a style are drawn
            in matplotlib's colour cycle.
        title: figure title.
        xlabel: label of the abscissa on the bottom row.
        shape: ``(rows, columns)`` of the panels (default one row).
        figsize: figure size [inch] (default 4.5 × 3.5 per panel).
        legend: keywords of the legend drawn on the first panel (default
            ``fontsize=8``).
    """
    import matplotlib.pyplot as plt

    rows, columns = (1, len(panels)) if shape is None else shape
    figsize = (4.5 * columns, 3.5 * rows) if figsize is None else figsize
    fig, axes = plt.subplots(rows, columns, figsize=figsize, squeeze=False, sharex=rows > 1)
    styles = {} if styles is None else styles
    for index, (axis, panel) in enumerate(zip(axes.flat, panels, strict=False)):
        ylabel, curves, *panel_title = panel
        for name, values in curves.items():
            style = {"label": name, **styles.get(name, {})}
            axis.plot(np.asarray(x), np.asarray(values), **style)
        axis.set(ylabel=ylabel, title=panel_title[0] if panel_title else "")
        if index >= (rows - 1) * columns:
            axis.set_xlabel(xlabel)
    axes.flat[0].legend(**({"fontsize": 8} if legend is None else legend))
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path)
