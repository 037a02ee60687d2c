"""navzoo eval pedestrians --seeds: the following protocol over several seeds (navzoo.benchmark.pedestrians)."""

import re

import numpy as np
import pytest

from navzoo.benchmark import pedestrians


@pytest.mark.parametrize("bad, msg", [([], "at least one"), ([0, 0], "distinct"), ([0, 1.5], "integers"),
                                      ([True], "integers")])
def test_bad_seed_lists_are_refused_by_name(bad, msg):
    with pytest.raises(ValueError, match=msg):
        pedestrians.check_seeds(bad)


def test_the_cli_refuses_seed_with_seeds_and_a_malformed_list():
    with pytest.raises(SystemExit, match="not both"):
        pedestrians.main(["--seed", "1", "--seeds", "0,1"])
    with pytest.raises(SystemExit, match="--seeds '0,x'"):
        pedestrians.main(["--seeds", "0,x"])
    with pytest.raises(SystemExit, match="distinct"):
        pedestrians.main(["--seeds", "2,2"])


def test_several_seeds_pool_the_trips_and_keep_each_seeds_own_rates():
    kw = dict(scenes=("station",), seconds=20.0, people=[3])  # a few trips per seed, ~10 s each
    multi, poses = pedestrians.following(seeds=[0, 1], **kw)
    one = [pedestrians.following(seed=s, **kw) for s in (0, 1)]
    assert multi["seeds"] == [0, 1]
    for row, (single, _) in zip(multi["by_seed"], one, strict=True):
        for k in pedestrians._SEED_KEYS:  # each seed's rates are those of a single-seed run (deterministic)
            assert row[k] == pytest.approx(single[k]), k
    assert multi["trips"] == one[0][0]["trips"] + one[1][0]["trips"]
    assert [r["seed"] for r in multi["scenes"]] == [0, 1]
    assert multi["trips"] > 0 and all(r["trips"] > 0 for r in multi["by_seed"])
    ended = sum(r["success"] for r in multi["scenes"])
    assert multi["success_rate"] == pytest.approx(ended / multi["trips"])
    # one trip per goal: never more trips or successes than the per-limit count, the same falls
    goal, rows = multi["per_goal"], multi["scenes"]
    assert 0 < goal["trips"] <= multi["trips"] and goal["success_rate"] * goal["trips"] <= ended + 1e-9
    assert sum(r["by_goal"]["fall"] for r in rows) == sum(r["fall"] for r in rows)
    assert multi["by_seed"][0]["per_goal"]["trips"] + multi["by_seed"][1]["per_goal"]["trips"] == goal["trips"]
    rates = [r["success_rate"] for r in multi["by_seed"]]
    assert multi["success_rate_seed_sd"] == pytest.approx(float(np.std(rates, ddof=1)))
    np.testing.assert_array_equal(poses, one[0][1])  # realism reads the first seed's poses only
    result = {"tracking": {k: 0.0 for k in pedestrians.PAPER["tracking"]} | {"n_clips": 1},
              "following": multi,
              "realism": {m: dict.fromkeys(("coverage_k50", "entropy_k50", "dist_k50", "coverage_k100",
                                            "entropy_k100", "dist_k100", "mmd", "n_generated"), 0.0)
                          for m in ("amp", "kinematic")} | {"reference_mmd_floor": 0.0}}
    text = pedestrians.markdown(result)
    assert "| seed | trips | success |" in text and "| station | 1 | 3 |" in text


def _timeless(metrics):
    """Following metrics without the scenes' wall-clock seconds (the only field a rerun changes)."""
    return metrics | {"scenes": [{k: v for k, v in r.items() if k != "wall_s"} for r in metrics["scenes"]]}


def test_an_interrupted_following_run_resumes_where_it_stopped(tmp_path, monkeypatch):
    kw = dict(scenes=("station",), seconds=20.0, people=[3], seeds=[0, 1])
    whole, whole_poses = pedestrians.following(**kw)
    rows_file = tmp_path / "ped.json.following.jsonl"
    first, _ = pedestrians.following(resume=rows_file, **kw)
    assert _timeless(first) == _timeless(whole)
    lines = rows_file.read_text().splitlines()
    assert len(lines) == 3 and "settings" in lines[0]
    rows_file.write_text("\n".join(lines[:2]) + '\n{"scene": "stat')  # killed after one run, mid-line
    calls = []
    real = pedestrians.follow_scene
    monkeypatch.setattr(pedestrians, "follow_scene", lambda *a: calls.append(a) or real(*a))
    resumed, poses = pedestrians.following(resume=rows_file, **kw)
    assert [c[3] for c in calls] == [1]  # only seed 1 ran again
    assert _timeless(resumed) == _timeless(whole)
    np.testing.assert_array_equal(poses, whole_poses)  # the first seed's poses came back from the file
    with pytest.raises(ValueError, match="other settings \\(seconds\\)"):
        pedestrians.following(resume=rows_file, **(kw | {"seconds": 10.0}))
    (tmp_path / "other.jsonl").write_text('{"rows": 1}\n')
    with pytest.raises(ValueError, match="no settings line"):
        pedestrians.following(resume=tmp_path / "other.jsonl", **kw)
    pedestrians.remove_resume_files(rows_file)
    assert not rows_file.exists() and not (tmp_path / "ped.json.following.jsonl.poses").exists()


