"""Motion library: safe loading, the shipped library, interpolation, mirroring, conversion checks, playback."""

from __future__ import annotations

import csv
import hashlib
import io
import json
import os
import pickle
from pathlib import Path

import numpy as np
import pybullet as p
import pytest

from navzoo import sim
from navzoo.agents import mocap_io
from navzoo.agents import motion_convert as mc
from navzoo.agents.mocap_io import MocapFormatError, RestrictedUnpickler, load_amp_npy, restricted_loads
from navzoo.agents.motion_lib import (
    FIELDS,
    MotionLibrary,
    compute_velocities,
    foot_heights,
    heading_of,
    humanoid_fk,
    mirror_frames,
    quat_conj,
    quat_mul,
    quat_to_rotvec,
)
from navzoo.agents.reference import ReferenceMotion

MOCAP = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "mocap"
ASSETS = Path(__file__).resolve().parents[2] / "navzoo" / "assets" / "motions"
needs_data = pytest.mark.skipif(not MOCAP.is_dir(), reason="../shared/data/mocap not available")


@pytest.fixture(scope="module")
def lib() -> MotionLibrary:
    return MotionLibrary.load()


@pytest.fixture(scope="module")
def client():
    cid = sim.connect()
    yield cid
    sim.disconnect(cid)


def _load_humanoid(cid: int, fixed: bool = True) -> int:
    with sim.quiet():
        return p.loadURDF(
            "humanoid/humanoid.urdf", [0, 0, 1], useFixedBase=fixed, globalScaling=0.25,
            flags=p.URDF_MAINTAIN_LINK_ORDER, physicsClientId=cid,
        )  # fmt: skip


# --- restricted unpickling ---------------------------------------------------------------------------


class _Evil:
    def __reduce__(self):
        return (os.system, ("echo pwned",))


def test_restricted_unpickler_rejects_other_globals(tmp_path):
    payload = pickle.dumps({"rotation": _Evil()}, protocol=2)
    with pytest.raises(pickle.UnpicklingError, match=r"system"):
        restricted_loads(payload)
    # The same pickle inside a .npy of dtype object, as the AMP clips are stored.
    path = tmp_path / "evil.npy"
    with open(path, "wb") as f:
        np.lib.format.write_array_header_1_0(f, {"descr": "|O", "fortran_order": False, "shape": ()})
        f.write(payload)
    with pytest.raises(
        MocapFormatError, match=r"evil\.npy.*refusing to unpickle global '(posix|os|nt)\.system'"
    ):
        load_amp_npy(path)
    # Builtins are refused too (e.g. eval), even though they are harmless-looking.
    with pytest.raises(pickle.UnpicklingError, match=r"builtins\.eval"):
        RestrictedUnpickler(io.BytesIO(b"cbuiltins\neval\n(S'1'\ntR.")).load()


@needs_data
def test_restricted_unpickler_reads_the_amp_clips():
    for name, frames in (("walk", 154), ("run", 82), ("hop", 297)):
        m = load_amp_npy(MOCAP / "amp_humanoid" / f"amp_humanoid_{name}.npy")
        assert m.node_names[0] == "pelvis" and len(m.node_names) == 15
        assert m.rotation.shape == (frames, 15, 4) and m.root_translation.shape == (frames, 3)
        assert m.fps == 60
        np.testing.assert_allclose(np.linalg.norm(m.rotation, axis=-1), 1.0, atol=1e-6)
    tpose = mocap_io.load_npy_dict(MOCAP / "amp_humanoid" / "amp_humanoid_tpose.npy")  # a SkeletonState
    assert tpose["rotation"].shape == (15, 4) and len(tpose["skeleton_tree"]["node_names"]) == 15


