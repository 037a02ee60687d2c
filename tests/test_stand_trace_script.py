"""scripts/amp_stand_trace.py: where and why physics pedestrians stand."""

from __future__ import annotations

import numpy as np
import pytest

from tests.script_modules import load_script

st = load_script("amp_stand_trace")


def _sample(**kw):
    base = {"speed": 0.0, "target_m": 1.0, "target_speed": 0.5, "wall": False, "nearest_m": 3.0, "clearance": 1.0}
    return {**base, **kw}


def test_each_standing_sample_gets_the_first_matching_cause():
    assert st.classify(_sample(target_m=0.2, target_speed=0.05, wall=True), 0.15) == "target stands"
    assert st.classify(_sample(target_m=0.2, target_speed=0.5, wall=True), 0.15) == "wall contact"  # target moves on
    assert st.classify(_sample(nearest_m=0.5), 0.15) == "person near"
    assert st.classify(_sample(), 0.15) == "held, no contact"


def test_summary_shares_split_into_narrow_and_open():
    samples = [dict(_sample(), cause=None, narrow=False),
               dict(_sample(), cause="target stands", narrow=True),
               dict(_sample(), cause="target stands", narrow=False),
               dict(_sample(), cause="person near", narrow=True)]
    s = st.summarize(samples)
    assert s["samples"] == 4 and s["standing_share"] == pytest.approx(0.75)
    ts = s["causes"]["target stands"]
    assert ts["share_of_person_time"] == pytest.approx(0.5) and ts["narrow"] == ts["open"] == pytest.approx(0.25)
    assert s["causes"]["wall contact"]["share_of_person_time"] == 0.0
    assert s["walls"] == {"contact_share": 0.0, "passing": 0.0, "alone": 0.0, "standing": 0.0}


def test_standing_samples_split_by_where_their_target_points_lie():
    samples = [dict(_sample(target_bearing_deg=170.0, target_points_m=0.3), cause="target stands", narrow=True),
               dict(_sample(target_bearing_deg=-100.0, target_points_m=0.5), cause="person near", narrow=False),
               dict(_sample(target_bearing_deg=60.0, target_points_m=0.4), cause="person near", narrow=False),
               dict(_sample(target_bearing_deg=-170.0), cause=None, narrow=False)]  # walking: not counted
    f = st.summarize(samples)["facing"]
    assert f["behind"] == pytest.approx(0.5) and f["side"] == pytest.approx(0.25) and f["ahead"] == 0.0
    assert f["target_points_m"] == pytest.approx(0.4)


def test_constants_are_checked_and_typed():
    assert st.parse_const(["STALL_WARP_S=1", "GRADED_WALL_MARGIN=0", "WAYPOINT_LOOKAHEAD=2"]) == {
        "STALL_WARP_S": 1.0, "GRADED_WALL_MARGIN": False, "WAYPOINT_LOOKAHEAD": 2}
    with pytest.raises(ValueError, match="upper-case constant"):
        st.parse_const(["NOT_A_CONSTANT=1"])
    with pytest.raises(ValueError, match="not a number"):
        st.parse_const(["STALL_WARP_S=soon"])


def test_wall_contacts_split_by_a_person_within_passing_range():
    samples = [dict(_sample(wall=True, nearest_m=0.8), cause=None, narrow=True),         # passing, walking
               dict(_sample(wall=True, nearest_m=st.PASSING_M + 0.1), cause=None, narrow=True),  # alone
               dict(_sample(wall=True, nearest_m=1.0), cause="wall contact", narrow=True),  # queued against the wall
               dict(_sample(), cause=None, narrow=False)]
    w = st.summarize(samples)["walls"]
    assert w == {"contact_share": 0.75, "passing": 0.5, "alone": 0.25, "standing": 0.25}


def test_a_short_trace_of_physics_pedestrians(tmp_path):
    r = st.trace("corridor", 2, "sfm", 2.0, 0, 0.5, 0.15, env_overrides={"amp_wall_strength": 0.3})
    assert r["env_overrides"] == {"amp_wall_strength": 0.3}
    assert r["samples"] and {s["id"] for s in r["samples"]} == {0, 1}
    assert len(r["samples"]) == 2 * 4  # two people, every 0.5 s of 2 s
    total = sum(c["share_of_person_time"] for c in r["summary"]["causes"].values())
    assert total == pytest.approx(r["summary"]["standing_share"])
    assert all((s["cause"] is None) == (s["speed"] >= 0.15) for s in r["samples"])
    assert all(-180.0 <= s["target_bearing_deg"] <= 180.0 and s["target_points_m"] >= 0 for s in r["samples"])
    assert set(r["summary"]["facing"]) == {"behind", "side", "ahead", "target_points_m"}
    assert all(len(s["goal"]) == 2 and len(s["waypoint"]) == 2 for s in r["samples"])
    assert all(s["door_state"] in ("none", "held", "waits", "against", "free") for s in r["samples"])  # AMP: door turns on
    assert 0.0 <= r["summary"]["standing_waypoint_hidden"] <= r["summary"]["waypoint_hidden"] <= 1.0
    st.plot(r, str(tmp_path / "t.png"))
    assert (tmp_path / "t.png").stat().st_size > 1000
    st.plot_contacts([r, r], str(tmp_path / "c.png"))
    assert (tmp_path / "c.png").stat().st_size > 1000


