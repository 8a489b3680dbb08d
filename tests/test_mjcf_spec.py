"""A user's file as it comes: a URDF with mesh files not at hand and no sites
(jaxbal._src.robots.mjcf_spec through from_urdf / from_mjcf and ``jaxbal balance``).

References: closed-form forward kinematics of the planar 2R (tool point), the same
robot compiled from the file with its mesh elements deleted by hand (wrench equal to
1e-14), MuJoCo's own error for a missing file.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from typer.testing import CliRunner

import jaxbal
from jaxbal.robots import from_mjcf, from_urdf

INERTIA = '<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/>'
MESH = (
    '<collision><geometry><mesh filename="package://arm/meshes/{name}.stl"/></geometry></collision>'
)
URDF = f"""<?xml version="1.0"?>
<robot name="arm">
  <link name="world"/>
  <link name="base_link">
    <inertial><mass value="2"/>{INERTIA.format(i=0.01)}</inertial>{MESH.format(name="base")}
  </link>
  <joint name="mount" type="fixed"><parent link="world"/><child link="base_link"/>
    <origin xyz="0 0 0.1"/></joint>
  <link name="link1">
    <inertial><origin xyz="0.15 0.01 0"/><mass value="1.5"/>{INERTIA.format(i=0.02)}</inertial>
    {MESH.format(name="link1")}
  </link>
  <joint name="shoulder" type="revolute"><parent link="base_link"/><child link="link1"/>
    <origin xyz="0 0 0.05"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="50" velocity="5"/></joint>
  <link name="link2">
    <inertial><origin xyz="0.12 0 0"/><mass value="1.0"/>{INERTIA.format(i=0.01)}</inertial>
    {MESH.format(name="link2")}
  </link>
  <joint name="elbow" type="continuous"><parent link="link1"/><child link="link2"/>
    <origin xyz="0.3 0 0"/><axis xyz="0 0 1"/></joint>
  <link name="tool"/>
  <joint name="flange" type="fixed"><parent link="link2"/><child link="tool"/>
    <origin xyz="0.25 0 0" rpy="0 0 0.5"/></joint>
