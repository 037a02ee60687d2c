"""Replay crowd: recorded ETH/UCY tracks played back exactly, in the recording's open scene."""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import navzoo
from navzoo.agents.replay import PARK_DISTANCE, RECORDINGS, ReplayCrowd, load_recording
from navzoo.envs.config import NavConfig
from navzoo.envs.nav_env import NavEnv
from navzoo.forecast.data import default_data_dir, discover, read_tracks
from navzoo.world.library import get_scene

try:
    _FILES = discover(default_data_dir())["all"]
except FileNotFoundError:  # pragma: no cover - the shared data is there in CI
    _FILES = {}
pytestmark = pytest.mark.skipif(not _FILES, reason="needs the shared ETH/UCY data")
AVAILABLE = [n for n, stems in RECORDINGS.items() if any(s in _FILES for s in stems)]


@functools.cache
def _raw_tracks(name: str) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Straight from the file: each person's sample times (s) and positions in the scene's frame."""
    rec = load_recording(name)
    tr = read_tracks(_FILES[rec.stem])  # the shared text file, not the packaged copy
    f0 = tr.frame.min()
    out = {}
    for pid in np.unique(tr.ped):
        sel = tr.ped == pid
        t = (tr.frame[sel] - f0) / tr.frame_step * tr.dt
        o = np.argsort(t)
        out[int(pid)] = (t[o], tr.xy[sel][o] - rec.offset)
    return out


def _raw_positions(name: str, tau: float) -> dict[int, np.ndarray]:
    """Every person present at recording time ``tau``, linearly interpolated between their samples."""
    out = {}
    for pid, (t, xy) in _raw_tracks(name).items():
        if t[0] - 1e-9 <= tau <= t[-1] + 1e-9:
            out[pid] = np.array([np.interp(tau, t, xy[:, 0]), np.interp(tau, t, xy[:, 1])])
    return out


def _zeros(env):
    return {a: np.zeros(env.action_space(a).shape, dtype=np.float32) for a in env.agents}


@pytest.mark.parametrize("name,start,dt", [("eth", 100.0, 0.1), ("zara1", 37.3, 0.25)])
def test_active_people_are_the_interpolated_recording(name, start, dt):
    env = NavEnv(crowd_model="replay", replay_scene=name, replay_start=start, dt=dt, time_limit=12.0)
    try:
        env.reset(seed=0)
        R, rec = env.n_robots, env.replay.recording
        assert rec.dt == pytest.approx(0.667 if name == "eth" else 0.4)  # biwi_eth's time base (data README)
        for k in range(env.max_steps + 1):
            tau = start + k * dt
            want = _raw_positions(name, tau)
            act = np.flatnonzero(env.human_active)
            # n_humans=None: every person of the window has a slot, nobody else is shown.
            assert len(act) == len(want), (k, tau)
            for j in act:
                pid = int(rec.ped[env.replay.track[k, j]])
                np.testing.assert_allclose(env.pos[R + j], want[pid], atol=1e-6)
                assert np.isfinite(env.yaw[R + j]) and np.linalg.norm(env.vel[R + j]) < 4.0
            if k < env.max_steps:
                env.step(_zeros(env))
        assert not env.agents  # the episode ended at the time limit
    finally:
        env.close()


def test_velocity_and_heading_come_from_the_track():
    env = NavEnv(crowd_model="replay", replay_scene="zara1", replay_start=50.0, dt=0.1, time_limit=6.0)
    env.reset(seed=0)
    R = env.n_robots
    prev, prev_vel = env.pos[R:].copy(), env.vel[R:].copy()
    prev_act = env.human_active.copy()
    checked = 0
    for _ in range(30):
        env.step(_zeros(env))
        both = prev_act & env.human_active & (env.replay.track[env.steps] == env.replay.track[env.steps - 1])
        # Positions are piecewise linear between the 0.4 s samples, and 50 s is on a sample: each 0.1 s
        # step stays within one piece, whose slope is the velocity reported at the step's start.
        disp = (env.pos[R:] - prev)[both]
        np.testing.assert_allclose(disp, prev_vel[both] * 0.1, atol=1e-9)
        checked += int(both.sum())
        moving = both & (np.linalg.norm(env.vel[R:], axis=1) > 0.3)
        head = np.stack([np.cos(env.yaw[R:]), np.sin(env.yaw[R:])], axis=1)
        v = env.vel[R:] / np.maximum(np.linalg.norm(env.vel[R:], axis=1, keepdims=True), 1e-9)
        np.testing.assert_allclose(np.sum(head * v, axis=1)[moving], 1.0, atol=1e-9)
        prev, prev_vel, prev_act = env.pos[R:].copy(), env.vel[R:].copy(), env.human_active.copy()
    assert checked > 30
    env.close()


def test_inactive_people_are_parked_unobserved_and_never_collide():
    # Two more slots than needed: the last two are parked for the whole episode.
    probe = ReplayCrowd("eth", 100.0, 0.1, 100)
    H = probe.max_concurrent + 2
    env = NavEnv(crowd_model="replay", replay_scene="eth", replay_start=100.0, time_limit=10.0, n_humans=H,
                 n_robots=2)
    try:
        park = env.replay.park[H - 1]
        obs, _ = env.reset(seed=1, options={"robot_starts": np.array([park, [0.0, 0.0]]),
                                            "robot_goals": np.array([park + [0.0, 5.0], [5.0, 5.0]])})
        R = env.n_robots
        xmax = env.scene.bounds[2]
        seen_inactive = 0
        while env.agents:
            inactive = np.flatnonzero(~env.human_active)
            seen_inactive += inactive.size
            assert np.all(env.pos[R + inactive, 0] > xmax + 0.5 * PARK_DISTANCE)
            # robot_0 stands among parked people: it observes nobody and collides with nobody.
            if "robot_0" in obs:
                assert obs["robot_0"]["agents_mask"].sum() == 0
            for a in ("robot_1",) if "robot_1" in obs else ():
                o = obs[a]
                now = o["agents_mask"][:, -1] > 0
                active_near = np.linalg.norm(env.pos[R:][env.human_active] - env.pos[1], axis=1) < env.config.sensor_range
                assert now.sum() == min(env.config.k_neighbors, int(active_near.sum()))
                # No observed entry (now or in the history) is a parked position (they would be clipped at 50 m).
                rel = o["agents"][..., :2][o["agents_mask"] > 0]
                assert np.all(np.abs(rel) < 40.0)
            acts = {a: np.zeros(2, dtype=np.float32) for a in env.agents}
            obs, _, term, _, infos = env.step(acts)
            assert infos.get("robot_0", {}).get("collision", "") == ""
            for j in range(H):
                if f"human_{j}" in infos:
                    assert infos[f"human_{j}"]["active"] == bool(env.human_active[j])
        assert seen_inactive > 0 and env.events.get("robot_0") is None  # timed out, no collision
    finally:
        env.close()


def test_a_person_appearing_on_the_robot_collides_only_once_there():
    env = NavEnv(crowd_model="replay", replay_scene="zara1", replay_start=20.0, time_limit=20.0)
    try:
        rp = env.replay
        # A person who appears during the episode where nobody else walks near.
        found = None
        for j, tr in rp.assignment:
            k = int(np.flatnonzero(rp.track[:, j] == tr)[0])
            if k < 3:
                continue
            spot = rp.pos[k, j]
            near = rp.active[: k + 1].copy()
            near[k, j] = False
            d = np.linalg.norm(rp.pos[: k + 1] - spot, axis=2)[near]
            if d.size == 0 or d.min() > 1.5:
                found = (j, k, spot)
                break
        assert found is not None
        j, k, spot = found
        # Their jump in from the parking is not a swept path: no collision before they are there.
        env.reset(seed=0, options={"robot_starts": spot[None], "robot_goals": (spot + [0.0, 8.0])[None]})
        for _ in range(k - 1):
            env.step(_zeros(env))
            assert env.events.get("robot_0") is None
        env.step(_zeros(env))
        assert env.human_active[j] and env.events.get("robot_0") == "collision_human"
    finally:
        env.close()


def test_fewer_slots_drop_whole_tracks_first_come_first_served():
    full = ReplayCrowd("univ", 10.0, 0.1, 200)
    small = ReplayCrowd("univ", 10.0, 0.1, 200, n_humans=full.max_concurrent // 2)
    assert small.n_slots == full.max_concurrent // 2 and len(small.dropped) > 0
    assert len(small.assignment) + len(small.dropped) == len(full.assignment) == full.window_tracks.size
    # Every played track is shown for all of its steps in the window (nobody vanishes mid-walk).
    for j, tr in small.assignment:
        np.testing.assert_array_equal(small.track[:, j] == tr, (full.track == tr).any(axis=1))
    assert small.active.sum(axis=1).max() <= small.n_slots
    env = NavEnv(crowd_model="replay", replay_scene="univ", replay_start=10.0, time_limit=2.0, n_humans=5)
    assert env.n_humans == 5 and env.possible_agents[-1] == "human_4"
    env.close()


@pytest.mark.parametrize("name", AVAILABLE)
def test_scene_contains_every_recorded_position_in_free_space(name):
    scene = get_scene(f"replay_{name}")
    assert scene.name == f"replay_{name}"
    rec = load_recording(name)
    tr = read_tracks(_FILES[rec.stem])  # the shared text file, not the packaged copy
    pts = tr.xy - rec.offset
    x0, y0, x1, y1 = scene.bounds
    assert np.all((pts[:, 0] > x0) & (pts[:, 0] < x1) & (pts[:, 1] > y0) & (pts[:, 1] < y1))
    # The four walls around the box, then the real scene's walls (eth only).
    assert [o.name for o in scene.obstacles[:4]] == ["south", "north", "west", "east"]
    assert len(scene.obstacles) == 4 + len(rec.walls) and len(rec.walls) == (4 if name == "eth" else 0)
    box = dataclasses.replace(scene, obstacles=scene.obstacles[:4])
    assert np.all(box.clearance(pts) >= 0.9)  # 1 m of margin to the box
    # A person's 0.3 m disc fits at every recorded position but a handful next to eth's walls.
    free = scene.occupancy(0.1).inflate(0.3).is_free(pts)
    assert free.mean() > 0.998 and (free.all() or name == "eth")
    assert abs(0.5 * (x0 + x1)) < 0.1 and abs(0.5 * (y0 + y1)) < 0.1  # data centred on the origin


@pytest.mark.skipif("eth" not in AVAILABLE, reason="biwi_eth is not in the shared data")
def test_eth_scene_has_the_real_walls_and_its_entrance():
    from navzoo.forecast.scene_maps import opentraj_walls
    from navzoo.world.planner import AStarPlanner

    rec = load_recording("eth")
    xml = opentraj_walls("biwi_eth", default_data_dir().parent / "opentraj")
    if xml is None or not len(xml):
        pytest.skip("the OpenTraj ETH map is not available")
    np.testing.assert_allclose(rec.walls, xml - rec.offset, atol=1e-9)  # packaged = map.xml, scene frame
    scene = get_scene("replay_eth")
    front = 14.2 - rec.offset[0]  # the building front (file x = 14.2), its entrance at file y 4.9 .. 6.4
    walkway, inside, behind_wall = (7.0, 6.0), (front + 0.7, 5.6), (front + 0.7, 2.0)
    walkway, inside, behind_wall = (np.array(q) - rec.offset for q in (walkway, inside, behind_wall))
    planner = AStarPlanner(scene.occupancy(0.1), agent_radius=0.3)
    path = planner.plan(walkway, inside)
    assert path is not None and planner.path_length(path) < 1.3 * np.linalg.norm(inside - walkway)  # straight in
    around = planner.plan(walkway + np.array([0.0, -4.0]), behind_wall)
    assert around is not None  # the building is reached through the entrance, not through the wall:
    assert np.any(np.abs(path[:, 1] - inside[1]) < 0.8) and np.all(
        np.abs(around[np.abs(around[:, 0] - front) < 0.15, 1] - inside[1]) < 0.75)
    # The replay crowd runs in it.
    env = NavEnv(scene="replay_eth", crowd_model="replay", replay_start=120.0, time_limit=1.0)
    env.reset(seed=0)
    env.step(_zeros(env))
    env.close()


def test_scene_is_chosen_from_the_recording_and_names_agree():
    a = NavConfig(crowd_model="replay", replay_scene="zara1")
    assert a.scene == "replay_zara1"
    b = NavConfig(crowd_model="replay", scene="replay_zara1")
    assert b.replay_scene == "zara1"
    c = NavConfig(crowd_model="replay", replay_scene="crowds_zara01", scene="replay_zara1")
    assert c.replay_scene == "zara1" and NavConfig.from_dict(c.to_dict()) == c
    # The open scene also works with the other crowd models.
    env = NavEnv(scene="replay_zara1", crowd_model="sfm", n_humans=3, time_limit=2.0)
    env.reset(seed=0)
    env.step(_zeros(env))
    env.close()


def test_seeding_is_deterministic():
    def run(seed):
        env = navzoo.make(crowd_model="replay", replay_scene="eth", replay_start=200.0, time_limit=3.0)
        obs, _ = env.reset(seed=seed)
        nav = env.unwrapped
        out = [nav.pos.copy(), obs["robot_0"]["agents"].copy()]
        while env.agents:
            obs, *_ = env.step({"robot_0": np.array([0.5, 0.1], dtype=np.float32)})
            if "robot_0" in obs:
                out.append(obs["robot_0"]["agents"].copy())
        out.append(nav.pos.copy())
        env.close()
        return out

    a, b, c = run(4), run(4), run(5)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a[0][0], c[0][0])  # another seed, another robot start
    np.testing.assert_array_equal(a[0][1:], c[0][1:])  # the people are the recording either way


def test_human_actions_are_ignored_and_agent_list_is_stable():
    env = NavEnv(crowd_model="replay", replay_scene="zara1", replay_start=30.0, time_limit=2.0)
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    base = list(env.possible_agents)
    pos = []
    for _ in range(5):
        acts = {a: rng.uniform(-1, 1, 2).astype(np.float32) for a in env.agents}
        env.step(acts)
        pos.append(env.pos[1:].copy())
        assert env.possible_agents == base and set(env.agents) == set(base)
    env.reset(seed=0)
    for k in range(5):
        env.step(_zeros(env))
        np.testing.assert_array_equal(env.pos[1:], pos[k])
    env.close()


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(crowd_model="replay", replay_scene="nowhere"), "unknown replay recording 'nowhere'"),
        (dict(crowd_model="replay", replay_scene="eth", replay_start=1e5), "beyond the end of recording 'eth'"),
        (dict(crowd_model="replay", replay_scene="eth", replay_start=-1.0), "replay_start must be"),
        (dict(crowd_model="replay", replay_scene="eth", human_model="amp", dt=1 / 30), "kinematic bodies only"),
        (dict(crowd_model="replay"), "needs a recording"),
        (dict(crowd_model="replay", replay_scene="eth", scene="station"), "its own open scene 'replay_eth'"),
        (dict(crowd_model="replay", replay_scene="eth", scene="replay_zara1"), "does not match"),
        (dict(crowd_model="sfm", replay_scene="eth"), "only used with crowd_model='replay'"),
    ],
)
def test_bad_configs_are_clear_errors(kwargs, match):
    with pytest.raises(ValueError, match=match):
        NavConfig(**kwargs)


@pytest.mark.skipif("biwi_hotel" in _FILES, reason="hotel is in this data folder")
def test_missing_recording_file_is_a_clear_error():
    with pytest.raises(ValueError, match="'hotel'.*biwi_hotel.*is not in"):
        NavConfig(crowd_model="replay", replay_scene="hotel")
    with pytest.raises(ValueError, match="replay_<recording>"):
        get_scene("nowhere_scene")
    with pytest.raises(ValueError, match="unknown replay recording"):
        get_scene("replay_nowhere")


def test_human_start_options_are_refused():
    env = NavEnv(crowd_model="replay", replay_scene="zara1", time_limit=2.0)
    with pytest.raises(ValueError, match="cannot be used with crowd_model='replay'"):
        env.reset(seed=0, options={"human_starts": np.zeros((env.n_humans, 2)),
                                   "human_goals": np.zeros((env.n_humans, 2))})
    env.close()


def test_parallel_api_raw_and_frozen():
    raw = NavEnv(crowd_model="replay", replay_scene="zara1", replay_start=60.0, n_robots=2,
                 max_episode_steps_override=60)
    parallel_api_test(raw, num_cycles=60)
    raw.close()
    env = navzoo.make(crowd_model="replay", replay_scene="eth", replay_start=300.0, max_episode_steps_override=60)
    assert env.possible_agents == ["robot_0"]
    parallel_api_test(env, num_cycles=60)
    env.close()


def test_robot_episode_runs_to_the_end_with_a_baseline_and_renders():
    from navzoo.agents.baselines import make_policy

    env = navzoo.make(crowd_model="replay", replay_scene="zara1", replay_start=100.0, time_limit=25.0,
                      render_mode="rgb_array")
    nav = env.unwrapped
    policy = make_policy("orca")
    obs, _ = env.reset(seed=2)
    policy.reset(nav)
    event = None
    steps = 0
    while env.agents:
        obs, rew, term, trunc, infos = env.step(policy.act(obs, nav))
        steps += 1
        assert np.isfinite(rew["robot_0"])
        if term["robot_0"] or trunc["robot_0"]:
            event = infos["robot_0"]["event"]
    assert event in ("goal", "timeout", "collision_human", "collision_obstacle")
    assert steps <= nav.max_steps
    img = env.render()
    assert img.ndim == 3 and img.shape[2] == 3
    env.close()


def test_packaged_tracks_equal_the_shared_text_files(tmp_path):
    from navzoo.agents import replay
    from navzoo.forecast.data import default_data_dir, discover, read_tracks

    files = discover(default_data_dir())["all"]
    assert files, "the shared ETH/UCY data is needed for this test"
    from navzoo.forecast.scene_maps import opentraj_walls

    maps = default_data_dir().parent / "opentraj"
    for stem, path in files.items():
        packaged, walls = replay._read_npz(replay.TRACKS_DIR / f"{stem}.npz")
        text = read_tracks(path)
        assert packaged.dt == text.dt and packaged.frame_step == text.frame_step
        np.testing.assert_array_equal(packaged.frame, text.frame)
        np.testing.assert_array_equal(packaged.ped, text.ped)
        np.testing.assert_array_equal(packaged.xy, text.xy)
        xml = opentraj_walls(stem, maps) if maps.is_dir() else None
        if xml is not None:
            np.testing.assert_array_equal(walls, xml)
        assert walls.shape == ((4, 2, 2) if stem == "biwi_eth" else (0, 2, 2))
    # The converter writes the same files again, and without the map's walls when asked.
    written = replay.convert_tracks(out_dir=tmp_path)
    assert sorted(p.name for p in written) == sorted(f"{s}.npz" for s in files)
    if "biwi_eth" in files:
        for src, n_walls in ((None, 4), ("none", 0)):
            replay.convert_tracks(out_dir=tmp_path, map_dir=src)
            assert replay._read_npz(tmp_path / "biwi_eth.npz")[1].shape == (n_walls, 2, 2)
        with pytest.raises(FileNotFoundError, match="--maps none"):
            replay.convert_tracks(out_dir=tmp_path, map_dir=tmp_path / "no_opentraj")
    # A file of an older navzoo (no walls) still loads, as a recording without walls.
    old = tmp_path / "old.npz"
    with np.load(written[0], allow_pickle=False) as z:
        np.savez(old, **{k: z[k] for k in z.files if k != "walls"})
    assert replay._read_npz(old)[1].shape == (0, 2, 2)
    bad = tmp_path / "bad.npz"
    np.savez(bad, frame=np.zeros(3))
    with pytest.raises(ValueError, match="not a navzoo track file"):
        replay._read_npz(bad)
    np.savez(bad, **{k: z for k, z in np.load(written[0], allow_pickle=False).items() if k != "walls"},
             walls=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="walls: expected"):
        replay._read_npz(bad)
