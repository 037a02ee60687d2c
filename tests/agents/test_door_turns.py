"""Door turns (navzoo.agents.door_turns): one way at a time, queues, waiting spots, lapses, and the env."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.crowd import CrowdPolicy
from navzoo.agents.door_turns import DoorParams, DoorTurns
from navzoo.envs.config import NavConfig
from navzoo.envs.doors import path_doors
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents
from navzoo.world.library import get_scene
from navzoo.world.occupancy import OccupancyGrid

CENTRE = np.array([0.0, 0.0])
AXIS = np.array([1.0, 0.0])  # the door in a wall along x = 0; crossing +x is sign +1


def _open(points: np.ndarray) -> np.ndarray:
    return np.full(len(points), 5.0)  # no wall near any waiting spot


def _turns(n: int, **kw) -> DoorTurns:
    dt = DoorTurns(n, _open, DoorParams(**kw))
    for j in range(n):
        dt.set_route(j, [])
    return dt


def test_one_way_at_a_time_and_the_same_way_follows():
    dt = _turns(3)
    east = [(CENTRE, AXIS)]
    west = [(CENTRE, -AXIS)]
    dt.set_route(0, east)
    dt.set_route(1, east)
    dt.set_route(2, west)
    pos = np.array([[-1.8, 0.0], [-2.3, 0.1], [1.9, 0.0]])  # all within reach of the door
    new = dt.update(0.0, pos)
    # the first to ask (ties: person order) is granted; the one behind it goes the same way and follows
    assert dt.granted[0] == 0 and dt.granted[1] == 0 and new[:2].all()
    assert dt.granted[2] == -1 and dt.waiting()[2]
    pref = np.array([[1.0, 0.0], [1.0, 0.0], [-1.0, 0.0]])
    out = dt.apply(pos, pref, np.ones(3))
    np.testing.assert_allclose(out[:2], pref[:2])  # holders keep their way
    spot = dt.spot(0, -1)
    assert spot[0] > 0.5 and abs(spot[1]) >= 1.0 - 1e-9  # the waiter's spot: on its side, out of the lane
    assert out[2] @ (spot - pos[2]) > 0  # and it walks there
    # once both are through (0.5 m beyond the centre), the door turns round
    pos[0], pos[1] = [0.8, 0.0], [0.7, 0.0]
    dt.update(1.0, pos)
    assert dt.granted[0] == -1 and dt.granted[1] == -1 and dt.k[0] == 1
    assert dt.granted[2] == 0


def test_waiting_person_stands_still_at_its_spot():
    dt = _turns(2)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    pos = np.array([[-0.9, 0.0], [2.0, 0.0]])
    dt.update(0.0, pos)
    assert dt.waiting()[1]
    pos[1] = dt.spot(0, -1)
    out = dt.apply(pos, np.array([[1.0, 0.0], [-1.0, 0.0]]), np.ones(2))
    np.testing.assert_allclose(out[1], 0.0)


def test_the_other_side_gets_the_door_after_platoon_s():
    dt = _turns(3, platoon_s=2.0)
    for j in range(2):
        dt.set_route(j, [(CENTRE, AXIS)])
    dt.set_route(2, [(CENTRE, -AXIS)])
    pos = np.array([[-2.0, 0.0], [-2.45, 0.0], [2.0, 0.0]])
    dt.update(0.0, pos)
    assert dt.granted[0] == 0 and dt.waiting()[2]
    dt.set_route(1, [(CENTRE, AXIS)])  # a new path: it asks again, after the west-bound person
    dt.update(2.5, pos)  # the other side has waited 2.5 s > platoon_s: no more grants eastward
    assert dt.granted[1] == -1 and dt.waiting()[1]
    pos[0] = [0.8, 0.0]  # the holder is through
    dt.update(3.0, pos)
    assert dt.granted[2] == 0 and dt.granted[1] == -1


def test_grant_lapses_and_queue_order():
    dt = _turns(2, grant_max_s=3.0)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    pos = np.array([[-2.0, 0.0], [2.0, 0.0]])
    dt.update(0.0, pos)
    assert dt.granted[0] == 0
    dt.update(3.5, pos)  # person 0 did not move: its grant lapses, it asks anew behind person 1
    assert dt.granted[0] == -1 and dt.granted[1] == 0


def test_someone_in_the_door_holds_it_and_inactive_people_let_go():
    dt = _turns(2)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    pos = np.array([[-0.3, 0.0], [2.0, 0.0]])
    dt.update(0.0, pos)
    assert dt.granted[0] == 0
    dt.update(0.1, pos, active=np.array([False, True]))  # person 0 fell in the door
    assert dt.granted[0] == -1 and dt.granted[1] == 0


def test_rollout_positions_wait_at_a_door_held_against_them():
    dt = _turns(2)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    dt.update(0.0, np.array([[-1.0, 0.0], [6.0, 0.0]]))  # person 1 is far: not asking yet
    assert dt.granted[0] == 0 and not dt.waiting()[1]
    pref = np.array([[1.0, 0.0], [-1.0, 0.0]])
    far = dt.apply(np.array([[-1.0, 0.0], [6.0, 0.0]]), pref, np.ones(2))
    np.testing.assert_allclose(far, pref)
    near = dt.apply(np.array([[-1.0, 0.0], [2.2, 0.0]]), pref, np.ones(2))  # rolled out to the door
    assert not np.allclose(near[1], pref[1])


@pytest.mark.parametrize("lateral", [None, 1.0])
def test_one_pushed_aside_beyond_the_door_is_through_only_without_passed_lateral(lateral):
    dt = _turns(2, passed_lateral=lateral)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    # person 0 (eastward) stands 0.8 m beyond the door's line but 1.5 m to its side, still west of the wall's door
    pos = np.array([[0.8, 1.5], [2.0, 0.0]])
    dt.update(0.0, pos)
    if lateral is None:
        assert dt.k[0] == 1 and dt._cur[0] == -1  # taken as through, it drops the door it never crossed
    else:
        assert dt.k[0] == 0 and dt._cur[0] == 0 and dt.granted[0] == 0  # it still asks for the door
    # through the door's throat it is through either way
    pos[0] = [0.7, 0.2]
    dt.update(0.5, pos)
    assert dt.k[0] == 1 and dt.granted[0] == -1


@pytest.mark.parametrize("slope", [None, 0.35])
def test_a_holder_beside_the_door_heads_for_its_axis_first_only_with_line_up(slope):
    dt = _turns(2, line_up=slope)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, AXIS)])
    # both hold the door (the same way); person 0 stands 0.5 m before it and 1.0 m to its side (off its waiting
    # spot, aiming at the door's middle), person 1 comes along the axis
    pos = np.array([[-0.5, -1.0], [-1.5, 0.1]])
    dt.update(0.0, pos)
    assert dt.granted[0] == 0 and dt.granted[1] == 0
    pref = (CENTRE - pos) / np.linalg.norm(CENTRE - pos, axis=1, keepdims=True)  # straight at the door's middle
    out = dt.apply(pos, pref, np.ones(2))
    np.testing.assert_allclose(out[1], pref[1])  # inside the cone: its own way
    if slope is None:
        np.testing.assert_allclose(out[0], pref[0])
    else:  # toward the line-up point 1 m before the centre on the axis, at its preferred speed
        to = np.array([-1.0, 0.0]) - pos[0]
        np.testing.assert_allclose(out[0], to / np.linalg.norm(to))
        # once inside the cone it goes its own way again; so does one who does not hold the door
        inside = np.array([[-0.9, -0.25], [-1.5, 0.1]])
        np.testing.assert_allclose(dt.apply(inside, pref, np.ones(2)), pref)
    dt2 = _turns(2, line_up=slope)
    dt2.set_route(0, [(CENTRE, AXIS)])
    dt2.set_route(1, [(CENTRE, -AXIS)])
    dt2.update(0.0, np.array([[-3.0, 0.0], [2.0, 0.0]]))  # person 1 holds the door westward, person 0 still far
    dt2.update(0.1, np.array([[-0.5, -1.0], [0.3, 0.0]]))  # person 0 asks, the door is held against it
    assert dt2.granted[0] == -1
    away = dt2.apply(np.array([[-0.5, -1.0], [0.3, 0.0]]), np.array([[1.0, 0.0], [-1.0, 0.0]]), np.ones(2))
    spot = dt2.spot(0, 1)
    assert away[0] @ (spot - np.array([-0.5, -1.0])) > 0  # a waiter walks to its spot, not to the axis


def test_holder_waiter_pairs_name_the_holder_of_the_door_each_waiter_waits_for():
    dt = _turns(4)
    other = (np.array([0.0, 6.0]), AXIS)  # a second door, far from the first
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    dt.set_route(2, [other])
    dt.set_route(3, [(other[0], -AXIS)])
    pos = np.array([[-1.8, 0.0], [1.9, 0.0], [-1.8, 6.0], [1.9, 6.0]])
    dt.update(0.0, pos)
    assert list(dt.granted) == [0, -1, 1, -1] and list(dt.waiting()) == [False, True, False, True]
    pairs = dt.holder_waiter_pairs()
    expected = np.zeros((4, 4), dtype=bool)
    expected[0, 1] = expected[2, 3] = True  # each holder with the one waiting for its own door, not the other's
    np.testing.assert_array_equal(pairs, expected)
    pos[0] = [0.8, 0.0]  # through: it holds nothing any more, and the waiter gets the door
    dt.update(0.5, pos)
    assert not dt.holder_waiter_pairs()[:2].any()


def test_amp_holders_pass_the_people_waiting_for_their_door_only_with_the_option(monkeypatch):
    """DOOR_PASS_WAITERS: the target rollout of a person who holds the doorway's door goes straight through and on,
    where the repulsion of the person waiting 1 m beside its lane beyond the door pushes it aside and slows it."""
    from navzoo.envs import amp_humans

    assert amp_humans.DOOR_PASS_WAITERS is False  # off by default

    def holder_path(on: bool) -> np.ndarray:
        monkeypatch.setattr(amp_humans, "DOOR_PASS_WAITERS", on)
        env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp", crowd_model="sfm", dt=1 / 30,
                     time_limit=10.0)
        try:
            env.reset(seed=0, options={"human_starts": [[6.2, 4.0], [10.3, 4.0]],
                                       "human_goals": [[12.0, 4.0], [4.0, 4.0]]})
            assert list(env.door_turns.granted) == [0, -1] and env.door_turns.waiting()[1]
            return env.amp.paths[0].copy()
        finally:
            env.close()

    off, on = holder_path(False), holder_path(True)
    k = 3 * 30  # 3 s into the plan
    assert on[k, 0] > off[k, 0] + 0.1  # further along
    assert np.abs(on[:, 1] - 4.0).max() < 0.05 < np.abs(off[:, 1] - 4.0).max()  # on the door's line, not pushed off


def test_params_are_checked():
    with pytest.raises(ValueError, match="approach"):
        DoorParams(approach=-1.0)
    with pytest.raises(ValueError, match="passed_lateral"):
        DoorParams(passed_lateral=0.0)
    with pytest.raises(ValueError, match="line_up"):
        DoorParams(line_up=float("nan"))
    with pytest.raises(ValueError, match="line_up_back"):
        DoorParams(line_up_back=0.0)
    with pytest.raises(ValueError, match="wait"):
        DoorParams(wait=3.0, approach=2.5)
    with pytest.raises(ValueError, match="human_door_turns"):
        NavConfig(human_door_turns=1)


def test_path_doors_finds_real_doors_only():
    grid = OccupancyGrid.from_scene(get_scene("doorway"))
    path = np.array([[4.0, 4.0], [8.0, 4.0], [12.0, 4.0]])
    doors = path_doors(path, np.array([3.0, 4.0]), grid, two_sided=True, end_margin=0.7)
    assert len(doors) == 1
    c, a, _ = doors[0]
    assert abs(c[0] - 8.0) < 0.2 and abs(c[1] - 4.0) < 0.3 and a[0] > 0.99
    along_wall = np.array([[12.0, 0.5], [15.5, 0.5], [15.5, 7.0]])  # hugging the walls, through no door
    assert path_doors(along_wall, np.array([10.5, 0.5]), grid, two_sided=True, end_margin=0.7) == []


def test_a_door_entered_slantwise_is_found_on_its_jambs():
    # the warehouse's site office door (1.0 m, in a wall along y = 4.5), entered from the passage north of it: the
    # path's narrowest point lies 0.1 m inside the office, off the jamb line, where one side finds no jamb
    grid = OccupancyGrid.from_scene(get_scene("warehouse_aisles"))
    path = np.array([[22.38, 5.19], [24.31, 5.17], [25.77, 5.15], [26.25, 5.15], [26.45, 4.85], [26.55, 4.4],
                     [26.65, 3.95], [27.0, 3.85], [29.19, 3.51]])
    start = np.array([20.93, 5.2])
    assert path_doors(path, start, grid, two_sided=True, end_margin=0.7) == []
    doors = path_doors(path, start, grid, two_sided=True, end_margin=0.7, jamb_search=0.3)
    assert len(doors) == 1
    c, a, _ = doors[0]
    assert abs(c[0] - 26.55) < 0.1 and 4.4 < c[1] < 4.6  # moved onto the jamb line
    assert a[1] < -0.99  # crossed southward, into the office
    # too short a search still misses it; and it finds no door along a single wall, nor moves a door found before
    assert path_doors(path, start, grid, two_sided=True, end_margin=0.7, jamb_search=0.05) == []
    grid = OccupancyGrid.from_scene(get_scene("doorway"))
    along_wall = np.array([[12.0, 0.5], [15.5, 0.5], [15.5, 7.0]])
    assert path_doors(along_wall, np.array([10.5, 0.5]), grid, two_sided=True, end_margin=0.7, jamb_search=0.3) == []
    straight = np.array([[4.0, 4.0], [8.0, 4.0], [12.0, 4.0]])
    a0 = path_doors(straight, np.array([3.0, 4.0]), grid, two_sided=True, end_margin=0.7)
    a1 = path_doors(straight, np.array([3.0, 4.0]), grid, two_sided=True, end_margin=0.7, jamb_search=0.3)
    assert len(a0) == len(a1) == 1 and np.array_equal(a0[0][0], a1[0][0])


def test_a_door_entered_round_a_jambs_corner_is_found_by_the_run_scan():
    # a path planned in the doorway scene (seed 0): it comes diagonally from the south-west, hugs the south jamb's
    # corner and crosses the 1.0 m door at y = 3.95. Its narrowest point is at that corner, outside the door, where
    # the jamb cells give the wall's direction as the axis, so neither the narrowest point nor the jamb search finds
    # the door; the run scan takes the stretch's next narrowest points and finds it on the jamb line
    grid = OccupancyGrid.from_scene(get_scene("doorway"))
    start = np.array([4.69, 0.56])
    path = np.array([[5.3, 1.24], [5.61, 1.58], [5.91, 1.92], [6.22, 2.25], [6.52, 2.59], [6.83, 2.93], [7.14, 3.27],
                     [7.44, 3.61], [7.75, 3.95], [8.1, 3.95], [8.45, 3.95], [8.84, 3.69], [9.23, 3.43], [9.62, 3.17],
                     [10.01, 2.92], [10.4, 2.66], [10.79, 2.4], [11.18, 2.14], [11.57, 1.88], [11.96, 1.62]])
    kw = dict(two_sided=True, end_margin=0.7)
    assert path_doors(path, start, grid, **kw) == []
    assert path_doors(path, start, grid, jamb_search=0.3, **kw) == []
    doors = path_doors(path, start, grid, run_scan=True, **kw)
    assert len(doors) == 1
    c, a, _ = doors[0]
    assert abs(c[0] - 8.0) < 0.15 and 3.5 < c[1] < 4.5 and a[0] > 0.99  # on the door's line, crossed eastward
    # a door the narrowest point finds stays where it was, and no door appears along a single wall
    straight = np.array([[4.0, 4.0], [8.0, 4.0], [12.0, 4.0]])
    a0 = path_doors(straight, np.array([3.0, 4.0]), grid, **kw)
    a1 = path_doors(straight, np.array([3.0, 4.0]), grid, run_scan=True, **kw)
    assert len(a0) == len(a1) == 1 and np.array_equal(a0[0][0], a1[0][0])
    along_wall = np.array([[12.0, 0.5], [15.5, 0.5], [15.5, 7.0]])
    assert path_doors(along_wall, np.array([10.5, 0.5]), grid, run_scan=True, **kw) == []
    # a door at either end of the path is still left out, whichever of its points has the jambs
    assert path_doors(path[:9], start, grid, run_scan=True, **kw) == []


def test_the_run_scan_adds_no_passage_two_people_pass_in(monkeypatch):
    # the held-out bottleneck's passage is 1.2 m wide: two bodies pass each other there, and the run scan adds no
    # door in it, while without the width limit it would
    from navzoo.envs import doors

    grid = OccupancyGrid.from_scene(get_scene("bottleneck"))
    kw = dict(two_sided=True, end_margin=0.7, run_scan=True)
    starts = [np.array([4.0, y]) for y in np.linspace(1.5, 6.5, 11)]
    goal = np.array([11.0, 4.0])
    paths = [np.array([[6.5, 4.0 + 0.6 * (s[1] - 4.0) / 2.5], [7.0, 3.9], [8.5, 4.1], goal]) for s in starts]
    plain = [path_doors(p, s, grid, two_sided=True, end_margin=0.7) for s, p in zip(starts, paths, strict=True)]
    scanned = [path_doors(p, s, grid, **kw) for s, p in zip(starts, paths, strict=True)]
    assert [len(x) for x in scanned] == [len(x) for x in plain]
    monkeypatch.setattr(doors, "DOOR_SCAN_MAX_WIDTH", 2.0)
    wide = [path_doors(p, s, grid, **kw) for s, p in zip(starts, paths, strict=True)]
    assert sum(len(x) for x in wide) > sum(len(x) for x in plain)


def test_the_jamb_search_option_reaches_the_door_turns_of_physics_pedestrians(monkeypatch):
    from navzoo.envs import amp_humans, nav_env

    seen = []

    def spy(*args, **kw):
        seen.append((kw.get("jamb_search"), kw.get("run_scan")))
        return []

    monkeypatch.setattr(nav_env, "path_doors", spy)
    monkeypatch.setattr(amp_humans, "DOOR_JAMB_SEARCH", 0.3)
    monkeypatch.setattr(amp_humans, "DOOR_RUN_SCAN", True)
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="kinematic", human_door_turns=True)
    env.reset(seed=0)
    assert seen and set(seen) == {(0.0, False)}  # kinematic crowds: never
    env.close()
    seen.clear()
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp")  # door turns on by default
    env.reset(seed=0)
    assert seen and set(seen) == {(0.3, True)}
    env.close()
    # the run scan: on by default with diffusion targets only (DIFFUSION_DOOR_RUN_SCAN), DOOR_RUN_SCAN for the others
    monkeypatch.setattr(amp_humans, "DOOR_RUN_SCAN", False)
    for crowd, want in (("sfm", False), ("diffusion", True)):
        seen.clear()
        env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp", crowd_model=crowd, time_limit=5.0)
        env.reset(seed=0)
        assert seen and {r for _, r in seen} == {want}, crowd
        env.close()
    monkeypatch.setattr(amp_humans, "DIFFUSION_DOOR_RUN_SCAN", False)
    seen.clear()
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp", crowd_model="diffusion", time_limit=5.0)
    env.reset(seed=0)
    assert seen and {r for _, r in seen} == {False}
    env.close()


def _goals(scene: str, n: int, doors: bool, seconds: float) -> tuple[int, int]:
    env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model="sfm", time_limit=seconds, human_door_turns=doors)
    w = FrozenAgents(env, lambda a: a.startswith("human_"), CrowdPolicy("sfm"))
    w.reset(seed=0)
    while not env._needs_reset:
        w.step({})
    found = env.door_turns.n_doors if doors else 0
    w.close()
    return int(env.goals_reached.sum()), found


def test_doorway_crowd_reaches_more_goals_with_door_turns():
    off, _ = _goals("doorway", 13, False, 60.0)
    on, found = _goals("doorway", 13, True, 60.0)
    assert found == 1
    assert on >= off + 3, (off, on)


def test_open_scene_finds_no_doors_and_is_unchanged():
    assert _goals("square_crossing", 6, False, 20.0)[0] == _goals("square_crossing", 6, True, 20.0)[0]


def test_waiting_spots_stay_on_the_door_side_and_off_narrow_corridors():
    grid = OccupancyGrid.from_scene(get_scene("home"))
    dt = DoorTurns(1, grid.distance_at)
    door, sign = dt.door_id(np.array([3.45, 6.0]), np.array([0.0, -1.0]))  # living-room door, crossed southward
    assert sign == 1
    assert not dt.can_queue(door, 1)  # from the 1.28 m corridor: nowhere to wait out of the way
    assert dt.can_queue(door, -1)
    spots = dt.spots(door, -1)
    assert (spots[:, 1] < 6.0).all()  # in the living room, not seen through the wall in another room
    assert (grid.distance_at(spots) >= dt.params.spot_clearance).all()
    dt.set_route(0, [(np.array([3.45, 6.0]), np.array([0.0, -1.0]))])
    dt.update(0.0, np.array([[3.45, 7.0]]))
    assert dt.granted[0] == door  # asking from the corridor side: granted at once


@pytest.mark.parametrize("passage_only", [False, True])
def test_a_table_beside_the_way_back_leaves_the_waiting_spots_only_with_spot_passage_only(passage_only):
    """DoorParams.spot_passage_only: the home's kitchen door (x = 8, y 2.5-3.4) seen from the living room has the
    dining table 0.4 m beside the way back to its spots; by default that refuses every spot (people from there take
    the door at once), with the option they wait beside it. The corridor side of the living-room door, a way back
    that runs into the bedroom's door across the corridor, has no spot either way."""
    grid = OccupancyGrid.from_scene(get_scene("home"))
    dt = DoorTurns(1, grid.distance_at, DoorParams(spot_passage_only=passage_only))
    kitchen, sign = dt.door_id(np.array([8.05, 2.95]), np.array([1.0, 0.0]))  # from the living room, eastward
    assert dt.can_queue(kitchen, sign) == passage_only
    if passage_only:
        spots = dt.spots(kitchen, sign)
        assert (spots[:, 0] < 8.0).all() and (grid.distance_at(spots) >= dt.params.spot_clearance).all()
    living, sign = dt.door_id(np.array([3.45, 6.0]), np.array([0.0, -1.0]))
    assert not dt.can_queue(living, sign) and dt.can_queue(living, -sign)


