"""scripts/device_fallen_obstacles.sh: each job line becomes the following run of its configuration name, with FLAGS."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "scripts" / "device_fallen_obstacles.sh"


def _run(tmp_path: Path, jobs: str, **env: str) -> tuple[subprocess.CompletedProcess, dict[str, str]]:
    """Run the script with ``PYTHON=echo`` (each run's log then holds its command line); logs by part name."""
    (tmp_path / "jobs.txt").write_text(jobs)
    out = tmp_path / "out"
    full = {"PATH": "/usr/bin:/bin", "PYTHON": "echo", "P": "2", "OUT": str(out), "JOBS": str(tmp_path / "jobs.txt"),
            **env}
    proc = subprocess.run(["bash", str(SCRIPT)], cwd=tmp_path, env=full, capture_output=True, text=True)
    logs = {p.stem: p.read_text() for p in (out / "parts").glob("*.log")}
    return proc, logs


@pytest.mark.skipif(shutil.which("xargs") is None or shutil.which("timeout") is None, reason="needs xargs and timeout")
def test_names_pick_the_target_generator_and_flags_fill_the_fallen_field(tmp_path: Path) -> None:
    proc, logs = _run(tmp_path, "kdtp1 doorway 4\nskdtp1 station 3\n", FLAGS="human_door_turns+amp_replan_seconds=1.0")
    assert proc.returncode == 0, proc.stderr
    assert set(logs) == {"kdtp1_doorway_4", "skdtp1_station_3"}
    d, s = logs["kdtp1_doorway_4"].split(), logs["skdtp1_station_3"].split()
    assert d[d.index("--crowd") + 1] == "diffusion" and s[s.index("--crowd") + 1] == "sfm"
    assert d[d.index("--configs") + 1] == ("kdtp1:0.1:0.1:4:2.0:human_door_turns+amp_replan_seconds=1.0::::::::::"
                                           "SFM_SIDE_BIAS=0.4+SFM_SIDE_NARROW_REACH=1.5")
    # the social-force configuration sets the target generator's own fields (as in "Falls come in cascades")
    assert s[s.index("--configs") + 1] == ("skdtp1:0.1:0.1:4:2.0:human_door_turns+amp_replan_seconds=1.0::::1:::::1:"
                                           "SFM_SIDE_BIAS=0.4+SFM_SIDE_NARROW_REACH=1.5")
    assert d[d.index("--seeds") + 1] == "4" and d[d.index("--scenes") + 1] == "doorway"
    assert d[d.index("--out") + 1].endswith("parts/kdtp1_doorway_4.jsonl")


@pytest.mark.skipif(shutil.which("xargs") is None or shutil.which("timeout") is None, reason="needs xargs and timeout")
def test_default_flags_and_diffusion_settings_and_an_unknown_name(tmp_path: Path) -> None:
    proc, logs = _run(tmp_path, "kdtfr lobby 0\nskdtfr lobby 0\nxyz lobby 0\n", DSET="fallen_in_map=1")
    assert "unknown configuration xyz" in proc.stderr
    d, s = logs["kdtfr_lobby_0"].split(), logs["skdtfr_lobby_0"].split()
    assert d[d.index("--configs") + 1].startswith("kdtfr:0.1:0.1:4:2.0:human_door_turns+human_fallen_obstacles::")
    # DSET reaches the runs with diffusion targets only
    assert d[d.index("--diffusion-set") + 1] == "fallen_in_map=1" and "--diffusion-set" not in s
    assert "xyz_lobby_0" not in logs


@pytest.mark.skipif(shutil.which("xargs") is None or shutil.which("timeout") is None, reason="needs xargs and timeout")
def test_set_adds_constants_to_every_run(tmp_path: Path) -> None:
    proc, logs = _run(tmp_path, "kdtfrd doorway 0\nskdtfrd home 1\n", SET="DIFFUSION_DOOR_REACH=1.5")
    assert proc.returncode == 0, proc.stderr
    for name in ("kdtfrd_doorway_0", "skdtfrd_home_1"):
        words = logs[name].split()
        assert words[words.index("--configs") + 1].endswith(
            ":SFM_SIDE_BIAS=0.4+SFM_SIDE_NARROW_REACH=1.5+DIFFUSION_DOOR_REACH=1.5")


@pytest.mark.skipif(shutil.which("xargs") is None or shutil.which("timeout") is None, reason="needs xargs and timeout")
def test_policy_fills_the_policy_field_and_pack_keeps_the_parts_in_one_file(tmp_path: Path,
                                                                            monkeypatch: pytest.MonkeyPatch) -> None:
    import tarfile

    monkeypatch.syspath_prepend(str(ROOT / "scripts"))
    from amp_target_ablation import parse_config

    policy = tmp_path / "pol"
    policy.mkdir()
    (policy / "config.json").write_text("{}")
    proc, _ = _run(tmp_path, "kdtx doorway 0\nskdtx home 1\n", POLICY=str(policy), PACK="1")
    assert proc.returncode == 0, proc.stderr
    out = tmp_path / "out"
    assert not (out / "parts").exists()  # packed: the device tool returns at most 8 files
    with tarfile.open(out / "parts.tgz") as tar:
        logs = {Path(m.name).stem: tar.extractfile(m).read().decode() for m in tar.getmembers() if m.name.endswith(".log")}
    assert set(logs) == {"kdtx_doorway_0", "skdtx_home_1"}
    for name, crowd_fields in (("kdtx_doorway_0", {}), ("skdtx_home_1", {"graded": True, "lag": True})):
        words = logs[name].split()
        cfg = parse_config(words[words.index("--configs") + 1])
        assert cfg["policy"] == str(policy) and cfg["trim"] is None
        assert cfg["set"] == {"SFM_SIDE_BIAS": 0.4, "SFM_SIDE_NARROW_REACH": 1.5}
        for key, value in crowd_fields.items():
            assert cfg[key] is value


@pytest.mark.skipif(shutil.which("xargs") is None or shutil.which("timeout") is None or shutil.which("pkill") is None,
                    reason="needs xargs, timeout and pkill")
def test_deadline_stops_the_list_and_keeps_what_finished(tmp_path: Path) -> None:
    # a fake python that finishes at once for seed 0 and hangs for seed 1, writing a row only when it finishes
    fake = tmp_path / "fake_python"
    fake.write_text('#!/bin/bash\nout=""; seed=""\nwhile [ $# -gt 0 ]; do case $1 in --out) out=$2;; --seeds) seed=$2;; esac; '
                    'shift; done\nif [ "$seed" = 1 ]; then trap \'kill $!; touch "$out.stopped"; exit 1\' TERM; '
                    'sleep 60 & wait; fi\necho \'{"seed": 0}\' > "$out"\n')
    fake.chmod(0o755)
    proc, _ = _run(tmp_path, "kdtx doorway 0\nkdtx doorway 1\n", PYTHON=str(fake), DEADLINE_S="3")
    out = tmp_path / "out"
    assert (out / "kdtx_fallen.jsonl").read_text() == '{"seed": 0}\n'
    assert not (out / "parts" / "kdtx_doorway_1.jsonl").exists()
    assert (out / "parts" / "kdtx_doorway_1.jsonl.stopped").exists()  # the run still going was stopped
