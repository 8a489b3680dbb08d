"""Studies of Geng, Arakelian, Chablat & Lemoine (2021) on the Orthoglide.

* §3: inputs, COM and designed COM acceleration of a move (:func:`kinematic_summary`);
* §3.2, Tables 1-2: peak shaking force and moment of the three motion laws over the
  payloads (:func:`payload_peaks`), and the moment reference point and slider offset
  fitted to Table 2 (:func:`fit_moment_reference`, quality recomputed end to end);
* §3.3, Tables 3-4: a payload error Δm (:func:`payload_error_peaks`, and its exact
  derivative :func:`payload_error_slopes`);
* plans for MuJoCo (:func:`payload_cases`), Fig 4 (:func:`case_histories`), tables.

The motion laws are those of :func:`jaxbal.robots.orthoglide_planning.motion_cases`:
case 1 quintic and case 2 bang-bang on the straight line of the platform point, case 3
bang-bang on the straight line of the total COM (eqs 4, 7), case 4 the case-3 plan made
for a wrong payload. Peaks are taken on :func:`switching_times` (the bang-bang switch at
``T/2`` included), the moment about a reference point ``c``: ``M_c = M_O − c × F``.

References:
    Geng, Arakelian, Chablat, Lemoine (2021). Balancing of the Orthoglide taking into
    account its varying payload. Robotics 10(1), 30. Eqs (1), (4)-(7), §3, Tables 1-4.
"""

from __future__ import annotations

from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp

from jaxbal._src.optimize import Solution, minimize
from jaxbal._src.planning import peak_norm, shaking_peaks, wrench_along
from jaxbal._src.report import Table
from jaxbal._src.robots.orthoglide import Orthoglide, motion_cases, switching_times
from jaxbal._src.sweep import sweep
from jaxbal._src.sweep_axes import grid
from jaxbal._src.types import Array, Float

__all__ = [
    "PAYLOAD_ERROR_PEAKS",
    "ReferenceFit",
    "case_histories",
    "fit_moment_reference",
    "fit_table",
    "kinematic_summary",
    "payload_cases",
    "payload_error_peaks",
    "payload_error_slopes",
    "payload_error_table",
    "payload_peaks",
    "peaks_table",
    "reference_errors",
    "with_payload",
]


def with_payload(robot: Orthoglide, payload) -> Orthoglide:
    """``robot`` carrying ``payload`` [kg] at P (works on traced payloads)."""
    return eqx.tree_at(lambda r: r.payload, robot, jnp.asarray(payload, dtype=float))


def kinematic_summary(robot: Orthoglide, start, end, duration, loaded_payload) -> dict:
    """The numbers of §3 for a move between two platform points, named as in the paper.

    Returns:
        ``name ↦ (value, unit)``, in this order: ``rho_xi, rho_yi, rho_zi`` and
        ``rho_xf, rho_yf, rho_zf`` the inputs at start and end [m] (eq 1); for each of
        ``x_Si, y_Si, z_Si, x_Sf, y_Sf, z_Sf`` the COM coordinate of the robot carrying
        ``loaded_payload`` and the same ``_rounded`` to 0.01 m (the paper's precision);
        the same coordinates ``_payload0`` of ``robot`` [m]; ``a_com`` the designed peak
        COM acceleration ``4|ΔS|/T²`` of the bang-bang COM plan [m/s²];
        ``a_com_swapped_masses`` the same with the parallelogram and slider masses
        exchanged (the other reading of §3) [m/s²]; ``theoretical_reduction``
        ``100 (1 − 4/(10/√3))``, the reduction of the peak acceleration from the quintic
        to the bang-bang profile [%].
    """
    start, end = jnp.asarray(start, dtype=float), jnp.asarray(end, dtype=float)
    loaded = with_payload(robot, loaded_payload)
    swapped = eqx.tree_at(
        lambda r: (r.parallelogram_mass, r.slider_mass, r.parallelogram_inertia),
        robot,
        (robot.slider_mass, robot.parallelogram_mass, robot.slider_mass * robot.length**2 / 12),
    )
    d_swapped = swapped.com_of_point(end) - swapped.com_of_point(start)
    quintic_peak, bang_peak = 10 / jnp.sqrt(3.0), 4.0
    rho = jnp.concatenate([robot.inverse_kinematics(p)[:3] for p in (start, end)])
    com_loaded = jnp.concatenate([loaded.com_of_point(start), loaded.com_of_point(end)])
    com = jnp.concatenate([robot.com_of_point(start), robot.com_of_point(end)])
    names = [f"{axis}_S{at}" for at in "if" for axis in "xyz"]
    rows = {f"rho_{axis}{at}": (rho[3 * k + i], "m") for k, at in enumerate("if")
            for i, axis in enumerate("xyz")}  # fmt: skip
    for name, value in zip(names, com_loaded, strict=True):
        rows[name] = (value, "m")
        rows[name + "_rounded"] = (jnp.round(value, 2), "m")
    rows.update({name + "_payload0": (value, "m") for name, value in zip(names, com, strict=True)})
    rows["a_com"] = (4 * jnp.linalg.norm(com[3:] - com[:3]) / duration**2, "m/s^2")
    rows["a_com_swapped_masses"] = (4 * jnp.linalg.norm(d_swapped) / duration**2, "m/s^2")
    rows["theoretical_reduction"] = (100 * (1 - bang_peak / quintic_peak), "%")
    return rows


