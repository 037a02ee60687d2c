"""The following-protocol ablation script's result files: resume keys and summaries (scripts/amp_target_ablation.py)."""

from __future__ import annotations

import json

import pytest

from tests.script_modules import load_script

ablation = load_script("amp_target_ablation")


def _row(config: dict, scene: str, seed: int, crowd: str | None = "sfm", success: int = 3, **extra) -> dict:
    row = {"config": config["name"], **{k: config[k] for k in ablation._PARAMS}, "seed": seed, "scene": scene,
           "success": success, "off_path": 1, "fall": 0, "timeout": 0, "map_trips": 1, "agent_trips": 0,
           "err_sum": 1.0, "err_n": 10, "diffusion_settings": {}, **extra}
    if crowd is not None:
        row["crowd"] = crowd
    return row


def test_runs_of_another_crowd_model_are_not_taken_as_done():
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0")
    done = ablation.done_runs([_row(cfg, "lobby", 0, "sfm"), _row(cfg, "home", 1, None)], [cfg])
    assert ("c", "sfm", "{}", 0, "amp", "lobby") in done
    assert ("c", "sfm", "{}", 1, "amp", "home") in done  # rows from before the crowd was recorded were social force
    assert ("c", "diffusion", "{}", 0, "amp", "lobby") not in done
    assert ("c", "sfm", "{}", 1, "amp", "lobby") not in done


def test_a_name_reused_with_other_parameters_is_refused():
    old = ablation.parse_config("c:0.1:0.1:4:2.0:0:0.05")
    new = ablation.parse_config("c:0.1:0.1:4:2.0:0:0.02")
    with pytest.raises(ValueError, match="'c'.*trim"):
        ablation.done_runs([_row(old, "lobby", 0)], [new])
    other = ablation.parse_config("d:0.1:0.1:4:2.0:0:0.02")
    assert ablation.done_runs([_row(old, "lobby", 0)], [other]) == {("c", "sfm", "{}", 0, "amp", "lobby")}


def test_the_summary_keeps_crowd_models_apart(tmp_path):
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0")
    rows = [_row(cfg, "lobby", 0, "sfm", success=3), _row(cfg, "lobby", 0, "diffusion", success=1)]
    path = tmp_path / "rows.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    table = ablation.summary(str(path)).splitlines()
    assert len(table) == 4
    assert table[2].startswith("| c, seed 0 (1 scenes) | 4 | 0.750 |")
    assert table[3].startswith("| c (diffusion), seed 0 (1 scenes) | 2 | 0.500 |")


def test_a_rerun_with_the_other_crowd_model_refuses_nothing_and_skips_nothing(tmp_path, monkeypatch):
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0")
    out = tmp_path / "rows.jsonl"
    out.write_text(json.dumps(_row(cfg, "lobby", 0, "sfm")) + "\n")
    seen = []

    class FakePool:  # records the jobs instead of running 200 s of physics
        def __init__(self, *a, **k):
            pass

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            return False

        def imap_unordered(self, fn, jobs):
            seen.extend(jobs)
            return iter(())

    class FakeContext:
        Pool = FakePool

    monkeypatch.setattr(ablation.mp, "get_context", lambda *_: FakeContext)
    ablation.main(["--configs", "c:0.1:0.1:4:2.0:0", "--scenes", "lobby", "--crowd", "diffusion", "--out", str(out)])
    assert [(j[1], j[5]) for j in seen] == [("lobby", "diffusion")]
    seen.clear()
    ablation.main(["--configs", "c:0.1:0.1:4:2.0:0", "--scenes", "lobby", "--out", str(out)])
    assert seen == []


def test_the_summary_by_scene_pools_seeds(tmp_path):
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0")
    rows = [_row(cfg, "lobby", 0, success=3, pedestrians=15), _row(cfg, "lobby", 1, success=1, pedestrians=15),
            _row(cfg, "home", 0, success=0, pedestrians=5)]
    path = tmp_path / "rows.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    table = ablation.summary(str(path), by_scene=True).splitlines()
    assert len(table) == 4
    assert table[2].startswith("| c, lobby (15 people, seeds 0,1) | 6 | 0.667 |")
    assert table[3].startswith("| c, home (5 people, seeds 0) | 1 | 0.000 |")


