"""Motion realism metric: keypoints, normalisation, k-means statistics, MMD and its floor, validation."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from navzoo import sim
from navzoo.agents.amp.features import reference_state_dict
from navzoo.agents.motion_lib import MotionLibrary, heading_of, quat_about_z, quat_mul, quat_rotate
from navzoo.benchmark.realism import (
    KEYPOINT_NAMES,
    METRIC_KEYS,
    RealismReference,
    clip_poses,
    hip_heading,
    keypoints_from_state,
    kmeans,
    library_realism,
    mmd_rbf,
    normalize_poses,
    poses_from_state,
    realism_metrics,
    spine_length,
)

FIT = {"ks": (50, 100), "seed": 0, "max_samples": 800, "n_init": 2}


@pytest.fixture(scope="module")
def lib() -> MotionLibrary:
    return MotionLibrary.load()


@pytest.fixture(scope="module")
def poses(lib) -> tuple[np.ndarray, np.ndarray]:
    return clip_poses(lib, return_clip_ids=True)


@pytest.fixture(scope="module")
def halves(poses) -> tuple[np.ndarray, np.ndarray]:
    """Two disjoint random halves of every third library frame (~2090 poses each)."""
    x = poses[0][::3]
    perm = np.random.default_rng(1).permutation(x.shape[0])
    h = x.shape[0] // 2
    return x[np.sort(perm[:h])], x[np.sort(perm[h:])]


@pytest.fixture(scope="module")
def ref(halves) -> RealismReference:
    return RealismReference.fit(halves[0], **FIT)


def _states(lib: MotionLibrary, n: int = 200, seed: int = 0):
    clip, t = lib.sample_times(np.random.default_rng(seed), n)
    return lib.state_at(clip, t)


# --- keypoints and normalisation ---------------------------------------------------------------------


def test_keypoints_are_pybullet_joint_centres(lib):
    """The 15 keypoints are the link frame origins PyBullet reports, pelvis = base position."""
    assert len(KEYPOINT_NAMES) == 15 and len(set(KEYPOINT_NAMES)) == 15
    s = _states(lib, 3, seed=3)
    kp = keypoints_from_state(s.root_pos, s.root_quat, s.sph, s.rev)
    assert kp.shape == (3, 15, 3)
    np.testing.assert_allclose(kp[:, 0], s.root_pos)
    cid = sim.connect()
    try:
        with sim.quiet():
            body = p.loadURDF(
                "humanoid/humanoid.urdf", [0, 0, 1], useFixedBase=True, globalScaling=0.25,
                flags=p.URDF_MAINTAIN_LINK_ORDER, physicsClientId=cid,
            )  # fmt: skip
        c, t = lib.sample_times(np.random.default_rng(3), 3)
        for i in range(3):
            st = lib.play(cid, [body], c[i], t[i], set_velocities=False)
            links = p.getLinkStates(body, list(range(15)), computeForwardKinematics=1, physicsClientId=cid)
            mine = keypoints_from_state(st.root_pos, st.root_quat, st.sph, st.rev)[0]
            np.testing.assert_allclose(mine, [ls[4] for ls in links], atol=1e-5)
    finally:
        sim.disconnect(cid)


def test_state_dict_and_reference_state_agree(lib):
    s = _states(lib, 50)
    a = poses_from_state(s)
    b = poses_from_state(reference_state_dict(s))  # a read_state()-like dict
    np.testing.assert_array_equal(a, b)
    one = keypoints_from_state(s.root_pos[0], s.root_quat[0], s.sph[0], s.rev[0])  # no batch axis
    np.testing.assert_allclose(one[0], keypoints_from_state(s.root_pos, s.root_quat, s.sph, s.rev)[0])


def test_normalisation_invariant_to_translation_yaw_and_scale(lib):
    s = _states(lib, 300, seed=1)
    base = poses_from_state(s)
    rng = np.random.default_rng(2)
    yaw = rng.uniform(-np.pi, np.pi, size=300)
    shift = rng.normal(scale=5.0, size=(300, 3))
    qz = quat_about_z(yaw)
    moved = keypoints_from_state(quat_rotate(qz, s.root_pos) + shift, quat_mul(qz, s.root_quat), s.sph, s.rev)
    np.testing.assert_allclose(normalize_poses(moved), base, atol=1e-9)
    kp = keypoints_from_state(s.root_pos, s.root_quat, s.sph, s.rev)
    np.testing.assert_allclose(normalize_poses(2.7 * kp + np.array([1.0, -3.0, 0.5])), base, atol=1e-9)
    # What the normalisation does: pelvis at 0, hip line along +y (left hip on the left), unit spine.
    n = base.reshape(-1, 15, 3)
    np.testing.assert_allclose(n[:, 0], 0.0, atol=1e-12)
    lat = n[:, 9] - n[:, 3]
    np.testing.assert_allclose(lat[:, 0], 0.0, atol=1e-9)
    assert np.all(lat[:, 1] > 0)
    np.testing.assert_allclose(spine_length(n), 1.0)
    # ... and is not trivial: a pitched body differs from an upright one.
    assert np.abs(base - base[:1]).max() > 0.1


def test_hip_heading_matches_root_heading(lib):
    s = _states(lib, 500, seed=4)
    kp = keypoints_from_state(s.root_pos, s.root_quat, s.sph, s.rev)
    d = np.angle(np.exp(1j * (hip_heading(kp) - heading_of(s.root_quat))))
    assert np.median(np.abs(d)) < 0.02 and np.abs(d).max() < 0.3


def test_clip_poses_are_the_30hz_frames(lib):
    sub = lib.select(names=lib.clip_names()[:3])
    x, cid = clip_poses(sub, return_clip_ids=True)
    assert x.shape == (sub.num_frames, 45)  # the library is stored at 30 Hz
    np.testing.assert_array_equal(np.bincount(cid), [sub.n_frames(i) for i in range(3)])
    fr = sub.frames(1)
    np.testing.assert_allclose(x[cid == 1], poses_from_state(fr), atol=1e-9)
    half = clip_poses(sub, fps=15.0)
    assert abs(half.shape[0] - x.shape[0] / 2) <= 3
    by_name = clip_poses(lib, clips=[sub.clip_names()[2]])
    np.testing.assert_allclose(by_name, x[cid == 2], atol=1e-12)


def test_clip_root_speeds_follow_the_clip_poses_frames(lib):
    from navzoo.benchmark.realism import clip_root_speeds

    sub = lib.select(names=lib.clip_names()[:3])
    _, cid = clip_poses(sub, return_clip_ids=True)
    v = clip_root_speeds(sub)
    assert v.shape == cid.shape and (v >= 0).all()
    xy = np.asarray(sub.frames(0)["root_pos"])[:, :2]
    path = np.linalg.norm(np.diff(xy, axis=0), axis=1).sum()
    assert np.mean(v[cid == 0]) == pytest.approx(path / sub.duration(0), rel=0.05)  # the mean speed of the clip


# --- k-means statistics and MMD ---------------------------------------------------------------------


def test_kmeans_recovers_separated_blobs():
    rng = np.random.default_rng(0)
    centres = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    truth = np.repeat(np.arange(3), 100)
    x = centres[truth] + rng.normal(scale=0.5, size=(300, 2))
    c, lab, _ = kmeans(x, 3, seed=5)
    for j in range(3):
        assert len(set(lab[truth == j])) == 1
    assert len(set(lab)) == 3
    np.testing.assert_allclose(np.sort(c, axis=0), np.sort(centres, axis=0), atol=0.2)


def test_reference_against_itself(ref, halves):
    m = realism_metrics(halves[0], ref)
    assert tuple(m) == METRIC_KEYS
    for k in (50, 100):
        assert m[f"coverage_k{k}"] == 1.0
        assert m[f"entropy_k{k}"] == pytest.approx(ref.self_metrics[f"entropy_k{k}"])
        assert m[f"dist_k{k}"] == pytest.approx(ref.self_metrics[f"dist_k{k}"])
        assert 0.8 < m[f"entropy_k{k}"] < 1.0
    assert m["dist_k100"] < m["dist_k50"]
    assert m["n_generated"] == halves[0].shape[0]
    assert 0 < ref.mmd_floor < 0.1
    assert m["mmd"] <= 1.5 * ref.mmd_floor


def test_held_out_reference_scores_at_the_floor(ref, halves):
    m = realism_metrics(halves[1], ref)
    assert m["coverage_k50"] == 1.0 and m["coverage_k100"] >= 0.95
    assert m["entropy_k50"] > 0.85
    assert m["dist_k50"] < 1.2 * ref.self_metrics["dist_k50"]
    assert 0.5 * ref.mmd_floor < m["mmd"] < 2.0 * ref.mmd_floor


def test_centroids_as_generated_poses_cover_evenly(ref):
    m = realism_metrics(ref.centroids[50], ref)
    assert m["coverage_k50"] == 1.0
    assert m["entropy_k50"] == pytest.approx(1.0)
    assert m["dist_k50"] == pytest.approx(0.0, abs=1e-6)


def test_degenerate_and_narrow_generators_score_badly(ref, halves, poses):
    one = np.repeat(halves[1][:1], 500, axis=0)
    m = realism_metrics(one, ref)
    assert m["coverage_k50"] == 1 / 50 and m["coverage_k100"] == 1 / 100
    assert m["entropy_k50"] == 0.0 and m["entropy_k100"] == 0.0
    assert m["mmd"] > 0.3 and m["mmd"] > 10 * ref.mmd_floor
    # A single clip: few clusters, far from the reference distribution, but closer than one pose.
    x, cid = poses
    clip = realism_metrics(x[cid == np.bincount(cid).argmax()], ref)
    assert clip["coverage_k50"] < 0.3
    assert 3 * ref.mmd_floor < clip["mmd"] < m["mmd"]
    assert clip["entropy_k50"] > 0.0


def test_mmd_basics(halves):
    a, b = halves[0][:300], halves[1][:200]
    assert mmd_rbf(a, a, 1.0) == pytest.approx(0.0, abs=1e-6)
    assert mmd_rbf(a, b, 1.0) == pytest.approx(mmd_rbf(b, a, 1.0))
    assert mmd_rbf(a, b + 1.0, 1.0) > mmd_rbf(a, b, 1.0)


def test_deterministic_with_seed(halves, ref):
    x = halves[0][:1500]
    r1 = RealismReference.fit(x, ks=(10, 20), seed=7, max_samples=300)
    r2 = RealismReference.fit(x, ks=(10, 20), seed=7, max_samples=300)
    for k in (10, 20):
        np.testing.assert_array_equal(r1.centroids[k], r2.centroids[k])
    assert (r1.sigma, r1.mmd_floor) == (r2.sigma, r2.mmd_floor)
    g = halves[1][:900]
    assert realism_metrics(g, r1) == realism_metrics(g, r2)
    r3 = RealismReference.fit(x, ks=(10, 20), seed=8, max_samples=300)
    assert not np.array_equal(r1.centroids[10], r3.centroids[10])
    assert realism_metrics(halves[1], ref) == realism_metrics(halves[1], ref)


def test_library_realism_and_clip_split_floor(lib):
    sub = lib.select(names=lib.clip_names()[:12])
    r = RealismReference.from_library(sub, ks=(5, 10), max_samples=300, n_init=1, split_by_clip=True)
    m = library_realism(sub, r)
    assert m == realism_metrics(clip_poses(sub), r)
    assert set(m) == {"coverage_k5", "entropy_k5", "dist_k5", "coverage_k10", "entropy_k10", "dist_k10",
                      "mmd", "mmd_floor", "n_generated"}  # fmt: skip
    assert m["coverage_k5"] == 1.0 and m["n_generated"] == sub.num_frames


# --- validation ------------------------------------------------------------------------------------


def test_input_validation(ref, halves, lib):
    good = halves[1][:10]
    with pytest.raises(ValueError, match="empty"):
        realism_metrics(np.zeros((0, 45)), ref)
    bad = good.copy()
    bad[3, 7] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        realism_metrics(bad, ref)
    with pytest.raises(ValueError, match="shape"):
        realism_metrics(good[:, :44], ref)
    with pytest.raises(ValueError, match="shape"):
        realism_metrics(good.reshape(10, 15, 3), ref)
    with pytest.raises(ValueError, match="shape"):
        normalize_poses(np.zeros((4, 14, 3)))
    with pytest.raises(ValueError, match="degenerate"):
        normalize_poses(np.zeros((4, 15, 3)))
    s = _states(lib, 4)
    with pytest.raises(ValueError, match="sph has shape"):
        keypoints_from_state(s.root_pos, s.root_quat, s.sph[:3], s.rev)
    with pytest.raises(ValueError, match="root_quat"):
        keypoints_from_state(s.root_pos, np.zeros((4, 4)), s.sph, s.rev)
    with pytest.raises(ValueError, match="non-finite"):
        keypoints_from_state(s.root_pos * np.nan, s.root_quat, s.sph, s.rev)
    with pytest.raises(ValueError, match="lacks"):
        poses_from_state({"root_pos": s.root_pos})
    with pytest.raises(ValueError, match="K = 50"):
        RealismReference.fit(good, ks=(50,))
    with pytest.raises(ValueError, match="empty"):
        RealismReference.fit(np.zeros((0, 45)))
