"""RLlib PPO on navzoo: a tiny run on a local multi-process Ray instance updates both policies; resume;
SIGINT saves; a frozen side loads a trained policy; a head + worker node cluster on loopback."""

from __future__ import annotations

import argparse
import json
import os
import queue
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ray.rllib")

from navzoo.rl.config import JointConfig  # noqa: E402
from navzoo.rl.train import add_arguments, build_config, init_ray, joint_config_from_args, run  # noqa: E402

# Five-second episodes (20 steps at dt 0.25 s) with 2 pedestrians, 200 env steps per iteration, a small net.
TINY = ["--n-humans", "2", "--set", "time_limit=5", "--batch-size", "200", "--minibatch-size", "100",
        "--epochs", "1", "--hidden", "32,32"]
REPO = Path(__file__).resolve().parents[2]


def _args(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    add_arguments(parser)
    return parser.parse_args(list(argv))


def _env() -> dict[str, str]:
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", PYTHONPATH=str(REPO))
    for var in ("RAY_ADDRESS", "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER", "RAY_AUTH_MODE", "RAY_AUTH_TOKEN"):
        env.pop(var, None)
    return env


@pytest.fixture
def local_ray():
    import ray

    init_ray(None, num_cpus=3, env_runners=2)
    yield ray
    ray.shutdown()


def test_tiny_run_updates_both_policies_then_resumes(tmp_path, local_ray):
    out = tmp_path / "run"
    args = _args(*TINY, "--env-runners", "2", "--iterations", "2", "--out", str(out))
    cfg = joint_config_from_args(args)
    lines = []
    summary = run(cfg, args, emit=lines.append)

    cluster = lines[0]["cluster"]
    assert lines[0]["policies"] == ["robot", "human"]
    pids = {r["pid"] for r in cluster["env_runners"]}
    assert len(cluster["env_runners"]) == 2 and len(pids) == 2 and os.getpid() not in pids  # separate processes
    assert cluster["node_ips"] == ["127.0.0.1"]  # the local instance stays on loopback

    iters = lines[1:]
    assert [d["iteration"] for d in iters] == [1, 2]
    for d in iters:
        assert d["env_steps_sampled"] >= 200 and d["env_steps_per_s"] > 0
        assert d["agent_steps_sampled"]["robot"] > 0 and d["agent_steps_sampled"]["human"] > 0
        for pid in ("robot", "human"):
            assert d["learner"][pid]["weights_delta_l2"] > 0  # both policies were updated
            assert np.isfinite(d["learner"][pid]["policy_loss"])
            assert d["reward_mean"][pid] is not None
    assert iters[1]["env_steps_sampled_lifetime"] >= 400
    assert summary["iterations"] == 2 and not summary["interrupted"]
    assert (out / "latest_checkpoint.txt").read_text().strip() == "checkpoints/iter_000002"
    assert len((out / "metrics.jsonl").read_text().splitlines()) == 2

    # The same --out resumes from the latest checkpoint and runs to --iterations in total.
    args = _args(*TINY, "--env-runners", "1", "--iterations", "3", "--out", str(out))
    lines = []
    summary = run(cfg, args, emit=lines.append)
    assert summary["resumed_from"] == 2 and [d["iteration"] for d in lines[1:]] == [3]
    assert lines[1]["env_steps_sampled_lifetime"] > iters[1]["env_steps_sampled_lifetime"]
    assert sorted(p.name for p in (out / "checkpoints").iterdir()) == ["iter_000002", "iter_000003"]

    # Another config in the same folder is refused.
    with pytest.raises(ValueError, match="another joint config"):
        run(joint_config_from_args(_args(*TINY, "--humans", "crowd", "--out", str(out))), args, emit=lines.append)

    # A trained side can be frozen in a later run: pedestrians on the trained "human" module.
    from navzoo.rl.rllib_env import NavzooMultiAgentEnv

    env = NavzooMultiAgentEnv({"n_humans": 2, "humans": "frozen", "human_policy": f"rllib:{out}"})
    assert env.possible_agents == ["robot_0"]
    obs, _ = env.reset(seed=0)
    nav = env.unwrapped_nav
    start = nav.pos[1:].copy()
    for _ in range(5):
        obs, *_ = env.step({"robot_0": np.zeros(2, np.float32)})
    assert np.abs(nav.pos[1:] - start).max() > 0  # the frozen pedestrians move under the trained policy

    # Both trained sides evaluated together, in this process.
    from navzoo.rl.evaluate import evaluate

    res = evaluate(JointConfig(robots="frozen", robot_policy=f"rllib:{out}", humans="frozen",
                               human_policy=f"rllib:{out}", n_humans=2, env={"time_limit": 5}), episodes=2)
    assert res["mean"]["episode_s"] <= 5.0 and res["mean"]["human_speed_mps"] > 0

    # The trained pedestrians as a crowd of `navzoo benchmark` (Dict observations for the robot's method,
    # flattened ones for the pedestrians), next to a rule-based crowd on the same seeded episode.
    import json

    from navzoo.benchmark.runner import BenchmarkSpec, run_benchmark

    spec = BenchmarkSpec(scenes=("circle_crossing",), methods=("dwa",), crowds=("sfm", f"rllib:{out}"),
                         humans=(2,), episodes=1, time_limit=4.0, save_trajectories=1)
    summary = run_benchmark(spec, tmp_path / "bench", workers=0, progress=False)
    assert summary["status"] == "complete" and not summary["errors"]
    recs = [json.loads(line) for line in (tmp_path / "bench" / "episodes.jsonl").read_text().splitlines()]
    assert sorted(r["crowd"] for r in recs) == sorted(["sfm", f"rllib:{out}"])
    learned = next(r for r in recs if r["crowd"].startswith("rllib:"))
    from navzoo.benchmark.runner import artifact_path

    traj = np.load(tmp_path / "bench" / "trajectories" / artifact_path(learned, ".npz"))
    assert np.abs(np.diff(traj["human_pos"], axis=0)).max() > 0  # the learned pedestrians walk
    with pytest.raises(ValueError, match="crowd 'rllib:"):
        from navzoo.benchmark.runner import validate_spec

        validate_spec(BenchmarkSpec(scenes=("circle_crossing",), methods=("dwa",), crowds=(f"rllib:{tmp_path}/none",)))

    # A robot trained (SB3, navzoo train robot) against the learned crowd, frozen in every env copy, in worker
    # processes; the exported policy records its crowd.
    from navzoo.agents.robot_train import add_arguments as robot_arguments
    from navzoo.agents.robot_train import run_cli as train_robot

    rargs = robot_arguments(argparse.ArgumentParser()).parse_args([
        "--out", str(tmp_path / "robot"), "--scenes", "navzoo/CircleCrossing-v0", "--crowd-policy", f"rllib:{out}",
        "--set", "n_humans=2", "--set", "humans_see_robots=true", "--n-envs", "2", "--num-cpus", "2",
        "--total-steps", "64", "--features-dim", "16", "--heads", "2", "--blocks", "1", "--net-arch", "16",
        "--threads", "1", "--n-epochs", "1"])
    assert train_robot(rargs) == 0
    rcfg = json.loads((tmp_path / "robot" / "policy" / "config.json").read_text())
    assert rcfg["training"]["crowd_policy"] == f"rllib:{out}"
    assert rcfg["training"]["env_overrides"] == {"n_humans": 2, "humans_see_robots": True}


def test_a_learner_actor_updates_both_policies(tmp_path):
    # --num-learners 1: the PPO update runs in a learner actor (a Ray process), not in the driver.
    out = tmp_path / "run"
    init_ray(None, num_cpus=3, env_runners=1, learners=1)
    try:
        args = _args(*TINY, "--env-runners", "1", "--num-learners", "1", "--iterations", "1", "--out", str(out))
        cfg = joint_config_from_args(args)
        assert build_config(cfg, args).num_learners == 1
        lines = []
        summary = run(cfg, args, emit=lines.append)
    finally:
        import ray

        ray.shutdown()
    assert summary["iterations"] == 1
    for pid in ("robot", "human"):
        assert lines[1]["learner"][pid]["weights_delta_l2"] > 0
        assert np.isfinite(lines[1]["learner"][pid]["policy_loss"])


def test_sigint_saves_and_exits(tmp_path):
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "navzoo.rl.train", *TINY, "--env-runners", "1", "--iterations", "1000",
           "--checkpoint-every", "1000", "--out", str(out), "--num-cpus", "2"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=_env(),
                            cwd=tmp_path)
    # Generous limits: Ray's start and shutdown take minutes on a busy 2-core machine. The lines are read on a thread
    # so that a trainer that hangs without printing fails the test at the deadline instead of blocking it.
    lines: queue.Queue = queue.Queue()

    def read() -> None:
        for x in proc.stdout:
            lines.put(x)
        lines.put(None)

    threading.Thread(target=read, daemon=True).start()
    try:
        deadline = time.time() + 300
        after: list[str] = []
        while True:
            try:
                line = lines.get(timeout=max(deadline - time.time(), 0.01))
            except queue.Empty:
                raise AssertionError("no iteration within 300 s") from None
            assert line is not None, "the trainer exited before its first iteration"
            if line.startswith("{") and "iteration" in json.loads(line):
                proc.send_signal(signal.SIGINT)
                break
        proc.wait(timeout=240)
        while (line := lines.get(timeout=30)) is not None:
            after.append(line)
        rest = "".join(after)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130
    done = [json.loads(x) for x in rest.splitlines() if x.startswith('{"done"')][0]["done"]
    assert done["interrupted"] and 1 <= done["iterations"] < 1000
    assert Path(done["checkpoint"]).is_dir() and (out / "latest_checkpoint.txt").is_file()