def test_the_graded_wall_margin_field():
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0")["graded"] is None  # the module's default
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::0")["graded"] is False
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::1")["graded"] is True
    with pytest.raises(ValueError, match="GRADED must be 1 or 0"):
        ablation.parse_config("c:0.1:0.1:4:2.0:0::::yes")
    on, off = ablation.parse_config("c:0.1:0.1:4:2.0:0::::1"), ablation.parse_config("c:0.1:0.1:4:2.0:0::::0")
    with pytest.raises(ValueError, match="'c'.*graded"):
        ablation.done_runs([_row(on, "lobby", 0)], [off])


def test_the_skip_field():
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::1")["skip"] is None
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::1:1")["skip"] is True
    with pytest.raises(ValueError, match="SKIP must be 1 or 0"):
        ablation.parse_config("c:0.1:0.1:4:2.0:0::::1:on")


def test_word_valued_config_fields_are_set_and_checked():
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:human_replan_blocked=off+human_door_entries")
    assert ablation.env_overrides(cfg["env_flags"]) == {"human_replan_blocked": "off", "human_door_entries": True}
    with pytest.raises(ValueError, match="human_replan_blocked"):
        ablation.parse_config("c:0.1:0.1:4:2.0:human_replan_blocked=sometimes")
    with pytest.raises(ValueError, match="human_door_entries must be a bool, got 'yes'"):
        ablation.parse_config("c:0.1:0.1:4:2.0:human_door_entries=yes")
    with pytest.raises(ValueError, match="boolean"):
        ablation.parse_config("c:0.1:0.1:4:2.0:human_replan_blocked")
    # a field that is a bool or None (None: on for AMP pedestrians) turns on by name, and off as name=false
    assert ablation.env_overrides(ablation.parse_config("c:0.1:0.1:4:2.0:human_door_turns")["env_flags"]) == \
        {"human_door_turns": True}
    assert ablation.env_overrides(ablation.parse_config("c:0.1:0.1:4:2.0:human_door_turns=false")["env_flags"]) == \
        {"human_door_turns": False}


def test_numeric_and_boolean_config_fields_take_their_types():
    """``name=value`` in the FALLEN field is read as ``--set`` values are: numbers and true/false typed, words kept."""
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:amp_wall_strength=0.3+human_door_entries=false+human_at_goal=stop")
    assert ablation.env_overrides(cfg["env_flags"]) == {"amp_wall_strength": 0.3, "human_door_entries": False,
                                                        "human_at_goal": "stop"}
    with pytest.raises(ValueError, match="amp_wall_strength must be None or a finite number > 0, got -1"):
        ablation.parse_config("c:0.1:0.1:4:2.0:amp_wall_strength=-1")
    with pytest.raises(ValueError, match="unknown NavConfig field.*amp_wall_strenght"):
        ablation.parse_config("c:0.1:0.1:4:2.0:amp_wall_strenght=0.3")
    with pytest.raises(ValueError, match="set by the following protocol"):
        ablation.parse_config("c:0.1:0.1:4:2.0:n_humans=4")


def test_kinematic_body_runs_are_their_own_sample(tmp_path):
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:human_replan_blocked=all")
    rows = [_row(cfg, "lobby", 0, "sfm", bodies="kinematic", pedestrians=15),
            _row(cfg, "lobby", 0, "sfm", success=5, pedestrians=15)]
    assert ablation.done_runs(rows, [cfg]) == {("c", "sfm", "{}", 0, "kinematic", "lobby"),
                                              ("c", "sfm", "{}", 0, "amp", "lobby")}
    f = tmp_path / "rows.jsonl"
    f.write_text("".join(json.dumps(r) + "\n" for r in rows))
    for by_scene in (False, True):
        lines = ablation.summary(str(f), by_scene=by_scene).splitlines()[2:]
        assert len(lines) == 2 and sum("[kinematic bodies]" in line for line in lines) == 1
    rows[0]["err_n"] = rows[0]["err_sum"] = 0  # no target trajectory to measure a path error against
    f.write_text("".join(json.dumps(r) + "\n" for r in rows))
    lines = ablation.summary(str(f)).splitlines()[2:]
    assert [line.split("|")[9].strip() == "n/a" for line in lines] == [True, False]  # the path error column