def test_door_turns_default_on_for_amp_pedestrians_only():
    assert NavConfig().door_turns is False
    assert NavConfig(human_model="amp").door_turns is True  # the default since 2026-12-06
    assert NavConfig(human_model="amp", human_door_turns=False).door_turns is False
    assert NavConfig(human_door_turns=True).door_turns is True
    env = NavEnv(scene="doorway", n_robots=0, n_humans=6, human_model="amp", crowd_model="sfm", time_limit=5.0)
    env.reset(seed=0)
    assert env.door_turns is not None and env.door_turns.n_doors == 1  # the AMP target rollouts wait their turn
    env.close()
    env = NavEnv(scene="doorway", n_robots=0, n_humans=6, human_model="amp", crowd_model="sfm", time_limit=5.0,
                 human_door_turns=False)
    env.reset(seed=0)
    assert env.door_turns is None
    env.close()


def _narrow_east(points: np.ndarray) -> np.ndarray:
    """A door between an open room (x < 0) and a narrow passage (x > 0.3): no waiting spot on the passage side."""
    return np.where(np.asarray(points)[:, 0] > 0.3, 0.2, 5.0)


@pytest.mark.parametrize("no_room_waits", [False, True])
def test_the_side_without_room_waits_only_with_no_room_waits(no_room_waits):
    dt = DoorTurns(2, _narrow_east, DoorParams(no_room_waits=no_room_waits))
    dt.set_route(0, [(CENTRE, AXIS)])  # from the room into the passage
    dt.set_route(1, [(CENTRE, -AXIS)])  # from the passage into the room
    assert dt.can_queue(0, 1) and not dt.can_queue(0, -1)
    pos = np.array([[-1.0, 0.0], [6.0, 0.0]])
    dt.update(0.0, pos)
    assert dt.granted[0] == 0  # the room side holds the door
    pos[1] = [1.2, 0.0]
    dt.update(0.1, pos)
    pref = np.array([[1.0, 0.0], [-1.0, 0.0]])
    if not no_room_waits:
        assert dt.granted[1] == 0  # it takes the door at once: the two ways meet in it
        np.testing.assert_allclose(dt.apply(pos, pref, np.ones(2)), pref)
        return
    assert dt.granted[1] == -1 and dt.waiting()[1]
    out = dt.apply(pos, pref, np.ones(2))
    np.testing.assert_allclose(out[0], pref[0])
    np.testing.assert_allclose(out[1], 0.0)  # stops in the passage, 1.2 m from the door
    further = dt.apply(np.array([[-1.0, 0.0], [2.0, 0.0]]), pref, np.ones(2))
    np.testing.assert_allclose(further[1], pref[1])  # walks on until it is `wait` from the door
    pos[0] = [0.8, 0.0]  # through
    dt.update(0.2, pos)
    assert dt.granted[1] == 0


