"""The design variables of an :class:`~jaxbal._src.robots.mjcf_robot.MjcfRobot`.

The counter-masses added by :func:`~jaxbal._src.robots.counter_mass.add_counter_mass`
(``counter_mass``, ``counter_position``) and the mass of the ``payload_body`` (``payload``,
a moving body's mass: not a field of its own, so replaced here rather than through the
base class's field mapping). Kept apart from the robot's class so that its file stays
one idea (kinematics and the contract) within the house's 400 lines.

References:
    Briot, Arakelian & Le Baron (2012), §3 (counter-masses as the design variables).
"""

from __future__ import annotations

from collections.abc import Mapping

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from jaxbal._src.robot import Robot
from jaxbal._src.types import Array
from jaxbal._src.validation import check_shape

__all__ = ["design", "design_lower_bounds", "position_bound", "with_design"]


def design(robot) -> dict[str, Array]:
    """``counter_mass (k,)`` [kg] and ``counter_position (k, 3)`` [m, body frame] when
    counter-masses were added; ``payload`` [kg], the mass of ``payload_body``."""
    out = {}
    if robot.counter_names:
        out["counter_mass"] = robot.counter_mass
        out["counter_position"] = robot.counter_position
    if robot.payload_body is not None:
        out["payload"] = robot.mass[robot.payload_body]
    return out


def with_design(robot, values: Mapping):
    """The robot with some design variables replaced (see :func:`design`).

    Raises:
        ValueError: an unknown name (``payload`` without a ``payload_body`` included)
            or a wrong shape.
    """
    if "payload" in values and robot.payload_body is None:
        raise ValueError(
            "unknown design variable 'payload': name a payload body (payload_body=) "
            f"in from_mjcf; this robot has {sorted(design(robot))}"
        )
    out = Robot.with_design(robot, {k: v for k, v in values.items() if k != "payload"})
    if "payload" in values:
        value = jnp.asarray(values["payload"], dtype=float)
        check_shape("design['payload']", value, ())
        mass = out.mass.at[robot.payload_body].set(value)
        out = eqx.tree_at(lambda r: r.mass, out, mass)
    return out


def design_lower_bounds(robot) -> dict[str, float]:
    """Masses ≥ 0; counter positions ≥ −:func:`position_bound` per coordinate."""
    bounds = {name: 0.0 for name in design(robot)}
    if "counter_position" in bounds:
        bounds["counter_position"] = -position_bound(robot)
    return bounds


def position_bound(robot) -> float:
    """Ten times the mechanism's size (largest body offset, anchor or site distance, at
    least 1 m) [m]: the default bound of counter positions."""
    arrays = (robot.body_pos, robot.joint_pos, robot.anchor1, robot.anchor2, robot.site_pos)
    sizes = [float(np.abs(np.asarray(a)).max(initial=0.0)) for a in arrays]
    return 10.0 * max(1.0, *sizes)