def test_malformed_sources_are_rejected_with_the_file_name(tmp_path):
    bad = tmp_path / "amp_humanoid_walk.npy"
    bad.write_text("not numpy")
    with pytest.raises(MocapFormatError, match="amp_humanoid_walk.npy"):
        load_amp_npy(bad)
    bvh = tmp_path / "x.bvh"
    bvh.write_text("HIERARCHY\nROOT Hips\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation\n"
                   "}\nMOTION\nFrames: 2\nFrame Time: 0.0083333\n0 0 0 0 0 0\n0 0 0 0 0\n")  # fmt: skip
    with pytest.raises(MocapFormatError, match=r"x\.bvh.*2 frames x 6 channels"):
        mocap_io.parse_bvh(bvh)
    with pytest.raises(MocapFormatError, match="mocap source folder not found"):
        mc.build_library(tmp_path / "missing")
    # A source folder whose AMP clip is corrupt: the converter names that file.
    (tmp_path / "src" / "amp_humanoid").mkdir(parents=True)
    (tmp_path / "src" / "amp_humanoid" / "amp_humanoid_walk.npy").write_bytes(b"\x93NUMPY garbage")
    with pytest.raises(MocapFormatError, match="amp_humanoid_walk.npy"):
        mc.build_library(tmp_path / "src")
    assert mc.main(["--src", str(tmp_path / "missing"), "--out", str(tmp_path / "out")]) == 2


@needs_data
def test_amc_with_unknown_bone_is_rejected(tmp_path):
    sk = mocap_io.parse_asf(MOCAP / "cmu" / "02" / "02.asf")
    amc = tmp_path / "bad.amc"
    amc.write_text(":FULLY-SPECIFIED\n:DEGREES\n1\nroot 0 0 0 0 0 0\nnosuchbone 1 2 3\n")
    with pytest.raises(MocapFormatError, match=r"bad\.amc:5: bone 'nosuchbone'"):
        mocap_io.parse_amc(amc, sk)


# --- the shipped library -------------------------------------------------------------------------------


def test_shipped_library_is_plain_arrays_and_small(lib):
    assert isinstance(lib, ReferenceMotion)
    npz, js = ASSETS / "library.npz", ASSETS / "library.json"
    assert npz.stat().st_size + js.stat().st_size + (ASSETS / "NOTICE.md").stat().st_size < 5e6
    with np.load(npz, allow_pickle=False) as z:
        assert all(z[k].dtype.kind in "fi" for k in z.files)
        assert set(z.files) == {*FIELDS, "offsets"}
    index = json.loads(js.read_text())
    assert index["fps"] == 30 and index["frames"] == lib.num_frames
    names = lib.clip_names()
    assert len(names) == len(set(names)) >= 150
    # Every clip has a mirrored copy, flagged and tagged with left/right swapped.
    for c in lib.clips:
        if not c["mirrored"]:
            m = lib.info(c["name"] + "_mirrored")
            assert m["mirrored"] and m["mirror_of"] == c["name"]
            swapped = [
                t.replace("left", "#").replace("right", "left").replace("#", "right") for t in c["tags"]
            ]
            assert sorted(m["tags"]) == sorted(swapped)
        assert c["licence"] and c["source_sha256"] and c["fps"] == 30
    notice = (ASSETS / "NOTICE.md").read_text()
    assert "mocap.cs.cmu.edu" in notice and "NSF EIA-0196217" in notice and "NVIDIA" in notice


@needs_data
def test_shipped_library_matches_the_source_files(lib):
    for c in lib.clips:
        digest = hashlib.sha256((MOCAP / c["source"]).read_bytes()).hexdigest()
        assert digest == c["source_sha256"], c["name"]


def test_state_at_is_batched_and_unit(lib):
    rng = np.random.default_rng(0)
    clip, t = lib.sample_times(rng, 257)
    s = lib.state_at(clip, t)
    b = 257
    shapes = {"root_pos": (3,), "root_quat": (4,), "sph": (8, 4), "rev": (4,), "root_lin_vel": (3,),
              "root_ang_vel": (3,), "sph_vel": (8, 3), "rev_vel": (4,)}  # fmt: skip
    for k, shp in shapes.items():
        assert getattr(s, k).shape == (b, *shp), k
        assert np.all(np.isfinite(getattr(s, k)))
    np.testing.assert_allclose(np.linalg.norm(s.root_quat, axis=-1), 1.0, atol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(s.sph, axis=-1), 1.0, atol=1e-9)
    # Scalars broadcast; times are clamped to [0, duration] (no clip loops).
    s1 = lib.state_at(3, [-1.0, 0.0, lib.duration(3), 1e3])
    np.testing.assert_allclose(s1.root_pos[0], s1.root_pos[1])
    np.testing.assert_allclose(s1.root_pos[2], s1.root_pos[3])
    # Sampling is proportional to duration.
    c, tt = lib.sample_times(rng, 20000)
    assert np.all(tt >= 0) and np.all(tt <= lib.durations()[c])
    share = np.bincount(c, minlength=len(lib)) / c.size
    np.testing.assert_allclose(share, lib.durations() / lib.durations().sum(), atol=0.01)