def test_a_window_of_samples_is_summarized_again():
    samples = [dict(_sample(target_speed=0.02, nearest_m=1.4), t=150.0, id=5, cause="target stands", narrow=True),
               dict(_sample(target_speed=0.5), t=50.0, id=5, cause=None, narrow=False),
               dict(_sample(target_speed=0.1, nearest_m=0.6), t=150.0, id=2, cause="person near", narrow=False)]
    late = st.window(samples, after=100.0)
    assert [s["id"] for s in late] == [5, 2]
    assert st.window(samples, after=100.0, people=[5]) == samples[:1]
    s = st.summarize(st.window(samples, people=[5]))
    assert s["standing_share"] == pytest.approx(0.5)
    assert s["standing_medians"] == {"target_speed": pytest.approx(0.02), "nearest_m": pytest.approx(1.4)}


def test_a_box_keeps_the_samples_inside_it():
    samples = [dict(_sample(), x=25.0, y=5.0, t=1.0, id=0, cause="target stands", narrow=True),
               dict(_sample(), x=25.0, y=3.0, t=1.0, id=1, cause=None, narrow=False),
               dict(_sample(), x=28.0, y=6.2, t=1.0, id=2, cause=None, narrow=False)]
    assert [s["id"] for s in st.window(samples, box=(23.9, 4.5, 27.8, 6.2))] == [0]
    assert [s["id"] for s in st.window(samples, box=(23.9, 4.5, 28.0, 6.2))] == [0, 2]  # edges count
    assert len(st.window(samples)) == 3


def test_door_state_of_a_person_at_a_door():
    from navzoo.agents.door_turns import DoorTurns

    turns = DoorTurns(3, lambda p: np.full(len(p), 2.0))  # open floor: both sides have waiting spots
    door = (np.array([0.0, 0.0]), np.array([1.0, 0.0]))
    for j in range(3):
        turns.set_route(j, [door])
    turns.set_route(2, [(door[0], -door[1])])  # person 2 crosses the other way
    pos = np.array([[-1.0, 0.0], [-2.0, 0.3], [2.0, 0.0]])
    turns.update(0.0, pos)
    assert st.door_state(None, 0, pos[0]) == {}
    s0, s1, s2 = (st.door_state(turns, j, pos[j]) for j in range(3))
    assert s0 == {"door": 0, "door_m": pytest.approx(1.0), "door_state": "held", "door_room": True}
    assert s1["door_state"] == "held"  # follows the first through, the same way
    assert s2["door_state"] == "waits"  # asked from the other side and was not granted
    far = np.array([9.0, 0.0])
    turns2 = DoorTurns(1, lambda p: np.full(len(p), 2.0))
    turns2.update(0.0, far[None])
    assert st.door_state(turns2, 0, far)["door_state"] == "none"


def test_standing_samples_near_doors_are_split_by_door_state():
    samples = [dict(_sample(door=0, door_m=1.0, door_state="waits", door_room=True), cause="target stands", narrow=True),
               dict(_sample(door=0, door_m=1.0, door_state="held", door_room=False), cause="person near", narrow=True),
               dict(_sample(door=0, door_m=9.0, door_state="free", door_room=True), cause="person near", narrow=False),
               dict(_sample(door=-1, door_m=float("inf"), door_state="none", door_room=False), cause=None,
                    narrow=False)]
    d = st.summarize(samples)["doors"]
    assert d["standing_near_door"] == pytest.approx(0.5)
    assert d["waits, room"] == pytest.approx(0.25) and d["held, no room"] == pytest.approx(0.25)
    assert d["free, room"] == 0.0  # standing, but beyond DOOR_NEAR_M
    assert "doors" not in st.summarize([dict(_sample(), cause=None, narrow=False)])  # door turns off


def test_a_waypoint_behind_a_wall_is_hidden():
    # the doorway scene: a wall with one door across the middle (x = 8 m); a waypoint straight across the wall is
    # hidden, one on the same side is not; samples without a waypoint get None
    from navzoo.world.library import get_scene

    scene = get_scene("doorway")
    assert scene is not None
    samples = [dict(x=6.0, y=1.0, waypoint=[10.0, 1.0], cause="target stands"),
               dict(x=6.0, y=1.0, waypoint=[6.0, 2.5], cause=None),
               dict(x=6.0, y=1.0, cause=None)]
    hidden = st.waypoint_hidden("doorway", samples)
    assert hidden == [True, False, None]
    assert st.sight_summary(samples, hidden) == {"waypoint_hidden": pytest.approx(1 / 3),
                                                 "standing_waypoint_hidden": pytest.approx(1 / 3)}