@eqx.filter_jit
def payload_peaks(
    robot: Orthoglide, payloads, start, end, duration, reference=None, samples: int = 401
) -> tuple[Float[Array, "p 3"], Float[Array, "p 3"]]:
    """Peak ``|F|`` [N] and ``|M_c|`` about ``reference`` [N·m] of cases 1-3 for every
    payload [kg] (``vmap``, compiled): ``(p, 3)`` each, columns cases 1-3.

    References: Geng et al. (2021), §3.2, Tables 1-2.
    """
    times = switching_times(duration, samples)

    def one(payload):
        loaded = with_payload(robot, payload)
        plans = motion_cases(loaded, start, end, duration).values()
        peaks = [shaking_peaks(loaded, plan, times, reference) for plan in plans]
        return jnp.stack([f for f, _ in peaks]), jnp.stack([m for _, m in peaks])

    return jax.vmap(one)(jnp.asarray(payloads, dtype=float))


def peaks_table(
    table_id: str, title: str, payloads, peaks, unit: str, paper=None, tolerance=None
) -> Table:
    """Peaks in the layout of Tables 1-2: a row ``payload{m}`` per payload, columns
    ``case1``-``case3`` [unit] and ``reduction2``, ``reduction3`` [%], the reduction
    ``100 (case1 − case_k)/case1`` of case k; ``paper`` maps a column to its published
    values (one per payload)."""
    table = Table(table_id, title, tolerance)
    for i, payload in enumerate(payloads):
        row = f"payload{int(payload)}"
        for k in range(3):
            column = f"case{k + 1}"
            table.add(row, column, peaks[i, k], unit, paper and paper[column][i])
        for k in (1, 2):
            column = f"reduction{k + 1}"
            reduction = 100 * (peaks[i, 0] - peaks[i, k]) / peaks[i, 0]
            table.add(row, column, reduction, "%", paper and paper[column][i])
    return table


def payload_cases(robot: Orthoglide, payloads, start, end, duration) -> dict:
    """``"payload{m} {case}" ↦ (robot carrying m, plan)`` for cases 1-3 of every payload."""
    cases = {}
    for payload in payloads:
        loaded = with_payload(robot, payload)
        for case, plan in motion_cases(loaded, start, end, duration).items():
            cases[f"payload{int(payload)} {case}"] = (loaded, plan)
    return cases


def case_histories(robot: Orthoglide, start, end, duration, times, reference=None):
    """Fig 4: ``({case: |F(t)|} [N], {case: |M_c(t)|} [N·m])``, each ``(t,)``, cases 1-3."""
    c = jnp.zeros(3) if reference is None else jnp.asarray(reference, dtype=float)
    forces, moments = {}, {}
    for name, plan in motion_cases(robot, start, end, duration).items():
        force, moment = wrench_along(robot, plan, times)
        forces[name] = jnp.linalg.norm(force, axis=1)
        moments[name] = jnp.linalg.norm(moment - jnp.cross(c, force), axis=1)
    return forces, moments


