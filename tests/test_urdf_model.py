"""The URDF model (ikbench.core.urdf_model) against Pinocchio reading the same file on its own.

Every shipped URDF, the test arm and a few robots of example-robot-data: the model's joints,
limits, velocities and link frames equal Pinocchio's; the text written for the libraries builds
the same Pinocchio model (placements to 1e-12; the shipped URDFs exactly); its edits (joints
held fixed, continuous joints as revolute, unit axes) do what they say; a broken file is one
line of error.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from ikbench.cli import main
from ikbench.core.errors import InputError
from ikbench.core.robot import load_robot
from ikbench.core.robot_packages import package_urdfs
from ikbench.core.urdf_model import UrdfModel, load_urdf_model

pin = pytest.importorskip("pinocchio")

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = sorted((ROOT / "urdf").glob("*.urdf"))
ARM = ROOT / "tests" / "data" / "unaligned_arm.urdf"
#: example-robot-data robots with continuous joints (kinova), rpy angles yourdfpy writes back
#: wrapped (kinova, talos, tiago, so101), mesh collision elements (ur5, panda_collision).
PACKAGE = ["ur5_robot", "panda_collision", "kinova", "talos_left_arm", "tiago", "so101",
           "xarm7"]


def _package(name: str) -> Path:
    found = package_urdfs("example-robot-data").get(name)
    if found is None:
        pytest.skip("example-robot-data is not installed")
    return found


def _urdfs() -> list:
    shipped = [pytest.param(p, id=p.name) for p in [*SHIPPED, ARM]]
    return shipped + [pytest.param(name, id=f"example-robot-data:{name}") for name in PACKAGE]


def _path(spec: Path | str) -> Path:
    return spec if isinstance(spec, Path) else _package(spec)


def _unit(axis: np.ndarray) -> np.ndarray:
    return axis / np.linalg.norm(axis)


def _rotation(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rodrigues' formula (written here, independently of the module under test)."""
    k = _unit(axis)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


def _link_frames(model: UrdfModel, q: dict[str, float]) -> dict[str, np.ndarray]:
    """(4, 4) every link's frame in the root link's at joint values ``q`` [rad, m], composed
    from the model's origins and axes."""
    frames = {model.root_link: np.eye(4)}
    pending = list(model.joints)
    while pending:
        rest = []
        for joint in pending:
            if joint.parent not in frames:
                rest.append(joint)
                continue
            motion = np.eye(4)
            value = q.get(joint.name, 0.0)
            if joint.type == "prismatic":
                motion[:3, 3] = _unit(joint.axis) * value
            elif joint.type in ("revolute", "continuous"):
                motion[:3, :3] = _rotation(joint.axis, value)
            frames[joint.child] = frames[joint.parent] @ joint.origin @ motion
        if len(rest) == len(pending):
            break
        pending = rest
    return frames


def _pinocchio_q(model, q: dict[str, float]) -> np.ndarray:
    """Pinocchio's configuration vector for joint values by name (cos/sin for continuous)."""
    config = pin.neutral(model)
    for name, value in q.items():
        j = model.getJointId(name)
        i, nq = model.idx_qs[j], model.nqs[j]
        config[i:i + nq] = [np.cos(value), np.sin(value)] if nq == 2 else [value]
    return config


def _random_q(model: UrdfModel, seed: int) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    q = {}
    for joint in model.joints:
        if joint.movable:
            lo, hi = (max(joint.lower, -np.pi), min(joint.upper, np.pi))
            q[joint.name] = float(rng.uniform(lo, hi))
    return q


def _frame_placements(pin_model, q: np.ndarray) -> dict[str, np.ndarray]:
    data = pin_model.createData()
    pin.framesForwardKinematics(pin_model, data, q)
    return {f.name: data.oMf[k].homogeneous for k, f in enumerate(pin_model.frames)
            if f.type == pin.FrameType.BODY}


@pytest.mark.parametrize("spec", _urdfs())
def test_joints_limits_velocities_and_frames_equal_pinocchios(spec):
    path = _path(spec)
    model = load_urdf_model(path)
    reference = pin.buildModelFromUrdf(str(path))
    movable = {j.name: j for j in model.joints if j.movable}
    assert set(movable) == set(reference.names[1:])
    assert model.links and model.root_link in model.links
    assert model.root_link not in {j.child for j in model.joints}
    for name, joint in movable.items():
        j = reference.getJointId(name)
        assert (reference.nqs[j] == 2) == (joint.type == "continuous"), name
        if joint.type != "continuous":
            i = reference.idx_qs[j]
            assert joint.lower == reference.lowerPositionLimit[i], name
            assert joint.upper == reference.upperPositionLimit[i], name
        if np.isfinite(joint.velocity):
            assert joint.velocity == reference.velocityLimit[reference.idx_vs[j]], name
    for seed in range(3):
        q = _random_q(model, seed)
        ours = _link_frames(model, q)
        theirs = _frame_placements(reference, _pinocchio_q(reference, q))
        assert set(ours) == set(model.links) and set(theirs) == set(model.links)
        for link in model.links:
            np.testing.assert_allclose(ours[link], theirs[link], atol=1e-12, err_msg=link)