def test_the_keep_and_diffusion_speed_cap_fields():
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::1::1")["keep"] is True
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::1.1")
    assert cfg["dcap"] == 1.1 and cfg["keep"] is None
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::1::1")["dcap"] is None  # the module's default
    with pytest.raises(ValueError, match="DCAP"):
        ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::0")
    old, new = ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::1.3"), ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::1.0")
    row = {"config": "c", **{k: old[k] for k in ablation._PARAMS}, "seed": 0, "scene": "lobby"}
    with pytest.raises(ValueError, match="dcap"):
        ablation.done_runs([row], [new])


def test_the_target_speed_cap_field():
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0::::::::1.0")
    assert cfg["scap"] == 1.0 and cfg["dcap"] is None
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::1.0")["scap"] is None  # the module's default
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::::::0")["scap"] == 0.0  # off
    with pytest.raises(ValueError, match="SCAP"):
        ablation.parse_config("c:0.1:0.1:4:2.0:0::::::::-1")
    with pytest.raises(ValueError, match="a configuration is"):
        ablation.parse_config("c:0.1:0.1:4:2.0:0::::::::1.0:1:START_LAG=1:5")


def test_the_lag_field():
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::::1")["lag"] is True
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::::0")["lag"] is False
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0::::::::1.0")["lag"] is None  # the module's default
    with pytest.raises(ValueError, match="LAG"):
        ablation.parse_config("c:0.1:0.1:4:2.0:0:::::::::yes")


def test_the_set_field_takes_amp_humans_constants_by_type():
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0::::::::::START_LAG=1+START_REPLAN_S=0.7")
    assert cfg["set"] == {"START_LAG": True, "START_REPLAN_S": 0.7}
    for bad, match in (("NO_SUCH=1", "SET takes"), ("START_LAG=yes", "1 or 0"), ("START_REPLAN_S=soon", "float"),
                       ("START_LAG", "SET takes"), ("heading=1", "SET takes")):
        with pytest.raises(ValueError, match=match):
            ablation.parse_config("c:0.1:0.1:4:2.0:0::::::::::" + bad)


def test_the_pooled_summary_counts_trips_over_seeds_and_scenes(tmp_path, capsys):
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0")
    other = ablation.parse_config("d:0.1:0.1:4:2.0:0")
    rows = [_row(cfg, "lobby", 0, success=3, pedestrians=15), _row(cfg, "home", 1, success=1, pedestrians=5),
            _row(cfg, "lobby", 2, success=7, pedestrians=15), _row(other, "lobby", 0, success=0, pedestrians=15)]
    path = tmp_path / "rows.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in rows))
    table = ablation.summary(str(path), pooled=True).splitlines()
    assert len(table) == 4
    # trips are summed, not rates averaged: (3 + 1 + 7) successes of (4 + 2 + 8) trips
    assert table[2].startswith("| c, seeds 0,1,2 pooled (2 scenes) | 14 | 0.786 |")
    assert table[3].startswith("| d, seeds 0 pooled (1 scenes) | 1 | 0.000 |")
    kept = ablation.summary(str(path), pooled=True, seeds=[0, 1]).splitlines()
    assert kept[2].startswith("| c, seeds 0,1 pooled (2 scenes) | 6 | 0.667 |")
    with pytest.raises(ValueError, match="no rows of seed"):
        ablation.summary(str(path), seeds=[5])
    with pytest.raises(ValueError, match="one of by_scene and pooled"):
        ablation.summary(str(path), by_scene=True, pooled=True)
    with pytest.raises(SystemExit):
        ablation.main(["--summary", str(path), "--summary-seeds", "7"])
    assert "no rows of seed(s) 7" in capsys.readouterr().err
    assert ablation.main(["--summary", str(path), "--pooled", "--summary-seeds", "2"]) == 0
    assert "| c, seeds 2 pooled (1 scenes) | 8 | 0.875 |" in capsys.readouterr().out
    # --summary-scenes: one scene set ('protocol', 'heldout' or names); a scene the files lack is refused
    assert ablation.summary(str(path), pooled=True, scenes=("home",)).splitlines()[2].startswith(
        "| c, seeds 1 pooled (1 scenes) | 2 | 0.500 |")
    assert ablation.main(["--summary", str(path), "--pooled", "--summary-scenes", "protocol"]) == 0
    assert "| c, seeds 0,1,2 pooled (2 scenes) | 14 |" in capsys.readouterr().out
    assert ablation.summary(str(path), scenes=("lobby", "bottleneck")) == ablation.summary(str(path), scenes=("lobby",))
    with pytest.raises(ValueError, match="no rows of scene.*bottleneck"):
        ablation.summary(str(path), scenes=("bottleneck",))
    with pytest.raises(SystemExit):
        ablation.main(["--summary", str(path), "--summary-scenes", "heldout"])
    assert "l_corridor" in capsys.readouterr().err
    # the contact-time column: n/a for rows without contact_steps, else the pooled shares of standing time
    assert table[2].endswith("| n/a |")
    timed = [_row(cfg, "lobby", 0, success=3, pedestrians=15, contact_steps=[10, 30, 1000]),
             _row(cfg, "home", 1, success=1, pedestrians=5, contact_steps=[30, 10, 1000])]
    path.write_text("".join(json.dumps(r) + "\n" for r in timed))
    assert ablation.summary(str(path), pooled=True).splitlines()[2].endswith("| 0.0200 / 0.0200 |")


