from __future__ import annotations

import json

import numpy as np
import pytest

from tests.script_modules import load_script

rp = load_script("amp_target_replay")


def test_replay_walks_the_recorded_targets_alone(tmp_path, capsys):
    out = tmp_path / "replay.json"
    assert rp.main(["--scene", "square_crossing:2", "--seconds", "6", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert [r["person"] for r in data["rows"]] == [0, 1] and data["rows"][0]["replay_policy"] is None
    for r in data["rows"]:
        assert r["up_s"] == pytest.approx(6.0, abs=0.05) and not r["crowd_fell"] and not r["replay_fell"]
        assert r["updates"] >= 3  # the start's plan and the replans every 2 s
        # alone, the body walks the recorded targets about as far as the person did in the crowd
        assert r["crowd_walked_m"] > 3.0 and r["replay_walked_m"] == pytest.approx(r["crowd_walked_m"], rel=0.25)
    s = data["summary"]
    assert s["people"] == 2 and s["crowd_falls"] == 0 and s["replay_per_minute"] == 0.0
    assert s["person_minutes"] == pytest.approx(0.2, abs=0.01)
    assert "all:" in capsys.readouterr().out


def test_summary_counts_falls_per_person_minute():
    rows = [{"up_s": 60.0, "crowd_fell": True, "crowd_cause": "none", "replay_fell": True, "replay_fell_at_s": 30.0,
             "crowd_walked_m": 50.0, "replay_walked_m": 25.0},
            {"up_s": 120.0, "crowd_fell": False, "crowd_cause": None, "replay_fell": False, "replay_fell_at_s": None,
             "crowd_walked_m": 100.0, "replay_walked_m": 98.0},
            {"up_s": 60.0, "crowd_fell": True, "crowd_cause": "person", "replay_fell": False, "replay_fell_at_s": None,
             "crowd_walked_m": 40.0, "replay_walked_m": 45.0}]
    s = rp.summary(rows)
    assert s["person_minutes"] == 4.0 and s["crowd_falls"] == 2 and s["crowd_untouched_falls"] == 1
    assert s["crowd_per_minute"] == 0.5 and s["crowd_untouched_per_minute"] == 0.25
    assert s["replay_per_minute"] == pytest.approx(1 / 3.5, abs=1e-3)  # the replay that fell stopped at 30 s
    assert s["walked_m_crowd"] == 190.0 and s["walked_m_replay"] == 168.0


def test_bad_input_is_named(capsys):
    for argv, msg in ((["--scene", "lobby"], "SCENE:N"), (["--scene", "lobby:0"], "at least 1"),
                      (["--scene", "lobby:3", "--seconds", "0"], "positive"),
                      (["--scene", "lobby:3", "--policy", "/nonexistent"], "not a folder"),
                      (["--scene", "lobby:3", "--replay-policy", "/nonexistent"], "--replay-policy")):
        with pytest.raises(SystemExit):
            rp.main(argv)
        assert msg in capsys.readouterr().err


def test_saved_targets_are_what_the_path_task_trains_on(tmp_path, capsys):
    from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig, load_recorded_targets
    from navzoo.agents.amp.train import locomotion_reference

    f = tmp_path / "targets.npz"
    assert rp.main(["--scene", "square_crossing:2", "--seconds", "5", "--save-targets", str(f), "--no-replay"]) == 0
    assert "saved the target updates of 2 people" in capsys.readouterr().out
    rec = load_recorded_targets(str(f))
    assert len(rec.up_steps) == 2 and (rec.up_steps == 150).all() and rec.step[0] == 0
    env = AmpPathEnv(2, locomotion_reference(), PathTaskConfig(episode_seconds=2.0, recorded_targets=str(f),
                                                               recorded_prob=1.0), seed=0)
    env.reset(seed=0)
    for _ in range(70):  # past the recordings' first replan, 2 s in, and an episode's end
        obs, rew, term, trunc, _ = env.step(np.zeros((2, env.act_dim)))
        assert np.isfinite(obs).all() and np.isfinite(rew).all()
    env.close()
    with pytest.raises(SystemExit):
        rp.main(["--scene", "square_crossing:2", "--no-replay"])
    assert "--save-targets" in capsys.readouterr().err
