"""The AMP + PPO learner on physics-free envs: pure parts, learning on the toy, checkpoints, robustness."""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from navzoo.agents.amp.checkpoint import CheckpointError, latest_checkpoint, load_checkpoint
from navzoo.agents.amp.learner import AmpConfig, AmpLearner, AmpVecEnv, compute_gae, load_policy
from navzoo.agents.amp.networks import Discriminator, gradient_penalty, style_reward
from navzoo.agents.amp.normalizer import RunningMeanStd, merge_moments
from navzoo.agents.amp.replay import ReplayBuffer
from navzoo.agents.amp.toy import CirclingPointMass, RandomAmpVecEnv, ToyConfig, evaluate, toy_amp_config

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(autouse=True)
def _one_thread():
    # One thread: faster for these small nets and far less sensitive to a busy machine.
    n = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(n)


def _small(**kw) -> AmpConfig:
    base = dict(
        rollout_steps=8,
        actor_hidden=(32, 32),
        critic_hidden=(32, 32),
        disc_hidden=(32, 32),
        minibatch_size=64,
        disc_minibatch_size=32,
        epochs=2,
        replay_size=1000,
        ckpt_replay_rows=1000,
    )
    base.update(kw)
    return toy_amp_config(**base)


def _toy(n: int = 16, **kw) -> CirclingPointMass:
    return CirclingPointMass(ToyConfig(num_envs=n, **kw))


# --------------------------------------------------------------------------- pure parts


def test_gae_hand_computed() -> None:
    # gamma 0.9, lambda 0.5 -> gamma * lambda = 0.45.
    # env 0, no episode end: deltas 1 + .9*1 - .5 = 1.4, 2 + .9*1.5 - 1 = 2.35, 3 + .9*2 - 1.5 = 3.3;
    #   A2 = 3.3, A1 = 2.35 + .45*3.3 = 3.835, A0 = 1.4 + .45*3.835 = 3.12575.
    # env 1: terminated at t0 (no bootstrap), truncated at t1 (bootstrap from V(final_obs) = 5),
    #   deltas 1 - 1 = 0, 1 + .9*5 - 1 = 4.5, 1 + .9*1 - 1 = 0.9; the recursion stops at both ends.
    rewards = torch.tensor([[1.0, 1.0], [2.0, 1.0], [3.0, 1.0]])
    values = torch.tensor([[0.5, 1.0], [1.0, 1.0], [1.5, 1.0]])
    next_values = torch.tensor([[1.0, 123.0], [1.5, 5.0], [2.0, 1.0]])  # 123: ignored (terminated)
    terminated = torch.tensor([[0, 1], [0, 0], [0, 0]])
    dones = torch.tensor([[0, 1], [0, 1], [0, 0]])
    adv, ret = compute_gae(rewards, values, next_values, terminated, dones, gamma=0.9, lam=0.5)
    expected = torch.tensor([[3.12575, 0.0], [3.835, 4.5], [3.3, 0.9]])
    torch.testing.assert_close(adv, expected)
    torch.testing.assert_close(ret, expected + values)


def test_gae_lambda_one_is_discounted_return() -> None:
    r = torch.rand(6, 3)
    v = torch.rand(6, 3)
    nv = torch.cat([v[1:], torch.zeros(1, 3)])
    z = torch.zeros(6, 3)
    _, ret = compute_gae(r, v, nv, z, z, gamma=0.8, lam=1.0)
    disc = torch.stack([sum(0.8**k * r[t + k] for k in range(6 - t)) for t in range(6)])
    torch.testing.assert_close(ret, disc)


def test_normalizer_matches_numpy_over_batches() -> None:
    rng = np.random.default_rng(0)
    batches = [rng.normal(3.0, 2.0, (n, 5)) for n in (1, 7, 100, 33)]
    norm = RunningMeanStd(5)
    for b in batches:
        norm.update(b)
    full = np.concatenate(batches)
    np.testing.assert_allclose(norm.mean.numpy(), full.mean(0), rtol=1e-12)
    np.testing.assert_allclose(norm.var.numpy(), full.var(0), rtol=1e-10)
    assert float(norm.count) == len(full)
    x = torch.as_tensor(full[:4])
    expected = np.clip((full[:4] - full.mean(0)) / np.sqrt(full.var(0) + norm.eps), -5, 5)
    np.testing.assert_allclose(norm.normalize(x).numpy(), expected, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(norm.denormalize(norm.normalize(x)).numpy(), full[:4], rtol=1e-5, atol=1e-5)


def test_merge_moments_of_two_halves_equals_whole() -> None:
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(10, 3)), rng.normal(5, 3, size=(25, 3))
    mean, var, count = merge_moments(
        torch.tensor(a.mean(0)),
        torch.tensor(a.var(0)),
        10,
        torch.tensor(b.mean(0)),
        torch.tensor(b.var(0)),
        25,
    )
    whole = np.concatenate([a, b])
    np.testing.assert_allclose(mean.numpy(), whole.mean(0), rtol=1e-12)
    np.testing.assert_allclose(var.numpy(), whole.var(0), rtol=1e-12)
    assert count == 35
    # an empty side changes nothing
    m2, v2, c2 = merge_moments(torch.zeros(3), torch.ones(3), 0, mean, var, 35)
    torch.testing.assert_close(m2, mean)
    torch.testing.assert_close(v2, var)