def test_interpolation_hits_frames_and_is_continuous(lib):
    c = lib.clip_index("cmu_16_15")
    fr = lib.frames(c)
    n = lib.n_frames(c)
    s = lib.state_at(np.full(n, c), np.arange(n) / lib.fps)
    np.testing.assert_allclose(s.root_pos, fr["root_pos"], atol=1e-9)
    np.testing.assert_allclose(np.abs(np.sum(s.sph * fr["sph"], axis=-1)), 1.0, atol=1e-9)
    t = np.linspace(0, lib.duration(c), 2001)
    s = lib.state_at(np.full(t.size, c), t)
    dt = t[1] - t[0]
    assert np.abs(np.diff(s.root_pos, axis=0)).max() < 3.0 * dt  # < 3 m/s per axis
    assert np.abs(np.diff(s.rev, axis=0)).max() < 15.0 * dt  # < 15 rad/s
    dq = np.abs(np.sum(s.sph[1:] * s.sph[:-1], axis=-1))
    assert 2 * np.arccos(np.clip(dq.min(), -1, 1)) < 15.0 * dt
    # Between two frames the state lies between them.
    mid = lib.state_at(c, 0.5 / lib.fps)
    np.testing.assert_allclose(mid.root_pos[0], 0.5 * (fr["root_pos"][0] + fr["root_pos"][1]), atol=1e-9)


def test_select_and_metadata(lib):
    walks = lib.select(tags="walk", mirrored=False, exclude_tags="uneven_feet")
    assert len(walks) >= 30
    assert all("walk" in walks.tags(i) and not walks.is_mirrored(i) for i in range(len(walks)))
    assert all(0.6 < walks.speed(i) < 2.1 for i in range(len(walks)))
    runs = lib.select(tags=["run"], mirrored=True)
    assert all(runs.speed(i) > 1.2 for i in range(len(runs)))
    # A selection keeps each clip's frames.
    name = runs.clip_names()[0]
    np.testing.assert_array_equal(runs.frames(name)["root_pos"], lib.frames(name)["root_pos"])
    with pytest.raises(ValueError, match="no clip matches"):
        lib.select(tags="moonwalk")
    # Clips start at the origin facing +x.
    s = lib.state_at(np.arange(len(lib)), np.zeros(len(lib)))
    np.testing.assert_allclose(s.root_pos[:, :2], 0.0, atol=1e-5)


def test_save_load_roundtrip(lib, tmp_path):
    sub = lib.select(names=["amp_walk", "cmu_02_01_mirrored"])
    sub.save(tmp_path)
    back = MotionLibrary.load(tmp_path)
    assert back.clip_names() == ["amp_walk", "cmu_02_01_mirrored"]
    s0, s1 = sub.state_at([0, 1], [0.3, 0.7]), back.state_at([0, 1], [0.3, 0.7])
    np.testing.assert_allclose(s0.root_pos, s1.root_pos, atol=1e-6)
    # The index guards the arrays.
    (tmp_path / "library.npz").write_bytes((tmp_path / "library.npz").read_bytes() + b"\0")
    with pytest.raises(ValueError, match="sha256"):
        MotionLibrary.load(tmp_path)


