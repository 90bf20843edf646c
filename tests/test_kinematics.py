"""FK cross-checks: pytorch-kinematics vs Pinocchio vs an independent transcription of the
paper's Eq. 4-11 written here (numpy, standard right-handed R_y)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import torch
import yourdfpy

from tests.conftest import PAPER_START, REPO


def _T(x, y, z):
    m = np.eye(4)
    m[:3, 3] = [x, y, z]
    return m


def _R(axis, deg):
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    m = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def paper_fk_cm(t):
    """Eq. 4-11 of the paper, translations in cm; returns (point_cm, z-axis)."""
    t1, t2, t3, t4, t5, t6, t7 = t
    chain = [
        _T(0, 5, 19.5), _R("z", 90), _R("z", t1),
        _T(0, -1.5, 2.5), _R("y", 90), _R("z", t2),
        _T(3, 0, 9.5), _R("x", -90), _R("z", -t3),
        _T(17.5, 0, 0), _R("x", 90), _R("z", 180), _R("z", -t4),
        _T(10, 0, 0), _R("y", 90), _R("z", -t5 / 2),
        _T(0, 0, 10), _R("x", -90), _R("z", -90), _R("z", t6 / 4.5 + 10),
        _T(0, -1, 0), _T(6, 0, 0), _R("z", 20 + (t7 + 180) / 4.5),
        _T(6, 0, 0), _R("y", 90),
    ]
    m = np.eye(4)
    for factor in chain:
        m = m @ factor
    return m[:3, 3], m[:3, 2]


def test_standard_ry_convention():
    # R_y(90) maps z onto +x in the standard right-handed convention.
    assert np.allclose(_R("y", 90)[:3, :3] @ [0, 0, 1], [1, 0, 0])


@pytest.fixture(scope="module")
def random_poses(robot):
    rng = np.random.default_rng(1234)
    return rng.uniform(robot.lower, robot.upper, size=(1000, robot.dof))


def test_backends_agree_float64(robot, random_poses):
    pin = robot.fk(random_poses, backend="pinocchio")
    tor = robot.fk(random_poses, backend="torch")
    assert np.max(np.abs(pin.point_mm - tor.point_mm)) / 1000.0 < 1e-9  # metres
    assert np.max(np.abs(pin.direction - tor.direction)) < 1e-9


def test_backends_agree_with_paper_transcription(robot, random_poses):
    expected = [paper_fk_cm(p) for p in random_poses[:200]]
    point_mm = np.array([e[0] for e in expected]) * 10.0
    direction = np.array([e[1] for e in expected])
    for backend in ("pinocchio", "torch"):
        got = robot.fk(random_poses[:200], backend=backend)
        assert np.max(np.abs(got.point_mm - point_mm)) / 1000.0 < 1e-9, backend
        assert np.max(np.abs(got.direction - direction)) < 1e-9, backend


REFERENCE_TABLE = [
    (PAPER_START, (-114.44, 293.53, 455.65), (-0.6798, -0.7313, 0.0553)),
    ([33, 39, 25, 134, 102, 77, -168], (-456.03, 33.58, 2.16), (-0.5243, -0.4186, -0.7415)),
    ([51, 54, 37, 161, 92, 38, -174], (-509.97, -16.08, 21.58), (-0.5582, -0.4152, -0.7183)),
    ([34, 17, 39, 107, 106, 78, -180], (-419.65, 81.61, 17.19), (-0.6634, -0.2856, -0.6917)),
]


@pytest.mark.parametrize("pose, point_mm, direction", REFERENCE_TABLE)
@pytest.mark.parametrize("backend", ["pinocchio", "torch"])
def test_reference_values(robot, backend, pose, point_mm, direction):
    got = robot.fk(pose, backend=backend)
    assert np.allclose(got.point_mm[0], point_mm, atol=0.006)
    assert np.allclose(got.direction[0], direction, atol=6e-5)


def test_torch_float32_close_and_differentiable(robot, random_poses):
    fk32 = robot.torch_fk(torch.float32)
    q = torch.tensor(random_poses[:50], dtype=torch.float32, requires_grad=True)
    point_m, direction = fk32(q)
    ref = robot.fk(random_poses[:50])
    assert point_m.dtype == torch.float32
    assert np.max(np.abs(point_m.detach().numpy() * 1000 - ref.point_mm)) < 1e-3  # mm
    (point_m.sum() + direction.sum()).backward()
    assert torch.isfinite(q.grad).all() and q.grad.abs().sum() > 0


def test_batched_equals_single(robot, random_poses):
    fk = robot.torch_fk(torch.float64)
    batch = torch.tensor(random_poses[:20], dtype=torch.float64)
    point_b, dir_b = fk(batch)
    for i in range(20):
        point_i, dir_i = fk(batch[i : i + 1])
        assert torch.allclose(point_b[i], point_i[0], atol=1e-12)
        assert torch.allclose(dir_b[i], dir_i[0], atol=1e-12)


def test_torch_jacobian_matches_finite_differences(robot):
    fk = robot.torch_fk(torch.float64)
    q = torch.tensor([[10.0, 60.0, 30.0, 100.0, 20.0, -30.0, 40.0]], dtype=torch.float64)
    jac = torch.autograd.functional.jacobian(lambda x: fk(x)[0], q).reshape(3, 7)
    eps = 1e-6
    for j in range(7):
        dq = torch.zeros_like(q)
        dq[0, j] = eps
        fd = (fk(q + dq)[0] - fk(q - dq)[0]) / (2 * eps)
        assert torch.allclose(jac[:, j], fd[0], atol=1e-8)


def test_urdf_loads_in_yourdfpy_with_motor_limits(robot):
    urdf = yourdfpy.URDF.load(str(robot.urdf_path), load_meshes=False)
    assert tuple(urdf.actuated_joint_names) == robot.joint_names
    assert robot.end_frame in urdf.link_map and urdf.base_link == robot.root_link
    for name, lo, hi, s, o in zip(robot.joint_names, robot.lower,
                                  robot.upper, robot.scale, robot.offset_deg):
        limit = urdf.joint_map[name].limit
        ends = sorted([math.radians(s * lo + o), math.radians(s * hi + o)])
        assert limit.lower == pytest.approx(ends[0], abs=1e-12)
        assert limit.upper == pytest.approx(ends[1], abs=1e-12)


def test_urdf_is_what_the_generator_writes():
    import importlib.util

    spec = importlib.util.spec_from_file_location("gen", REPO / "urdf" / "generate_urdf.py")
    gen = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(gen)
    motors = json.loads((REPO / "urdf" / "nico_right_arm.motors.json").read_text())
    assert gen.build_urdf(motors) == (REPO / "urdf" / "nico_right_arm.urdf").read_text()


def test_motor_joint_map_round_trip(robot, random_poses):
    q_rad = robot.motor_to_joint_rad(random_poses)
    assert np.allclose(robot.joint_rad_to_motor_deg(q_rad), random_poses, atol=1e-10)
    t = torch.tensor(random_poses)
    assert torch.allclose(robot.motor_to_joint_rad(t), torch.tensor(q_rad))


def test_skeleton_is_pinocchios_joint_placements(robot, random_poses):
    """Base origin, every joint's origin (data.oMi) and the end point, in mm."""
    import pinocchio as pin

    fk = robot.pinocchio_fk()
    skeleton = robot.skeleton_mm(random_poses[:10])
    for pose, points in zip(random_poses[:10], skeleton):
        pin.forwardKinematics(fk.model, fk.data, robot.to_urdf(pose))
        joints = [fk.data.oMi[j].translation * 1000 for j in range(1, fk.model.njoints)]
        np.testing.assert_allclose(points[1:-1], joints, rtol=0, atol=1e-9)
    np.testing.assert_allclose(skeleton[:, 0], 0.0, atol=0)
    np.testing.assert_allclose(skeleton[:, -1], robot.fk(random_poses[:10]).point_mm, atol=1e-9)
