"""Recorded crowd targets in the AMP path task (PathTaskConfig.recorded_targets / recorded_prob)."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.amp.features import heading
from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig, load_recorded_targets
from navzoo.agents.amp.train import locomotion_reference

DT = 1.0 / 30


def _write(path, up_steps=90, dt=DT, **changes):
    k = np.arange(226)[:, None] * DT
    ahead = np.concatenate([1.0 * k, 0 * k], axis=1)  # 1 m/s along the recorded body's heading (0 rad) ...
    left = np.concatenate([0 * k, 0.5 * k], axis=1)  # ... then, from step 60, 0.5 m/s to its left
    arrays = {"person_start": np.array([0, 2]), "up_steps": np.atleast_1d(up_steps), "step": np.array([0, 60]),
              "plan_t": np.array([0, 60]), "heading": np.array([0.0, 0.0], dtype=np.float32),
              "paths": np.stack([ahead, left]).astype(np.float32), "dt": np.float64(dt)}
    arrays.update(changes)
    np.savez(path, **arrays)
    return str(path)


@pytest.fixture(scope="module")
def reference():
    return locomotion_reference()


def test_an_episode_walks_the_recorded_updates_turned_to_the_body(tmp_path, reference):
    f = _write(tmp_path / "rec.npz")
    env = AmpPathEnv(2, reference, PathTaskConfig(episode_seconds=3.0, rsi_prob=0.0, recorded_targets=f,
                                                  recorded_prob=1.0), seed=0)
    env.reset(seed=0)
    state = env.bodies.read_state()
    head = heading(state["root_quat"])
    assert (env._rec_person == 0).all() and (env._rec_offset == 0).all()  # the recording is one episode long
    for i in range(2):
        assert np.allclose(env.paths[i, 0], state["root_pos"][i, :2])  # it starts at the body ...
        d = env.paths[i, 30] - env.paths[i, 0]  # ... and goes 1 m ahead of it in 1 s, whatever its heading
        assert np.allclose(d, [np.cos(head[i]), np.sin(head[i])], atol=1e-6)
    # the second update comes at step 60: from the body then, 0.5 m/s to the left of the first heading
    env.t[:] = 60
    env.k[:] = 60  # the target index: the clock's (no recorded_lag_s)
    env._step_recorded(state)
    for i in range(2):
        assert np.allclose(env.paths[i, 60], state["root_pos"][i, :2])
        d = env.paths[i, 90] - env.paths[i, 60]
        assert np.allclose(d, 0.5 * np.array([-np.sin(head[i]), np.cos(head[i])]), atol=1e-6)
        assert env._rec_next[i] == env._rec_end[i] == 2  # nothing left to come
    env.close()


def test_recorded_episodes_are_the_share_asked_and_get_no_generated_replans(tmp_path, reference):
    f = _write(tmp_path / "rec.npz", up_steps=400)
    env = AmpPathEnv(40, reference, PathTaskConfig(stage=3, episode_seconds=3.0, rsi_prob=0.0, recorded_targets=f,
                                                   recorded_prob=0.5), seed=1)
    env.reset(seed=1)
    walks = env._rec_person >= 0
    assert 8 <= walks.sum() <= 32 and not env._crowd[walks].any()
    assert (env._rec_offset[walks] <= 400 - env.episode_steps).all()
    _, _, _, _, info = env.step(np.zeros((40, env.act_dim)))
    assert np.array_equal(info["log/recorded"], walks.astype(float))
    assert np.array_equal(info["log/fall_recorded"] + info["log/fall_generated"], info["fallen"].astype(float))
    assert not (info["log/fall_recorded"] * ~walks).any()
    env.close()


def test_bad_recordings_and_settings_are_named(tmp_path):
    with pytest.raises(ValueError, match="needs recorded_targets"):
        PathTaskConfig(recorded_prob=0.5)
    with pytest.raises(ValueError, match="recorded_prob"):
        PathTaskConfig(recorded_prob=1.5, recorded_targets="x.npz")
    with pytest.raises(ValueError, match="cannot read"):
        load_recorded_targets(str(tmp_path / "missing.npz"))
    with pytest.raises(ValueError, match="missing"):
        np.savez(tmp_path / "partial.npz", step=np.zeros(2))
        load_recorded_targets(str(tmp_path / "partial.npz"))
    with pytest.raises(ValueError, match="not the task's"):
        load_recorded_targets(_write(tmp_path / "slow.npz", dt=0.1))
    with pytest.raises(ValueError, match="person_start"):
        load_recorded_targets(_write(tmp_path / "gap.npz", person_start=np.array([0, 3])))
    with pytest.raises(ValueError, match="finite"):
        load_recorded_targets(_write(tmp_path / "nan.npz", heading=np.array([0.0, np.nan])))
    rec = load_recorded_targets(_write(tmp_path / "ok.npz"))
    assert rec.paths.shape == (2, 226, 2) and list(rec.step) == [0, 60]


def test_several_recordings_are_pooled_and_short_paths_held_at_their_end(tmp_path):
    a = _write(tmp_path / "a.npz")
    short = np.zeros((1, 100, 2), dtype=np.float32)
    short[0, :, 1] = np.arange(100) * DT  # 1 m/s to the left, 100 points
    b = _write(tmp_path / "b.npz", up_steps=50, person_start=np.array([0, 1]), step=np.array([0]),
               plan_t=np.array([5]), heading=np.array([0.5], dtype=np.float32), paths=short)
    rec = load_recorded_targets(f"{a}, {b}")
    assert list(rec.person_start) == [0, 2, 3] and list(rec.up_steps) == [90, 50]
    assert list(rec.step) == [0, 60, 0] and list(rec.plan_t) == [0, 60, 5]
    assert np.allclose(rec.heading, [0.0, 0.0, 0.5])
    assert rec.paths.shape == (3, 226, 2)
    assert np.array_equal(rec.paths[:2], load_recorded_targets(a).paths)
    assert np.array_equal(rec.paths[2, :100], short[0]) and np.all(rec.paths[2, 100:] == short[0, -1])
    with pytest.raises(ValueError, match="empty file name"):
        load_recorded_targets(f"{a},")
    with pytest.raises(ValueError, match="cannot read"):
        load_recorded_targets(f"{a},{tmp_path / 'none.npz'}")


def test_training_names_a_bad_recording_before_it_starts(tmp_path):
    from navzoo.agents.amp.train import TrainArgs, run

    with pytest.raises(ValueError, match="cannot read"):
        run(TrainArgs(out=str(tmp_path / "run"), recorded_targets=str(tmp_path / "none.npz"), recorded_prob=0.3))


def test_in_patches_with_boxes_recorded_episodes_are_drawn_clear_of_them(tmp_path, reference):
    # four people: three walk 1.2 m/s straight ahead for 10 s, one stands; in box patches a course 12 m long rarely
    # stays clear of every box, and the draws must prefer the clear ones
    k = np.arange(301)[:, None] * DT
    ahead = np.concatenate([1.2 * k, 0 * k], axis=1).astype(np.float32)
    still = np.zeros_like(ahead)
    f = _write(tmp_path / "rec.npz", up_steps=np.array([300, 300, 300, 300]), person_start=np.arange(5),
               step=np.zeros(4, dtype=int), plan_t=np.zeros(4, dtype=int), heading=np.zeros(4, dtype=np.float32),
               paths=np.stack([ahead, ahead, ahead, still]))
    cfg = PathTaskConfig(stage=3, obstacle_obs=True, boxes_per_patch=4, pair_patches=True, episode_seconds=10.0,
                         rsi_prob=0.0, recorded_targets=f, recorded_prob=1.0)
    env = AmpPathEnv(16, reference, cfg, seed=3)
    env.reset(seed=3)
    state = env.bodies.read_state()
    rec = env._recorded
    clear = []
    for i in range(16):
        p = int(env._rec_person[i])
        course = env._recorded_course(int(rec.person_start[p]), int(rec.person_start[p + 1]), int(env._rec_offset[i]),
                                      float(env._rec_turn[i]), state["root_pos"][i, :2])
        assert course.shape == (env.episode_steps + 1, 2)
        assert np.allclose(course[0], state["root_pos"][i, :2])
        if p < 3:  # the course is the path the episode walks: 12 m straight along the body's heading
            assert np.allclose(np.linalg.norm(course[-1] - course[0]), 12.0, atol=1e-3)
        clear.append(env._clearance(i, course).min())
    clear = np.array(clear)
    assert (clear >= 0.6).all()  # the standing person is always clear: without the redraws 5 of these 16 are not
    env.close()


def test_the_course_chains_later_updates_where_the_targets_stood(tmp_path, reference):
    f = _write(tmp_path / "rec.npz")
    env = AmpPathEnv(1, reference, PathTaskConfig(episode_seconds=3.0, rsi_prob=0.0, recorded_targets=f,
                                                  recorded_prob=1.0), seed=0)
    course = env._recorded_course(0, 2, 0, 0.0, np.array([1.0, 2.0]))
    assert course.shape == (91, 2)
    assert np.allclose(course[60], [3.0, 2.0])  # 2 s at 1 m/s ahead ...
    assert np.allclose(course[90], [3.0, 2.5])  # ... then 1 s at 0.5 m/s to the left
    env.close()


def test_packed_paths_come_back_within_half_a_rounding_step():
    from navzoo.agents.amp.path_env import pack_recorded_paths, unpack_recorded_paths

    rng = np.random.default_rng(0)
    knots = np.cumsum(rng.normal(0, 0.1, (5, 76, 2)), axis=1)  # straight between every third point, as the planners'
    t = np.arange(226) / 3.0
    straight = np.stack([np.stack([np.interp(t, np.arange(76), knots[u, :, c]) for c in range(2)], -1)
                         for u in range(5)])
    packed = pack_recorded_paths(straight)
    assert int(packed["path_stride"]) == 3 and packed["paths_q"].dtype == np.int16
    assert packed["paths_q"].shape == (5, 76, 2)
    assert np.abs(unpack_recorded_paths(packed) - straight).max() <= 0.0025 + 1e-9
    bent = straight + 0.05 * np.sin(np.arange(226))[None, :, None]  # not straight between the knots: every point kept
    packed = pack_recorded_paths(bent)
    assert int(packed["path_stride"]) == 1
    assert np.abs(unpack_recorded_paths(packed) - bent).max() <= 0.0025 + 1e-9


def test_packed_recordings_load_and_bad_packing_is_named(tmp_path):
    from navzoo.agents.amp.path_env import pack_recorded_paths

    plain = load_recorded_targets(_write(tmp_path / "plain.npz"))
    with np.load(tmp_path / "plain.npz") as d:
        arrays = {k: d[k] for k in d.files if k != "paths"}
    np.savez(tmp_path / "packed.npz", **arrays, **pack_recorded_paths(plain.paths))
    rec = load_recorded_targets(str(tmp_path / "packed.npz"))
    assert np.abs(rec.paths - plain.paths).max() <= 0.0025 + 1e-9 and list(rec.step) == list(plain.step)
    bad = pack_recorded_paths(plain.paths)
    bad["path_len"] = np.int64(300)
    np.savez(tmp_path / "bad.npz", **arrays, **bad)
    with pytest.raises(ValueError, match="paths_q must be"):
        load_recorded_targets(str(tmp_path / "bad.npz"))


def test_with_recorded_lag_the_target_waits_for_the_body(tmp_path, reference):
    f = _write(tmp_path / "rec.npz", up_steps=300)
    runs = {}
    for lag in (0.0, 0.3):
        env = AmpPathEnv(4, reference, PathTaskConfig(episode_seconds=3.0, rsi_prob=0.0, recorded_targets=f,
                                                      recorded_prob=0.5, recorded_lag_s=lag), seed=4)
        env.reset(seed=4)
        walks = env._rec_person >= 0
        assert walks.any() and (~walks).any()
        for _ in range(20):  # 2/3 s of standing (zero actions; bodies fall at about 1 s): the target walks on
            env.step(np.zeros((4, env.act_dim)))
        runs[lag] = (walks, env.k.copy(), env.t.copy())
        env.close()
    walks, k, t = runs[0.0]
    assert np.array_equal(k, t)  # on the clock
    walks, k, t = runs[0.3]
    assert np.array_equal(k[~walks], t[~walks])  # generated paths stay on the clock
    assert (t[walks] == 20).all() and (k[walks] <= 9 + 3).all()  # 0.3 s ahead of a body that hardly moved
    with pytest.raises(ValueError, match="recorded_lag_s"):
        PathTaskConfig(recorded_lag_s=-0.1)


def test_a_held_target_never_goes_back_to_an_earlier_path(tmp_path, reference):
    # the second update turns the person round: its path runs back over the first one's points
    k = np.arange(226)[:, None] * DT
    ahead = np.concatenate([1.0 * k, 0 * k], axis=1)
    back = np.concatenate([-1.0 * k, 0 * k], axis=1)
    f = _write(tmp_path / "rec.npz", up_steps=90, paths=np.stack([ahead, back]).astype(np.float32))
    env = AmpPathEnv(1, reference, PathTaskConfig(episode_seconds=3.0, rsi_prob=0.0, recorded_targets=f,
                                                  recorded_prob=1.0, recorded_lag_s=0.3), seed=0)
    env.reset(seed=0)
    env.k[:] = 40  # the body is on its first path, 40 steps in; the turn comes at step 60 of the recording
    env.t[:] = 60
    state = env.bodies.read_state()
    env._step_recorded(state)
    assert env._k_from[0] == 40
    for _ in range(10):
        env.step(np.zeros((1, env.act_dim)))
        assert env.k[0] >= 40  # not back on the first path's points, though the body stands among them
    env.close()
