"""``ikbench fk`` as a user meets it."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from ikbench.cli import main


@pytest.mark.parametrize("backend", ["torch", "pinocchio"])
def test_fk_json_exact_object(capsys, backend):
    pose = "-24.92,81.45,46.55,94.37,-59.03,28.0,45.67"
    assert main(["fk", f"--pose={pose}", "--backend", backend, "--json"]) == 0
    out = capsys.readouterr().out
    obj = json.loads(out)
    assert out.strip().count("\n") == 0
    assert set(obj) == {"robot", "backend", "pose_deg", "pose_unit", "point_mm", "direction"}
    assert obj["backend"] == backend and obj["robot"] == "nico_right_arm"
    assert obj["pose_unit"] == "motor deg"
    assert obj["point_mm"] == pytest.approx([-114.44, 293.53, 455.65], abs=0.006)
    assert obj["direction"] == pytest.approx([-0.6798, -0.7313, 0.0553], abs=6e-5)


def test_fk_console_script_no_traceback():
    exe = [sys.executable, "-m", "ikbench.cli", "fk", "--pose=1,2,x,4,5,6,7"]
    proc = subprocess.run(exe, capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip() == (
        "ikbench: error: --pose: 'x' is not a number; give 7 comma-separated motor angles "
        "(r_shoulder_z, r_shoulder_y, r_arm_x, r_elbow_y, r_wrist_z, r_wrist_x, "
        "r_indexfinger_x)"
    )
    assert proc.stdout == ""


def test_help_lists_fk(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    assert "fk" in capsys.readouterr().out
