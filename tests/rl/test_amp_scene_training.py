"""AMP pedestrians trained over worker processes and scenes (``SubprocNavAmpVecEnv``, ``amp_joint train
--workers --scenes``): the wrapper is transparent, the scenes and options are checked, training runs,
snapshots its policy and refuses to resume with other workers."""

from __future__ import annotations

import json

import numpy as np
import pytest

from navzoo.agents.amp.checkpoint import load_policy
from navzoo.agents.amp.pedestrian_policy import default_policy_dir
from navzoo.rl.amp_joint import AmpJointArgs, NavAmpVecEnv, SubprocNavAmpVecEnv, stats_from_counters, train


def test_each_worker_runs_its_scene_exactly_as_one_process_would():
    act = load_policy(default_policy_dir())
    scenes = ["apartment", "campus_plaza"]
    vec = SubprocNavAmpVecEnv("navzoo/Lobby-v0", 1, 2, 0, seed=5, workers=2, scenes=scenes)
    solo = [NavAmpVecEnv("navzoo/Lobby-v0", 1, 2, 0, seed=5 + 1009 * w, env_overrides={"scene": sc})
            for w, sc in enumerate(scenes)]
    try:
        assert (vec.num_envs, vec.obs_dim, vec.amp_obs_dim) == (4, solo[0].obs_dim, solo[0].amp_obs_dim)
        assert vec.amp_obs_version == solo[0].amp_obs_version
        obs = vec.reset(seed=11)
        ref = [s.reset(seed=11 + w) for w, s in enumerate(solo)]
        np.testing.assert_array_equal(obs, np.concatenate(ref))
        for _ in range(6):
            a = np.clip(act(obs), -1.0, 1.0)
            obs, rew, term, trunc, info = vec.step(a)
            parts = [s.step(a[2 * w:2 * w + 2]) for w, s in enumerate(solo)]
            np.testing.assert_array_equal(obs, np.concatenate([p[0] for p in parts]))
            np.testing.assert_array_equal(rew, np.concatenate([p[1] for p in parts]))
            np.testing.assert_array_equal(info["amp_obs"], np.concatenate([p[4]["amp_obs"] for p in parts]))
        stats = vec.stats()
        assert stats["pedestrian_steps"] == 24
        assert stats == stats_from_counters([s.counters() for s in solo], solo[0].dt)
        assert vec.sample_reference_amp_obs(5, np.random.default_rng(0)).shape == (5, vec.amp_obs_dim)
        vec.reset_stats()
        assert vec.stats()["pedestrian_steps"] == 0
    finally:
        vec.close()
        for s in solo:
            s.close()


def test_counters_add_up_to_the_rates():
    a = {"pedestrian_steps": 30, "falls": 1, "agent_contact_steps": 3, "robot_contact_steps": 0,
         "map_contact_steps": 6, "path_error_sum": 3.0, "stance_sum": 6.0, "robot_episodes": 0, "robot_goals": 0, "robot_collisions": 0}
    b = {**a, "pedestrian_steps": 90, "falls": 0, "map_contact_steps": 0, "path_error_sum": 9.0, "stance_sum": 30.0}
    s = stats_from_counters([a, b], 1.0 / 30.0)
    assert s["pedestrian_steps"] == 120 and s["falls_per_pedestrian_minute"] == pytest.approx(1 / (120 / 30 / 60))
    assert s["map_contact_share"] == pytest.approx(6 / 120) and s["path_error_m"] == pytest.approx(0.1)
    assert s["stance_split_m"] == pytest.approx(36 / 120)


def test_bad_scenes_and_options_are_rejected(tmp_path):
    with pytest.raises(ValueError, match="unknown scene.*no_such_scene"):
        SubprocNavAmpVecEnv("navzoo/Lobby-v0", 1, 1, 0, workers=2, scenes=["apartment", "no_such_scene"])
    with pytest.raises(ValueError, match="workers must be"):
        SubprocNavAmpVecEnv("navzoo/Lobby-v0", 1, 1, 0, workers=0)
    with pytest.raises(ValueError, match="not both"):
        SubprocNavAmpVecEnv("navzoo/Lobby-v0", 1, 1, 0, env_overrides={"scene": "cafe"}, scenes=["apartment"])
    with pytest.raises(ValueError, match="learning robots need one process"):
        train(AmpJointArgs(out=str(tmp_path / "r"), workers=2, robot_learn={}))
    with pytest.raises(ValueError, match="unknown scene"):
        train(AmpJointArgs(out=str(tmp_path / "r"), scenes=["nowhere"]))


def test_training_over_workers_and_scenes_snapshots_and_resumes_only_as_itself(tmp_path):
    args = AmpJointArgs(out=str(tmp_path / "run"), n_envs=1, n_humans=1, n_robots=0, workers=2,
                        scenes=["apartment", "two_doors"], steps=64, minibatch_size=16, ckpt_every=1,
                        snapshot_every=1, keep_checkpoints=10)
    first = train(args)
    start = first["start_global_step"]
    assert first["global_step"] == start + 64 and first["train_stats"]["pedestrian_steps"] == 64
    snaps = sorted(p.name for p in (tmp_path / "run" / "snapshots").iterdir())
    assert len(snaps) == 3 and all((tmp_path / "run" / "snapshots" / s / "config.json").is_file() for s in snaps)
    assert json.loads((tmp_path / "run" / "amp_joint_args.json").read_text())["scenes"] == ["apartment", "two_doors"]
    with pytest.raises(ValueError, match="holds a run with other"):
        train(AmpJointArgs(**{**args.__dict__, "workers": 3}))


def test_the_start_policy_is_the_anchor_of_a_scene_fine_tune(tmp_path):
    import torch

    from navzoo.agents.amp.checkpoint import latest_checkpoint, load_checkpoint

    args = AmpJointArgs(out=str(tmp_path / "run"), n_envs=1, n_humans=1, n_robots=0, workers=2,
                        scenes=["apartment", "two_doors"], steps=32, minibatch_size=16, ckpt_every=1,
                        anchor_coef=0.5)
    train(args)
    tensors, meta = load_checkpoint(latest_checkpoint(tmp_path / "run" / "checkpoints"))
    assert meta["config"]["anchor_coef"] == 0.5
    shipped = torch.load(default_policy_dir() / "policy.pt", weights_only=True)
    for part in ("actor", "obs_norm"):
        for k, v in tensors["anchor"][part].items():
            if k != "log_std":  # the exploration std is the learner's hyper-parameter
                assert torch.equal(v, shipped[f"{part}.{k}"]), (part, k)
    rows = [json.loads(line) for line in (tmp_path / "run" / "metrics.jsonl").read_text().splitlines()]
    assert all(row["anchor/kl"] >= 0 for row in rows if "anchor/kl" in row) and any("anchor/kl" in r for r in rows)


def test_a_worker_that_cannot_build_its_env_is_reported_with_its_traceback():
    with pytest.raises(RuntimeError, match=r"(?s)AMP worker 0 failed during 'start'.*NoSuchScenario"):
        SubprocNavAmpVecEnv("navzoo/NoSuchScenario-v0", 1, 1, 0, workers=2)