def test_a_resumed_run_must_use_the_same_models(tmp_path, monkeypatch):
    """The settings a resume checks name the AMP policy and, for diffusion crowds, the diffusion model."""
    import shutil

    from navzoo.agents.diffusion.crowd import default_model_dir

    args = (("station",), [3], 20.0, [0], None)
    base = pedestrians._settings(*args, "diffusion", "amp", 1)
    assert base["policy_config_sha256"] and base["diffusion_config_sha256"]
    assert "diffusion_config_sha256" not in pedestrians._settings(*args, "sfm", "amp", 1)
    assert pedestrians._settings(*args, "sfm", "kinematic", 1)["policy_config_sha256"] is None
    other = tmp_path / "diffusion"
    shutil.copytree(default_model_dir(), other, ignore=shutil.ignore_patterns("*.md", "*.pt"))
    (other / "config.json").write_text((other / "config.json").read_text().replace("{", '{"retrained": 1, ', 1))
    monkeypatch.setenv("NAVZOO_DIFFUSION_MODEL", str(other))
    changed = pedestrians._settings(*args, "diffusion", "amp", 1)
    assert changed["diffusion_config_sha256"] != base["diffusion_config_sha256"]
    assert {k for k in base if base[k] != changed[k]} == {"diffusion_config_sha256"}


def test_a_trip_after_a_timeout_is_timed_on_the_path_still_ahead():
    """The limit of the trip that follows a timeout counts the waypoints not yet reached, not the whole path
    again (which held the part already walked and made such trips lenient)."""
    from types import SimpleNamespace

    import navzoo
    from navzoo.benchmark.pedestrians import remaining_path_length

    path = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0]])
    env = SimpleNamespace(paths=[path], wp_index=np.array([1]), pos=np.array([[3.0, 0.0]]))
    assert remaining_path_length(env, 0) == pytest.approx(1.0 + 3.0)
    env.wp_index[0] = 2
    env.pos[0] = [4.0, 1.0]
    assert remaining_path_length(env, 0) == pytest.approx(2.0)
    env.wp_index[0] = 7  # past the end: what is left is the way to the goal
    env.pos[0] = [4.0, 2.5]
    assert remaining_path_length(env, 0) == pytest.approx(0.5)
    # on a fresh trip it is about the env's own shortest path length (a first waypoint within the reach
    # tolerance may already count as reached)
    nav = navzoo.make(None, scene="lobby", n_robots=0, n_humans=3, raw=True).unwrapped
    nav.reset(seed=0)
    for i in range(nav.n_total):
        left = remaining_path_length(nav, i)
        assert left <= nav.shortest_path_length[i] + 1e-9 and left == pytest.approx(nav.shortest_path_length[i], abs=0.1)
    nav.close()


def test_heldout_scenes_are_followed_with_their_own_people(monkeypatch, capsys):
    """``navzoo eval pedestrians --scenes heldout``: the ten held-out scenes with HELDOUT_SCENES' people, in the
    following runs and the kinematic realism crowd; an unknown scene is refused before the clip tracking."""
    import navzoo.agents.amp.tracking as tracking

    names = tuple(n for n, _ in pedestrians.HELDOUT_SCENES)
    counts = [n for _, n in pedestrians.HELDOUT_SCENES]
    assert pedestrians.people_per_scene(len(names)) == counts  # the spread gives each its own count
    assert pedestrians.expand_scenes("heldout") == names
    assert pedestrians.expand_scenes(["lobby", "heldout"]) == ("lobby", *names)
    for bad, msg in (("lobby,atlantis", "atlantis"), ("", "no scene given")):
        with pytest.raises(ValueError, match=msg):
            pedestrians.expand_scenes(bad)
    # result filters: 'protocol' also stands for the eight scenes, each name kept once
    assert pedestrians.scene_names("protocol") == pedestrians.SCENES
    assert pedestrians.scene_names("lobby,heldout,protocol") == ("lobby", *names, *pedestrians.SCENES[:-1])
    with pytest.raises(ValueError, match="atlantis"):
        pedestrians.scene_names("protocol,atlantis")
    monkeypatch.setattr(tracking, "track_clips", lambda **k: pytest.fail("tracked clips before checking the scenes"))
    from navzoo.cli import main

    assert main(["eval", "pedestrians", "--scenes", "heldout,atlantis", "--no-throughput"]) == 2
    assert "atlantis" in capsys.readouterr().err

    seen = {}

    class Stop(Exception):
        pass

    def fake_following(scenes, seconds, seed, policy_dir, **kw):
        seen["scenes"] = tuple(scenes)
        raise Stop

    monkeypatch.setattr(tracking, "track_clips", lambda **k: {k2: 0.0 for k2 in (
        "mean_pos_error_m", "max_pos_error_m", "mean_rot_error_rad", "clip_success_rate", "worst_pos_error_m",
        "fall_rate", "n_clips")})
    monkeypatch.setattr(pedestrians, "following", fake_following)
    with pytest.raises(Stop):
        pedestrians.evaluate(scenes="heldout", with_throughput=False)
    assert seen["scenes"] == names