def _payload_error(robot, payload, delta, start, end, duration, reference, samples):
    executed = with_payload(robot, payload + delta)
    plans = motion_cases(executed, start, end, duration, planned_payload=payload)
    times = switching_times(duration, samples)
    f3, m3 = shaking_peaks(executed, plans["case3"], times, reference)
    f4, m4 = shaking_peaks(executed, plans["case4"], times, reference)
    return jnp.stack([f3, f4, m3, m4])


#: the peaks of :func:`payload_error_peaks` (its dimension ``peak``) and their units.
PAYLOAD_ERROR_PEAKS = {"force_case3": "N", "force_case4": "N", "moment_case3": "N·m",
                       "moment_case4": "N·m"}  # fmt: skip
#: most 3×3 LUs (points × instants) per call in :func:`payload_error_peaks`: jaxlib 0.10
#: splits a batch of more than ~7,400 over the XLA threads, and two split at once
#: deadlocked 2 CPU threads.
MAX_LU_BATCH = 4096


def _error_move(start, end, duration, reference, samples, robot, theta):
    """The sweep's motion factory (a ``jax.tree_util.Partial`` of the move): ``Δm``, move."""
    return theta["payload_error"], (start, end, duration, reference, samples)


def _error_peaks(robot: Orthoglide, motion) -> Array:  # the sweep's metric; m = robot.payload
    return _payload_error(robot, robot.payload, motion[0], *motion[1])