def test_normalizer_constant_feature_and_bad_input() -> None:
    norm = RunningMeanStd(2)
    norm.update(np.array([[1.0, 4.0], [1.0, 6.0]]))
    out = norm.normalize(torch.tensor([[1.0, 5.0]]))
    assert torch.isfinite(out).all() and out[0, 0] == 0.0
    with pytest.raises(ValueError, match="non-finite"):
        norm.update(np.array([[np.nan, 1.0]]))


def test_gradient_penalty_zero_for_constant_discriminator_and_exact_for_linear() -> None:
    disc = Discriminator(4, [8, 8])
    with torch.no_grad():
        disc.logits.weight.zero_()
        disc.logits.bias.fill_(0.7)
    x = torch.randn(16, 4, requires_grad=True)
    assert gradient_penalty(disc(x), x).item() == 0.0
    x2 = torch.randn(16, 4, requires_grad=True)
    assert float(gradient_penalty(torch.full((16,), 0.3), x2)) == 0.0  # output independent of input
    w = torch.tensor([1.0, -2.0, 0.5, 3.0])
    x3 = torch.randn(16, 4, requires_grad=True)
    gp = gradient_penalty(x3 @ w + 1.0, x3)
    assert math.isclose(float(gp), float(w.square().sum()), rel_tol=1e-6)


def test_style_reward_is_the_bce_form_and_bounded() -> None:
    logits = torch.tensor([-50.0, -2.0, 0.0, 1.5, 9.0, 50.0, 1e4])
    expected = -torch.log(torch.clamp(1 - torch.sigmoid(logits.double()), min=1e-4))
    torch.testing.assert_close(style_reward(logits).double(), expected, rtol=1e-5, atol=1e-6)
    assert torch.isfinite(style_reward(logits)).all()


def test_replay_buffer_fifo_sampling_and_state() -> None:
    buf = ReplayBuffer(5, 2)
    rows = np.arange(16, dtype=np.float32).reshape(8, 2)
    buf.push(rows[:3])
    np.testing.assert_array_equal(buf.chronological().numpy(), rows[:3])
    buf.push(rows[3:8])  # wraps: the oldest three are overwritten
    assert len(buf) == 5
    np.testing.assert_array_equal(buf.chronological().numpy(), rows[3:8])
    buf.push(np.arange(40, dtype=np.float32).reshape(20, 2))  # more than the capacity at once
    np.testing.assert_array_equal(
        buf.chronological().numpy(), np.arange(30, 40, dtype=np.float32).reshape(5, 2)
    )
    bad = np.array([[np.nan, 1.0], [np.inf, 0.0], [7.0, 7.0]], dtype=np.float32)
    assert buf.push(bad) == 1  # non-finite rows never enter
    s = buf.sample(1000, np.random.default_rng(0))
    assert s.shape == (1000, 2) and torch.isfinite(s).all()
    assert set(map(tuple, s.numpy().tolist())) <= set(map(tuple, buf.chronological().numpy().tolist()))
    copy = ReplayBuffer(5, 2)
    copy.load_state_dict(buf.state_dict())
    torch.testing.assert_close(
        copy.sample(50, np.random.default_rng(3)), buf.sample(50, np.random.default_rng(3))
    )
    with pytest.raises(RuntimeError, match="empty"):
        ReplayBuffer(3, 2).sample(1, np.random.default_rng(0))
    part = buf.state_dict(max_rows=2)
    assert part["data"].shape == (2, 2)
    keep = ReplayBuffer(100, 1, keep_prob=0.1)
    keep.push(np.zeros((100, 1)))
    assert keep.push(np.ones((1000, 1)), np.random.default_rng(0)) < 200  # ~10% kept once full