def test_amp_pedestrians_door_params_follow_the_constant(monkeypatch):
    from navzoo.envs import amp_humans

    assert amp_humans.DOOR_GRANT_MAX_S == DoorParams().grant_max_s  # by default the grants of every crowd
    monkeypatch.setattr(amp_humans, "DOOR_NO_ROOM_WAITS", True)
    monkeypatch.setattr(amp_humans, "DOOR_GRANT_MAX_S", 6.0)
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp", crowd_model="sfm", time_limit=5.0)
    env.reset(seed=0)
    assert env.door_turns.params.no_room_waits and env.door_turns.params.grant_max_s == 6.0
    assert not env.door_turns.params.spot_passage_only
    env.close()
    monkeypatch.setattr(amp_humans, "DOOR_SPOT_PASSAGE_ONLY", True)
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp", crowd_model="sfm", time_limit=5.0)
    env.reset(seed=0)
    assert env.door_turns.params.spot_passage_only and env.door_turns.params.passed_lateral is None
    env.close()
    monkeypatch.setattr(amp_humans, "DOOR_PASSED_LATERAL", 1.0)
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp", crowd_model="sfm", time_limit=5.0)
    env.reset(seed=0)
    assert env.door_turns.params.passed_lateral == 1.0 and env.door_turns.params.line_up is None
    env.close()
    monkeypatch.setattr(amp_humans, "DOOR_LINE_UP", 0.35)
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model="amp", crowd_model="sfm", time_limit=5.0)
    env.reset(seed=0)
    assert env.door_turns.params.line_up == 0.35
    env.close()
    kin = NavEnv(scene="doorway", n_robots=0, n_humans=2, crowd_model="sfm", human_door_turns=True)
    kin.reset(seed=0)
    # kinematic crowds keep the rules as they were
    assert not kin.door_turns.params.no_room_waits and kin.door_turns.params.grant_max_s == DoorParams().grant_max_s
    kin.close()