def test_looping_clip_repeats_with_the_root_carried_on(lib):
    fr = lib.frames("amp_walk")
    meta = dict(lib.info("amp_walk"), name="loop", loop=True)
    loop = MotionLibrary.from_clips([(meta, fr)], lib.fps)
    d = loop.duration(0)
    # At the wrap the root continues on the ground from the last frame (the pose, root height included,
    # jumps back to the first frame's, which for a true loop is the same).
    s = loop.state_at([0, 0], [d - 1e-9, d + 1e-9])
    np.testing.assert_allclose(s.root_pos[0, :2], s.root_pos[1, :2], atol=1e-6)
    np.testing.assert_allclose(heading_of(s.root_quat[0]), heading_of(s.root_quat[1]), atol=1e-6)
    # Two cycles later: the pose of t, the root moved on by two cycles of displacement.
    s = loop.state_at([0, 0], [0.4, 0.4 + 2 * d])
    np.testing.assert_allclose(np.abs(np.sum(s.sph[0] * s.sph[1], -1)), 1.0, atol=1e-9)
    np.testing.assert_allclose(s.rev[0], s.rev[1], atol=1e-9)
    assert np.linalg.norm(s.root_pos[1, :2] - s.root_pos[0, :2]) > 1.8 * np.linalg.norm(
        fr["root_pos"][-1, :2]
    )


# --- mirroring ---------------------------------------------------------------------------------------------


def test_mirroring_twice_is_identity_and_swaps_sides(lib):
    fr = lib.frames("cmu_16_23")
    back = mirror_frames(mirror_frames(fr))
    for k in FIELDS:
        if k in ("root_quat", "sph"):
            np.testing.assert_allclose(np.abs(np.sum(back[k] * fr[k], axis=-1)), 1.0, atol=1e-9)
        else:
            np.testing.assert_allclose(back[k], fr[k], atol=1e-12)
    m = lib.frames("cmu_16_23_mirrored")
    pos, quat = humanoid_fk(fr["root_pos"], fr["root_quat"], fr["sph"], fr["rev"])
    mpos, mquat = humanoid_fk(m["root_pos"], m["root_quat"], m["sph"], m["rev"])
    # Right and left foot heights swap; every body is reflected through the x-z plane.
    np.testing.assert_allclose(foot_heights(mpos, mquat), foot_heights(pos, quat)[:, ::-1], atol=1e-5)
    swap = [0, 1, 2, 9, 10, 11, 12, 13, 14, 3, 4, 5, 6, 7, 8]
    np.testing.assert_allclose(mpos, pos[:, swap] * np.array([1.0, -1.0, 1.0]), atol=1e-5)
    # A veer to the left becomes a veer to the right.
    assert lib.info("cmu_16_23")["metrics"]["heading_change_deg"] > 20
    assert lib.info("cmu_16_23_mirrored")["metrics"]["heading_change_deg"] < -20
    assert "veer_right" in lib.tags("cmu_16_23_mirrored")


# --- conversion checks ---------------------------------------------------------------------------------


@needs_data
def test_amp_walk_matches_its_own_fk_and_pybullet(client):
    m = load_amp_npy(MOCAP / "amp_humanoid" / "amp_humanoid_walk.npy")
    frames, diag = mc.convert_amp(m)
    # The URDF and the AMP skeleton have identical segments: the frame change C^-1 q C (C = R_x(90))
    # reproduces the clip's body positions to float precision (knees/elbows are exact hinges).
    assert diag["fk_scale"] == pytest.approx(1.0, abs=1e-6)
    assert diag["fk_err_max_m"] < 1e-6
    assert max(v["max"] for v in diag["hinge_residual_deg"].values()) < 0.1
    # ... and PyBullet puts the links where the numpy FK does.
    body = _load_humanoid(client)
    pos, _ = humanoid_fk(frames["root_pos"], frames["root_quat"], frames["sph"], frames["rev"])
    joints = [1, 2, 3, 4, 5, 6, 7, 9, 10, 11, 12, 13]
    for i in range(0, m.n_frames, 15):
        p.resetBasePositionAndOrientation(
            body, frames["root_pos"][i].tolist(), frames["root_quat"][i].tolist(), physicsClientId=client
        )
        s, r = frames["sph"][i].tolist(), frames["rev"][i].tolist()
        p.resetJointStatesMultiDof(body, joints, [s[0], s[1], s[2], [r[0]], s[3], s[4], [r[1]], s[5], [r[2]], s[6], s[7], [r[3]]],
                                   physicsClientId=client)  # fmt: skip
        st = p.getLinkStates(body, list(range(15)), computeForwardKinematics=True, physicsClientId=client)
        np.testing.assert_allclose(np.array([x[4] for x in st]), pos[i], atol=1e-5)
    p.removeBody(body, physicsClientId=client)


