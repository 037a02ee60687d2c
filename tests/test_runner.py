"""The benchmark runner: seeds, determinism across worker counts, resume after a kill, crashes, CLI errors.

The policies that fail on purpose are registered here at import time; the runs that use them pass
``--import tests.test_runner`` so that every worker process registers them too.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from navzoo.agents.baselines import PurePursuitPolicy, register_policy
from navzoo.benchmark.report import build_report
from navzoo.benchmark.runner import (
    BenchmarkSpec,
    build_tasks,
    current_episode,
    episode_seed,
    load_episodes,
    resolve_spec,
    run_benchmark,
)
from navzoo.cli import main


class _FailingPolicy(PurePursuitPolicy):
    """Pure pursuit that fails in one episode (by index): raises, kills its worker process, or hangs."""

    def __init__(self, mode: str, episode: int) -> None:
        self.mode, self.episode = mode, episode

    def act(self, observations, env):
        ep = current_episode()
        if ep is not None and ep["episode"] == self.episode and env.steps >= 2:
            if self.mode == "raise":
                raise RuntimeError(f"deliberate failure in episode {ep['episode']}")
            if self.mode == "exit":
                os._exit(3)  # a worker dying without a Python exception (as a segfault would)
            if self.mode == "hang":
                time.sleep(3600)
        return super().act(observations, env)


register_policy("test-crash", lambda **kw: _FailingPolicy("raise", 1), overwrite=True)
register_policy("test-die", lambda **kw: _FailingPolicy("exit", 0), overwrite=True)
register_policy("test-hang", lambda **kw: _FailingPolicy("hang", 1), overwrite=True)

TINY = dict(scenes="corridor,doorway", methods="orca,pure-pursuit", humans="2", episodes=2, max_steps=12,
            save_trajectories=1)


def _tiny() -> BenchmarkSpec:
    return resolve_spec(**TINY)[0]


def _lines(out: Path) -> list[str]:
    return sorted(line for line in (out / "episodes.jsonl").read_text().splitlines() if line.strip())


@pytest.fixture(scope="module")
def reference_run(tmp_path_factory) -> Path:
    """The tiny benchmark, uninterrupted, with 2 worker processes."""
    out = tmp_path_factory.mktemp("bench") / "ref"
    summary = run_benchmark(_tiny(), out, workers=2, progress=False)
    assert summary["status"] == "complete" and not summary["errors"]
    return out


def test_episode_seed_depends_on_the_cell_and_index_only():
    s = episode_seed(0, "lobby", "sfm", "d0.15", 3)
    assert s == episode_seed(0, "lobby", "sfm", "d0.15", 3) and 0 <= s < 2**63
    others = [episode_seed(1, "lobby", "sfm", "d0.15", 3), episode_seed(0, "home", "sfm", "d0.15", 3),
              episode_seed(0, "lobby", "orca", "d0.15", 3), episode_seed(0, "lobby", "sfm", "d0.3", 3),
              episode_seed(0, "lobby", "sfm", "d0.15", 4)]
    assert len({s, *others}) == 6
    tasks = build_tasks(_tiny(), "unused")
    assert len(tasks) == 2 * 2 * 2
    by_episode: dict = {}
    for t in tasks:  # every method of an episode gets the same seed
        by_episode.setdefault((t.cell.scene, t.episode), set()).add(t.seed)
    assert all(len(v) == 1 for v in by_episode.values()) and len(by_episode) == 4


def test_crowdnav_protocol_is_the_registry_preset(tmp_path):
    import navzoo

    spec, _ = resolve_spec(protocol="crowdnav-circle", methods="orca-crowdnav")
    assert spec.scenes == ("circle_crossing",) and spec.crowds == ("orca_rvo2",) and spec.humans == (5,)
    assert spec.episodes == 500 and spec.time_limit == 25.0
    assert resolve_spec(protocol="crowdnav-circle", methods="orca-crowdnav", episodes=7)[0].episodes == 7
    task = build_tasks(spec, tmp_path)[0]
    mine = navzoo.make(None, **task.env_kwargs).unwrapped.config
    preset = navzoo.make("navzoo/CircleCrossing-v0", n_humans=5).unwrapped.config
    assert mine == preset
    assert mine.robot.kinematics == "holonomic" and mine.robot.radius == 0.3 and mine.robot.max_speed == 1.0
    assert mine.dt == 0.25 and not mine.humans_see_robots and mine.crowd_model == "orca_rvo2"
    square = resolve_spec(protocol="crowdnav-square", methods="orca")[0]
    assert square.scenes == ("square_crossing",)


def test_spec_file_and_command_line_merge(tmp_path):
    path = tmp_path / "spec.yaml"
    path.write_text("scenes: [corridor, lobby]\nmethods: orca,dwa\ncrowd: [sfm, orca]\ndensity: [0.05, 0.15]\n"
                    "episodes: 3\nseed: 7\nworkers: 2\nenv: {robot: {kinematics: holonomic}}\n")
    spec, run_opts = resolve_spec(spec_file=path, episodes=5)
    assert spec.scenes == ("corridor", "lobby") and spec.methods == ("orca", "dwa")
    assert spec.crowds == ("sfm", "orca") and spec.densities == (0.05, 0.15) and spec.humans is None
    assert spec.episodes == 5 and spec.seed == 7 and run_opts == {"workers": 2}
    tasks = build_tasks(spec, tmp_path)
    assert len(tasks) == 2 * 2 * 2 * 5 * 2
    lobby = next(t for t in tasks if t.cell.scene == "lobby" and t.cell.level == "d0.15")
    assert lobby.cell.n_humans == round(0.15 * lobby.cell.free_area_m2) and lobby.env_kwargs["robot"]["kinematics"] == "holonomic"
    assert resolve_spec(spec_file=path, humans="4")[0].humans == (4,)  # counts replace the file's densities
    path.write_text("scenes: corridor\nmethods: orca\nepisodez: 3\n")
    with pytest.raises(ValueError, match="episodez"):
        resolve_spec(spec_file=path)


def test_tiny_run_records_every_metric_and_same_starts(reference_run):
    recs = load_episodes(reference_run)
    assert len(recs) == 8
    for key in ("method", "scene", "group", "crowd", "density", "n_humans", "episode", "seed", "event", "success",
                "collision", "timeout", "nav_time_s", "path_length_m", "spl", "min_distance_m",
                "discomfort_frequency", "intrusion_time_ratio", "personal_space_cost", "social_work", "mean_jerk"):
        assert all(key in r for r in recs), key
    assert {r["method"] for r in recs} == {"orca", "pure-pursuit"}
    for r in recs:
        assert r["seed"] == episode_seed(0, r["scene"], r["crowd"], r["level"], r["episode"])
        assert r["steps"] <= 12
    # Same episode, two methods: identical start, goal and crowd at t = 0.
    for scene in ("corridor", "doorway"):
        a = np.load(reference_run / "trajectories" / "orca" / scene / "sfm_n2_ep0000.npz")
        b = np.load(reference_run / "trajectories" / "pure-pursuit" / scene / "sfm_n2_ep0000.npz")
        np.testing.assert_array_equal(a["robot_pos"][0], b["robot_pos"][0])
        np.testing.assert_array_equal(a["human_pos"][0], b["human_pos"][0])
        np.testing.assert_array_equal(a["goal"], b["goal"])
        assert a["human_pos"].shape[1] == 2
    pairs: dict = {}
    for r in recs:
        pairs.setdefault((r["scene"], r["episode"]), []).append((r["start"], r["goal"]))
    assert all(len(v) == 2 and v[0] == v[1] for v in pairs.values())
    run = json.loads((reference_run / "run.json").read_text())
    assert run["spec"]["methods"] == ["orca", "pure-pursuit"] and run["episodes_done"] == 8
    assert run["machine"]["cores"] >= 1 and run["machine"]["python"]
    assert run["sessions"][-1]["status"] == "complete" and run["sessions"][-1]["episodes_per_hour"] > 0


def test_results_do_not_depend_on_the_worker_count(reference_run, tmp_path):
    out = tmp_path / "one_worker"
    run_benchmark(_tiny(), out, workers=1, progress=False)
    assert _lines(out) == _lines(reference_run)


def test_killed_run_resumes_to_the_same_tables(reference_run, tmp_path):
    out = tmp_path / "killed"
    cmd = [sys.executable, "-m", "navzoo.cli", "benchmark", "--scenes", TINY["scenes"], "--methods", TINY["methods"],
           "--humans", "2", "--episodes", "2", "--max-steps", "12", "--save-trajectories", "1", "--workers", "1",
           "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    episodes = out / "episodes.jsonl"
    deadline = time.time() + 120
    while time.time() < deadline and proc.poll() is None:
        if episodes.is_file() and episodes.read_text().count("\n") >= 3:
            break
        time.sleep(0.02)
    assert proc.poll() is None, f"run ended before it could be killed: {proc.stderr.read().decode()[-2000:]}"
    os.killpg(proc.pid, signal.SIGKILL)  # the whole process group, workers included, as kill -9 / a crash
    proc.wait(timeout=30)
    proc.stderr.close()
    before = len(load_episodes(out))
    assert 3 <= before < 8
    summary = run_benchmark(_tiny(), out, workers=2, progress=False)
    assert summary["skipped"] == before and summary["episodes_run"] == 8 - before
    assert summary["status"] == "complete" and summary["episodes_done"] == 8
    assert _lines(out) == _lines(reference_run)
    a = build_report(reference_run, tmp_path / "ra", plots=False)
    b = build_report(out, tmp_path / "rb", plots=False)
    for name in ("overall.csv", "groups.csv", "cells.csv"):
        assert (tmp_path / "ra" / name).read_text() == (tmp_path / "rb" / name).read_text()
    assert a["cells"] == b["cells"]
    # a rerun of a finished run does nothing; other result-changing settings are refused
    assert run_benchmark(_tiny(), out, workers=2, progress=False)["episodes_run"] == 0
    with pytest.raises(ValueError, match="different settings"):
        run_benchmark(resolve_spec(**{**TINY, "seed": 1})[0], out, workers=1, progress=False)


def test_a_line_cut_off_by_a_kill_is_dropped_and_rerun(reference_run, tmp_path):
    out = tmp_path / "cut"
    out.mkdir()
    lines = (reference_run / "episodes.jsonl").read_text().splitlines(keepends=True)
    (out / "episodes.jsonl").write_text("".join(lines[:6]) + lines[6][: len(lines[6]) // 2])
    assert len(load_episodes(out)) == 6
    summary = run_benchmark(_tiny(), out, workers=0, progress=False)  # in-process: same episodes as the pools
    assert summary["skipped"] == 6 and summary["episodes_run"] == 2
    assert _lines(out) == _lines(reference_run)


def test_crashes_are_recorded_and_the_run_goes_on(tmp_path, capsys):
    out = tmp_path / "crash"
    t0 = time.time()
    rc = main(["benchmark", "--scenes", "corridor", "--methods", "pure-pursuit,test-crash,test-die,test-hang",
               "--humans", "2", "--episodes", "2", "--max-steps", "12", "--episode-timeout", "4", "--workers", "2",
               "--import", "tests.test_runner", "--out", str(out), "--no-progress"])
    assert time.time() - t0 < 80
    assert rc == 1
    err = capsys.readouterr().err
    assert "3 episode(s) failed" in err and "test-crash on corridor" in err
    errors = {e["method"]: e for e in map(json.loads, (out / "errors.jsonl").read_text().splitlines())}
    assert set(errors) == {"test-crash", "test-die", "test-hang"}
    for method, ep in (("test-crash", 1), ("test-die", 0), ("test-hang", 1)):
        e = errors[method]
        assert e["scene"] == "corridor" and e["episode"] == ep
        assert e["seed"] == episode_seed(0, "corridor", "sfm", "n2", ep)
    assert errors["test-crash"]["type"] == "RuntimeError"
    assert "deliberate failure in episode 1" in errors["test-crash"]["traceback"]
    assert errors["test-die"]["type"] == "WorkerDied" and errors["test-die"]["exit_code"] == 3
    assert "timed out" in errors["test-hang"]["message"]
    done = {(r["method"], r["episode"]) for r in load_episodes(out)}
    assert done == {("pure-pursuit", 0), ("pure-pursuit", 1), ("test-crash", 0), ("test-die", 1), ("test-hang", 0)}
    report = build_report(out, plots=False)
    assert report["n_errors"] == 3 and not (out / ".inflight").exists()


def test_a_pool_that_broke_before_a_submit_is_restarted(tmp_path, monkeypatch):
    """A worker can die while the runner is still submitting: ``submit`` then raises BrokenProcessPool
    itself (seen under load with test-die). The pool restarts and every episode still runs."""
    from concurrent.futures import ProcessPoolExecutor
    from concurrent.futures.process import BrokenProcessPool

    import navzoo.benchmark.runner as runner

    pools = []

    class BreaksOnSecondSubmit(ProcessPoolExecutor):
        def __init__(self, *a, **k):
            super().__init__(*a, **k)
            pools.append(self)
            self._submits = 0

        def submit(self, fn, /, *args, **kwargs):
            self._submits += 1
            if len(pools) == 1 and self._submits == 2:
                raise BrokenProcessPool("simulated: a child process terminated abruptly")
            return super().submit(fn, *args, **kwargs)

    monkeypatch.setattr(runner, "ProcessPoolExecutor", BreaksOnSecondSubmit)
    out = tmp_path / "broken"
    summary = run_benchmark(_tiny(), out, workers=2, progress=False)
    assert len(pools) >= 2  # restarted
    assert summary["episodes_run"] == len(load_episodes(out)) and len(load_episodes(out)) > 0
    assert not (out / "errors.jsonl").exists() or not (out / "errors.jsonl").read_text().strip()


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--scenes", "atlantis", "--methods", "orca"], "atlantis"),
        (["--scenes", "corridor", "--methods", "teleport"], "teleport"),
        (["--protocol", "crowdnav-moon", "--methods", "orca"], "crowdnav-circle"),
        (["--scenes", "corridor", "--methods", "orca", "--crowd", "herd"], "herd"),
        (["--scenes", "corridor", "--methods", "orca", "--density", "a,b"], "density"),
        (["--methods", "orca"], "scenes"),
        (["--scenes", "corridor", "--methods", "orca", "--spec", "/nonexistent/spec.yaml"], "spec.yaml"),
        (["--scenes", "corridor,replay_zara1", "--methods", "orca", "--crowd", "replay"], "['corridor']"),
    ],
)
def test_cli_bad_input_exits_2_naming_the_problem(tmp_path, capsys, args, needle):
    rc = main(["benchmark", *args, "--out", str(tmp_path / "run"), "--no-progress"])
    assert rc == 2
    assert needle in capsys.readouterr().err
    assert not (tmp_path / "run" / "episodes.jsonl").exists()  # nothing started


def test_report_of_a_missing_run_exits_2(tmp_path, capsys):
    assert main(["report", str(tmp_path)]) == 2
    assert "episodes.jsonl" in capsys.readouterr().err


def test_a_diffusion_crowd_is_benchmarked_the_same_in_and_out_of_worker_processes(tmp_path):
    """``--crowd diffusion``: the shipped trajectory diffusion model plans the people; the episode (torch
    sampling included) is the same run in this process and in a worker."""
    spec = resolve_spec(scenes="corridor", methods="orca", crowd="diffusion", humans="3", episodes=1, max_steps=24,
                        save_trajectories=1)[0]
    run_benchmark(spec, tmp_path / "in_process", workers=0, progress=False)
    run_benchmark(spec, tmp_path / "worker", workers=1, progress=False)
    assert _lines(tmp_path / "in_process") == _lines(tmp_path / "worker")
    (rec,) = load_episodes(tmp_path / "worker")
    assert rec["crowd"] == "diffusion" and rec["n_humans"] == 3 and rec["steps"] == 24
    assert "people_fallen" not in rec  # kinematic people do not fall
    people = np.load(tmp_path / "worker" / "trajectories" / "orca" / "corridor" / "diffusion_n3_ep0000.npz")["human_pos"]
    walked = np.linalg.norm(people[-1] - people[0], axis=-1)
    assert (walked > 0.5).all()  # every person walked on their plan


def test_a_diffusion_crowd_without_a_model_is_refused_before_any_episode(tmp_path):
    empty = tmp_path / "no_model"
    empty.mkdir()
    spec = resolve_spec(scenes="corridor", methods="orca", crowd="diffusion", humans="3", episodes=1,
                        env={"diffusion_model": str(empty)})[0]
    with pytest.raises(ValueError, match="no_model"):
        run_benchmark(spec, tmp_path / "run", workers=0, progress=False)
    assert not (tmp_path / "run" / "episodes.jsonl").exists()


def test_physics_pedestrians_are_benchmarked_with_their_falls_counted(tmp_path):
    """``env: {human_model: amp}``: the shipped AMP controller walks the people (here on diffusion plans);
    the records count the people who fell, and a run in a worker repeats the in-process one."""
    spec = resolve_spec(scenes="corridor", methods="orca", crowd="diffusion", humans="3", episodes=1, max_steps=30,
                        save_trajectories=1, env={"human_model": "amp"})[0]
    run_benchmark(spec, tmp_path / "in_process", workers=0, progress=False)
    run_benchmark(spec, tmp_path / "worker", workers=1, progress=False)
    assert _lines(tmp_path / "in_process") == _lines(tmp_path / "worker")
    (rec,) = load_episodes(tmp_path / "worker")
    assert rec["people_fallen"] == 0 and rec["steps"] == 30  # three people walk a corridor for 3 s without falling
    people = np.load(tmp_path / "worker" / "trajectories" / "orca" / "corridor" / "diffusion_n3_ep0000.npz")["human_pos"]
    assert (np.linalg.norm(people[-1] - people[0], axis=-1) > 0.2).all()  # bodies start from rest


def test_cli_diffusion_crowd_without_a_model_exits_2(tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("NAVZOO_DIFFUSION_MODEL", str(tmp_path / "missing_model"))
    rc = main(["benchmark", "--scenes", "corridor", "--methods", "orca", "--crowd", "diffusion", "--humans", "3",
               "--out", str(tmp_path / "run"), "--no-progress"])
    assert rc == 2
    assert "missing_model" in capsys.readouterr().err
    assert not (tmp_path / "run" / "episodes.jsonl").exists()


def test_an_episode_among_physics_pedestrians_does_not_depend_on_the_episodes_before_it(tmp_path, monkeypatch):
    """A worker reuses its env from episode to episode; among physics pedestrians NavEnv.reset rebuilds the world,
    so each episode's record is the one it gets in a fresh world (until 2026-12-03 PyBullet's broadphase carried
    the pair order over a reset, and the runner dropped such envs after every episode)."""
    from navzoo.benchmark import runner

    amp = resolve_spec(scenes="corridor", methods="orca", crowd="sfm", humans="3", episodes=2, max_steps=40,
                       env={"human_model": "amp"})[0]
    run_benchmark(amp, tmp_path / "reused", workers=0, progress=False)
    runner.close_envs()
    real = runner._run_episode

    def fresh(task):  # every episode in a new env
        runner.close_envs()
        return real(task)

    monkeypatch.setattr(runner, "_run_episode", fresh)
    run_benchmark(amp, tmp_path / "fresh", workers=0, progress=False)
    strip = ("wall_s", "time", "worker", "pid")

    def records(out):
        return sorted(({k: v for k, v in r.items() if k not in strip} for r in runner.load_episodes(out)),
                      key=lambda r: r["episode"])

    reused, fresh_runs = records(tmp_path / "reused"), records(tmp_path / "fresh")
    assert len(reused) == 2 and reused == fresh_runs


def test_replay_episodes_play_a_window_of_the_recording_that_every_method_shares():
    """``--crowd replay``: level "recorded" whatever the counts; each episode another window with people in it,
    the same for every method of the episode, from the episode's seed."""
    from navzoo.agents.replay import load_recording

    spec = resolve_spec(scenes="replay_zara1,replay_eth", methods="orca,sfm", crowd="replay,sfm", humans="4",
                        episodes=6, time_limit=20.0)[0]
    tasks = build_tasks(spec, "unused")
    replay = [t for t in tasks if t.cell.crowd == "replay"]
    assert {t.cell.level for t in replay} == {"recorded"}
    assert {t.cell.level for t in tasks if t.cell.crowd == "sfm"} == {"n4"}  # counts apply to the simulated crowd
    for scene in ("replay_zara1", "replay_eth"):
        rec = load_recording(scene.removeprefix("replay_"))
        starts = {}
        for t in (t for t in replay if t.cell.scene == scene):
            assert t.env_kwargs["crowd_model"] == "replay" and t.env_kwargs["n_humans"] is None
            starts.setdefault(t.episode, set()).add(t.env_kwargs["replay_start"])
        assert all(len(v) == 1 for v in starts.values())  # both methods, one window
        windows = [v.pop() for _, v in sorted(starts.items())]
        assert len(set(windows)) > 1  # episodes differ
        for w in windows:
            assert 0 <= w <= rec.duration - 20.0
            assert np.any((rec.t0 <= w + 20.0) & (rec.t1() >= w))  # someone walks in the window
    again = build_tasks(spec, "unused")
    assert [t.env_kwargs for t in again] == [t.env_kwargs for t in tasks]