def _netns_pids(inode: str) -> list[int]:
    pids = []
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                if os.readlink(d / "ns" / "net") == inode:
                    pids.append(int(d.name))
            except OSError:
                pass
    return pids


@pytest.mark.slow
def test_head_and_worker_node_on_loopback(tmp_path):
    """The multi-node recipe of docs/scaling.md on one machine, in a private network namespace (only
    loopback exists there): a head node without CPUs, a worker node with 2, the trainer joins with --address."""
    if shutil.which("unshare") is None:
        pytest.skip("needs unshare (util-linux) for a private network namespace")
    probe = subprocess.run(["unshare", "-n", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip(f"cannot create a network namespace here: {probe.stderr.decode().strip()}")
    bindir = Path(sys.executable).parent
    ray_cli = bindir / "ray"
    short = Path(tempfile.mkdtemp(prefix="nzray", dir="/tmp"))  # Ray's unix socket paths must stay < 108 bytes
    script = f"""
set -e
ip link set lo up 2>/dev/null || true
readlink /proc/self/ns/net > {tmp_path}/netns
export RAY_USAGE_STATS_ENABLED=0 PATH={bindir}:$PATH
{ray_cli} start --head --node-ip-address 127.0.0.1 --port 6390 --num-cpus 0 --temp-dir {short}/h --disable-usage-stats > {tmp_path}/head.log 2>&1
{ray_cli} start --address 127.0.0.1:6390 --node-ip-address 127.0.0.1 --num-cpus 2 --temp-dir {short}/w > {tmp_path}/worker.log 2>&1
{sys.executable} -m navzoo.rl.train --address 127.0.0.1:6390 {' '.join(TINY)} --env-runners 2 --iterations 1 --out {tmp_path}/run
"""
    # Token authentication, as a real cluster: every node and the driver hold the same token.
    env = dict(_env(), RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32))
    proc = subprocess.Popen(["unshare", "-n", "bash", "-c", script], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=env, cwd=tmp_path)
    inode = None
    try:
        out, err = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            proc.kill()
        if (tmp_path / "netns").is_file():
            inode = (tmp_path / "netns").read_text().strip()
            # Everything in the private namespace is ours (both nodes' daemons and workers): end it by pid.
            for _ in range(3):
                pids = [p for p in _netns_pids(inode) if p != os.getpid()]
                if not pids:
                    break
                for p in pids:
                    try:
                        os.kill(p, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
                time.sleep(1)
        shutil.rmtree(short, ignore_errors=True)
    logs = "".join((tmp_path / f).read_text() for f in ("head.log", "worker.log") if (tmp_path / f).is_file())
    assert proc.returncode == 0, f"{out[-3000:]}\n{err[-3000:]}\n{logs[-3000:]}"
    lines = [json.loads(x) for x in out.splitlines() if x.startswith("{")]
    cluster = lines[0]["cluster"]
    assert cluster["nodes"] == 2 and cluster["cluster_cpus"] == 2 and cluster["node_ips"] == ["127.0.0.1"]
    # The head has no CPUs: both env runners run on the worker node, apart from the driver.
    assert len(cluster["env_runners"]) == 2 and cluster["env_runners_on_other_nodes"] == 2
    it = lines[1]
    assert it["iteration"] == 1 and it["env_steps_sampled"] >= 200
    assert all(it["learner"][p]["weights_delta_l2"] > 0 for p in ("robot", "human"))
    assert inode is not None and not _netns_pids(inode)
