"""scripts/amp_lateral_reach.py: the hands' and feet's sideways reach from the pelvis, by walking speed."""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.script_modules import load_script

reach = load_script("amp_lateral_reach")


def _quat_yaw(yaw: float) -> np.ndarray:
    return np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])  # PyBullet's (x, y, z, w)


def test_the_reach_is_taken_across_the_heading():
    root = np.array([[1.0, 2.0, 0.9], [1.0, 2.0, 0.9]])
    quat = np.stack([_quat_yaw(0.0), _quat_yaw(np.pi / 2)])  # facing +x, then +y
    # key bodies: right hand, left hand, right foot, left foot, head
    offsets = np.array([[0.3, -0.25, 0.0], [-0.2, 0.22, 0.0], [0.1, -0.1, -0.8], [0.0, 0.12, -0.8], [0.0, 0.0, 0.6]])
    key = np.stack([root[0] + offsets, root[1] + offsets])
    hand, foot = reach.sideways(root, quat, key)
    assert hand[0] == pytest.approx(0.25) and foot[0] == pytest.approx(0.12)  # sideways is y when facing +x
    assert hand[1] == pytest.approx(0.3) and foot[1] == pytest.approx(0.1)  # and x when facing +y


def test_samples_are_pooled_by_speed_band():
    speed = np.array([0.1, 0.2, 0.5, 1.2, 1.4])
    hand = np.array([0.3, 0.5, 0.2, 0.25, 0.25])
    out = reach.summarise(speed, hand, hand / 2)
    assert [v["n"] for v in out.values()] == [2, 1, 2]
    assert out["0-0.3"]["hand_median_m"] == pytest.approx(0.4) and out["0-0.3"]["foot_median_m"] == pytest.approx(0.2)
    assert reach.summarise(np.array([1.0]), np.array([0.2]), np.array([0.1]))["0-0.3"] == {"n": 0}


def test_a_short_run_writes_both_rows(tmp_path):
    out = tmp_path / "reach.json"
    assert reach.main(["--scenes", "station:3", "--seconds", "3", "--out", str(out)]) == 0
    result = json.loads(out.read_text())
    for row in (result["clips"], result["policy"]["all"]):
        assert sum(v["n"] for v in row.values()) > 0
        for v in row.values():
            if v["n"]:
                assert 0.0 < v["hand_median_m"] <= v["hand_p95_m"] < 1.0 and 0.0 <= v["foot_median_m"] < 0.6
    assert set(result["policy"]["by_scene"]) == {"station"}


def test_bad_arguments_are_refused_by_name(capsys):
    for argv, word in ((["--scenes", "lobby"], "--scenes"), (["--seconds", "1"], "--seconds"),
                       (["--policy", "/nonexistent"], "--policy")):
        with pytest.raises(SystemExit):
            reach.main(argv)
        assert word in capsys.readouterr().err