def test_config_validation_names_the_field() -> None:
    with pytest.raises(ValueError, match="gamma"):
        AmpConfig(gamma=1.5)
    with pytest.raises(ValueError, match="actor_hidden"):
        AmpConfig(actor_hidden=())
    with pytest.raises(ValueError, match="disc_lr"):
        AmpConfig(disc_lr=float("nan"))
    with pytest.raises(ValueError, match="minibatchsize.*valid keys"):
        AmpConfig.from_dict({"minibatchsize": 3})
    cfg = AmpConfig.from_dict(json.loads(json.dumps(AmpConfig().to_dict())))
    assert cfg == AmpConfig()


def test_envs_satisfy_the_protocol_and_bad_env_output_is_named() -> None:
    assert isinstance(_toy(), AmpVecEnv) and isinstance(RandomAmpVecEnv(4), AmpVecEnv)

    class NanReward(CirclingPointMass):
        def step(self, actions):
            obs, r, te, tr, info = super().step(actions)
            r[3] = np.nan
            return obs, r, te, tr, info

    learner = AmpLearner(NanReward(ToyConfig(num_envs=8)), _small())
    with pytest.raises(ValueError, match=r"non-finite task_reward for env indices \[3\]"):
        learner.collect(2)


# --------------------------------------------------------------------------- learning on the toy


def test_truncated_episodes_keep_their_final_observation() -> None:
    env = _toy(8, episode_steps=5)
    learner = AmpLearner(env, _small())
    learner.collect(8)
    ro = learner._rollout
    assert ro is not None and [t for t, _, _ in ro.finals] == [4]  # steps 5 of all envs, t index 4
    t, idx, final = ro.finals[0]
    assert idx.tolist() == list(range(8))
    # the final observation is the pre-reset one, continuous with the stored previous observation
    prev = ro.obs[t].numpy()
    assert np.abs(final.numpy()[:, 2:4] - prev[:, 2:4]).max() < 0.5  # velocity changed by <= a dt step
    assert ro.dones[t].all() and not ro.terminated[t].any()
    learner.update()


def test_discriminator_separates_random_policy_from_reference_early() -> None:
    env = _toy(64)
    learner = AmpLearner(env, toy_amp_config(actor_lr=1e-9))  # policy frozen: the disc's job only
    probe = _toy(64)
    random_amp = evaluate(probe, lambda o: learner.act(o, deterministic=False), 40)["amp_obs"]
    ref = env.sample_reference_amp_obs(len(random_amp), np.random.default_rng(5))
    for _ in range(5):
        learner.collect(learner.cfg.rollout_steps)
        stats = learner.update()
    with torch.no_grad():
        lp = learner.disc(learner.amp_norm.normalize(torch.as_tensor(random_amp)))
        lr = learner.disc(learner.amp_norm.normalize(torch.as_tensor(ref)))
    acc = 0.5 * (float((lp < 0).float().mean()) + float((lr > 0).float().mean()))
    assert acc > 0.8, (acc, stats)
    assert learner.style_rewards(ref).mean() > learner.style_rewards(random_amp).mean() + 0.2


def test_short_training_improves_style_and_task_over_random_policies() -> None:
    env = _toy(64)
    learner = AmpLearner(env, toy_amp_config(seed=0))
    probe = _toy(64)
    rng = np.random.default_rng(0)
    uniform = evaluate(probe, lambda o: rng.uniform(-1, 1, (len(o), 2)), 150)
    initial = evaluate(probe, lambda o: learner.act(o, deterministic=False), 150)
    for _ in range(100):  # ~200k env steps, ~20 s on one busy core
        learner.collect(learner.cfg.rollout_steps)
        learner.update()
    trained = evaluate(probe, lambda o: learner.act(o, deterministic=True), 150)
    style = {
        k: float(learner.style_rewards(v["amp_obs"]).mean())
        for k, v in (("uniform", uniform), ("initial", initial), ("trained", trained))
    }
    summary = {
        k: (v["task_reward"], v["style_error"])
        for k, v in (("uniform", uniform), ("initial", initial), ("trained", trained))
    }
    for base in ("uniform", "initial"):
        assert style["trained"] > style[base] + 0.05, (style, summary)
        assert trained["task_reward"] > summary[base][0] + 0.2, summary
        assert trained["style_error"] < 0.7 * summary[base][1], summary  # ground truth: speed near 1 m/s


# --------------------------------------------------------------------------- checkpoints


_RESUME_CFG = dict(
    seed=3,
    rollout_steps=8,
    actor_hidden=[32, 32],
    critic_hidden=[32, 32],
    disc_hidden=[32, 32],
    minibatch_size=64,
    disc_minibatch_size=32,
    epochs=2,
    replay_size=256,
    ckpt_replay_rows=256,
)