def test_a_summary_of_several_files_counts_a_repeated_run_once_and_refuses_a_different_one(tmp_path, capsys):
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0")
    first, second, clash = tmp_path / "a.jsonl", tmp_path / "b.jsonl", tmp_path / "c.jsonl"
    first.write_text(json.dumps(_row(cfg, "lobby", 0, success=3)) + "\n" + json.dumps(_row(cfg, "home", 0, success=1)))
    # the lobby run again (another machine repeats it trip for trip, path error to rounding) and a new seed
    again = _row(cfg, "lobby", 0, success=3, err_sum=1.0 + 1e-12)
    second.write_text(json.dumps(again) + "\n" + json.dumps(_row(cfg, "lobby", 1, success=5)) + "\n")
    table = ablation.summary([str(first), str(second)], pooled=True).splitlines()
    # (3 + 1 + 5) successes of (4 + 2 + 6) trips: the repeated lobby run counted once
    assert table[2].startswith("| c, seeds 0,1 pooled (2 scenes) | 12 | 0.750 |")
    assert ablation.summary(str(first), pooled=True) == ablation.summary([str(first), str(first)], pooled=True)
    clash.write_text(json.dumps(_row(cfg, "lobby", 0, success=4)) + "\n")
    with pytest.raises(ValueError, match=r"seed 0 lobby is in .*a\.jsonl and .*c\.jsonl with different counts"):
        ablation.summary([str(first), str(clash)])
    # rows that record their CPU say so when two of them differ
    first.write_text(json.dumps(_row(cfg, "lobby", 0, success=3, cpu="Intel Xeon")) + "\n")
    clash.write_text(json.dumps(_row(cfg, "lobby", 0, success=4, cpu="AMD EPYC")) + "\n")
    with pytest.raises(ValueError, match=r"not the same run \(run on different CPUs: (Intel Xeon and AMD EPYC|AMD EPYC and Intel Xeon)\)"):
        ablation.summary([str(first), str(clash)])
    # rows that record their packages name the versions that differ when the CPUs do not
    pk = {"python": "3.11.7", "numpy": "2.4.6", "scipy": "1.17.1", "torch": "2.13.0", "pybullet": "3.2.7"}
    first.write_text(json.dumps(_row(cfg, "lobby", 0, success=3, cpu="AMD EPYC", packages=pk)) + "\n")
    clash.write_text(json.dumps(_row(cfg, "lobby", 0, success=4, cpu="AMD EPYC",
                                     packages={**pk, "numpy": "2.4.7"})) + "\n")
    with pytest.raises(ValueError, match=r"not the same run \(run with different packages: numpy 2\.4\.6 and 2\.4\.7\)"):
        ablation.summary([str(first), str(clash)])
    with pytest.raises(SystemExit):
        ablation.main(["--summary", str(first), str(tmp_path / "missing.jsonl")])
    assert "missing.jsonl" in capsys.readouterr().err


