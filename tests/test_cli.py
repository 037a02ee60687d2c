"""The `navzoo` command line, run as a user would (subprocess, JSON output parsed)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import cv2
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
    for name in ("library.npz", "library.json"):
        assert (tmp_path / name).read_bytes() == (shipped / name).read_bytes(), name


def test_motions_convert_rejects_a_missing_source(tmp_path: Path):
    r = _navzoo("motions", "convert", "--src", str(tmp_path / "nope"), "--out", str(tmp_path / "out"))
    assert r.returncode == 2 and "not found" in r.stderr