def _resume_learner() -> AmpLearner:
    return AmpLearner(_toy(16, episode_steps=12), toy_amp_config(**_RESUME_CFG))


def _rows(log_dir: Path) -> dict[int, dict]:
    rows = [json.loads(line) for line in (log_dir / "metrics.jsonl").read_text().splitlines()]
    return {
        r["iteration"]: {k: v for k, v in r.items() if not k.startswith("perf/") and k != "wall_s"}
        for r in rows
    }


def test_resume_is_bit_identical_in_a_new_process(tmp_path: Path) -> None:
    per_it = 8 * 16
    # Uninterrupted: 4 iterations (the replay buffer wraps, episodes truncate, Adam has history).
    ref = _resume_learner()
    ref.train(4 * per_it, log_dir=tmp_path / "a")
    # Interrupted: 3 iterations and a checkpoint, then a fresh process resumes for the 4th.
    first = _resume_learner()
    first.train(3 * per_it, log_dir=tmp_path / "b", ckpt_dir=tmp_path / "ckpt", ckpt_every=2)
    assert sorted(p.name for p in (tmp_path / "ckpt").iterdir()) == [
        "ckpt_00000002",
        "ckpt_00000003",
        "latest.json",
    ]
    script = (
        "import json, sys, torch; torch.set_num_threads(1)\n"
        "from navzoo.agents.amp.learner import AmpLearner\n"
        "from navzoo.agents.amp.toy import CirclingPointMass, ToyConfig, toy_amp_config\n"
        f"learner = AmpLearner(CirclingPointMass(ToyConfig(num_envs=16, episode_steps=12)), "
        f"toy_amp_config(**json.loads({json.dumps(json.dumps(_RESUME_CFG))})))\n"
        f"out = learner.train({4 * per_it}, log_dir=sys.argv[1], ckpt_dir=sys.argv[2])\n"
        "learner.export_policy(sys.argv[3])\n"
        "print(json.dumps(out))\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "b"), str(tmp_path / "ckpt"), str(tmp_path / "policy")],
        capture_output=True,
        text=True,
        cwd=REPO,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout.strip().splitlines()[-1])
    assert out["resumed_from"].endswith("ckpt_00000003") and out["iteration"] == 4
    a, b = _rows(tmp_path / "a"), _rows(tmp_path / "b")
    assert sorted(b) == [1, 2, 3, 4]  # the resumed run appended to the same jsonl
    assert a[4] == b[4]  # every loss, reward and accuracy of the resumed update, bit for bit
    assert a[4]["losses/disc"] is not None and a[4]["replay/size"] == 256
    resumed_policy = load_policy(tmp_path / "policy")
    obs = np.random.default_rng(0).normal(size=(32, 6)).astype(np.float32)
    np.testing.assert_array_equal(resumed_policy(obs), ref.act(obs))


def test_checkpoint_roundtrip_in_process_restores_everything(tmp_path: Path) -> None:
    a = _resume_learner()
    a.train(2 * 128, ckpt_dir=tmp_path)
    b = _resume_learner()
    b.load_checkpoint(latest_checkpoint(tmp_path))
    for net in ("actor", "critic", "disc", "obs_norm", "amp_norm", "value_norm"):
        for (k, va), vb in zip(
            getattr(a, net).state_dict().items(), getattr(b, net).state_dict().values(), strict=True
        ):
            assert torch.equal(va, vb), (net, k)
    assert (a.iteration, a.global_step) == (b.iteration, b.global_step) == (2, 256)
    assert a.rng.random() == b.rng.random()
    assert torch.equal(torch.randn(3, generator=a.torch_gen), torch.randn(3, generator=b.torch_gen))
    sa, sb = a.collect(8), b.collect(8)
    assert sa == sb and torch.equal(a._rollout.obs, b._rollout.obs)


def test_a_resumed_fixed_action_std_takes_the_new_config_value(tmp_path: Path) -> None:
    a = _resume_learner()
    a.train(128, ckpt_dir=tmp_path)
    assert torch.allclose(a.actor.log_std, torch.tensor(a.cfg.init_log_std)) and a.cfg.init_log_std != -3.5
    b = AmpLearner(_toy(16, episode_steps=12), toy_amp_config(**{**_RESUME_CFG, "init_log_std": -3.5}))
    with pytest.warns(UserWarning, match="init_log_std"):
        b.load_checkpoint(latest_checkpoint(tmp_path))
    assert torch.allclose(b.actor.log_std, torch.tensor(-3.5)) and not b.actor.log_std.requires_grad
    for (k, va), vb in zip(a.actor.state_dict().items(), b.actor.state_dict().values(), strict=True):
        assert k == "log_std" or torch.equal(va, vb), k  # the mean network is the checkpoint's
    b.collect(8)  # and it samples with the new std
    assert float(b.actor.log_std.exp().mean()) == pytest.approx(math.exp(-3.5))


