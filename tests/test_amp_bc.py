"""The behaviour-cloning warm start of AMP training (navzoo.agents.amp.bc)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import torch

from navzoo.agents.amp.bc import clip_waypoints, fit_actor, main, oracle_rollouts, write_run
from navzoo.agents.amp.checkpoint import latest_checkpoint, load_policy
from navzoo.agents.amp.features import policy_observation
from navzoo.agents.amp.path_env import PathTaskConfig
from navzoo.agents.amp.sim import targets_to_actions
from navzoo.agents.amp.train import grounded_locomotion_reference


@pytest.fixture(scope="module")
def ref():
    return grounded_locomotion_reference()


def test_waypoints_follow_the_clip_and_go_on_at_its_final_velocity(ref):
    clips = np.array([0, 3])
    t = np.array([0.2, 0.5])
    wp = clip_waypoints(ref, clips, t, 10, 0.5)
    assert wp.shape == (2, 10, 2)
    for i, c in enumerate(clips):
        d = ref.duration(int(c))
        for k in range(10):
            when = t[i] + 0.5 * (k + 1)
            if when <= d:
                np.testing.assert_allclose(wp[i, k], np.asarray(ref.state_at(np.array([c]), np.array([when])).root_pos)[0, :2])
        after = [k for k in range(10) if t[i] + 0.5 * (k + 1) > d]
        assert len(after) >= 2  # clips are shorter than 5 s: the path goes on after the end ...
        steps = np.diff(wp[i, after], axis=0)
        np.testing.assert_allclose(steps - steps[:1], 0.0, atol=1e-9)  # ... in a straight line at one speed


def test_oracle_rollouts_label_the_clips_own_targets(ref):
    cfg = PathTaskConfig()
    data = oracle_rollouts(ref, 6, seconds=0.3, lead=2, noise=0.055, seed=1, config=cfg)
    m = len(data["obs"])
    assert data["obs"].shape == (m, 105 + 2 * cfg.n_waypoints) and data["act"].shape == (m, 28)
    assert m > 6 * 5 and data["up_s"].shape == (6,) and (data["up_s"] > 0).all()
    assert np.isfinite(data["obs"]).all() and np.abs(data["act"]).max() <= 1.0
    # every label is the clean action of the clip's pose two control steps ahead
    c, t = data["clip"], data["time"]
    dur = np.array([ref.duration(int(x)) for x in c])
    target = ref.state_at(c, np.minimum(t + 2 / cfg.control_hz, dur))
    np.testing.assert_allclose(data["act"], np.clip(targets_to_actions(target.sph, target.rev), -1, 1), atol=1e-6)
    # the first observation of each start is the reference state's own
    first = data["time"][:6]
    obs0 = policy_observation(
        {k: v for k, v in __import__("navzoo.agents.amp.features", fromlist=["x"]).reference_state_dict(
            ref.state_at(c[:6], first)).items()},
        clip_waypoints(ref, c[:6], first, cfg.n_waypoints, cfg.waypoint_dt))
    np.testing.assert_allclose(data["obs"][:6, :13], obs0[:, :13], atol=1e-4)  # height, tilt, root velocities
    for bad in ({"starts": 0}, {"seconds": 0.0}, {"lead": 0}, {"noise": -1.0}):
        kw = {"starts": 2, "seconds": 0.1, **bad}
        with pytest.raises(ValueError, match="need starts"):
            oracle_rollouts(ref, **kw)


def test_fit_actor_learns_a_mapping_better_than_the_mean():
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(3000, 12)) * np.linspace(0.1, 10, 12)
    act = np.tanh(obs[:, :4] / np.linspace(0.1, 10, 12)[:4] @ rng.normal(size=(4, 28)) * 0.3).astype(np.float32)
    actor, norm, fit = fit_actor(obs, act, (64, 64), epochs=20, lr=3e-3, log=None)
    assert fit["val_mse"] < 0.2 * fit["val_mse_zero"]
    with torch.no_grad():
        pred = actor(norm.normalize(torch.as_tensor(obs[:5], dtype=torch.float32)).float()).numpy()
    assert np.abs(pred - act[:5]).mean() < 0.1
    with pytest.raises(ValueError, match="matching"):
        fit_actor(obs[:5], act[:5])


def test_the_run_resumes_from_the_cloned_actor(ref, tmp_path):
    from navzoo.agents.amp.learner import AmpConfig, AmpLearner
    from navzoo.agents.amp.path_env import AmpPathEnv

    cfg = PathTaskConfig()
    data = oracle_rollouts(ref, 4, seconds=0.2, seed=2, config=cfg)
    actor, norm, _ = fit_actor(data["obs"], data["act"], (32, 32), epochs=2, log=None)
    kw = {"actor_hidden": (32, 32), "critic_hidden": (32, 32), "disc_hidden": (32, 32)}
    paths = write_run(tmp_path, actor, norm, kw, cfg, ref)
    policy = load_policy(paths["policy"])
    with torch.no_grad():
        expect = actor(norm.normalize(torch.as_tensor(data["obs"][:3])).float()).numpy()
    np.testing.assert_allclose(policy(data["obs"][:3]), np.clip(expect, -1, 1), atol=1e-5)
    env = AmpPathEnv(2, ref, cfg, seed=0)  # another env count, as on the training host
    try:
        learner = AmpLearner(env, AmpConfig(**kw))
        learner.load_checkpoint(latest_checkpoint(tmp_path / "checkpoints"), any_num_envs=True)
        assert learner.iteration == 0
        for k, v in actor.state_dict().items():
            assert torch.equal(learner.actor.state_dict()[k].cpu(), v), k
    finally:
        env.close()


def test_cli_writes_a_run_and_its_summary(tmp_path, capsys):
    assert main(["--out", str(tmp_path), "--starts", "3", "--seconds", "0.2", "--epochs", "1", "--hidden", "16,16"]) == 0
    summary = json.loads((tmp_path / "bc.json").read_text())
    assert summary["samples"] > 0 and (tmp_path / "policy" / "policy.pt").exists()
    assert latest_checkpoint(tmp_path / "checkpoints") is not None
    with pytest.raises(SystemExit):
        main(["--out", str(tmp_path / "x"), "--starts", "0"])


def test_cloning_pairs_round_trip_and_bad_files_are_named(ref, tmp_path):
    from navzoo.agents.amp.bc import load_data, save_data

    data = oracle_rollouts(ref, 2, seconds=0.1, seed=3)
    back = load_data(save_data(tmp_path / "pairs.npz", data))
    for k in ("obs", "act", "clip", "time"):
        np.testing.assert_array_equal(back[k], data[k])
    with pytest.raises(FileNotFoundError, match="no behaviour-cloning data"):
        load_data(tmp_path / "missing.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ValueError, match="junk.npz"):
        load_data(tmp_path / "junk.npz")
    np.savez(tmp_path / "short.npz", obs=np.zeros((3, 4)), act=np.zeros((2, 28)))
    with pytest.raises(ValueError, match="matching rows"):
        load_data(tmp_path / "short.npz")
    np.savez(tmp_path / "nan.npz", obs=np.full((3, 4), np.nan), act=np.zeros((3, 28)))
    with pytest.raises(ValueError, match="non-finite"):
        load_data(tmp_path / "nan.npz")


def test_an_interrupted_write_of_the_pairs_leaves_no_file(ref, tmp_path, monkeypatch):
    from navzoo.agents.amp.bc import save_data

    data = oracle_rollouts(ref, 2, seconds=0.1, seed=3)

    def interrupted(f, **arrays):
        f.write(b"PK half a zip")
        raise KeyboardInterrupt

    monkeypatch.setattr(np, "savez_compressed", interrupted)
    with pytest.raises(KeyboardInterrupt):
        save_data(tmp_path / "pairs.npz", data)
    assert not (tmp_path / "pairs.npz").exists()  # a later call (the device script's BC_PAIRS) makes them again


def test_train_refuses_a_cloning_weight_without_pairs(tmp_path):
    from navzoo.agents.amp.train import TrainArgs, run

    with pytest.raises(ValueError, match="needs --bc-data"):
        run(TrainArgs(out=str(tmp_path), bc_coef=1.0))


def test_oracle_rollouts_are_the_same_for_any_number_of_workers(ref, monkeypatch):
    import navzoo.agents.amp.bc as bc

    monkeypatch.setattr(bc, "BATCH", 3)  # 7 starts -> batches of 3, 3 and 1
    one = oracle_rollouts(ref, 7, seconds=0.2, seed=4, workers=1)
    two = oracle_rollouts(ref, 7, seconds=0.2, seed=4, workers=2)
    assert one["up_s"].shape == (7,)
    for k in ("obs", "act", "clip", "time", "ahead_s", "up_s"):
        np.testing.assert_array_equal(one[k], two[k])
    other = oracle_rollouts(ref, 7, seconds=0.2, seed=5, workers=1)
    assert not np.array_equal(one["obs"], other["obs"])
    with pytest.raises(ValueError, match="workers >= 1"):
        oracle_rollouts(ref, 2, seconds=0.1, workers=0)


def test_cli_pairs_only_writes_just_the_pairs(tmp_path, capsys):
    from navzoo.agents.amp.bc import load_data, main

    with pytest.raises(SystemExit):
        main(["--pairs-only", "--starts", "2"])  # no --data-out
    assert "--pairs-only needs --data-out" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["--starts", "2"])  # neither --out nor --pairs-only
    assert "--out DIR is required" in capsys.readouterr().err
    f = tmp_path / "pairs.npz"
    assert main(["--pairs-only", "--data-out", str(f), "--starts", "3", "--seconds", "0.2", "--workers", "2"]) == 0
    data = load_data(f)
    assert data["obs"].shape[0] == data["act"].shape[0] > 3
    assert list(tmp_path.iterdir()) == [f]  # no training run written


def test_ahead_s_counts_the_seconds_the_oracle_stayed_up_and_viable_pairs_drops_the_last_ones(ref, tmp_path):
    from navzoo.agents.amp.bc import load_data, save_data, viable_pairs

    hz = PathTaskConfig().control_hz
    # one body, pushed over by heavy action noise: every pair's seconds-to-fall, down to 0 at the fall
    fell = oracle_rollouts(ref, 1, seconds=3.0, noise=0.6, seed=6)
    m = len(fell["obs"])
    assert 0 < m < 3.0 * hz and fell["up_s"][0] == pytest.approx((m - 1) / hz)
    np.testing.assert_allclose(fell["ahead_s"], (m - 1 - np.arange(m)) / hz, atol=1e-5)
    kept = viable_pairs(fell, 0.5)
    n_keep = int(np.sum((m - 1 - np.arange(m)) / hz >= 0.5 - 1e-6))
    assert len(kept["obs"]) == len(kept["act"]) == len(kept["time"]) == n_keep < m
    np.testing.assert_array_equal(kept["obs"], fell["obs"][:n_keep])  # the first pairs of the body stay
    assert len(viable_pairs(fell, 0.0)["obs"]) == m
    # a body that stays up through a short rollout: all its pairs are viable however long the margin
    short = oracle_rollouts(ref, 2, seconds=0.2, noise=0.0, seed=6)
    assert np.isinf(short["ahead_s"]).all() and len(viable_pairs(short, 10.0)["obs"]) == len(short["obs"])
    back = load_data(save_data(tmp_path / "pairs.npz", fell))
    np.testing.assert_array_equal(back["ahead_s"], fell["ahead_s"])
    with pytest.raises(ValueError, match="min_ahead_s"):
        viable_pairs(fell, -1.0)
    with pytest.raises(ValueError, match="no 'ahead_s'"):
        viable_pairs({k: v for k, v in fell.items() if k != "ahead_s"}, 0.5)


def test_cli_min_ahead_writes_fewer_pairs(tmp_path, capsys):
    from navzoo.agents.amp.bc import load_data, main

    args = ["--pairs-only", "--starts", "2", "--seconds", "2.0", "--noise", "0.6", "--seed", "6"]
    assert main([*args, "--data-out", str(tmp_path / "all.npz")]) == 0
    assert main([*args, "--data-out", str(tmp_path / "viable.npz"), "--min-ahead", "0.5"]) == 0
    assert "dropped, made less than 0.5 s before a fall" in capsys.readouterr().out
    every, viable = load_data(tmp_path / "all.npz"), load_data(tmp_path / "viable.npz")
    assert 0 < len(viable["obs"]) < len(every["obs"]) and (viable["ahead_s"] >= 0.5).all()


def test_pairs_get_clear_obstacle_rays_for_an_obstacle_aware_learner():
    from navzoo.agents.amp.bc import with_clear_rays
    from navzoo.agents.amp.features import N_RAYS, heading, obstacle_observation

    data = {"obs": np.arange(12, dtype=np.float32).reshape(3, 4), "act": np.zeros((3, 2), np.float32)}
    assert with_clear_rays(data, 4) is data
    wide = with_clear_rays(data, 4 + N_RAYS)
    assert wide["obs"].shape == (3, 4 + N_RAYS) and wide["obs"].dtype == np.float32
    np.testing.assert_array_equal(wide["obs"][:, :4], data["obs"])
    assert not wide["obs"][:, 4:].any() and wide["act"] is data["act"]
    with pytest.raises(ValueError, match="4 observation columns; the learner takes 7"):
        with_clear_rays(data, 7)
    # what an obstacle-aware policy's rays read in the oracle rollouts and clip tracking: bodies 40 m apart
    root = np.array([[0.0, 0.0], [40.0, 0.0]])
    quat = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 1.0]])
    rays = obstacle_observation(root, heading(quat), None, root, 0.3, self_disc=np.arange(2))
    assert rays.shape == (2, N_RAYS) and not rays.any()


def test_an_obstacle_aware_run_trains_on_pairs_made_without_rays(tmp_path):
    from navzoo.agents.amp.bc import save_data
    from navzoo.agents.amp.features import FEATURE_DIM
    from navzoo.agents.amp.train import TrainArgs, run

    base = FEATURE_DIM + 2 * PathTaskConfig().n_waypoints  # the pairs' width: no rays
    rng = np.random.default_rng(0)
    f = save_data(tmp_path / "pairs.npz", {"obs": rng.normal(size=(64, base)).astype(np.float32),
                                           "act": rng.uniform(-1, 1, (64, 28)).astype(np.float32),
                                           "clip": np.zeros(64, np.int64), "time": np.zeros(64)})
    out = run(TrainArgs(out=str(tmp_path / "run"), total_steps=64, workers=1, envs_per_worker=2, stage=1,
                        obstacles=1, hidden="32,32", minibatch_size=32, bc_coef=1.0, bc_data=str(f)))
    assert out["global_step"] >= 64
    assert json.loads((tmp_path / "run" / "policy" / "config.json").read_text())["obs_dim"] == base + 16
