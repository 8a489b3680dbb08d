"""The regressor fast path of the co-design (jaxbal._src.reduced_motion): the reduced RMS
force and moment and the added inertia equal the direct metrics, value and gradient, on a
serial arm and on the closed-chain DUAL-V; the reduced co-design reaches the direct one's
optimum; a design variable that moves a body frame is detected; and the host-driven
L-BFGS-B restores the BLAS thread limit it sets."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxbal
from jaxbal._src.lbfgsb import one_blas_thread
from jaxbal._src.reduced_motion import reduce_motion, wanted_parts
from jaxbal._src.robots.planar_arm import PlanarArm
from jaxbal.design import (
    Motion,
    added_inertia,
    codesign,
    motion_samples,
    rms_force,
    rms_moment,
)


def _arm_motion(dof: int, samples: int = 200) -> Motion:
    t = jnp.linspace(0.0, 0.5, samples)[:, None]
    amplitude, omega, phase = jnp.linspace(0.8, 0.3, dof), 2 * jnp.pi / 0.5, jnp.arange(dof)
    q = amplitude * jnp.sin(omega * t + phase)
    qd = amplitude * omega * jnp.cos(omega * t + phase)
    qdd = -amplitude * omega**2 * jnp.sin(omega * t + phase)
    return Motion(q, qd, qdd)


@pytest.fixture(scope="module")
def arm():
    design = {"counter_mass": [1.0, 0.5, 0.2], "counter_distance": [0.1, 0.2, 0.05]}
    robot = jaxbal.robots.planar_3r().with_design({n: jnp.array(v) for n, v in design.items()})
    return robot, _arm_motion(3)


@pytest.fixture(scope="module")
def dual_v():
    robot = jaxbal.robots.dual_v()
    line = jaxbal.StraightLine(
        jnp.array([0.0, -0.05, 0.0]), jnp.array([0.05, 0.05, 0.0]), jaxbal.profiles.Quintic(), 0.1
    )
    move = jaxbal.planning.EndEffectorLine(robot, line)
    return robot, motion_samples(robot, [move], jaxbal.sample_times(0.1, 32))


FREE = ("counter_mass", "counter_distance")


def _designs(robot):
    design = robot.design()
    return [
        {n: np.asarray(design[n], dtype=float) * s + o for n in FREE}
        for s, o in ((1.0, 0.0), (0.3, 0.05), (2.0, 0.01))
    ]


def _loss(x, robot, m):
    r = robot.with_design(x)
    return rms_force(r, m) + rms_moment(r, m) + 10.0 * added_inertia(r, m)


#: the three metrics and the loss's gradient, each compiled once per structure
_METRICS = jax.jit(lambda r, m: [f(r, m) for f in (rms_force, rms_moment, added_inertia)])
_GRAD = jax.jit(jax.grad(_loss))


@pytest.mark.parametrize("case", ["arm", pytest.param("dual_v", marks=pytest.mark.slow)])
def test_reduced_rms_equals_the_direct_metric(case, request):
    robot, motion = request.getfixturevalue(case)
    reduced = reduce_motion(robot, motion, FREE, ("rms_force", "rms_moment", "added_inertia"))
    assert reduced is not None and reduced.force is not None and reduced.moment is not None
    assert reduced.inertia is not None
    # the QR factor has at most as many rows as the kept columns
    assert reduced.force.shape[0] <= len(reduced.force_columns)
    for design in _designs(robot):
        candidate = robot.with_design(design)
        for direct, fast in zip(
            _METRICS(candidate, motion), _METRICS(candidate, reduced), strict=True
        ):
            np.testing.assert_allclose(float(fast), float(direct), rtol=1e-11)
            assert abs(float(direct)) > 1e-3  # a real, non-trivial value
        x = {n: jnp.asarray(v) for n, v in design.items()}
        grad_direct = _GRAD(x, robot, motion)
        grad_fast = _GRAD(x, robot, reduced)
        for n in FREE:
            assert np.all(np.isfinite(grad_fast[n]))
            np.testing.assert_allclose(grad_fast[n], grad_direct[n], rtol=1e-9, atol=1e-12)


def test_only_the_parts_in_use_are_built(arm):
    robot, motion = arm

    def moment_only(r, m):
        return rms_moment(r, m) + jaxbal.design.added_mass(r)

    def neither(r, m):
        return jaxbal.design.peak_force(r, m)

    def inertia_only(r, m):
        return added_inertia(r, m) ** 2

    assert wanted_parts(robot, motion, ("rms_force", "added_mass")) == (True, False, False)
    assert wanted_parts(robot, motion, (moment_only,)) == (False, True, False)
    assert wanted_parts(robot, motion, (neither, "peak_moment")) == (False, False, False)
    assert wanted_parts(robot, motion, (inertia_only, "rms_force")) == (True, False, True)
    assert reduce_motion(robot, motion, FREE, (neither,)) is None
    reduced = reduce_motion(robot, motion, FREE, (moment_only,))
    assert reduced.force is None and reduced.moment is not None and reduced.inertia is None
    reduced = reduce_motion(robot, motion, FREE, (inertia_only,))
    assert reduced.force is None and reduced.moment is None and reduced.inertia is not None


class _LengthArm(PlanarArm):
    """A planar arm whose link lengths are a design variable (they move the frames)."""

    design_fields = {**PlanarArm.design_fields, "length": "lengths"}


def test_a_variable_that_moves_a_frame_is_evaluated_directly(arm):
    robot, motion = arm
    fields = {f: getattr(robot, f) for f in ("lengths", "com_ratios", "masses", "inertias")}
    moving = _LengthArm(**fields, payload=robot.payload)
    assert reduce_motion(moving, motion, ("counter_mass", "length"), ("rms_force",)) is None
    assert reduce_motion(moving, motion, ("counter_mass",), ("rms_force",)) is not None


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_reduced_codesign_reaches_the_direct_optimum(arm):
    robot, motion = arm
    objective = {"rms_force": 1.0, "rms_moment": 0.1, "added_mass": 0.1, "added_inertia": 0.1}
    solutions = [
        codesign(robot, motion, objective, free=FREE, gtol=1e-12, max_steps=300, reduce=flag)
        for flag in (True, False)
    ]
    fast, direct = solutions
    assert bool(fast.converged) and bool(direct.converged)
    np.testing.assert_allclose(float(fast.value), float(direct.value), rtol=1e-9)
    # the optimum sets the counter-masses and their moments m·d; the distance of a
    # counter-mass that reaches zero is free (here the third: the two optimisers, the
    # compiled BFGS and L-BFGS-B, leave it at different values)
    masses = [np.asarray(s.design["counter_mass"]) for s in solutions]
    moments = [
        m * np.asarray(s.design["counter_distance"]) for m, s in zip(masses, solutions, strict=True)
    ]
    np.testing.assert_allclose(masses[0], masses[1], rtol=1e-5, atol=1e-8)
    np.testing.assert_allclose(moments[0], moments[1], rtol=1e-5, atol=1e-8)
    where = masses[1] > 1e-6
    np.testing.assert_allclose(
        fast.design["counter_distance"][where], direct.design["counter_distance"][where], rtol=1e-5
    )
    # the reported metrics are the direct ones of the optimised robot
    np.testing.assert_allclose(
        fast.metrics["rms_force"][1], float(rms_force(fast.robot, motion)), rtol=1e-10
    )


def test_blas_thread_limit_is_restored():
    from threadpoolctl import threadpool_info

    before = [(pool["internal_api"], pool["num_threads"]) for pool in threadpool_info()]
    with one_blas_thread():
        inside = [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]
    assert all(n == 1 for n in inside)
    assert [(pool["internal_api"], pool["num_threads"]) for pool in threadpool_info()] == before