def test_policy_snapshots_need_a_folder_and_a_non_negative_period() -> None:
    learner = _resume_learner()
    with pytest.raises(ValueError, match="snapshot_every"):
        learner.train(128, snapshot_every=5)
    with pytest.raises(ValueError, match="snapshot_every"):
        learner.train(128, snapshot_dir="x", snapshot_every=-1)


@pytest.mark.filterwarnings("ignore:Detected pickle protocol")
def test_corrupted_or_foreign_checkpoints_are_rejected_naming_the_file(tmp_path: Path) -> None:
    learner = _resume_learner()
    learner.train(128, ckpt_dir=tmp_path / "ck")
    ck = latest_checkpoint(tmp_path / "ck")
    state, meta = ck / "state.pt", ck / "meta.json"

    # 1. flipped bytes in the state
    data = bytearray(state.read_bytes())
    data[len(data) // 2] ^= 0xFF
    state.write_bytes(bytes(data))
    with pytest.raises(CheckpointError, match=str(state).replace(".", r"\.")):
        load_checkpoint(ck)
    with pytest.raises(CheckpointError, match="state.pt"):  # train() refuses to resume from it
        _resume_learner().train(256, ckpt_dir=tmp_path / "ck")

    # 2. a pickle of an arbitrary object, with a matching hash: weights_only refuses to run it
    import pickle

    class Evil:
        def __reduce__(self):
            return (os.system, ("echo pwned",))

    state.write_bytes(pickle.dumps({"actor": Evil()}))
    m = json.loads(meta.read_text())
    m["state_sha256"] = __import__("hashlib").sha256(state.read_bytes()).hexdigest()
    meta.write_text(json.dumps(m))
    with pytest.raises(CheckpointError, match=r"state\.pt: not a tensor-only torch file"):
        load_checkpoint(ck)

    # 3. a foreign metadata file, and a torn (truncated) one
    meta.write_text(json.dumps({"format": "someone-else", "version": 1}))
    with pytest.raises(CheckpointError, match=r"meta\.json: not a navzoo AMP checkpoint"):
        load_checkpoint(ck)
    meta.write_text('{"format": "navzoo-amp-ch')
    with pytest.raises(CheckpointError, match=r"meta\.json.*not valid JSON"):
        load_checkpoint(ck)

    # 4. a checkpoint of another env size is named too
    other = tmp_path / "other"
    _resume_learner().train(128, ckpt_dir=other)
    small = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(**_RESUME_CFG))
    with pytest.raises(CheckpointError, match=r"meta\.json: made for env dims.*--any-num-envs 1"):
        small.load_checkpoint(latest_checkpoint(other))


def test_train_resumes_a_checkpoint_of_another_env_count_only_when_asked(tmp_path: Path) -> None:
    """A run of 16 envs goes on with 8 (a smaller host): weights, optimisers and counters carry over."""
    big = _resume_learner()
    big.train(128, ckpt_dir=tmp_path)
    saved = {k: v.clone() for k, v in big.actor.state_dict().items()}
    small = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(**_RESUME_CFG))
    with pytest.raises(CheckpointError, match="made for env dims"):
        small.train(256, ckpt_dir=tmp_path)
    small = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(**_RESUME_CFG))
    small.load_checkpoint(latest_checkpoint(tmp_path), any_num_envs=True)
    assert small.global_step == big.global_step and small.iteration == big.iteration
    for k, v in small.actor.state_dict().items():
        if k != "log_std":
            assert torch.equal(v, saved[k]), k
    assert len(small.replay) == len(big.replay)
    small = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(**_RESUME_CFG))
    result = small.train(256, ckpt_dir=tmp_path, any_num_envs=True)
    assert result["resumed_from"] is not None and small.global_step >= 256
    assert small.global_step - big.global_step == 8 * small.cfg.rollout_steps * (small.iteration - big.iteration)


def test_interrupted_save_keeps_the_last_good_checkpoint(tmp_path: Path, monkeypatch) -> None:
    learner = _resume_learner()
    learner.train(128, ckpt_dir=tmp_path)
    good = latest_checkpoint(tmp_path)
    learner.collect(8)
    learner.update()

    def crash(*args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(torch, "save", crash)
    with pytest.raises(OSError, match="disk full"):
        learner.save_checkpoint(tmp_path)
    monkeypatch.undo()
    assert latest_checkpoint(tmp_path) == good
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".tmp")]
    load_checkpoint(good)  # still verifies


