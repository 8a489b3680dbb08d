"""jit at the boundary: a second call on a robot of the same structure with other
parameter values compiles nothing new (counted with JAX's backend-compile events)."""

import jax
import jax.numpy as jnp
import numpy as np
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


def test_codesign_compiles_once(setup):
    robot, other, _, _, motion = setup

    def call(r):
        return jaxbal.design.codesign(r, motion, "rms_force", free=("counter_mass",), max_steps=5)

    assert _compiles_of(call, robot, other) == 0


def test_eager_inverse_kinematics_is_one_program_compiled_once(setup):
    """Called eagerly, the IK runs as one compiled program (op by op it compiled dozens
    of primitives the first time in a process): another pose given as a list, another
    parameter value and a NumPy-scalar branch compile nothing; the values equal the
    traced IK's, and an unreachable pose still raises ValueError naming it."""
    robot, other, path, _, _ = setup
    start, end = path.line.start, path.line.end
    branch = robot.default_branch
    q = robot.inverse_kinematics(start, branch=branch)
    n = len(_COMPILES)
    # a list of Python floats and NumPy-scalar signs: passed as arrays / Python ints
    as_list = np.asarray(end).tolist()
    q_end = other.inverse_kinematics(as_list, branch=tuple(np.int64(s) for s in branch))
    assert len(_COMPILES) == n
    traced = jax.jit(lambda r, u: r.inverse_kinematics(u, branch=branch))
    np.testing.assert_allclose(q, traced(robot, start), rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(q_end, traced(other, end), rtol=1e-14, atol=1e-15)
    far = jnp.full(start.shape, 50.0)
    with pytest.raises(ValueError, match=r"(outside|out of).*50\."):
        robot.inverse_kinematics(far, branch=branch)