def _csv_speeds() -> dict[str, float]:
    with open(MOCAP / "cmu" / "clips.csv", newline="") as f:
        return {r["clip"]: float(r["mean_speed_mps"]) for r in csv.DictReader(f) if r["mean_speed_mps"]}


@needs_data
@pytest.mark.parametrize(("name", "fmt"), [("02_01", "amc"), ("16_21", "amc"), ("07_08", "bvh")])
def test_cmu_retargeting_of_walks(name, fmt):
    subject = name.split("_")[0]
    path = MOCAP / "cmu" / subject / f"{name}.{fmt}"
    if fmt == "amc":
        clip = mocap_io.parse_amc(path, mocap_io.parse_asf(MOCAP / "cmu" / subject / f"{subject}.asf"))
    else:
        clip = mocap_io.parse_bvh(path).slice(1)
    rt = mc.retarget_cmu(clip)
    # Bone directions (thighs, shins, upper arms, forearms, neck) follow the mocap's: exact except
    # where a near-straight elbow or knee leaves its bending plane undefined.
    all_err = np.concatenate([rt.bone_err_deg[b] for b in mc.BONES])
    assert all_err.mean() < 0.5 and all_err.max() < 5.0
    assert rt.hinge_clipped == 0
    assert np.mean([e.mean() for e in rt.pos_err_m.values()]) < 0.08  # proportions differ (m)
    out, _ = mc.finish(rt.frames, clip.fps)
    met = mc.clip_metrics(out, 30.0)
    assert met["speed_mps"] == pytest.approx(_csv_speeds()[name], rel=0.15)
    # Feet on the ground: the lowest foot reaches z = 0 (5th percentile) and barely goes below.
    pos, quat = humanoid_fk(out["root_pos"], out["root_quat"], out["sph"], out["rev"])
    low = foot_heights(pos, quat).min(axis=1)
    assert abs(np.percentile(low, 5)) < 0.003 and low.min() > -0.02 and np.median(low) < 0.03
    assert met["flight_frac"] < 0.05  # a walk: always a foot on the ground
    # Retargeting adds no foot skating: the humanoid's planted heel/toe moves like the mocap's.
    assert rt.planted_skate_mps < 0.15 and rt.planted_skate_mps < rt.planted_skate_src_mps + 0.02
    assert np.median(rt.foot_tilt_deg) < 6.0  # flat mocap feet give flat humanoid feet (degrees)


@needs_data
def test_library_walking_speeds_match_clips_csv(lib):
    csv_speed = _csv_speeds()
    n = 0
    for c in lib.clips:
        short = c["name"].removeprefix("cmu_").removesuffix("_mirrored")
        if (
            "walk" in c["tags"] and short in csv_speed and short != "07_12"
        ):  # 07_12's csv speed counts a glitch frame
            assert lib.speed(c["name"]) == pytest.approx(csv_speed[short], rel=0.15), c["name"]
            n += 1
    assert n >= 60


# --- velocities and playback ------------------------------------------------------------------------------


def test_velocities_match_finite_differences(lib):
    c = lib.clip_index("cmu_16_36")
    fr = lib.frames(c)
    dt = 1.0 / lib.fps
    # Stored frame velocities are central differences of the stored poses ...
    np.testing.assert_allclose(
        fr["root_lin_vel"][1:-1], (fr["root_pos"][2:] - fr["root_pos"][:-2]) / (2 * dt), atol=1e-4
    )
    np.testing.assert_allclose(compute_velocities(fr, lib.fps)["sph_vel"], fr["sph_vel"], atol=1e-3)
    # ... and agree with differences of the interpolated states over one frame at any time (exact for
    # positions and angles, which are interpolated linearly; close for the slerped rotations).
    t = np.linspace(2 * dt, lib.duration(c) - 2 * dt, 40)
    s, s0, s1 = (lib.state_at(np.full(t.size, c), t + d) for d in (0.0, -dt, dt))
    np.testing.assert_allclose(s.root_lin_vel, (s1.root_pos - s0.root_pos) / (2 * dt), atol=1e-4)
    np.testing.assert_allclose(s.rev_vel, (s1.rev - s0.rev) / (2 * dt), atol=1e-3)
    fd_ang = quat_to_rotvec(quat_mul(s1.root_quat, quat_conj(s0.root_quat))) / (2 * dt)
    fd_sph = quat_to_rotvec(quat_mul(quat_conj(s0.sph), s1.sph)) / (2 * dt)
    assert np.abs(s.root_ang_vel - fd_ang).max() < 0.05 * np.abs(fd_ang).max()
    assert np.abs(s.sph_vel - fd_sph).max() < 0.1 * np.abs(fd_sph).max()