def test_a_grant_ends_when_its_holder_does_not_come_on():
    dt = _turns(2, grant_stall_s=2.0, grant_stall_gain=0.3)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    pos = np.array([[-2.0, 0.0], [2.0, 0.0]])
    dt.update(0.0, pos)
    assert dt.granted[0] == 0 and dt.waiting()[1]
    pos[0] = [-1.6, 0.0]  # 0.4 m closer: it comes on, the stall clock starts again at 1 s
    dt.update(1.0, pos)
    assert dt.granted[0] == 0
    pos[0] = [-1.5, 0.0]  # only 0.1 m closer since: not coming on
    dt.update(2.5, pos)
    assert dt.granted[0] == 0  # 1.5 s without coming on < 2 s
    dt.update(3.1, pos)  # 2.1 s: its grant ends, the other side's waiting person gets the door
    assert dt.granted[0] == -1 and dt.granted[1] == 0 and dt.waiting()[0]


def test_a_stalled_grant_is_kept_while_nobody_else_asks_or_the_holder_is_in_the_door():
    dt = _turns(2, grant_stall_s=2.0)
    dt.set_route(0, [(CENTRE, AXIS)])
    dt.set_route(1, [(CENTRE, -AXIS)])
    pos = np.array([[-2.0, 0.0], [6.0, 0.0]])  # person 1 far from the door: not asking
    dt.update(0.0, pos)
    dt.update(5.0, pos)
    assert dt.granted[0] == 0 and dt.grant_t[0] == 0.0  # nobody else asks: the grant goes on (not re-granted)
    pos = np.array([[-0.3, 0.0], [2.0, 0.0]])  # the holder stands in the door, the other side asks
    dt.update(5.5, pos)
    dt.update(9.0, pos)
    assert dt.granted[0] == 0 and dt.granted[1] == -1
    # off (the default): the same stall keeps the grant until grant_max_s
    off = _turns(2)
    off.set_route(0, [(CENTRE, AXIS)])
    off.set_route(1, [(CENTRE, -AXIS)])
    far = np.array([[-2.0, 0.0], [2.0, 0.0]])
    off.update(0.0, far)
    off.update(5.0, far)
    assert off.granted[0] == 0