def test_replay_with_physics_bodies_is_refused_before_any_episode(tmp_path):
    spec = resolve_spec(scenes="replay_zara1", methods="orca", crowd="replay", episodes=1,
                        env={"human_model": "amp"})[0]
    with pytest.raises(ValueError, match="replay.*kinematic"):
        run_benchmark(spec, tmp_path / "run", workers=0, progress=False)
    assert not (tmp_path / "run" / "episodes.jsonl").exists()


def test_a_replay_episode_is_benchmarked_without_the_parked_peoples_jumps(tmp_path):
    """A robot among recorded people: the record names the window and its people; absent people (parked 1 km
    east) count neither in the distances nor in the trajectory file's people."""
    spec = resolve_spec(scenes="replay_zara1", methods="orca", crowd="replay", episodes=2, max_steps=60,
                        save_trajectories=2)[0]
    run_benchmark(spec, tmp_path / "run", workers=0, progress=False)
    recs = load_episodes(tmp_path / "run")
    assert len(recs) == 2
    for rec in recs:
        assert rec["crowd"] == "replay" and rec["level"] == "recorded" and rec["n_humans"] >= 1
        assert rec["people_in_window"] >= rec["n_humans"] and rec["replay_start"] >= 0
        z = np.load(tmp_path / "run" / "trajectories" / "orca" / "replay_zara1"
                    / f"replay_recorded_ep{rec['episode']:04d}.npz")
        present, people, robot = z["human_present"], z["human_pos"], z["robot_pos"]
        assert present.shape == people.shape[:2] and present.any() and not present.all()
        from navzoo.benchmark.metrics import min_person_distance

        gaps = np.linalg.norm(people - robot[:, None], axis=-1) - z["robot_radius"] - z["human_radius"]
        seen = np.where(present, gaps, np.inf).min()
        assert rec["min_distance_m"] <= seen + 1e-9  # swept gaps are at most the sampled ones
        # the record's distance is the one over present people (tests/test_metrics.py: why it matters)
        assert rec["min_distance_m"] == pytest.approx(
            min_person_distance(robot, people, float(z["robot_radius"]), z["human_radius"], present=present))
        assert np.all(np.linalg.norm(people[~present], axis=-1) > 900)  # the absent ones are the parked ones