</robot>
"""
NO_MESHES = "\n".join(line for line in URDF.splitlines() if "<mesh" not in line)
_WRENCH = jax.jit(jaxbal.shaking_wrench)  # one program per robot structure
STATE = tuple(jnp.asarray(v) for v in ([0.4, -1.1], [1.5, -2.0], [3.0, 4.5]))


def _tip(q, offset):
    """Tool point of the 2R in the world (links 0.3 m and 0.25 m, tool frame turned
    0.5 rad about z from link 2's) [m]."""
    a, b = q[0], q[0] + q[1]
    c = b + 0.5
    x = 0.3 * np.cos(a) + 0.25 * np.cos(b) + offset[0] * np.cos(c) - offset[1] * np.sin(c)
    y = 0.3 * np.sin(a) + 0.25 * np.sin(b) + offset[0] * np.sin(c) + offset[1] * np.cos(c)
    return np.array([x, y])


def test_missing_meshes_are_named_with_the_remedy_and_ignored_on_request():
    """MuJoCo cannot open the URDF's meshes: the error says so and names the remedy;
    with ignore_meshes the robot is the one compiled from the file without its mesh
    elements (same masses, COMs, inertias and shaking wrench, 1e-14)."""
    with pytest.raises(ValueError, match="mesh file is missing: ignore_meshes=True"):
        from_urdf(URDF)
    robot, reference = from_urdf(URDF, ignore_meshes=True), from_urdf(NO_MESHES)
    assert robot.mass_names() == reference.mass_names() == ("link1", "link2")
    for name in ("mass", "com", "inertia"):
        np.testing.assert_allclose(getattr(robot, name), getattr(reference, name), atol=1e-15)
    force, moment = _WRENCH(robot, *STATE)
    expected = _WRENCH(reference, *STATE)
    np.testing.assert_allclose(force, expected[0], rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(moment, expected[1], rtol=1e-14, atol=1e-14)


def test_an_end_effector_link_fused_by_mujoco_keeps_its_frame():
    """The tool link hangs on a fixed joint, so MuJoCo fuses it into link2; its origin
    (and a point off it, in its turned frame) is the end-effector, equal to the closed
    form of the 2R to 1e-15 m at two configurations."""
    for offset in (None, (0.04, -0.02, 0.0)):
        robot = from_urdf(URDF, ignore_meshes=True, end_effector_body="tool",
                          end_effector_offset=offset)  # fmt: skip
        assert robot.pose_labels() == ("tool.x", "tool.y")
        for q in ([0.0, 0.0], [0.7, -1.3]):
            point = np.asarray(robot.end_effector(jnp.asarray(q)))
            np.testing.assert_allclose(point, _tip(q, offset or (0.0, 0.0)), atol=1e-15)


def test_mesh_inertia_and_bad_names_are_refused():
    """A moving link with no <inertial>, whose inertia MuJoCo takes from its mesh, is
    refused by name (dropping the mesh would change it); unknown bodies are listed; the
    offset alone, a site and a body together, a bad offset and an MjModel to edit are
    errors."""
    import mujoco

    inertial = '<inertial><origin xyz="0.12 0 0"/><mass value="1.0"/>'
    no_inertial = URDF.replace(inertial, "<!--").replace(
        f"{INERTIA.format(i=0.01)}</inertial>\n    {MESH.format(name='link2')}",
        f"-->{MESH.format(name='link2')}",
    )
    assert no_inertial.count("<inertial>") == 2
    with pytest.raises(ValueError, match=r"bodies \['link2'\] take their mass"):
        from_urdf(no_inertial, ignore_meshes=True)
    with pytest.raises(ValueError, match=r"unknown body 'flange'; bodies: \['base_link', "):
        from_urdf(URDF, ignore_meshes=True, end_effector_body="flange")
    with pytest.raises(ValueError, match="end_effector_offset needs end_effector_body"):
        from_urdf(NO_MESHES, end_effector_offset=(0.0, 0.0, 0.1))
    with pytest.raises(ValueError, match="not both"):
        from_urdf(NO_MESHES, end_effector_site="x", end_effector_body="tool")
    with pytest.raises(ValueError, match="3 finite numbers"):
        from_urdf(NO_MESHES, end_effector_body="tool", end_effector_offset=(0.0, np.nan, 0.0))
    with pytest.raises(ValueError, match="not an MjModel"):
        from_mjcf(mujoco.MjModel.from_xml_string(NO_MESHES), end_effector_body="tool")


@pytest.mark.slow  # make test: the CLI test below writes a URDF through the same check
def test_counter_masses_written_into_a_urdf_stay_urdf(tmp_path):
    """A counter-mass (with an inertia tensor) on link2 is written as a URDF link on a
    fixed joint, full precision: the file read back (meshes still missing, ignored) has
    the robot's shaking wrench (1e-12)."""
    from jaxbal.robots import add_counter_mass, export_balanced

    source = tmp_path / "arm.urdf"
    source.write_text(URDF)
    robot = from_urdf(source, ignore_meshes=True)
    inertia = np.array([[2e-4, 1e-5, 0.0], [1e-5, 3e-4, 0.0], [0.0, 0.0, 4e-4]])
    robot = add_counter_mass(robot, "link2", (-0.1234567891, 0.01, 0.0), 0.7654321, inertia=inertia)
    path = tmp_path / "balanced.urdf"
    text = export_balanced(source, robot, path, ignore_meshes=True)
    assert text.lstrip().startswith("<robot") and 'value="0.76543209999999995"' in text
    written = from_urdf(path, ignore_meshes=True)
    for ours, theirs in zip(_WRENCH(robot, *STATE),
                            _WRENCH(written, *STATE), strict=True):  # fmt: skip
        np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12)


def test_mjcf_with_a_missing_mesh_loads_without_it():
    """An MJCF body with an <inertial> and a visual mesh whose file is absent (a model
    copied without its assets) loads with ignore_meshes; its mass is the inertial's."""
    xml = (
        '<mujoco><asset><mesh name="shell" file="no/such/shell.stl"/></asset><worldbody>'
        '<body name="l1"><joint name="j1" axis="0 0 1"/><geom type="mesh" mesh="shell"/>'
        '<inertial pos="0.1 0 0" mass="0.7" diaginertia="1e-3 1e-2 1e-2"/>'
        '<site name="tip" pos="0.2 0 0"/></body></worldbody></mujoco>'
    )
    with pytest.raises(ValueError, match="ignore_meshes=True"):
        from_mjcf(xml)
    robot = from_mjcf(xml, ignore_meshes=True)
    np.testing.assert_array_equal(robot.mass, [0.7])


@pytest.mark.slow  # make test-all (make test's 10-minute budget)
def test_cli_balances_a_urdf_arm_by_its_tool_link(tmp_path):
    """``jaxbal balance arm.urdf --body tool --ignore-meshes``: the 2R is force-balanced
    (peak force < 1e-9 of the unbalanced one); without --ignore-meshes it exits 2 with
    the remedy."""
    from jaxbal._src.cli import app

    path = tmp_path / "arm.urdf"
    path.write_text(URDF)
    move = ["balance", str(path), "--body", "tool", "--start", "0.45,0.1", "--end", "0.3,0.3"]
    runner = CliRunner()
    out = tmp_path / "balanced.urdf"
    result = runner.invoke(app, [*move, "--ignore-meshes", "--samples", "11", "--out", str(out)])
    assert result.exit_code == 0, result.output
    assert f"wrote {out}" in result.output and out.read_text().count("<link name=") == 5 + 2
    peaks = _numbers(result.output, "peak shaking force", "balanced peak shaking force")
    assert peaks["balanced peak shaking force"] < 1e-9 * peaks["peak shaking force"]
    refused = runner.invoke(app, move)
    assert refused.exit_code == 2 and "--ignore-meshes" in refused.output
    joints = [*move[:4], "--ignore-meshes", "--samples", "11", "--joints"]
    flipped = runner.invoke(app, [*joints, "--start", "0.3,0.8", "--end", "1.4,-0.8"])
    assert flipped.exit_code == 2 and "not in end's assembly mode" in flipped.output
    negative = runner.invoke(app, [*joints, "--start", "0.3,0.8", "--end", "1.2,0.6",
                                   "--moment-weight", "-1"])  # fmt: skip
    assert negative.exit_code == 2 and "--moment-weight must be finite and >= 0" in negative.output
    zero = runner.invoke(app, [*joints, "--start", "0.3,0.8", "--end", "1.2,0.6",
                               "--position-bound", "0"])  # fmt: skip
    assert zero.exit_code == 2 and "--position-bound must be finite and > 0" in zero.output


def _numbers(output: str, *keys: str) -> dict[str, float]:
    found = {}
    for line in output.splitlines():
        for key in keys:
            if line.strip().startswith(key + " "):
                found[key] = float(line.split()[-2])
    return found


@pytest.mark.slow
def test_cli_trades_force_for_moment_and_added_mass(tmp_path):
    """``--moment-weight`` (and ``--mass-weight``) with ``--free-masses``: the 2R's
    counter-masses then lower the peak shaking moment below the force-balanced design's
    (by more than half) for a bit of force; ``--mass-weight`` lowers the added mass."""
    from jaxbal._src.cli import app

    path = tmp_path / "arm.urdf"
    path.write_text(URDF)
    move = ["balance", str(path), "--body", "tool", "--ignore-meshes", "--joints", "--start",
            "0.3,0.8", "--end", "1.2,0.6", "--duration", "0.3", "--samples", "31",
            "--free-masses"]  # fmt: skip
    keys = ("balanced peak shaking force", "balanced peak shaking moment", "added mass")
    runner = CliRunner()
    weights = ([], ["--moment-weight", "0.3"], ["--moment-weight", "0.3", "--mass-weight", "1"])
    runs = [runner.invoke(app, [*move, *extra]) for extra in weights]
    assert all(run.exit_code == 0 for run in runs), [run.output for run in runs]
    force_only, moment, lighter = (_numbers(run.output, *keys) for run in runs)
    assert force_only["balanced peak shaking force"] < 1e-9
    assert moment["balanced peak shaking moment"] < 0.5 * force_only["balanced peak shaking moment"]
    assert lighter["added mass"] < moment["added mass"]