def test_set_passes_navconfig_fields_to_the_following_runs_and_refuses_bad_ones(tmp_path, monkeypatch, capsys):
    """``navzoo eval pedestrians --set KEY=VALUE``: NavConfig fields for every following run (recorded in the
    resume file's settings); unknown fields, fields the protocol sets and refused values are errors before any
    clip is tracked."""
    import navzoo.agents.amp.tracking as tracking
    from navzoo.cli import main

    monkeypatch.setattr(tracking, "track_clips", lambda **k: pytest.fail("tracked clips before checking --set"))
    for args, msg in ((["--set", "amp_wall_strenght=0.3"], "unknown NavConfig field"),
                      (["--set", "n_humans=4"], "set by the following protocol"),
                      (["--set", "amp_wall_strength=-1"], "amp_wall_strength"),
                      (["--set", "amp_wall_strength"], "KEY=VALUE"),
                      (["--set", "amp_wall_strength=0.3", "--set", "amp_wall_strength=0.5"], "given twice")):
        assert main(["eval", "pedestrians", "--no-throughput", *args]) == 2
        assert msg in capsys.readouterr().err
    assert pedestrians.env_set_option("x", ["amp_wall_strength=0.3", "human_yielding=false"]) == {
        "amp_wall_strength": 0.3, "human_yielding": False}

    seen = []
    real_make = pedestrians._make

    def spy(*a, **k):
        wrapped, env = real_make(*a, **k)
        seen.append(env.amp.a_wall)
        return wrapped, env

    monkeypatch.setattr(pedestrians, "_make", spy)
    kw = dict(scenes=("station",), seconds=2.0, people=[3])
    resume = tmp_path / "f.following.jsonl"
    pedestrians.following(env_overrides={"amp_wall_strength": 0.3}, resume=resume, **kw)
    pedestrians.following(**kw)
    from navzoo.envs.amp_humans import SFM_A_WALL

    assert seen == [0.3, SFM_A_WALL]
    with pytest.raises(ValueError, match="other settings \\(env_overrides\\)"):
        pedestrians.following(resume=resume, **kw)


def test_scene_runs_count_the_person_time_in_contact():
    """``contact_steps``: person-steps of standing people in wall contact, in people contact, and in all."""
    row = pedestrians.follow_scene("doorway", 4, 3.0, 0)
    wall, people, standing = row["contact_steps"]
    assert standing == 4 * 90  # 4 people standing for 3 s at 30 Hz (no fall this early)
    assert 0 <= wall <= standing and 0 <= people <= standing
    m = pedestrians._following_metrics([row, row | {"contact_steps": [wall + 10, people, standing + 40]}], 3.0)
    assert m["map_contact_time"] == pytest.approx((2 * wall + 10) / (2 * standing + 40))
    assert m["agent_contact_time"] == pytest.approx(2 * people / (2 * standing + 40))
    old = {k: v for k, v in row.items() if k != "contact_steps"}  # a row resumed from an older file
    assert pedestrians._following_metrics([row, old], 3.0)["map_contact_time"] is None


def test_scene_counts_are_parsed_and_bad_items_named():
    assert pedestrians.parse_scene_counts("lobby:15,corridor:12") == [("lobby", 15), ("corridor", 12)]
    assert pedestrians.parse_scene_counts(" lobby : 3 , home:1") == [("lobby", 3), ("home", 1)]
    for bad, item in (("lobby", "lobby"), (":4", ":4"), ("lobby:", "lobby:"), ("lobby:x", "lobby:x"),
                      ("lobby:-2", "lobby:-2"), ("lobby:0", "lobby:0"), ("lobby:15,", ""), ("home:2,lobby:1.5", "lobby:1.5")):
        with pytest.raises(ValueError, match=re.escape(f"--scenes: {item!r} is not SCENE:PEOPLE")):
            pedestrians.parse_scene_counts(bad)