def test_scenes_outside_the_protocol_need_a_people_count():
    from navzoo.benchmark.pedestrians import HELDOUT_SCENES, SCENES

    assert list(ablation.parse_scenes(None)) == list(SCENES)
    assert ablation.parse_scenes("lobby,home") == {"lobby": 15, "home": 5}  # the protocol's own counts
    assert ablation.parse_scenes("bottleneck:7,lobby:4") == {"bottleneck": 7, "lobby": 4}
    assert ablation.parse_scenes("heldout") == dict(HELDOUT_SCENES)
    with pytest.raises(ValueError, match="'bottleneck'.*bottleneck:N"):
        ablation.parse_scenes("bottleneck")
    with pytest.raises(ValueError, match="unknown scene 'atlantis'"):
        ablation.parse_scenes("atlantis:4")
    with pytest.raises(ValueError, match="integer, got 'x'"):
        ablation.parse_scenes("bottleneck:x")
    with pytest.raises(ValueError, match="at least 1"):
        ablation.parse_scenes("bottleneck:0")
    with pytest.raises(ValueError, match="'bottleneck' given with 7 and 9"):
        ablation.parse_scenes("heldout,bottleneck:9")


def test_held_out_scenes_are_outside_everything_tuned_on():
    from navzoo.benchmark.pedestrians import HELDOUT_SCENES, SCENES, people_per_scene
    from navzoo.world.library import list_scenes

    names = [s for s, _ in HELDOUT_SCENES]
    assert set(names) <= set(list_scenes()) and not set(names) & set(SCENES)
    # the scenes of the AMP controller's scene training (runs 26-35, training/amp_scenes and training/amp_stance_scenes)
    scene_training = {"apartment", "kitchen", "studio_flat", "cafe", "office_floor", "office_open", "hospital_corridor",
                      "school_corridor", "campus_plaza", "waiting_room", "convenience_store", "shopping_mall",
                      "airport_gate", "train_platform", "two_doors", "x_junction"}
    assert not set(names) & scene_training
    assert [n for _, n in HELDOUT_SCENES] == people_per_scene(len(HELDOUT_SCENES))


def test_a_scene_rerun_with_another_people_count_is_refused(tmp_path):
    cfg = ablation.parse_config("c:0.1:0.1:4:2.0:0")
    out = tmp_path / "rows.jsonl"
    out.write_text(json.dumps(_row(cfg, "bottleneck", 0, pedestrians=7)) + "\n")
    ablation.check_people([_row(cfg, "bottleneck", 0, pedestrians=7)], [cfg], {"bottleneck": 7})
    with pytest.raises(ValueError, match="'bottleneck' is in the result file with 7 people.*asked for 9"):
        ablation.check_people([_row(cfg, "bottleneck", 0, pedestrians=7)], [cfg], {"bottleneck": 9})
    other = ablation.parse_config("d:0.1:0.1:4:2.0:0")
    ablation.check_people([_row(cfg, "bottleneck", 0, pedestrians=7)], [other], {"bottleneck": 9})
    with pytest.raises(SystemExit):
        ablation.main(["--configs", "c:0.1:0.1:4:2.0:0", "--scenes", "bottleneck:9", "--out", str(out)])


def test_rows_record_whether_people_plan_around_fallen_bodies():
    # left out or 0: NavConfig's default, on since 2026-12-06; rows record the value the run used
    assert ablation.parse_config("c:0.1:0.1:4")["fallen_obstacles"] is True
    assert ablation.parse_config("c:0.1:0.1:4:2.0:0")["fallen_obstacles"] is True
    assert ablation.parse_config("c:0.1:0.1:4:2.0:1")["fallen_obstacles"] is True
    assert ablation.parse_config("c:0.1:0.1:4:2.0:human_door_turns")["fallen_obstacles"] is True
    off = ablation.parse_config("c:0.1:0.1:4:2.0:human_door_turns+human_fallen_obstacles=false")
    assert off["fallen_obstacles"] is False
    assert ablation.env_overrides(off["env_flags"])["human_fallen_obstacles"] is False
