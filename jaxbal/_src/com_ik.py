"""Generic centre-of-mass inverse kinematics: the pose that puts the COM at a target.

For a robot without a closed-form COM inverse kinematics (the SCARA, the DUAL-V, a
robot loaded from MJCF), the COM is a smooth function of the end-effector pose through
the robot's own inverse kinematics: ``S(pose) = x_S(IK(pose))``. With a ``d``-dim COM
target in the robot's COM components (:mod:`~jaxbal._src.com_components`: ``(x, y)``
of a planar robot, ``(x, z)`` of an arm in the vertical plane), the first ``d`` pose
components are solved by Newton's method and the others are held at the given ``free``
values (e.g. the platform angle θ5 of the DUAL-V). The
solution is differentiated implicitly (:func:`jaxbal._src.implicit.newton_solve`), so
planned motions have exact velocities and accelerations and gradients with respect to
every robot parameter.

References:
    Briot, Arakelian & Le Baron (2012), §2 (COM planning through the COM IK);
    Geng et al. (2021), eqs (4)-(7) (the same for a parallel robot, solved numerically).
"""

from __future__ import annotations

import functools

import jax.numpy as jnp

from jaxbal._src.com_components import com_components, planned_com, world_com_target
from jaxbal._src.implicit import newton_solve
from jaxbal._src.solution_guard import guard_solution


def _pose(x, free):
    return jnp.concatenate([x, free])


def _residual(branch, components, x, params):
    robot, target, free = params
    q, _ = robot.inverse_kinematics(_pose(x, free), branch=branch, return_valid=True)
    return planned_com(robot, q, components) - target


@functools.cache
def _residual_for(branch: tuple[int, ...], components: tuple[int, ...]):
    # One hashable residual per branch and projection: repeated solves reuse one
    # compilation.
    return functools.partial(_residual, branch, components)


def com_inverse_kinematics(robot, com, free=None, *, branch=None, return_valid=False, guess=None):
    """Coordinates ``q`` of ``robot`` whose total COM is ``com``.

    Uses the robot's own closed form (a ``com_inverse_kinematics`` method) when it has
    one, else :func:`numerical_com_inverse_kinematics`.
    """
    own = getattr(robot, "com_inverse_kinematics", None)
    solve = own if own is not None else functools.partial(numerical_com_inverse_kinematics, robot)
    return solve(com, free, branch=branch, return_valid=return_valid, guess=guess)


def numerical_com_inverse_kinematics(
    robot, com, free=None, *, branch=None, return_valid=False, guess=None
):
    """Coordinates ``q`` of ``robot`` whose total COM is ``com`` (generic, Newton).

    Args:
        robot: any :class:`~jaxbal.Robot`.
        com: ``(d,)`` target COM [m] in the robot's COM components (``d`` = 2 for
            planar robots, 3 for spatial ones), or a ``(3,)`` world COM for a robot
            whose components are not the leading ones (an arm in the x-z plane: its
            ``(x, z)`` are taken, :func:`~jaxbal._src.com_components.world_com_target`).
        free: the remaining ``k − d`` pose components (default zeros), for a pose of
            length ``k``.
        branch: working mode of the robot's inverse kinematics.
        return_valid: return ``(q, valid)`` (converged and reachable) and never raise.
        guess: ``(d,)`` initial guess of the solved pose components (default: the COM
            target itself, a good guess when the COM follows the end-effector).

    Raises:
        ValueError: eagerly (``return_valid=False``), naming the target, when Newton
            does not converge to a reachable pose.
    """
    com = world_com_target(robot, jnp.atleast_1d(jnp.asarray(com, dtype=float)))
    branch = robot.branch(branch)
    pose_size = jnp.shape(robot.end_effector(jnp.zeros(robot.dof)))[0]
    d = com.shape[0]
    if com.ndim != 1 or d > pose_size:
        raise ValueError(f"com must have shape (d,) with d <= {pose_size}, got {com.shape}")
    free = jnp.zeros(pose_size - d) if free is None else jnp.atleast_1d(jnp.asarray(free, float))
    if free.shape != (pose_size - d,):
        raise ValueError(f"free must have shape ({pose_size - d},), got {free.shape}")
    x0 = com if guess is None else jnp.asarray(guess, dtype=float)[:d]
    residual = _residual_for(branch, com_components(robot, d))
    solution = newton_solve(
        residual, x0, (robot, com, free), throw=False, what="COM inverse kinematics"
    )
    q, reachable = robot.inverse_kinematics(
        _pose(solution.value, free), branch=branch, return_valid=True
    )
    valid = solution.converged & reachable
    if return_valid:
        return q, valid
    return guard_solution(
        q, ~valid, f"COM target not reachable by {type(robot).__name__}", com, robot=robot
    )
