"""The `navzoo` command line, run as a user would (subprocess, JSON output parsed)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest


def _navzoo(*args: str, timeout: float = 300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "navzoo.cli", *args], capture_output=True, text=True, timeout=timeout)


def test_help_lists_commands():
    r = _navzoo("--help")
    assert r.returncode == 0
    for cmd in ("demo", "scenes", "speed"):
        assert cmd in r.stdout


def test_scenes_json():
    r = _navzoo("scenes", "--json")
    assert r.returncode == 0, r.stderr
    scenes = {s["name"]: s for s in json.loads(r.stdout)["scenes"]}
    for name in ("station", "home", "grocery", "circle_crossing", "square_crossing", "corridor", "doorway", "lobby"):
        assert name in scenes
        assert scenes[name]["free_area_m2"] > 0


def test_demo_writes_video_plot_metrics(tmp_path: Path):
    out = tmp_path / "demo"
    r = _navzoo("demo", "--scene", "circle_crossing", "--out", str(out), "--json")
    assert r.returncode == 0, r.stderr
    metrics = json.loads(r.stdout)  # stdout is exactly one JSON object
    assert metrics["robots"][0]["event"] in {"goal", "collision_human", "collision_obstacle", "timeout"}
    files = metrics["files"]
    for key in ("video", "trajectory_plot", "metrics", "episode"):
        assert Path(files[key]).is_file() and Path(files[key]).stat().st_size > 0
    cap = cv2.VideoCapture(files["video"])
    ok, frame = cap.read()
    assert ok and frame.shape[0] > 100 and frame.shape[1] > 100
    assert json.loads(Path(files["metrics"]).read_text())["scene"] == "circle_crossing"


def test_speed_json_reports_the_documented_keys():
    r = _navzoo("speed", "--humans", "2,4", "--steps", "5", "--repeats", "1", "--json")
    assert r.returncode == 0, r.stderr
    results = json.loads(r.stdout)["results"]
    assert [x["humans"] for x in results] == [2, 4]
    for x in results:
        for key in ("env_steps_per_s", "agent_steps_per_s", "physics_fraction"):
            assert x[key] > 0
        assert 0 < x["physics_fraction"] <= 1


@pytest.mark.parametrize("args, msg", [
    (("demo", "--scene", "atlantis", "--no-video"), "atlantis"),
    (("speed", "--humans", "five"), "comma-separated integers"),
])
def test_bad_input_gives_a_clear_error(args, msg, tmp_path):
    r = _navzoo(*args, "--out", str(tmp_path)) if args[0] == "demo" else _navzoo(*args)
    assert r.returncode != 0
    assert msg in r.stderr


def test_motions_convert_reproduces_the_shipped_library(tmp_path: Path):
    src = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
    if not src.is_dir():
        pytest.skip("../shared/data/mocap is not available")
    r = _navzoo("motions", "convert", "--src", str(src), "--out", str(tmp_path), "--json")
    assert r.returncode == 0, r.stderr
    summary = json.loads(r.stdout)
    assert summary["clips"] == 170
    shipped = Path(__file__).resolve().parents[1] / "navzoo" / "assets" / "motions"
    # Same arrays and index up to floating-point rounding: numpy's vectorised maths takes other code
    # paths on other CPUs (seen: 12 of 300,528 sph_vel values 5e-15 apart on another AMD EPYC, same
    # numpy 2.4.6), so the bytes, and the index's sha256 of them, may differ across machines.
    new, old = np.load(tmp_path / "library.npz"), np.load(shipped / "library.npz")
    assert sorted(new.files) == sorted(old.files)
    for key in old.files:
        assert new[key].dtype == old[key].dtype and new[key].shape == old[key].shape, key
        if new[key].dtype.kind in "fc":
            np.testing.assert_allclose(new[key], old[key], rtol=1e-9, atol=1e-12, err_msg=key)
        else:
            np.testing.assert_array_equal(new[key], old[key], err_msg=key)
    _assert_json_close(json.loads((tmp_path / "library.json").read_text()),
                       json.loads((shipped / "library.json").read_text()), "library.json")


def _assert_json_close(a, b, where: str) -> None:
    """Equal JSON values, numbers up to rounding (relative 1e-6), the arrays' sha256 excepted."""
    assert type(a) is type(b) or {type(a), type(b)} <= {int, float}, where
    if isinstance(a, dict):
        assert a.keys() == b.keys(), where
        for k in a:
            if k != "arrays_sha256":
                _assert_json_close(a[k], b[k], f"{where}.{k}")
    elif isinstance(a, list):
        assert len(a) == len(b), where
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_json_close(x, y, f"{where}[{i}]")
    elif isinstance(a, float | int) and not isinstance(a, bool):
        assert a == pytest.approx(b, rel=1e-6, abs=1e-12), where
    else:
        assert a == b, where


def test_motions_convert_rejects_a_missing_source(tmp_path: Path):
    r = _navzoo("motions", "convert", "--src", str(tmp_path / "nope"), "--out", str(tmp_path / "out"))
    assert r.returncode == 2 and "not found" in r.stderr