def payload_error_peaks(
    robot: Orthoglide, payloads, deltas, start, end, duration, reference=None, samples: int = 401
):
    """Peaks ``(F3, F4, M3, M4)`` [N, N, N·m, N·m] when the payload is ``m + Δm``.

    Case 3: the COM plan made for the true payload ``m + Δm``; case 4: the plan made for
    the nominal ``m`` (the error not taken into account), both executed with ``m + Δm``.

    Args:
        payloads: ``(p,)`` nominal payloads m [kg].
        deltas: ``()`` or ``(d,)`` payload errors Δm [kg].

    Returns:
        A :func:`jaxbal.sweep` :class:`xarray.DataArray`, ``(p, 4)`` for a scalar Δm and
        ``(p, d, 4)`` otherwise: dimensions ``payload``, ``payload_error`` [kg] and
        ``peak`` (:data:`PAYLOAD_ERROR_PEAKS`, with a ``units`` coordinate).

    References: Geng et al. (2021), §3.3, Tables 3-4.
    """
    axes = {"payload": grid(payloads, units="kg"),
            "payload_error": grid(jnp.atleast_1d(deltas), units="kg")}  # fmt: skip
    reference = None if reference is None else jnp.asarray(reference, dtype=float)
    move = jax.tree_util.Partial(_error_move, start, end, duration, reference, samples)
    peaks = sweep(_error_peaks, robot, move, axes, output_dims={"value": ("peak",)},
                  chunk_size=max(MAX_LU_BATCH // (samples + 1), 1), progress=False)  # fmt: skip
    labels = {"peak": list(PAYLOAD_ERROR_PEAKS), "units": ("peak", [*PAYLOAD_ERROR_PEAKS.values()])}
    peaks = peaks["value"].assign_coords(labels).rename("payload_error_peaks")
    return peaks.isel(payload_error=0) if jnp.ndim(deltas) == 0 else peaks


@eqx.filter_jit
def payload_error_slopes(
    robot: Orthoglide, payloads, delta, start, end, duration, reference=None, samples: int = 401
) -> Float[Array, "p 4"]:
    """Exact ``d(F3, F4, M3, M4)/dΔm`` at ``Δm = delta`` (forward mode): case 3 through
    the COM planner (implicit differentiation of the COM inverse kinematics), case 4
    with its plan fixed. ``(p, 4)`` [N/kg, N·m/kg]."""

    def one(payload):
        return jax.jacfwd(_payload_error, argnums=2)(
            robot, payload, delta, start, end, duration, reference, samples
        )

    return jax.vmap(one)(jnp.asarray(payloads, dtype=float))


def payload_error_table(
    table_id: str, title: str, payloads, peaks, slopes, unit: str, paper=None, kinds=None, tol=None
) -> Table:
    """Tables 3-4: rows ``payload{m}``, columns ``case3``, ``case4``, ``difference``
    [unit], ``dcase3_ddm``, ``dcase4_ddm`` [unit/kg] from ``peaks``/``slopes`` ``(p, 2)``
    (:func:`payload_error_peaks`, :func:`payload_error_slopes`); optional ``paper``
    ``{column: (p,) values}``, ``kinds`` ``{column: kind}``, tolerance ``tol``."""
    paper, kinds = paper or {}, kinds or {}
    table = Table(table_id, title, tol)
    for i, payload in enumerate(payloads):
        row = f"payload{int(payload)}"
        values = {"case3": peaks[i, 0], "case4": peaks[i, 1]}
        values["difference"] = peaks[i, 1] - peaks[i, 0]
        for column, value in values.items():
            published = paper[column][i] if column in paper else None
            table.add(row, column, value, unit, published, kinds.get(column))
        table.add(row, "dcase3_ddm", slopes[i, 0], unit + "/kg")
        table.add(row, "dcase4_ddm", slopes[i, 1], unit + "/kg")
    return table


# --- §3.2: the moment reference point and slider offset of Table 2 -----------------


class ReferenceFit(NamedTuple):
    """Result of :func:`fit_moment_reference`.

    Attributes:
        slider_offset, reference: the fitted l [m] and c ``(3,)`` [m].
        relative_errors: ``(p, 3)`` ``(ours − paper)/paper`` of the moment peaks,
            recomputed with :func:`payload_peaks` at the fitted l and c.
        rms_error, max_error: root mean square and largest ``|relative_errors|`` [-].
        solution: the optimiser's :class:`~jaxbal.Solution` (variables ``(l, c)``).
    """

    slider_offset: Array
    reference: Array
    relative_errors: Array
    rms_error: Array
    max_error: Array
    solution: Solution


@eqx.filter_jit
def _moment_basis(robot, payloads, start, end, duration, samples):
    """``F``, ``M_O`` at l = 0 and ``∂M_O/∂l`` along the plans of every payload and case,
    each ``(p, 3, t, 3)``."""
    times = switching_times(duration, samples)

    def one(payload):
        parts = []
        for offset in (0.0, 1.0):
            loaded = eqx.tree_at(
                lambda r: (r.payload, r.slider_offset), robot, (payload, jnp.asarray(offset))
            )
            plans = motion_cases(loaded, start, end, duration).values()
            parts.append([wrench_along(loaded, plan, times) for plan in plans])
        force = jnp.stack([f for f, _ in parts[0]])
        moment0 = jnp.stack([m for _, m in parts[0]])
        moment1 = jnp.stack([m for _, m in parts[1]])
        return force, moment0, moment1 - moment0

    return jax.vmap(one)(jnp.asarray(payloads, dtype=float))


def _fit_loss(params, basis, paper, fixed_offset):
    force, moment0, per_offset = basis
    offset = params[0] if fixed_offset is None else fixed_offset
    moment = moment0 + offset * per_offset - jnp.cross(params[1:], force)
    peaks = jax.vmap(jax.vmap(peak_norm))(moment)
    return jnp.sum(((peaks - paper) / paper) ** 2)


def reference_errors(
    robot: Orthoglide, payloads, paper_moments: Float[Array, "p 3"], start, end, duration,
    slider_offset, reference, samples: int = 401,
) -> Float[Array, "p 3"]:  # fmt: skip
    """``(ours − paper)/paper`` of the peak moments of cases 1-3 about ``reference``
    [m] with the slider offset ``slider_offset`` [m], computed with :func:`payload_peaks`."""
    fitted = eqx.tree_at(lambda r: r.slider_offset, robot, jnp.asarray(slider_offset, float))
    reference = jnp.asarray(reference, dtype=float)
    _, moments = payload_peaks(fitted, payloads, start, end, duration, reference, samples)
    paper = jnp.asarray(paper_moments, dtype=float)
    return (moments - paper) / paper


def fit_moment_reference(
    robot: Orthoglide, payloads, paper_moments: Float[Array, "p 3"], start, end, duration,
    guess=(0.0, 0.0, 0.0, 0.0), fixed_offset: float | None = None, samples: int = 401,
) -> ReferenceFit:  # fmt: skip
    """Slider offset l and moment reference point c that reproduce a table of peak
    shaking moments (Table 2 of Geng et al. 2021): least squares in relative error.

    The paper's moments grow with the payload although, about the intersection O of the
    prismatic axes, the payload adds no moment (it moves on a line through O): ADAMS
    took them about another point c, and the sliders' lever arms depend on l, neither
    given. The moment about c of the robot with offset l is exactly
    ``M_O,0(t) + l ∂M_O/∂l(t) − c × F(t)``: the slider COMs ride rigidly at ``l/2·d_i``
    on the sliders and neither F nor the plans depend on l. So the wrenches are computed
    once (l = 0 and l = 1) and the fit (optax L-BFGS on the variables ``(l, c)``, or
    ``c`` alone with ``fixed_offset``) only recombines them. The fit quality is then
    recomputed through the whole pipeline (:func:`payload_peaks`) at the result.

    Args:
        robot: the Orthoglide (its payload and slider offset are replaced).
        payloads: ``(p,)`` payloads [kg].
        paper_moments: ``(p, 3)`` published peak moments of cases 1-3 [N·m].
        start, end, duration: the move [m, m, s].
        guess: ``(l, c_x, c_y, c_z)`` starting point [m] (the fit has several minima).
        fixed_offset: fit c only, with this l [m].
        samples: instants of :func:`switching_times`.
    """
    paper = jnp.asarray(paper_moments, dtype=float)
    basis = _moment_basis(robot, payloads, start, end, duration, samples)
    start_params = jnp.asarray(guess, dtype=float)
    if fixed_offset is not None:
        start_params = start_params.at[0].set(fixed_offset)
        fixed_offset = jnp.asarray(fixed_offset, dtype=float)
    solution = minimize(
        _fit_loss, start_params, max_steps=500, gtol=1e-12, args=(basis, paper, fixed_offset)
    )
    offset, reference = solution.params[0], solution.params[1:]
    if fixed_offset is not None:
        offset = fixed_offset
    errors = reference_errors(
        robot, payloads, paper, start, end, duration, offset, reference, samples
    )
    rms, largest = jnp.sqrt(jnp.mean(errors**2)), jnp.max(jnp.abs(errors))
    return ReferenceFit(offset, reference, errors, rms, largest, solution)


def fit_table(
    table_id: str, title: str, robot: Orthoglide, payloads, paper_moments: Float[Array, "p 3"],
    start, end, duration, starts: dict, points: dict | None = None, samples: int = 401,
) -> Table:  # fmt: skip
    """:func:`fit_moment_reference` from several starting points, as a table.

    Args:
        starts: ``row ↦ (guess, fixed_offset)`` (see :func:`fit_moment_reference`).
        points: ``row ↦ (l, c)``: points evaluated without fitting (e.g. the values a
            table was computed with), listed first.

    Returns:
        Columns ``l``, ``c_x``, ``c_y``, ``c_z`` [m] of each point and its quality
        ``rms_rel``, ``max_rel`` [-] (computed through :func:`payload_peaks`).
    """
    args = (robot, payloads, paper_moments, start, end, duration)
    rows = {}
    for name, (offset, reference) in ({} if points is None else points).items():
        errors = reference_errors(*args, offset, reference, samples)
        rows[name] = (offset, jnp.asarray(reference, dtype=float), errors)
    for name, (guess, fixed) in starts.items():
        fit = fit_moment_reference(*args, guess, fixed, samples)
        rows[name] = (fit.slider_offset, fit.reference, fit.relative_errors)
    table = Table(table_id, title)
    for name, (offset, reference, errors) in rows.items():
        for column, value in zip(("l", "c_x", "c_y", "c_z"), (offset, *reference), strict=True):
            table.add(name, column, value, "m")
        table.add(name, "rms_rel", jnp.sqrt(jnp.mean(errors**2)), "-")
        table.add(name, "max_rel", jnp.max(jnp.abs(errors)), "-")
    return table