def _same_model(a, b, atol: float) -> None:
    assert list(a.names) == list(b.names)
    assert [f.name for f in a.frames] == [f.name for f in b.frames]
    for k in range(a.njoints):
        np.testing.assert_allclose(a.jointPlacements[k].homogeneous,
                                   b.jointPlacements[k].homogeneous, rtol=0, atol=atol)
    for fa, fb in zip(a.frames, b.frames):
        np.testing.assert_allclose(fa.placement.homogeneous, fb.placement.homogeneous, rtol=0,
                                   atol=atol, err_msg=fa.name)
    for field in ("lowerPositionLimit", "upperPositionLimit", "velocityLimit", "effortLimit"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field), err_msg=field)


@pytest.mark.parametrize("spec", _urdfs())
def test_the_text_written_for_a_library_builds_the_same_pinocchio_model(spec):
    path = _path(spec)
    model = load_urdf_model(path)
    reference = pin.buildModelFromUrdf(str(path))
    shipped = spec in SHIPPED  # their rpy come back from yourdfpy's matrices bit for bit
    for text in (model.to_xml(), model.to_xml(visuals=True, collisions=False)):
        _same_model(pin.buildModelFromXML(text), reference, atol=0.0 if shipped else 1e-12)
    if model.collisions:
        dirs = [str(p) for p in path.parents][:8]
        ours = pin.buildGeomFromUrdfString(reference, model.to_xml(), pin.GeometryType.COLLISION,
                                           package_dirs=dirs)
        theirs = pin.buildGeomFromUrdf(reference, str(path), pin.GeometryType.COLLISION,
                                       package_dirs=dirs)
        assert ours.ngeoms == theirs.ngeoms == len(model.collisions)
        for a, b in zip(ours.geometryObjects, theirs.geometryObjects):
            assert a.name == b.name and a.meshPath == b.meshPath
            np.testing.assert_allclose(a.placement.homogeneous, b.placement.homogeneous,
                                       rtol=0, atol=1e-12)


def test_collision_elements_are_read_with_their_links_and_meshes():
    model = load_urdf_model(_package("ur5_robot"))
    assert {c.link for c in model.collisions} <= set(model.links)
    meshes = [c for c in model.collisions if c.kind == "mesh"]
    assert meshes and all(c.mesh and c.mesh.startswith("package://") for c in meshes)
    assert all(c.mesh is None for c in model.collisions if c.kind != "mesh")
    assert not load_urdf_model(ARM).collisions


def test_a_joint_held_fixed_carries_its_value_in_its_origin():
    model = load_urdf_model(ARM)
    held = {"slide": 0.12, "j3": 0.4, "roll": -1.1}
    fixed = pin.buildModelFromXML(model.to_xml(fixed=held))
    reference = pin.buildModelFromUrdf(str(ARM))
    assert set(fixed.names[1:]) == {"j1", "j4", "j6", "sensor_joint"}
    rng = np.random.default_rng(1)
    for _ in range(5):
        free = {"j1": rng.uniform(-2, 2), "j4": rng.uniform(-2, 2), "j6": rng.uniform(-1, 1),
                "sensor_joint": rng.uniform(-1, 1)}
        ours = _frame_placements(fixed, _pinocchio_q(fixed, free))
        theirs = _frame_placements(reference, _pinocchio_q(reference, {**free, **held}))
        for link in model.links:
            np.testing.assert_allclose(ours[link], theirs[link], atol=1e-12, err_msg=link)


