"""Benchmark reports: Markdown, CSV, HTML with plots and videos, JSON with the METRICS.md names."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from navzoo.benchmark.report import SCENE_GROUPS, build_report, scene_group, summarize
from navzoo.benchmark.runner import load_episodes, resolve_spec, run_benchmark
from navzoo.cli import main

# The names `navzoo report --json` must give every method x cell (METRICS.md / docs/metrics.md).
REQUIRED = ("success_rate", "collision_rate", "timeout_rate", "human_collision_rate", "obstacle_collision_rate",
            "stuck_rate", "nav_time_s", "path_length_m", "path_length_ratio", "spl", "extra_time_s", "mean_speed",
            "max_accel", "mean_jerk", "heading_change_rad", "path_irregularity", "min_distance_m",
            "discomfort_frequency", "discomfort_mean_min_gap_m", "proxemic_intimate", "proxemic_personal",
            "proxemic_social", "intrusion_time_ratio", "min_ttc_s", "ttc_below_1s", "personal_space_cost",
            "disturbance_lateral_m", "disturbance_velocity_loss_mps", "social_work")


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    """2 scenes (two groups; the flat gets 0 and 1 people) x 2 densities x 2 methods x 2 episodes, in-process."""
    out = tmp_path_factory.mktemp("report") / "run"
    spec, _ = resolve_spec(scenes="corridor,studio_flat", methods="orca,pure-pursuit", density="0.02,0.05",
                           episodes=2, max_steps=10, save_trajectories=1, videos=1)
    summary = run_benchmark(spec, out, workers=0, progress=False)
    assert summary["status"] == "complete" and not summary["errors"], summary["errors"]
    # one unresolved failure, as a crashed episode leaves it
    err = {"method": "orca", "scene": "corridor", "crowd": "sfm", "level": "d0.05", "n_humans": 3, "episode": 9,
           "seed": 1, "type": "RuntimeError", "message": "boom", "traceback": "Traceback ...\nRuntimeError: boom"}
    with open(out / "errors.jsonl", "a") as f:
        f.write(json.dumps(err) + "\n")
    return out


@pytest.fixture(scope="module")
def report(run_dir) -> dict:
    return build_report(run_dir)


def test_every_library_scene_has_a_group():
    from navzoo.world.library import list_scenes

    assert {scene_group(s) for s in list_scenes()} <= set(SCENE_GROUPS)
    assert scene_group("procedural_rooms_3") == "procedural" and scene_group("my_scene.yaml") == "other"


def test_report_writes_markdown_csv_html_json(run_dir, report):
    rep = run_dir / "report"
    for name in ("report.md", "report.html", "report.json", "groups.csv", "cells.csv", "overall.csv"):
        assert (rep / name).is_file() and (rep / name).stat().st_size > 0, name
    md = (rep / "report.md").read_text()
    assert "## All scenes" in md and "## homes (studio_flat)" in md and "## primitives (corridor)" in md
    assert "| orca | sfm | 0.02 /m² | 4 |" in md and "## Failed episodes" in md and "boom" in md
    html = (rep / "report.html").read_text()
    for fig in report["figures"] + report["trajectory_plots"]:
        assert f"src='{fig['file']}'" in html and (rep / fig["file"]).stat().st_size > 5000
    assert {Path(f["file"]).name for f in report["figures"]} == {"metric_bars.png", "group_bars.png",
                                                                 "density_sweep_sfm.png"}
    assert len(report["trajectory_plots"]) == 4  # one per scene x level (episode 0 saved), both methods on it
    assert len(report["videos"]) == 8
    for v in report["videos"]:
        assert f"href='{v['video']}'" in html and (rep / v["video"]).is_file() and (rep / v["poster"]).is_file()
    with open(rep / "groups.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 2 * 2  # method x group x level
    assert {"method", "group", "crowd", "level", "n_episodes", "success_rate", "success_rate_ci95"} <= set(rows[0])


def test_json_numbers_match_the_episodes(run_dir, report):
    recs = load_episodes(run_dir)
    assert report["n_episodes"] == len(recs) == 16 and report["n_errors"] == 1
    assert report["errors"][0]["message"] == "boom" and "traceback" not in report["errors"][0]
    assert len(report["cells"]) == 2 * 2 * 2
    for cell in report["cells"]:
        for name in REQUIRED:
            assert name in cell and name in cell["ci95"], name
        mine = [r for r in recs if all(r[k] == cell[k] for k in ("method", "scene", "crowd", "level"))]
        assert cell["n_episodes"] == len(mine) == 2
        assert cell["success_rate"] == pytest.approx(np.mean([r["success"] for r in mine]))
        assert cell["timeout_rate"] == pytest.approx(np.mean([r["timeout"] for r in mine]))
        assert cell["path_length_m"] == pytest.approx(np.mean([r["path_length_m"] for r in mine]))
        steps = sum(r["total_steps"] for r in mine)
        assert cell["discomfort_frequency"] == pytest.approx(sum(r["discomfort_steps"] for r in mine) / steps)
    empty = [c for c in report["cells"] if c["scene"] == "studio_flat" and c["level"] == "d0.02"]
    assert all(c["n_humans"] == 0 and c["min_distance_m"] is None for c in empty)  # no people: undefined
    assert {r["method"] for r in report["overall"]} == {"orca", "pure-pursuit"}
    assert report["methods"] == ["orca", "pure-pursuit"]


def test_summarize_groups_and_sorts():
    recs = [{"method": "b", "scene": "home", "crowd": "sfm", "level": lv, "success": s, "nav_time_s": t,
             "time_limit_s": 20.0} for lv, s, t in (("d0.3", True, 10.0), ("d0.05", False, None), ("d0.05", True, 8.0))]
    rows = summarize(recs, ("method", "group", "level"))
    assert [r["level"] for r in rows] == ["d0.05", "d0.3"] and rows[0]["group"] == "homes"
    assert rows[0]["success_rate"] == 0.5 and rows[0]["nav_time_s"] == 8.0 and rows[0]["n"]["nav_time_s"] == 1


def test_report_cli_json(run_dir, tmp_path, capsys):
    assert main(["report", str(run_dir), "--json", "--no-plots", "--out", str(tmp_path / "r")]) == 0
    data = json.loads(capsys.readouterr().out)  # stdout is exactly one JSON object
    assert (tmp_path / "r" / "report.md").is_file()
    cell = data["cells"][0]
    assert {"method", "scene", "group", "crowd", "level", "n_episodes", "ci95"} <= set(cell)
    assert all(name in cell for name in REQUIRED)


def test_learned_crowd_names_with_slashes_get_safe_plot_names(run_dir, tmp_path):
    """``rllib:PATH`` crowds hold slashes; their plots must still land in plots/ (it crashed before)."""
    import shutil

    from navzoo.benchmark.runner import artifact_path

    run = tmp_path / "run"
    shutil.copytree(run_dir, run)
    shutil.rmtree(run / "report", ignore_errors=True)
    crowd = "rllib:runs/joint_study/with_robots_seed0"
    recs = [json.loads(line) for line in (run / "episodes.jsonl").read_text().splitlines()]
    for r in recs:
        renamed = {**r, "crowd": crowd}
        for sub, suffix in (("trajectories", ".npz"), ("videos", ".mp4"), ("videos", ".png")):
            old = run / sub / artifact_path(r, suffix)
            if old.is_file():
                new = run / sub / artifact_path(renamed, suffix)
                new.parent.mkdir(parents=True, exist_ok=True)
                old.rename(new)
        r["crowd"] = crowd
    (run / "episodes.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    build_report(run)
    plots = {p.name for p in (run / "report" / "plots").iterdir()}
    assert "density_sweep_rllib_runs_joint_study_with_robots_seed0.png" in plots
    assert any(n.startswith("traj_") and "rllib_runs_joint_study_with_robots_seed0" in n for n in plots)
    assert "rllib:runs/joint_study/with_robots_seed0" in (run / "report" / "report.md").read_text()


def _small_run(out: Path, methods: str, seed: int = 0) -> Path:
    spec, _ = resolve_spec(scenes="corridor", methods=methods, density="0.05", episodes=2, max_steps=5, seed=seed)
    summary = run_benchmark(spec, out, workers=0, progress=False)
    assert summary["status"] == "complete" and not summary["errors"], summary["errors"]
    return out


def test_report_merges_separate_runs_of_other_methods(tmp_path, capsys):
    import gzip
    import shutil

    a = _small_run(tmp_path / "a", "orca")
    b = _small_run(tmp_path / "b", "stop")
    committed = tmp_path / "committed"  # a committed run: episodes.jsonl.gz + run.json, as benchmarks/full_sfm
    committed.mkdir()
    with open(a / "episodes.jsonl", "rb") as src, gzip.open(committed / "episodes.jsonl.gz", "wb") as dst:
        shutil.copyfileobj(src, dst)
    shutil.copy(a / "run.json", committed / "run.json")
    out = tmp_path / "merged"
    assert main(["report", str(committed), str(b), "--json", "--no-plots", "--out", str(out)]) == 0
    rep = json.loads(capsys.readouterr().out)
    assert rep["methods"] == ["orca", "stop"] and rep["n_episodes"] == 4
    assert {src["run"]: src["methods"] for src in rep["merged_from"]} == {str(committed): ["orca"], str(b): ["stop"]}
    # the same episodes (start, goal, crowd) for both methods
    recs = load_episodes(out / "merged_run")
    seeds = {(r["method"], r["episode"]): r["seed"] for r in recs}
    assert seeds[("orca", 0)] == seeds[("stop", 0)] and seeds[("orca", 1)] == seeds[("stop", 1)]
    assert "merged from" in (out / "report.md").read_text()


def test_report_merge_refuses_runs_that_do_not_compare(tmp_path, capsys):
    a = _small_run(tmp_path / "a", "stop")
    other_seed = _small_run(tmp_path / "s", "orca", seed=3)
    assert main(["report", str(a), str(other_seed), "--out", str(tmp_path / "r1")]) == 2
    assert "differ in seed" in capsys.readouterr().err
    assert main(["report", str(a), str(a), "--out", str(tmp_path / "r2")]) == 2  # the same episodes twice
    assert "is in both" in capsys.readouterr().err
    assert main(["report", str(a), str(tmp_path / "s")]) == 2  # several runs need --out
    assert "needs --out" in capsys.readouterr().err
    assert main(["report", str(a), str(tmp_path / "nothing"), "--out", str(tmp_path / "r3")]) == 2
    assert "not a benchmark run" in capsys.readouterr().err


def test_tables_show_fallen_people_only_for_physics_crowds():
    from navzoo.benchmark.report import _html_table, _md_table

    base = {"method": "orca", "scene": "home", "crowd": "sfm", "level": "n10", "success": True, "nav_time_s": 8.0,
            "time_limit_s": 20.0}
    kinematic = summarize([dict(base), dict(base)], ("method", "crowd"))
    assert "people fallen" not in _md_table(kinematic, [("method", "method")])[0]
    physics = summarize([dict(base, people_fallen=0), dict(base, people_fallen=3)], ("method", "crowd"))
    head, _, row = _md_table(physics, [("method", "method")])
    assert head.endswith("| people fallen |")
    assert row.split("|")[-2].strip().startswith("1.50 ± ")  # the mean per episode, with its interval
    assert "<th>people fallen</th>" in _html_table(physics, [("method", "method")])


def test_the_cpu_model_names_the_machine_and_machine_info_uses_it():
    from navzoo.benchmark.runner import cpu_model, machine_info

    cpu = cpu_model()
    assert isinstance(cpu, str) and cpu.strip()
    assert machine_info()["cpu"] == cpu
    from navzoo.machine import package_versions

    assert machine_info()["packages"] == package_versions()
    # the training and study records name the same CPU (once they recorded only platform.processor(), often empty)
    from navzoo.agents import scaling_study
    from navzoo.agents.amp import stage0

    assert scaling_study.machine_info()["cpu"] == cpu
    assert stage0._machine()["cpu"] == cpu


def test_package_versions_name_the_installed_numeric_packages_without_importing_them():
    import platform

    import numpy
    import scipy

    from navzoo.machine import NUMERIC_PACKAGES, package_versions

    v = package_versions()
    assert set(v) == {"python", *NUMERIC_PACKAGES}
    assert v["python"] == platform.python_version()
    assert v["numpy"] == numpy.__version__ and v["scipy"] == scipy.__version__
    assert all(isinstance(x, str) and x for x in v.values())
    assert package_versions(("no-such-package-navzoo",))["no-such-package-navzoo"] == "absent"
