"""The value checks of a robot's parameters, shared by every physics function.

Body masses (as the physics sees them, derived bodies included) finite and non-negative,
inertias finite, symmetric and positive semi-definite, every floating-point parameter
finite (the class's ``nonnegative_parameters`` also ≥ 0), and the result finite: eagerly
a ``ValueError`` naming the offending values, under ``jit`` a runtime check
(:func:`jaxbal.set_runtime_checks`), in compiled programs that must stay free of
callbacks a mask (:func:`robot_faulty`).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from jaxbal._src.robot import Robot
from jaxbal._src.types import Array
from jaxbal._src.validation import (
    ROUNDING,
    guard,
    is_traced,
    runtime_checks_enabled,
)

#: Relative tolerance of the inertia tensor's symmetry and of its principal minors.
INERTIA_RTOL = 1e-9


def _unphysical(inertia, triangle: bool):
    """Mask ``(b,)``: an inertia tensor ``(b, 3, 3)`` that is not symmetric or not
    positive semi-definite, or with ``triangle`` whose principal moments break the
    triangle inequality ``I₁ ≤ I₂ + I₃`` (no mass distribution has it; MuJoCo refuses
    it when compiling). Tested on the seven principal minors of ``I`` (or of
    ``tr(I)/2·1 − I``, PSD exactly when the triangle inequality holds), each to
    :data:`INERTIA_RTOL` of its scale plus :data:`ROUNDING` kg·m² (a derived inertia
    that is zero up to rounding, −1.8e-18, passes as a derived mass does; the floor was
    1e-21 kg·m²): no eigendecomposition in the traced checks."""
    scale = jnp.max(jnp.abs(inertia), axis=(-2, -1)) + ROUNDING
    asymmetric = jnp.max(jnp.abs(inertia - jnp.swapaxes(inertia, -1, -2)), axis=(-2, -1))
    m = 0.5 * (inertia + jnp.swapaxes(inertia, -1, -2))
    if triangle:
        m = 0.5 * jnp.trace(m, axis1=-2, axis2=-1)[..., None, None] * jnp.eye(3) - m
    tol = INERTIA_RTOL * scale + ROUNDING
    first = jnp.diagonal(m, axis1=-2, axis2=-1)
    pairs = ((0, 1), (0, 2), (1, 2))
    second = jnp.stack([m[..., i, i] * m[..., j, j] - m[..., i, j] ** 2 for i, j in pairs], -1)
    third = jnp.linalg.det(m)
    return (
        (asymmetric > tol)
        | jnp.any(first < -tol[..., None], -1)
        | jnp.any(second < -(tol * scale)[..., None], -1)
        | (third < -tol * scale**2)
    )


def _triangle(robot: Robot) -> bool:
    """Are the robot's inertias those of real bodies (the class sets
    ``physical_inertias``, e.g. an MJCF robot), so the triangle inequality applies? A
    planar model's ``diag(0, 0, I_zz)`` is not one."""
    return getattr(type(robot), "physical_inertias", False)


def _body_faults(robot: Robot):
    """``(bodies, bad mass (b,), bad inertia (b,))`` (masks)."""
    bodies = robot.mass_properties()
    bad_mass = ~(jnp.isfinite(bodies.mass) & (bodies.mass >= -ROUNDING))
    finite = jnp.all(jnp.isfinite(bodies.inertia), axis=(-2, -1))
    if getattr(type(robot), "signed_inertias", False):
        return bodies, bad_mass, ~finite
    inertia = jnp.where(finite[..., None, None], bodies.inertia, 0.0)
    bad_inertia = ~finite | _unphysical(inertia, _triangle(robot))
    return bodies, bad_mass, bad_inertia


