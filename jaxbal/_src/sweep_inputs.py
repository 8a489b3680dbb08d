"""Checks of a sweep's inputs that run before anything compiles, each refusing with a
``ValueError`` that names the axis or parameter at fault.

* :func:`check_bounds`: design variables swept below their lower bound;
* :func:`check_trajectory_domain`: a trapezoid's switch times ``u2``, ``ratio`` (and
  its ``duration``), swept or fixed, out of their domain;
* :func:`check_shapes`: a design variable's values, or a ``where=`` leaf's, of a shape
  that does not broadcast to the variable's (e.g. ``(n, 3)`` values of a ``(2,)``
  counter-mass vector);
* :func:`trajectory_values`: a fixed θ (``trajectory=``) given with a motion that takes
  none (not a factory), or not finite;
* :func:`check_names`: an axis or parameter named like an array the store holds
  already (the metric's outputs, e.g. ``value``, and the ``_jaxbal`` manifest), or an
  axis named like another axis's parameter;
* :func:`check_payload_axis`: a swept ``payload`` that the metric replaces by its own
  (:func:`jaxbal.design.over_payloads`);
* :func:`trajectory_shapes`: the outputs' shapes, a motion factory that reads a
  trajectory variable that is neither swept nor given (``trajectory=``) named.
"""

from __future__ import annotations

import numpy as np

from jaxbal._src.sweep_program import output_shapes
from jaxbal._src.sweep_store import MANIFEST, parameter_key

__all__ = [
    "check_bounds",
    "check_names",
    "check_payload_axis",
    "check_shapes",
    "check_trajectory_domain",
    "trajectory_shapes",
    "trajectory_values",
]


def check_bounds(axes: dict, robot, plan) -> None:
    """Design variables swept below their lower bound (``robot.design_lower_bounds()``,
    e.g. a negative mass) are refused before anything runs, naming axis and value."""
    if not hasattr(robot, "design_lower_bounds"):
        return
    lower = robot.design_lower_bounds()
    kinds = {name: how for name, how, _ in plan}
    for dim, axis in axes.items():
        for name, values in axis.values.items():
            if kinds.get(name) != "design" or name not in lower:
                continue
            bound = np.asarray(lower[name], dtype=float)
            bad = np.any(values.reshape(len(values), -1) < bound.reshape(-1), axis=1)
            if bad.any():
                worst = values[np.argmax(bad)].tolist()
                raise ValueError(
                    f"sweep axis {dim!r}: {name} = {worst!r} is below its lower bound "
                    f"{bound.tolist()} ({type(robot).__name__}.design_lower_bounds())"
                )


def check_trajectory_domain(axes: dict, motion, theta: dict) -> None:
    """Refuse, before anything compiles or a store is created, switch times of a
    trapezoid factory (:class:`~jaxbal.design.TrapezoidLine`, ``ComTrapezoid``) swept
    or fixed out of their domain (``0 < u2 < 1/2``, ``0 < ratio ≤ 1``, ``duration >
    0``): the factory's runtime check failed in the first block, after an empty store
    was written.

    Raises:
        ValueError: naming the axis (or ``trajectory=``), the variable and the value.
    """
    from jaxbal._src.motion_factories import THETA_DOMAIN, ComTrapezoid, TrapezoidLine, in_domain

    if not isinstance(motion, TrapezoidLine | ComTrapezoid):
        return
    given = [(f"sweep axis {dim!r}", name, values) for dim, axis in axes.items()
             for name, values in axis.values.items()]  # fmt: skip
    given += [("trajectory=", name, values) for name, values in theta.items()]
    for where, name, values in given:
        if name not in THETA_DOMAIN:
            continue
        outside = ~in_domain(name, values)
        if outside.any():
            least, most, closed = THETA_DOMAIN[name]
            raise ValueError(
                f"{where}: {name} = {np.asarray(values)[outside].ravel()[0]:g} is outside its "
                f"domain {least:g} < {name} {'≤' if closed else '<'} {most:g} (the switch "
                "times of the trapezoid, 0 < u1 = ratio·u2 ≤ u2 < 1/2)"
            )


def check_shapes(axes: dict, robot, plan) -> None:
    """Refuse a design variable, or a leaf set by ``grid(..., where=)``, swept with
    values ``(n, *shape)`` whose ``shape`` does not broadcast to the leaf's (a scalar
    per point always does).

    Raises:
        ValueError: naming the axis, the variable, its shape and the values' shape.
    """
    design = robot.design() if hasattr(robot, "design") else {}
    kinds = {name: how for name, how, _ in plan}
    for dim, axis in axes.items():
        for name, values in axis.values.items():
            where = getattr(axis.setters.get(name), "where", None)  # grid(..., where=)
            if where is not None:
                leaf, what = tuple(np.shape(where(robot))), "the where= leaf"
            elif kinds.get(name) == "design":
                leaf, what = tuple(np.shape(design[name])), "a design variable"
            else:
                continue
            try:
                fits = np.broadcast_shapes(values.shape[1:], leaf) == leaf
            except ValueError:
                fits = False
            if not fits:
                n = len(values)
                raise ValueError(
                    f"sweep axis {dim!r}: {name} is {what} of shape {leaf} of "
                    f"{type(robot).__name__}, so its {n} values need shape {(n, *leaf)} (or "
                    f"({n},), a scalar per point); got values of shape {values.shape}"
                )


