"""jit at the boundary: a second call on a robot of the same structure with other
parameter values compiles nothing new (counted with JAX's backend-compile events)."""

import jax
import jax.numpy as jnp
import pytest

import jaxbal
from jaxbal.planning import EndEffectorLine, wrench_along
from jaxbal.profiles import Quintic

_COMPILES = []


def _listener(event, duration, **kwargs):
    if "backend_compile" in event:
        _COMPILES.append(event)


jax.monitoring.register_event_duration_secs_listener(_listener)


@pytest.fixture(scope="module", params=["planar_3r", "dual_v"])
def setup(request):
    robot = jaxbal.robots.by_name(request.param)
    start, end = {
        "planar_3r": (jnp.array([0.4, 0.3, 0.5]), jnp.array([0.2, 0.5, 1.0])),
        "dual_v": (jnp.array([0.0, -0.05, 0.0]), jnp.array([0.05, 0.05, 0.0])),
    }[request.param]
    path = EndEffectorLine(robot, jaxbal.StraightLine(start, end, Quintic(), 0.2))
    times = jaxbal.sample_times(0.2, 16)
    motion = jaxbal.design.motion_samples(robot, [path], times)
    other = robot.with_design({"payload": jnp.asarray(1.5)})
    return robot, other, path, times, motion


def _compiles_of(call, first, second):
    call(first)
    before = len(_COMPILES)
    call(second)
    return len(_COMPILES) - before


def test_confirm_compiles_once(setup):
    robot, other, _, _, motion = setup
    assert _compiles_of(lambda r: jaxbal.confirm(r, *motion), robot, other) == 0


def test_wrench_along_compiles_once(setup):
    robot, other, path, times, _ = setup
    other_path = EndEffectorLine(other, path.line)
    assert (
        _compiles_of(lambda a: wrench_along(a[0], a[1], times), (robot, path), (other, other_path))
        == 0
    )


def test_sensitivity_compiles_once(setup):
    robot, other, _, _, motion = setup

    def call(r):
        return jaxbal.sensitivity.sensitivity(r, motion, "rms_force", wrt=("payload",))

    assert _compiles_of(call, robot, other) == 0


@pytest.mark.parametrize("reduce", [False, True])
def test_codesign_compiles_once(setup, reduce):
    """Both optimisers: L-BFGS-B around one program, and (``reduce=True``) the compiled
    BFGS loop along the reduced motion (the other payload is a new reduction)."""
    robot, other, _, _, motion = setup

    def call(r):
        return jaxbal.design.codesign(
            r, motion, "rms_force", free=("counter_mass",), max_steps=5, reduce=reduce
        )

    assert _compiles_of(call, robot, other) == 0