def test_grant_stall_params_are_checked():
    for bad in (0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="grant_stall_s"):
            DoorParams(grant_stall_s=bad)
    with pytest.raises(ValueError, match="grant_stall_gain"):
        DoorParams(grant_stall_gain=0.0)


def test_amp_pedestrians_take_the_grant_stall_constant(monkeypatch):
    """Off for social-force targets and for kinematic crowds, 3 s for diffusion targets (the defaults); each
    constant reaches only its own target generator."""
    from navzoo.envs import amp_humans

    assert DoorParams().grant_stall_s is None  # off for the kinematic crowds

    def stall(crowd, human_model="amp"):
        env = NavEnv(scene="doorway", n_robots=0, n_humans=2, human_model=human_model, crowd_model=crowd,
                     time_limit=5.0, human_door_turns=True)
        env.reset(seed=0)
        out = env.door_turns.params.grant_stall_s
        env.close()
        return out

    assert stall("sfm") is None and stall("diffusion") == 3.0 and stall("diffusion", "kinematic") is None
    monkeypatch.setattr(amp_humans, "DOOR_GRANT_STALL_S", 2.0)
    assert stall("sfm") == 2.0 and stall("diffusion") == 3.0
    monkeypatch.setattr(amp_humans, "DIFFUSION_DOOR_GRANT_STALL_S", 0.0)
    assert stall("diffusion") is None


def test_grant_stall_with_no_doors_on_any_path():
    dt = _turns(2, grant_stall_s=2.0)  # no routes: no door registered
    pos = np.array([[-2.0, 0.0], [2.0, 0.0]])
    assert not dt.update(0.0, pos).any() and not dt.update(5.0, pos).any()
    assert (dt.granted == -1).all()