def test_keyboard_interrupt_checkpoints_before_exit(tmp_path: Path) -> None:
    class Interrupting(CirclingPointMass):
        calls = 0

        def step(self, actions):
            Interrupting.calls += 1
            if Interrupting.calls == 8 * 3 + 4:  # in the middle of the 4th rollout
                raise KeyboardInterrupt
            return super().step(actions)

    cfg = toy_amp_config(**_RESUME_CFG)
    learner = AmpLearner(Interrupting(ToyConfig(num_envs=16, episode_steps=12)), cfg)
    with pytest.raises(KeyboardInterrupt):
        learner.train(10 * 128, ckpt_dir=tmp_path, ckpt_every=100)
    ck = latest_checkpoint(tmp_path)
    assert ck is not None and ck.name == "ckpt_00000003"
    resumed = _resume_learner()
    out = resumed.train(5 * 128, ckpt_dir=tmp_path)
    assert out["resumed_from"] == str(ck) and resumed.iteration == 5


def test_sigint_finishes_the_iteration_then_checkpoints(tmp_path: Path) -> None:
    class Signalling(CirclingPointMass):
        calls = 0

        def step(self, actions):
            Signalling.calls += 1
            if Signalling.calls == 8 + 3:  # during the 2nd rollout
                os.kill(os.getpid(), signal.SIGINT)
            return super().step(actions)

    learner = AmpLearner(Signalling(ToyConfig(num_envs=16, episode_steps=12)), toy_amp_config(**_RESUME_CFG))
    before = signal.getsignal(signal.SIGINT)  # the default handler, or SIG_IGN under nohup / a background job
    out = learner.train(10 * 128, ckpt_dir=tmp_path, ckpt_every=100)
    assert out["interrupted"] and out["iteration"] == 2
    assert latest_checkpoint(tmp_path).name == "ckpt_00000002"
    assert signal.getsignal(signal.SIGINT) is before  # the learner puts the caller's handler back


def test_export_and_load_policy(tmp_path: Path) -> None:
    learner = _resume_learner()
    learner.train(2 * 128)
    out = learner.export_policy(tmp_path / "pol")
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["obs_dim"] == 6 and cfg["act_dim"] == 2 and len(cfg["weights_sha256"]) == 64
    tensors = torch.load(out / "policy.pt", weights_only=True)
    assert all(isinstance(v, torch.Tensor) for v in tensors.values())
    policy = load_policy(out)
    obs = np.random.default_rng(1).normal(size=(10, 6)).astype(np.float32) * 3
    act = policy(obs)
    assert act.shape == (10, 2) and act.dtype == np.float32 and np.abs(act).max() <= 1.0
    np.testing.assert_array_equal(act, learner.act(obs))
    np.testing.assert_allclose(policy(obs[0]), act[0], rtol=1e-5, atol=1e-7)  # unbatched: other BLAS path
    with pytest.raises(ValueError, match="obs_dim=6"):
        policy(np.zeros((3, 5)))
    (out / "policy.pt").write_bytes((out / "policy.pt").read_bytes()[:-10])
    with pytest.raises(CheckpointError, match=r"policy\.pt: sha256 does not match"):
        load_policy(out)


# --------------------------------------------------------------------------- robustness


class _Spiky(CirclingPointMass):
    """Task rewards with rare huge spikes of either sign."""

    def __init__(self, magnitude: float, **kw) -> None:
        super().__init__(ToyConfig(**kw))
        self.magnitude = magnitude
        self._spike_rng = np.random.default_rng(7)

    def step(self, actions):
        obs, r, te, tr, info = super().step(actions)
        spikes = self._spike_rng.random(len(r)) < 0.02
        r = np.where(spikes, self.magnitude * self._spike_rng.choice([-1.0, 1.0], len(r)), r)
        return obs, r, te, tr, info


@pytest.mark.parametrize(("magnitude", "reward_clip"), [(1e6, None), (1e30, 100.0)])
def test_no_nan_under_reward_spikes(magnitude: float, reward_clip: float | None) -> None:
    learner = AmpLearner(_Spiky(magnitude, num_envs=32), _small(reward_clip=reward_clip))
    for _ in range(6):
        learner.collect(8)
        stats = learner.update()
        finite = {k: v for k, v in stats.items() if not k.startswith("ppo/explained")}
        assert all(math.isfinite(v) for v in finite.values()), stats
    for net in (learner.actor, learner.critic, learner.disc, learner.obs_norm, learner.value_norm):
        assert all(torch.isfinite(t).all() for t in net.state_dict().values())
    assert np.isfinite(learner.act(np.zeros((3, 6), np.float32))).all()