def robot_faulty(robot: Robot):
    """Scalar bool (traceable, never raises): would :func:`checked_bodies` or
    :func:`checked_parameters` reject ``robot``? For compiled code that must stay free of
    runtime-error callbacks (e.g. to be stored in the persistent compilation cache): it
    returns the mask, and the caller raises the named error eagerly."""
    _, bad_mass, bad_inertia = _body_faults(robot)
    faulty = jnp.any(bad_mass) | jnp.any(bad_inertia)
    for invalid in _parameter_faults(robot):
        faulty = faulty | jnp.any(invalid)
    return faulty


@eqx.filter_jit
def _faulty(robot: Robot):
    return robot_faulty(robot)


def check_leaves(robot: Robot) -> None:
    """Refuse a robot parameter that is a Python number, not an array (``eqx.tree_at(
    lambda r: r.payload, arm, 1.0)``): the physics indexed it, a ``TypeError: 'float'
    object is not subscriptable``. At trace time, nothing in the compiled program."""
    leaves, _ = jax.tree_util.tree_flatten_with_path(robot)
    for path, leaf in leaves:
        if isinstance(leaf, int | float | complex) and not isinstance(leaf, bool):
            name = type(robot).__name__ + jax.tree_util.keystr(path)
            raise ValueError(
                f"robot parameter {name} is a Python number ({leaf!r}), not an array: "
                f"set arrays, e.g. eqx.tree_at(..., jnp.asarray({leaf!r}))"
            )


def check_robot(robot: Robot) -> None:
    """Raise ``ValueError`` naming the values where :func:`checked_bodies` or
    :func:`checked_parameters` would reject ``robot`` (an eager call: the entry points
    check the robot before compiling their program). The test is one small compiled
    mask per robot structure (~0.3 s the first time; the same checks run op by op
    took 1–1.6 s), the checks that name the values run only when it is set. Under a
    trace (``jit``, ``vmap``, ``grad``) it does nothing: the traced physics guards the
    robot itself."""
    check_leaves(robot)  # before tracing: a Python number is static to filter_jit
    faulty = _faulty(robot)
    if isinstance(faulty, jax.core.Tracer):
        return
    if bool(faulty):
        checked_parameters(robot, checked_bodies(robot, None))


def checked_bodies(robot: Robot, value):
    """``value``, guarded by the robot's mass properties as the physics sees them: every
    body mass finite and ≥ 0 (derived masses included, e.g. the DUAL-V's brass
    counter-mass ``m_cm − m_tun``), to :data:`ROUNDING` (a derived quantity that is zero
    up to rounding passes), every inertia finite, symmetric and positive semi-definite
    (real bodies: the triangle inequality too; :func:`_unphysical`). A robot whose class sets
    ``signed_inertias = True`` (an exact equivalent model, e.g. the DUAL-V's split model
    with residual inertias ``I − m·p·(l − p)``) is checked for finite inertias only."""
    if is_traced(robot) and not runtime_checks_enabled():
        return value  # the masks would be traced for nothing
    bodies, bad_mass, bad_inertia = _body_faults(robot)
    message = "body masses must be finite and >= 0 [kg]"
    value = guard(value, bad_mass, message, bodies.mass, bodies.names)
    message = (
        "body inertias must be finite, symmetric and positive semi-definite"
        + (", principal moments obeying the triangle inequality" if _triangle(robot) else "")
        + " [kg m^2]"
    )
    return guard(value, bad_inertia, message, bodies.inertia, bodies.names)


def _parameters(robot: Robot) -> list[tuple[str, Array]]:
    """``(name, leaf)`` of every floating-point array leaf of the robot (its lengths,
    masses, inertias, ...), named ``Class.field``."""
    flat, _ = jax.tree_util.tree_flatten_with_path(robot)
    prefix = type(robot).__name__
    return [(prefix + jax.tree_util.keystr(p), x) for p, x in flat if eqx.is_inexact_array(x)]


def _signed_parameters(robot: Robot) -> list[tuple[str, Array]]:
    """``(name, value)`` of the fields in the class's ``nonnegative_parameters``."""
    prefix = type(robot).__name__ + "."
    names = getattr(type(robot), "nonnegative_parameters", ())
    return [(prefix + name, jnp.asarray(getattr(robot, name))) for name in names]