def test_continuous_joints_as_wide_revolute_ones_and_unit_axes():
    """Read back with ElementTree (a reader independent of yourdfpy)."""
    model = load_urdf_model(ARM)
    text = model.to_xml(continuous_limit=1e6, unit_axes=True)
    wide = pin.buildModelFromXML(text)
    j = wide.getJointId("roll")
    assert wide.nqs[j] == 1 and wide.upperPositionLimit[wide.idx_qs[j]] == 1e6
    joints = {j.get("name"): j for j in ET.fromstring(text).iter("joint")}
    assert joints["roll"].get("type") == "revolute"
    for name, joint in joints.items():
        axis = joint.find("axis")
        if joint.get("type") == "fixed":
            assert axis is None, name  # ikpy warns about an axis on a fixed joint
        else:
            xyz = np.array([float(v) for v in axis.get("xyz").split()])
            assert np.linalg.norm(xyz) == pytest.approx(1.0, abs=1e-15), name
    as_written = {j.get("name"): j for j in ET.fromstring(model.to_xml()).iter("joint")}
    assert as_written["roll"].get("type") == "continuous"
    assert as_written["j1"].find("axis").get("xyz") == "0.1 0.2 1.0"


def test_models_are_cached_per_file_and_content(tmp_path):
    copy = tmp_path / "arm.urdf"
    copy.write_text(ARM.read_text())
    first = load_urdf_model(copy)
    assert load_urdf_model(str(copy)) is first
    copy.write_text(ARM.read_text().replace('xyz="0.2 0 0"', 'xyz="0.21 0 0"'))
    second = load_urdf_model(copy)
    assert second is not first and second.sha256 != first.sha256
    assert second.joint("j4").origin[0, 3] == 0.21 and first.joint("j4").origin[0, 3] == 0.2


def test_the_robot_holds_the_model_it_was_built_from():
    robot = load_robot(ARM, "tool")
    assert robot.urdf_model is load_urdf_model(ARM)
    assert robot.urdf_sha256 == robot.urdf_model.sha256
    np.testing.assert_array_equal(robot.urdf_model.velocity_limits(robot.joint_names),
                                  [1.0, 1.0, 1.0, 1.0, np.nan, 1.0])


@pytest.mark.parametrize("text, message", [
    ('<robot name="a"><link name="x"/>', "Premature end of data"),
    ("", "Document is empty"),
    ('<robot><link name="x"/></robot>', "an element lacks its 'name' attribute"),
    ('<robot name="a"><link name="x"/><joint name="j" type="fixed"><parent link="x"/>'
     "</joint></robot>", "not a URDF yourdfpy can read (AttributeError"),
    ('<robot name="a"><link name="x"/><link name="y"/><joint name="j" type="revolute">'
     '<parent link="x"/><child link="y"/><limit lower="a" upper="1" effort="1" velocity="1"/>'
     "</joint></robot>", "could not convert string to float: 'a'"),
])
def test_a_broken_urdf_is_one_line_of_error(tmp_path, capsys, text, message):
    bad = tmp_path / "bad.urdf"
    bad.write_text(text)
    logger = logging.getLogger("yourdfpy.urdf")
    handlers, propagate = list(logger.handlers), logger.propagate
    with pytest.raises(InputError, match="cannot read URDF") as caught:
        load_urdf_model(bad)
    assert message in str(caught.value) and "\n" not in str(caught.value)
    assert logger.handlers == handlers and logger.propagate == propagate
    assert main(["fk", "--robot", str(bad), "--end-frame", "x"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ikbench: error: cannot read URDF") and err.count("\n") == 1
    assert message in err


def test_a_yourdfpy_copy_can_be_changed_without_changing_the_model():
    model = load_urdf_model(ARM)
    before = model.to_xml()
    urdf = model.to_yourdfpy(build_scene_graph=True, load_meshes=False)
    assert urdf.base_link == model.root_link
    for joint in urdf.robot.joints:
        joint.axis = np.zeros(3)
        joint.type = "fixed"
    assert model.to_xml() == before
    assert load_urdf_model(ARM).joint("j1").type == "revolute"


def _origins(text: str) -> dict[str, list[float]]:
    """joint name -> its origin's six numbers as written, read with ElementTree."""
    out = {}
    for joint in ET.fromstring(text).iter("joint"):
        origin = joint.find("origin")
        words = ("0 0 0 0 0 0" if origin is None
                 else f"{origin.get('xyz', '0 0 0')} {origin.get('rpy', '0 0 0')}").split()
        out[joint.get("name", "")] = [float(w) for w in words]
    return out


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_a_shipped_urdf_is_written_back_number_for_number(path):
    """Origins as the file has them, the sign of a zero included (PyRoki's rotations follow
    it); the libraries' outputs on the shipped robots depend on it."""
    written = _origins(load_urdf_model(path).to_xml())
    for name, numbers in _origins(path.read_text()).items():
        assert written[name] == numbers, name
        assert [np.copysign(1, v) for v in written[name]] == \
            [np.copysign(1, v) for v in numbers], name