def test_random_env_of_humanoid_size_runs_one_update() -> None:
    env = RandomAmpVecEnv(num_envs=24, episode_steps=5)
    cfg = AmpConfig(rollout_steps=8, actor_hidden=(64,), critic_hidden=(64,), disc_hidden=(64,), epochs=1)
    learner = AmpLearner(env, cfg)
    learner.collect(8)
    stats = learner.update()
    assert learner.global_step == 192 and math.isfinite(stats["losses/disc"])
    with pytest.raises(RuntimeError, match="collect"):
        learner.update()


# --------------------------------------------------------------------------- mirror-symmetry loss


def _asymmetry(learner: AmpLearner, obs: np.ndarray) -> float:
    from navzoo.agents.amp.symmetry import action_mirror, observation_mirror

    mo, ma = observation_mirror(obs.shape[1]), action_mirror()
    x = torch.as_tensor(obs)
    with torch.no_grad():
        a = learner.actor(learner.obs_norm.normalize(x))
        b = ma(learner.actor(learner.obs_norm.normalize(mo(x))))
    return float((a - b).square().sum(-1).mean())


def test_mirror_loss_makes_the_actor_symmetric() -> None:
    # Humanoid-sized random env (125 observations, 28 actions): the mirror loss, weighted heavily, drives the
    # asymmetry of the mean action down; without it, it is not logged and the actor stays asymmetric.
    probe = np.random.default_rng(5).standard_normal((512, 125)).astype(np.float32)
    results = {}
    for coef in (0.0, 50.0):
        env = RandomAmpVecEnv(num_envs=32, episode_steps=20, seed=1)
        learner = AmpLearner(env, _small(mirror_coef=coef, actor_lr=1e-3))
        torch.nn.init.normal_(learner.actor.mean.weight, std=0.02)  # an asymmetric start, inside the bounds
        learner.reset(seed=0)
        before = _asymmetry(learner, probe)
        for _ in range(6):
            learner.collect(learner.cfg.rollout_steps)
            stats = learner.update()
        results[coef] = (before, _asymmetry(learner, probe), stats)
    before, after, stats = results[50.0]
    assert "losses/mirror" in stats and after < 0.2 * before
    assert "losses/mirror" not in results[0.0][2] and results[0.0][1] > 0.5 * results[0.0][0]


def test_mirror_loss_refuses_other_layouts() -> None:
    with pytest.raises(ValueError, match="cannot mirror an observation of 40 columns"):
        AmpLearner(RandomAmpVecEnv(num_envs=4, obs_dim=40), _small(mirror_coef=1.0))
    with pytest.raises(ValueError, match="28 actions"):
        AmpLearner(RandomAmpVecEnv(num_envs=4, act_dim=6), _small(mirror_coef=1.0))
    with pytest.raises(ValueError, match="mirror_coef"):
        AmpConfig(mirror_coef=-1.0)


def test_a_resumed_run_takes_the_new_task_weight_and_actor_lr(tmp_path: Path) -> None:
    a = _resume_learner()
    a.train(128, ckpt_dir=tmp_path)
    b = AmpLearner(_toy(16, episode_steps=12),
                   toy_amp_config(**{**_RESUME_CFG, "task_weight": 1.0, "actor_lr": 1e-5}))
    with pytest.warns(UserWarning, match=r"actor_lr.*task_weight"):
        b.load_checkpoint(latest_checkpoint(tmp_path))
    assert all(g["lr"] == 1e-5 for g in b.actor_opt.param_groups)
    assert b.cfg.task_weight == 1.0 and a.cfg.task_weight != 1.0


def test_train_flags_reach_the_learner_config(tmp_path: Path, monkeypatch) -> None:
    import argparse

    import navzoo.agents.amp.learner as learner_module
    from navzoo.agents.amp.train import TrainArgs, add_arguments, run

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    ns = vars(parser.parse_args(["--task-weight", "1.0", "--actor-lr", "2e-5", "--envs-per-worker", "1",
                                 "--out", str(tmp_path)]))
    ns.pop("json")
    seen = {}

    class Built(Exception):
        pass

    def capture(env, config, device="cpu"):
        seen["config"] = config
        raise Built

    monkeypatch.setattr(learner_module, "AmpLearner", capture)
    with pytest.raises(Built):
        run(TrainArgs(**ns))
    assert (seen["config"].task_weight, seen["config"].actor_lr) == (1.0, 2e-5)
    assert (TrainArgs().task_weight, TrainArgs().actor_lr) == (AmpConfig().task_weight, AmpConfig().actor_lr)