def _parameter_faults(robot: Robot) -> tuple:
    """Masks of :func:`checked_parameters`: a non-finite parameter ``(p,)``, and a
    negative one ``(s,)`` when the class names ``nonnegative_parameters``."""
    parameters, signed = _parameters(robot), _signed_parameters(robot)
    faults = ()
    if parameters:
        faults += (jnp.stack([~jnp.all(jnp.isfinite(x)) for _, x in parameters]),)
        if signed:
            faults += (jnp.stack([jnp.any(x < -ROUNDING) for _, x in signed]),)
    return faults


def checked_parameters(robot: Robot, value):
    """``value``, guarded by every floating-point parameter of the robot being finite,
    and the fields in the class's ``nonnegative_parameters`` (lengths, masses,
    inertias) being ``>= 0`` to :data:`ROUNDING` (so that a subnormal ``-1e-309``,
    flushed to zero in compiled code, is judged alike eagerly and under ``jit``).

    The body checks (:func:`checked_bodies`) see masses and inertias only; a NaN length
    set with ``eqx.tree_at`` gave a silent NaN wrench, centre of mass or torque, and a
    negative one a mirrored link. Eagerly a ``ValueError`` naming the parameters
    (``PlanarArm.lengths``) and their values; under ``jit`` a runtime error
    (:func:`jaxbal.set_runtime_checks`).
    """
    parameters, signed = _parameters(robot), _signed_parameters(robot)
    if not parameters:
        return value
    message = "robot parameters must be finite"
    negative = "robot parameters must be >= 0"
    if not is_traced([x for _, x in parameters], [x for _, x in signed]):
        bad = {n: np.asarray(x).tolist() for n, x in parameters if not np.all(np.isfinite(x))}
        if bad:
            raise ValueError(f"{message}: {bad}")
        bad = {n: np.asarray(x).tolist() for n, x in signed if np.any(np.asarray(x) < -ROUNDING)}
        if bad:
            raise ValueError(f"{negative}: {bad}")
        return value
    if not runtime_checks_enabled():
        return value
    for invalid, text in zip(_parameter_faults(robot), (message, negative), strict=False):
        value = guard(value, invalid, text, invalid)
    return value


def checked_finite(what: str, robot: Robot, value):
    """``value`` (a pytree of arrays), guarded by being finite: the result of finite
    inputs overflows when a parameter or the state is too large (a 1e300 m link).
    Eagerly the ``ValueError`` names the largest robot parameter."""
    leaves = jax.tree_util.tree_leaves(value)
    message = f"{what} is not finite (overflow: robot parameters or state too large)"
    if not is_traced(leaves):  # in NumPy: no small JAX operations dispatched eagerly
        arrays = [np.asarray(x) for x in leaves]
        if all(np.all(np.isfinite(x)) for x in arrays):
            return value
        parameters = [(n, np.max(np.abs(x), initial=0.0)) for n, x in _parameters(robot)]
        if parameters:
            name, size = max(parameters, key=lambda item: item[1])
            message += f"; largest robot parameter: {name} with |x| = {size:.3g}"
        raise ValueError(f"{message}: {np.concatenate([np.ravel(x) for x in arrays])!r}")
    if not runtime_checks_enabled():
        return value
    invalid = ~jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in leaves]))
    return guard(value, invalid, message, jnp.concatenate([jnp.ravel(x) for x in leaves]))


def checked_physics(what: str, robot: Robot, value):
    """``value`` guarded by :func:`checked_bodies`, :func:`checked_parameters` and
    :func:`checked_finite` (the checks of every physics output; under a trace, call it
    in :func:`~jaxbal._src.merged_guards.merged_guards`)."""
    return checked_finite(what, robot, checked_parameters(robot, checked_bodies(robot, value)))
