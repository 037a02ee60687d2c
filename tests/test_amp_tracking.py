"""Closed-loop clip tracking by the AMP pedestrian policy (navzoo.agents.amp.tracking)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from navzoo import sim as nzsim
from navzoo.agents.amp.sim import PhysicsHumanoids
from navzoo.agents.amp.tracking import (
    DEFAULT_POLICY_DIR,
    ROOT_OFFSET_KEYS,
    ROT_PART_KEYS,
    main,
    rigid_bodies,
    rigid_body_errors,
    root_offsets,
    rotation_parts,
    track_clips,
)
from navzoo.agents.amp.train import locomotion_reference
from navzoo.agents.quat import heading, quat_about_z, quat_from_rotvec, quat_mul
from navzoo.agents.reference import ReferenceState

CLIPS = ["amp_walk", "cmu_07_12", "cmu_16_27"]


@pytest.fixture(scope="module")
def library():
    return locomotion_reference()


@pytest.fixture(scope="module")
def short_run(library):
    return track_clips(DEFAULT_POLICY_DIR, library, CLIPS, max_seconds=1.0)


def _replace(ref: ReferenceState, **kw) -> ReferenceState:
    fields = dict(ref.__dict__)
    fields.update(kw)
    return ReferenceState(**fields)


def test_error_of_a_reference_against_itself_and_moved_copies(library):
    ref = library.state_at(np.array([0, 5, 20]), np.array([0.0, 1.0, 2.5]))
    pos, rot = rigid_body_errors(ref, ref)
    assert pos.shape == rot.shape == (3,)
    np.testing.assert_allclose(pos, 0.0, atol=1e-12)
    np.testing.assert_allclose(rot, 0.0, atol=1e-7)
    # Translated by 1 m: every body is 1 m off, no body is turned.
    moved = _replace(ref, root_pos=np.asarray(ref.root_pos) + np.array([0.6, -0.8, 0.0]))
    pos, rot = rigid_body_errors(moved, ref)
    np.testing.assert_allclose(pos, 1.0, atol=1e-9)
    np.testing.assert_allclose(rot, 0.0, atol=1e-7)
    # The base turned by 0.3 rad about the vertical: every body is turned by exactly 0.3 rad.
    turned = _replace(ref, root_quat=quat_mul(quat_about_z(np.full(3, 0.3)), np.asarray(ref.root_quat)))
    pos, rot = rigid_body_errors(turned, ref)
    np.testing.assert_allclose(rot, 0.3, atol=1e-9)
    assert (pos > 0.01).all()
    # Quaternion signs do not matter (q and -q are the same rotation).
    flipped = _replace(ref, root_quat=-np.asarray(ref.root_quat), sph=-np.asarray(ref.sph))
    np.testing.assert_allclose(rigid_body_errors(flipped, ref)[1], 0.0, atol=1e-7)
    with pytest.raises(ValueError, match="batch"):
        rigid_body_errors(library.state_at(np.array([0]), np.array([0.0])), ref)


def test_root_offsets_tell_lag_veer_and_crouch_apart(library):
    clips = np.array([library.clip_names().index(c) for c in CLIPS])
    ref = library.state_at(clips, np.full(3, 0.5))
    pos, quat = np.asarray(ref.root_pos), np.asarray(ref.root_quat)
    h = heading(quat)
    fwd = np.stack([np.cos(h), np.sin(h), np.zeros(3)], axis=1)
    side = np.stack([-np.sin(h), np.cos(h), np.zeros(3)], axis=1)
    for value in root_offsets(pos, pos, quat):
        np.testing.assert_allclose(value, 0.0, atol=1e-12)
    moved = pos - 0.3 * fwd + 0.2 * side - np.array([0.0, 0.0, 0.05])  # behind, to the left, lower
    along, across, height = root_offsets(moved, pos, quat)
    np.testing.assert_allclose(along, -0.3, atol=1e-9)
    np.testing.assert_allclose(across, 0.2, atol=1e-9)
    np.testing.assert_allclose(height, -0.05, atol=1e-9)
    np.testing.assert_allclose(root_offsets(pos - 0.2 * side, pos, quat)[1], 0.2, atol=1e-9)  # either side
    # The heading frame is the walking direction: a walking clip 0.2 s later is ahead of itself, not beside it.
    later = library.state_at(clips, np.full(3, 0.7))
    along, across, _ = root_offsets(np.asarray(later.root_pos), pos, quat)
    assert (along > 0.1).all() and (across < 0.5 * along).all()


def test_rotation_parts_tell_heading_tilt_and_pose_apart(library):
    ref = library.state_at(np.array([0, 5, 20]), np.array([0.0, 1.0, 2.5]))

    def parts(other):
        return rotation_parts(rigid_bodies(other)[1], rigid_bodies(ref)[1])

    for value in parts(ref):
        np.testing.assert_allclose(value, 0.0, atol=1e-6)
    # Turned about the vertical: all heading, no tilt, the same pose.
    yaw, tilt, pose = parts(_replace(ref, root_quat=quat_mul(quat_about_z(np.full(3, 0.3)), np.asarray(ref.root_quat))))
    np.testing.assert_allclose(yaw, 0.3, atol=1e-9)
    np.testing.assert_allclose(tilt, 0.0, atol=1e-6)
    np.testing.assert_allclose(pose, 0.0, atol=1e-6)
    # Leaning forward about the body's horizontal side axis: tilt only (the heading stays).
    q = np.asarray(ref.root_quat)
    h = heading(q)
    side = np.stack([-np.sin(h), np.cos(h), np.zeros(3)], axis=1)
    leaned = quat_mul(quat_from_rotvec(0.2 * side), q)
    np.testing.assert_allclose(heading(leaned), h, atol=1e-9)
    yaw, tilt, pose = parts(_replace(ref, root_quat=leaned))
    np.testing.assert_allclose(yaw, 0.0, atol=1e-9)
    np.testing.assert_allclose(tilt, 0.2, atol=1e-6)
    np.testing.assert_allclose(pose, 0.0, atol=1e-6)
    # One knee bent further by 0.7 rad: a pose error only; the knee link and the ankle below it turn
    # by 0.7 relative to the root, the other 12 of the 14 links not at all.
    rev = np.array(ref.rev, copy=True)
    rev[:, 0] -= 0.7
    yaw, tilt, pose = parts(_replace(ref, rev=rev))
    np.testing.assert_allclose(yaw, 0.0, atol=1e-9)
    np.testing.assert_allclose(tilt, 0.0, atol=1e-9)
    np.testing.assert_allclose(pose, 2 * 0.7 / 14, atol=1e-9)


def test_reference_state_initialisation_puts_the_body_exactly_on_the_reference(library):
    ref = library.state_at(np.array([0, 14]), np.array([0.0, 0.7]))
    ref = _replace(ref, root_pos=np.asarray(ref.root_pos) + np.array([[0.0, 0.0, 0.0], [40.0, 0.0, 0.0]]))
    cid = nzsim.connect()
    try:
        bodies = PhysicsHumanoids(cid, 2, pd_mode="motor")
        bodies.set_state(ref)
        pos, rot = rigid_body_errors(bodies.read_state(), ref)
    finally:
        nzsim.disconnect(cid)
    assert pos.max() < 1e-6 and rot.max() < 1e-5


def test_a_free_body_with_the_reference_velocities_lands_on_the_next_frame(library):
    """The clips' root and joint velocities mean what PyBullet means by them: without gravity, contacts
    or motors, a body started in a clip's state with its velocities moves, in 1/30 s, to the clip's
    next frame (errors here would be the tracking error's floor, not the policy's)."""
    import pybullet as p

    from navzoo.agents.amp.sim import CONTROL_JOINTS

    n, t0, dt = 6, 0.5, 1.0 / 30.0
    clips = np.arange(n) * 3
    lift = np.stack([6.0 * np.arange(n), np.zeros(n), np.ones(n)], axis=1)  # in the air, 6 m apart
    ref0 = library.state_at(clips, np.full(n, t0))
    ref1 = library.state_at(clips, np.full(n, t0 + dt))
    cid = nzsim.connect()
    try:
        bodies = PhysicsHumanoids(cid, n, physics_hz=120, control_hz=30)
        p.setGravity(0, 0, 0, physicsClientId=cid)
        bodies.set_state(_replace(ref0, root_pos=np.asarray(ref0.root_pos) + lift))
        for body in bodies.ids:  # no joint torques at all (set_state leaves the PD targets for step())
            for j in CONTROL_JOINTS:
                if p.getJointInfo(body, j, physicsClientId=cid)[2] == p.JOINT_SPHERICAL:
                    p.setJointMotorControlMultiDof(body, j, p.POSITION_CONTROL, targetPosition=[0, 0, 0, 1],
                                                   positionGain=0, velocityGain=0, force=[0, 0, 0], physicsClientId=cid)
                else:
                    p.setJointMotorControl2(body, j, p.VELOCITY_CONTROL, force=0, physicsClientId=cid)
        for _ in range(4):
            p.stepSimulation(physicsClientId=cid)
        state = bodies.read_state()
        state = {**state, "root_pos": state["root_pos"] - lift}
        pos, rot = rigid_body_errors(state, ref1)
        still_pos, still_rot = rigid_body_errors(ref0, ref1)  # how far the clip itself moved
    finally:
        nzsim.disconnect(cid)
    assert still_rot.mean() > 0.04 and still_pos.mean() > 0.03  # the clips do move in 1/30 s
    assert rot.max() < 0.05 and pos.max() < 0.01
    assert rot.mean() < 0.3 * still_rot.mean()


def test_short_tracking_run(short_run):
    r = short_run
    for key in ("mean_pos_error_m", "max_pos_error_m", "worst_pos_error_m", "mean_rot_error_rad",
                "clip_success_rate", "fall_rate", "n_clips", "seconds_simulated", "per_clip"):
        assert key in r
    assert r["n_clips"] == 3 and [c["name"] for c in r["per_clip"]] == CLIPS
    for key in ("mean_pos_error_m", "max_pos_error_m", "worst_pos_error_m", "mean_rot_error_rad"):
        assert math.isfinite(r[key]) and r[key] >= 0.0
    assert 0.0 <= r["clip_success_rate"] <= 1.0 and 0.0 <= r["fall_rate"] <= 1.0
    assert r["mean_pos_error_m"] <= r["max_pos_error_m"] <= r["worst_pos_error_m"]
    assert 0.0 < r["seconds_simulated"] <= 3.0 + 1e-9
    for c in r["per_clip"]:
        assert c["duration_s"] == pytest.approx(1.0) and c["clip_duration_s"] > 1.0
        assert 0.0 < c["tracked_s"] <= 1.0 + 1e-9
        assert c["mean_pos_error_m"] <= c["max_pos_error_m"]
        # the clip's rotation error is the mean over its 15 bodies
        assert c["mean_rot_error_rad"] == pytest.approx(np.mean(c["mean_rot_error_by_body_rad"]))
        assert c["failed"] == (c["max_pos_error_m"] > 0.5)
        if not c["failed"]:
            assert c["tracked_s"] == pytest.approx(1.0)
    for key in ROT_PART_KEYS:  # where the rotation error comes from: per clip and overall
        assert 0.0 <= r[key] <= math.pi and all(0.0 <= c[key] <= math.pi for c in r["per_clip"])
        assert r[key] == pytest.approx(np.mean([c[key] for c in r["per_clip"]]))
    for key in ROOT_OFFSET_KEYS:  # where the root is against the clip's: per clip and overall
        assert r[key] == pytest.approx(np.mean([c[key] for c in r["per_clip"]]))
        assert all(abs(c[key]) < c["max_pos_error_m"] + 0.5 for c in r["per_clip"])
    assert all(c["mean_root_cross_error_m"] >= 0.0 for c in r["per_clip"])
    by_body = r["mean_rot_error_by_body_rad"]
    assert list(by_body)[:3] == ["root", "chest", "neck"] and len(by_body) == 15
    assert np.mean(list(by_body.values())) == pytest.approx(r["mean_rot_error_rad"])
    # The closed loop works: one second of walking from the reference state stays near the clip.
    assert r["mean_pos_error_m"] < 0.4
    json.dumps(r)  # JSON-serialisable


def test_tracking_runs_on_one_torch_thread_and_gives_the_callers_back(monkeypatch):
    """The policy's float sums depend on the thread count (two threads against one moved 3 of 78 clips of a
    checkpoint on the 2-core VM), so the protocol runs on one, whatever the caller has set."""
    from navzoo.agents.amp import tracking
    from tests.amp_helpers import threads_seen

    seen, after = threads_seen(monkeypatch, tracking, "_track_batch", lambda: track_clips(clips=[0], max_seconds=0.2))
    assert seen == [1] and after == 2


def test_cli_prints_json(capsys):
    assert main([str(DEFAULT_POLICY_DIR), "--clips", "0", "--max-seconds", "0.3", "--json"]) == 0
    out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert out["n_clips"] == 1 and "per_clip" not in out


def test_bad_inputs(tmp_path, library):
    with pytest.raises(FileNotFoundError, match="policy directory not found"):
        track_clips(tmp_path / "nope", library, [0], max_seconds=0.1)
    with pytest.raises(FileNotFoundError, match="config.json"):
        track_clips(tmp_path, library, [0], max_seconds=0.1)
    empty = tmp_path / "motions"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match="no motion library"):
        track_clips(DEFAULT_POLICY_DIR, empty, max_seconds=0.1)
    with pytest.raises(FileNotFoundError, match="motion folder not found"):
        track_clips(DEFAULT_POLICY_DIR, tmp_path / "missing", max_seconds=0.1)
    with pytest.raises(ValueError, match="no clip named"):
        track_clips(DEFAULT_POLICY_DIR, library, ["no_such_clip"], max_seconds=0.1)
    with pytest.raises(ValueError, match="out of range"):
        track_clips(DEFAULT_POLICY_DIR, library, [len(library)], max_seconds=0.1)
    with pytest.raises(ValueError, match="no clips"):
        track_clips(DEFAULT_POLICY_DIR, library, [], max_seconds=0.1)
    with pytest.raises(ValueError, match="max_seconds"):
        track_clips(DEFAULT_POLICY_DIR, library, [0], max_seconds=0.0)
    with pytest.raises(SystemExit) as e:
        main([str(tmp_path / "nope")])
    assert e.value.code == 2


def test_path_end_extends_at_the_final_velocity_or_holds(library):
    from navzoo.agents.amp.tracking import END_VELOCITY_WINDOW_S, _extend_paths

    clip = np.array([library.clip_index("amp_walk")])
    full = np.array([library.duration(int(clip[0]))])
    dt = 1.0 / 30.0
    times = np.arange(int(full[0] / dt) + 60) * dt
    held = np.asarray(library.state_at(np.repeat(clip, len(times)), np.minimum(times, full[0])).root_pos)[:, :2]
    shift = np.array([[3.0, -2.0]])
    ext = _extend_paths(held[None] + shift, library, clip, full, shift, times)[0]
    inside = times <= full[0]
    np.testing.assert_array_equal(ext[inside], held[inside] + shift)  # the clip's own path is untouched
    end = np.asarray(library.state_at(clip, full).root_pos)[0, :2]
    before = np.asarray(library.state_at(clip, full - END_VELOCITY_WINDOW_S).root_pos)[0, :2]
    vel = (end - before) / END_VELOCITY_WINDOW_S
    assert np.linalg.norm(vel) > 0.5  # the walk ends mid-stride
    after = ~inside
    np.testing.assert_allclose(ext[after], end + shift[0] + vel * (times[after] - full[0])[:, None], atol=1e-9)
    assert np.all(np.diff(np.linalg.norm(ext[after] - end - shift[0], axis=1)) > 0)  # walks on, where hold stops


def test_path_end_is_recorded_and_checked(library):
    hold = track_clips(DEFAULT_POLICY_DIR, library, ["amp_walk"], max_seconds=0.5, path_end="hold")
    ext = track_clips(DEFAULT_POLICY_DIR, library, ["amp_walk"], max_seconds=0.5)
    assert hold["path_end"] == "hold" and ext["path_end"] == "extend"
    with pytest.raises(ValueError, match="path_end"):
        track_clips(DEFAULT_POLICY_DIR, library, [0], max_seconds=0.1, path_end="stop")


def test_pose_sink_collects_the_standing_bodies_poses_and_speeds(library):
    from navzoo.benchmark.realism import POSE_DIM

    sink: list = []
    res = track_clips(DEFAULT_POLICY_DIR, library, CLIPS[:2], max_seconds=0.5, pose_sink=sink)
    steps = round(res["seconds_simulated"] * 30)  # 30 Hz control, both clips tracked to the end
    assert res["n_fell"] == 0 and sum(len(p) for p, _ in sink) == steps
    for poses, speeds in sink:
        assert poses.shape[1] == POSE_DIM and speeds.shape == (len(poses),)
        assert np.isfinite(poses).all() and (speeds >= 0).all() and (speeds < 5).all()
    assert track_clips(DEFAULT_POLICY_DIR, library, CLIPS[:2], max_seconds=0.5)["mean_pos_error_m"] == \
        res["mean_pos_error_m"]  # collecting poses does not change the rollout


def test_a_loaded_policy_tracks_as_its_folder_does(library):
    from navzoo.agents.amp.checkpoint import load_policy

    by_dir = track_clips(DEFAULT_POLICY_DIR, library, CLIPS[:1], max_seconds=0.3)
    loaded = track_clips(load_policy(DEFAULT_POLICY_DIR), library, CLIPS[:1], max_seconds=0.3)
    assert loaded["mean_pos_error_m"] == by_dir["mean_pos_error_m"]
    assert loaded["policy_dir"] != by_dir["policy_dir"] and isinstance(loaded["policy_dir"], str)