def check_names(axes: dict, outputs: dict) -> None:
    """Refuse an axis or parameter stored under a name that the store gives to an output
    of the metric (``outputs``; ``value`` for a metric returning one array) or to its
    manifest (``_jaxbal``), and an axis named like a parameter of another axis.

    Raises:
        ValueError: naming the clashing name and the reserved ones.
    """
    reserved = {*outputs, MANIFEST}
    _check_axis_names(axes)
    for dim, axis in axes.items():
        stored = {dim} | {
            parameter_key(dim, name)
            for name, values in axis.values.items()
            if not (axis.kind == "grid" and values.ndim == 1)
        }
        clash = sorted(stored & reserved)
        if clash:
            raise ValueError(
                f"sweep axis {dim!r}: the name {clash[0]!r} is reserved in the store (the "
                f"metric's outputs and the manifest: {sorted(reserved)}); name the axis "
                "otherwise (grid(..., name=PARAMETER) keeps the parameter it sets)"
            )


def _check_axis_names(axes: dict) -> None:
    """Refuse an axis named like a parameter of another axis (the store would hold two
    arrays of that name; zarr refused the second), naming both axes."""
    for dim in axes:
        for other, axis in axes.items():
            if other != dim and dim in axis.values:
                raise ValueError(
                    f"sweep axis {dim!r} is named like the parameter {dim!r} of axis "
                    f"{other!r}: the store and the dataset would hold two variables of that "
                    f"name; name the axis otherwise (grid(..., name=PARAMETER) keeps the "
                    "parameter it sets)"
                )


def check_payload_axis(metric, axes: dict) -> None:
    """Refuse a ``payload`` parameter swept with a metric that sets the payload itself
    (:func:`jaxbal.design.over_payloads`): it replaces the swept payload at every point,
    so the axis would have no effect.

    Raises:
        ValueError: naming the axis and the metric.
    """
    from jaxbal._src.payload_metric import OverPayloads

    if not isinstance(metric, OverPayloads):
        return
    inner = getattr(metric.metric, "__name__", metric.metric)
    for dim, axis in axes.items():
        if "payload" in axis.values:
            raise ValueError(
                f"sweep axis {dim!r} sets the payload, but the metric over_payloads("
                f"{inner!r}, …) sets its own payloads {list(metric.payloads)} kg at every "
                "point, so the axis would have no effect: sweep another parameter, or "
                f"sweep the payload with the metric {inner!r} itself"
            )


def trajectory_shapes(program, dynamic, first: dict, motion, theta: dict) -> dict:
    """:func:`~jaxbal._src.sweep_program.output_shapes`, with a trajectory variable that
    a motion factory reads but nobody gives refused.

    Raises:
        ValueError: naming the missing variable and the two ways to give it.
    """
    try:
        return output_shapes(program, dynamic, first)
    except KeyError as error:
        key = error.args[0] if error.args else None
        if not callable(motion) or not isinstance(key, str) or key in first or key in theta:
            raise
        given = sorted({*first, *theta})
        raise ValueError(
            f"the motion factory {type(motion).__name__} needs the trajectory variable "
            f"{key!r}, which is neither swept nor given (swept or given: {given}): add an "
            f"axis {key!r}, or pass trajectory={{{key!r}: value}} to jaxbal.sweep "
            f"([motion] {key} = … in a spec)"
        ) from None


def trajectory_values(motion, trajectory) -> dict:
    """The fixed θ ``{name: float64 array}`` of a motion factory.

    Raises:
        ValueError: θ given with a motion that takes none (a fixed motion, not a
            factory ``motion(robot, θ)``: it would be ignored), or a value that is not
            finite; naming the variable.
    """
    theta = dict(trajectory or {})
    if theta and not callable(motion):
        raise ValueError(
            f"trajectory={theta!r} is given, but the motion {type(motion).__name__} is fixed "
            "(not a factory motion(robot, θ)) and takes no trajectory variables: drop it, "
            "or pass a motion factory such as jaxbal.design.TrapezoidLine"
        )
    values = {}
    for name, value in theta.items():
        try:
            values[name] = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"trajectory {name!r} must be numbers, got {value!r}") from None
        if not np.all(np.isfinite(values[name])):
            raise ValueError(f"trajectory {name!r} must be finite, got {value!r}")
    return values
