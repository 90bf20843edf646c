"""The shipped collision data: CppFlow problems, robot capsules, NICO's touchscreen.

Reads the files directly (JSON, YAML, TOML, URDF) so a broken file fails here with its name,
independently of the collision checker that uses them.
"""

from __future__ import annotations

import json
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import yaml

ROOT = Path(__file__).resolve().parents[1]
URDF_DIR = ROOT / "urdf"
CPPFLOW = ROOT / "ikbench" / "data" / "cppflow"
# CppFlow's benchmark (ALL_PROBLEM_FILENAMES in cppflow/data_type_utils.py)
CPPFLOW_BENCHMARK = [
    "fetch_arm__hello", "fetch_arm__circle", "fetch_arm__rot_yz2", "fetch_arm__s",
    "fetch_arm__square", "fetch__circle", "fetch__hello", "fetch__rot_yz2", "fetch__s",
    "fetch__square", "panda__1cube", "panda__2cubes", "panda__flappy_bird",
]
ROBOTS_WITH_CAPSULES = ["panda", "fetch", "fetch_arm", "nico_right_arm"]


def _config(robot: str) -> dict:
    return tomllib.loads((URDF_DIR / f"{robot}.toml").read_text(encoding="utf-8"))


def _collision(robot: str) -> dict:
    return json.loads((URDF_DIR / _config(robot)["collision"]).read_text(encoding="utf-8"))


def _urdf_links(robot: str) -> set[str]:
    root = ET.parse(URDF_DIR / _config(robot)["urdf"]).getroot()
    return {link.get("name") for link in root.iter("link")}


def _problem_files() -> list[Path]:
    return sorted((CPPFLOW / "problems").glob("*.yaml"))


def test_every_cppflow_benchmark_problem_ships():
    shipped = {p.stem for p in _problem_files()}
    assert set(CPPFLOW_BENCHMARK) <= shipped, sorted(set(CPPFLOW_BENCHMARK) - shipped)


@pytest.mark.parametrize("path", _problem_files(), ids=lambda p: p.stem)
def test_problem_parses_and_names_a_shipped_path(path):
    doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    assert isinstance(doc, dict), path.name
    assert doc["robot"] in ("panda", "fetch", "fetch_arm"), path.name
    csv = CPPFLOW / "paths" / f"{doc['path_name']}.csv"
    assert csv.is_file(), f"{path.name}: path {doc['path_name']!r} not shipped"
    rows = np.loadtxt(csv, delimiter=",", skiprows=1, ndmin=2)
    assert rows.shape[1] == 8 and len(rows) >= 2, csv.name
    assert np.allclose(np.linalg.norm(rows[:, 4:], axis=1), 1.0, atol=1e-3), csv.name
    for obstacle in doc.get("obstacles") or []:
        keys = {k for item in obstacle for k in item}  # CppFlow: a list of one-key mappings
        assert keys == {"x", "y", "z", "roll", "pitch", "yaw", "size_x", "size_y", "size_z"}


def test_torm_path_lengths_cover_the_benchmark():
    lines = (CPPFLOW / "torm_path_lengths.csv").read_text(encoding="utf-8").splitlines()
    assert lines[0] == "problem,torm_joint_path_length_rad,torm_prismatic_path_length_m"
    problems = [line.split(",")[0] for line in lines[1:]]
    assert sorted(problems) == sorted(CPPFLOW_BENCHMARK)


@pytest.mark.parametrize("robot", ROBOTS_WITH_CAPSULES)
def test_capsules_are_on_links_of_the_urdf(robot):
    doc = _collision(robot)
    links = _urdf_links(robot)
    assert doc["capsules"], robot
    for capsule in doc["capsules"]:
        assert capsule["link"] in links, f"{robot}: {capsule['link']} is not a link of its URDF"
        assert capsule["radius_mm"] > 0, capsule
        assert len(capsule["a_mm"]) == 3 and len(capsule["b_mm"]) == 3, capsule
    assert doc["description"] and doc["source"] and doc["licence"]


@pytest.mark.parametrize("robot", ROBOTS_WITH_CAPSULES)
def test_never_collide_pairs_name_links_with_capsules(robot):
    doc = _collision(robot)
    with_capsules = {c["link"] for c in doc["capsules"]}
    for pair in doc["never_collide"]:
        assert len(pair) == 2 and pair[0] != pair[1], pair
        assert set(pair) <= with_capsules, f"{robot}: {pair} names a link without a capsule"
    keys = [frozenset(p) for p in doc["never_collide"]]
    assert len(keys) == len(set(keys)), f"{robot}: a never_collide pair is listed twice"


def test_obstacle_sets_exist():
    for robot in ROBOTS_WITH_CAPSULES:
        for name, file in _collision(robot).get("obstacle_sets", {}).items():
            assert (URDF_DIR / file).is_file(), f"{robot}: obstacle set {name}: {file} missing"


def _nico():
    from ikbench.core.robot import load_robot

    robot = load_robot("nico_right_arm")
    targets = json.loads((URDF_DIR / "nico_right_arm.targets.json").read_text("utf-8"))
    return robot, targets


def test_nico_finger_capsule_reaches_the_fingertip():
    import pinocchio as pin

    robot, targets = _nico()
    (finger,) = [c for c in _collision("nico_right_arm")["capsules"]
                 if c["link"] == "r_indexfinger_link"]
    a, b = np.array(finger["a_mm"]), np.array(finger["b_mm"])
    far_end = b + finger["radius_mm"] * (b - a) / np.linalg.norm(b - a)  # the surface point
    start = np.array(targets["start_pose"], dtype=float)
    model = robot.pinocchio_fk().model
    data = model.createData()
    pin.framesForwardKinematics(model, data, np.asarray(robot.to_urdf(start), float).ravel())
    placement = data.oMf[model.getFrameId("r_indexfinger_link")]
    far_end_base_mm = placement.rotation @ far_end + placement.translation * 1000.0
    tip_mm = robot.fk(start).point_mm[0]
    assert np.linalg.norm(far_end_base_mm - tip_mm) < 0.01


def test_touchscreen_lies_beyond_every_touch_point():
    robot, targets = _nico()
    doc = json.loads((URDF_DIR / "nico_right_arm.touchscreen.json").read_text("utf-8"))
    (screen,) = doc["obstacles"]
    assert screen["type"] == "halfspace"
    point, normal = np.array(screen["point_mm"]), np.array(screen["normal"])
    normal = normal / np.linalg.norm(normal)
    touches = robot.fk(np.array(list(targets["targets"].values()), dtype=float)).point_mm
    assert len(touches) == 7
    heights = (touches - point) @ normal  # > 0: on the free side
    assert heights.min() >= 3.0 - 1e-6, heights
    assert heights.min() <= 3.0 + 1e-6, "the surface should be 3 mm beyond the deepest touch"
    start = robot.fk(np.array(targets["start_pose"], dtype=float)).point_mm[0]
    assert (start - point) @ normal > 100.0, "the normal must point toward the robot"