def test_actor_warmup_holds_the_actor_while_critic_and_discriminator_learn() -> None:
    learner = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(actor_warmup_iters=2))

    def snap(net):
        return {k: v.clone() for k, v in net.state_dict().items()}

    actor0, critic0, disc0 = snap(learner.actor), snap(learner.critic), snap(learner.disc)
    for _ in range(2):  # iterations 0 and 1: the actor waits
        learner.collect(8)
        learner.update()
    assert all(torch.equal(v, actor0[k]) for k, v in learner.actor.state_dict().items())
    assert not all(torch.equal(v, critic0[k]) for k, v in learner.critic.state_dict().items())
    assert not all(torch.equal(v, disc0[k]) for k, v in learner.disc.state_dict().items())
    learner.collect(8)
    learner.update()  # iteration 2: the actor moves
    assert not all(torch.equal(v, actor0[k]) for k, v in learner.actor.state_dict().items())
    with pytest.raises(ValueError, match="actor_warmup_iters"):
        AmpConfig(actor_warmup_iters=-1)


def test_the_cloning_term_pulls_the_actor_to_the_pairs_actions() -> None:
    env = _toy(8, episode_steps=12)
    rng = np.random.default_rng(0)
    obs = rng.normal(size=(256, env.obs_dim)).astype(np.float32)
    target = np.full((256, env.act_dim), 0.6, dtype=np.float32)

    def gap(learner):
        with torch.no_grad():
            mu = learner.actor(learner.obs_norm.normalize(torch.as_tensor(obs)).float()).numpy()
        return float(np.abs(mu - target).mean())

    plain = AmpLearner(env, toy_amp_config(actor_lr=1e-3))
    cloned = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(actor_lr=1e-3, bc_coef=10.0))
    cloned.set_bc_data(obs, target)
    for learner in (plain, cloned):
        for _ in range(6):
            learner.collect(8)
            stats = learner.update()
    assert "losses/bc" in stats and gap(cloned) < 0.5 * gap(plain)
    with pytest.raises(ValueError, match="no behaviour-cloning pairs"):
        lone = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(bc_coef=1.0))
        lone.collect(8)
        lone.update()
    with pytest.raises(ValueError, match="behaviour-cloning pairs must be"):
        cloned.set_bc_data(obs[:, :2], target)
    with pytest.raises(ValueError, match="non-finite"):
        cloned.set_bc_data(np.full_like(obs, np.nan), target)
    with pytest.raises(ValueError, match="bc_coef"):
        AmpConfig(bc_coef=-1.0)


def test_the_anchor_term_holds_the_actor_near_its_start_and_survives_a_resume(tmp_path: Path) -> None:
    def run(coef: float) -> tuple[AmpLearner, float]:
        learner = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(actor_lr=1e-3, anchor_coef=coef))
        learner.set_anchor()
        start = {k: v.clone() for k, v in learner.actor.state_dict().items()}
        for _ in range(6):
            learner.collect(8)
            stats = learner.update()
        # the anchor is a frozen copy: the actor moved, the anchor did not
        assert all(torch.equal(v, start[k]) for k, v in learner.anchor[0].state_dict().items())
        assert not all(torch.equal(v, start[k]) for k, v in learner.actor.state_dict().items())
        return learner, stats["anchor/kl"]

    free, kl_free = run(0.0)  # no weight: the KL from the start is only logged
    held, kl_held = run(20.0)
    assert kl_free > 0 and kl_held < 0.25 * kl_free
    # a checkpoint keeps the anchor (the start policy and its normaliser, not the moved actor)
    held.save_checkpoint(tmp_path)
    again = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(actor_lr=1e-3, anchor_coef=20.0))
    again.load_checkpoint(latest_checkpoint(tmp_path))
    for mine, saved in zip(again.anchor, held.anchor, strict=True):
        assert all(torch.equal(v, saved.state_dict()[k]) for k, v in mine.state_dict().items())
    with pytest.raises(ValueError, match="has no anchor"):
        lone = AmpLearner(_toy(8, episode_steps=12), toy_amp_config(anchor_coef=1.0))
        lone.collect(8)
        lone.update()
    with pytest.raises(ValueError, match="anchor_coef"):
        AmpConfig(anchor_coef=float("nan"))