def test_playback_in_pybullet(lib, client):
    with sim.quiet():
        plane = p.loadURDF("plane.urdf", physicsClientId=client)
    bodies = [_load_humanoid(client) for _ in range(2)]
    walk = lib.select(tags="walk", exclude_tags="uneven_feet")
    names = ["cmu_16_15", "cmu_07_08_mirrored"]
    for name in names:
        c = lib.clip_index(name)
        for t in np.linspace(0.0, lib.duration(c), 25):
            lib.play(client, bodies, [c, c], [t, t], origin=np.array([[0.0, 0.0, 0.0], [0.0, 3.0, 0.0]]))
            for body in bodies:
                feet = [p.getAABB(body, j, physicsClientId=client)[0][2] for j in (5, 11)]
                assert -0.03 < min(feet) < 0.05, (name, t, feet)
                head = p.getAABB(body, 2, physicsClientId=client)[1][2]
                assert 1.5 < head < 1.8, (name, t, head)
    # Crown height over every standing/walking clip (by the library's own FK).
    s = walk.state_at(np.arange(len(walk)), np.zeros(len(walk)) + 0.5)
    pos, quat = humanoid_fk(s.root_pos, s.root_quat, s.sph, s.rev)
    assert np.all(np.abs(foot_heights(pos, quat).min(axis=1)) < 0.05)
    for body in bodies:
        p.removeBody(body, physicsClientId=client)
    p.removeBody(plane, physicsClientId=client)


def test_playback_velocities_are_consistent_in_pybullet(lib, client):
    """The velocities ``play`` sets (base in the world frame, spherical joints in the child frame) make
    PyBullet report link velocities that match the links' motion between neighbouring times."""
    body = _load_humanoid(client, fixed=False)
    c = lib.clip_index("cmu_02_02")
    links = [2, 5, 8, 11, 14]  # head, feet, hands
    for t in (1.0, 1.5):  # on frames: the stored velocities are central differences there
        com = []
        for d in (-1.0 / lib.fps, 1.0 / lib.fps):
            lib.play(client, [body], c, t + d)
            com.append(
                np.array(
                    [
                        p.getLinkState(body, j, computeForwardKinematics=True, physicsClientId=client)[0]
                        for j in links
                    ]
                )
            )
        fd = (com[1] - com[0]) * lib.fps / 2
        lib.play(client, [body], c, t)
        vel = np.array(
            [
                p.getLinkState(
                    body, j, computeLinkVelocity=True, computeForwardKinematics=True, physicsClientId=client
                )[6]
                for j in links
            ]
        )
        assert np.abs(vel - fd).max() < 0.1 * np.abs(fd).max(), (vel, fd)
    p.removeBody(body, physicsClientId=client)


def test_a_translated_reference_state_moves_and_keeps_everything_else():
    from navzoo.agents.motion_lib import MotionLibrary

    lib = MotionLibrary.load()
    ref = lib.state_at(np.array([0, 1]), np.array([0.1, 0.2]))
    moved = ref.translated(np.array([[1.0, -2.0, 0.5], [0.0, 0.0, 0.0]]))
    np.testing.assert_allclose(np.asarray(moved.root_pos) - np.asarray(ref.root_pos), [[1.0, -2.0, 0.5], [0, 0, 0]])
    for field in ("root_quat", "sph", "rev", "root_lin_vel", "root_ang_vel", "sph_vel", "rev_vel"):
        assert getattr(moved, field) is getattr(ref, field)
    np.testing.assert_allclose(np.asarray(ref.translated(np.array([0.0, 0.0, 1.0])).root_pos)[:, 2],
                               np.asarray(ref.root_pos)[:, 2] + 1.0)  # one offset for the whole batch
