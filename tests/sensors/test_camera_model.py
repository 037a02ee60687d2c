"""Camera geometry and keypoint detector noise on cases with known answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navzoo.sensors import (
    COCO_KEYPOINTS,
    COCO_SKELETON,
    KeypointNoise,
    PinholeCamera,
    default_robot_cameras,
    occlusion_visible,
)

W, H = 640, 480
T30 = math.tan(math.radians(30.0))


def _cam(**kwargs) -> PinholeCamera:
    return PinholeCamera(W, H, **kwargs)


def _person_uv(n: int, u: float = 320.0, v: float = 240.0) -> np.ndarray:
    """(n, 17, 2) keypoints spread in a small box around (u, v)."""
    offsets = np.stack([np.linspace(-20, 20, 17), np.linspace(-60, 60, 17)], axis=-1)
    return np.broadcast_to(np.array([u, v]) + offsets, (n, 17, 2)).copy()


def _clean(**kwargs) -> KeypointNoise:
    base = dict(
        miss_prob=0.0,
        miss_prob_per_m=0.0,
        person_miss_prob=0.0,
        person_miss_prob_per_m=0.0,
        min_keypoints=0,
        false_positive_rate=0.0,
    )
    base.update(kwargs)
    return KeypointNoise(**base)


# --- COCO layout -------------------------------------------------------------------------------------


def test_coco_layout():
    assert len(COCO_KEYPOINTS) == 17
    assert COCO_KEYPOINTS[0] == "nose" and COCO_KEYPOINTS[5] == "left_shoulder"
    assert COCO_KEYPOINTS[16] == "right_ankle"
    assert len(COCO_SKELETON) == 19
    assert all(0 <= a < 17 and 0 <= b < 17 and a != b for a, b in COCO_SKELETON)
    limbs = {frozenset(p) for p in COCO_SKELETON}
    assert len(limbs) == 19
    for pair in [(5, 6), (11, 12), (5, 7), (7, 9), (13, 15), (0, 1), (5, 11), (3, 5)]:
        assert frozenset(pair) in limbs


# --- geometry ----------------------------------------------------------------------------------------


def test_intrinsics():
    cam = _cam()
    fx = 320.0 / T30
    np.testing.assert_allclose(cam.intrinsics(), [[fx, 0, 320], [0, fx, 240], [0, 0, 1]])
    assert cam.vfov_deg == pytest.approx(math.degrees(2 * math.atan(240 / fx)))


def test_straight_ahead_projects_to_principal_point():
    cam = _cam(mount_z=1.0)
    uv, depth = cam.project(np.array([5.0, 0.0, 1.0]), (0.0, 0.0, 0.0))
    np.testing.assert_allclose(uv, [320.0, 240.0], atol=1e-9)
    assert depth == pytest.approx(5.0)
    np.testing.assert_allclose(
        cam.world_to_camera(np.array([5.0, 0.0, 1.0]), (0, 0, 0)), [0, 0, 5], atol=1e-12
    )


def test_fov_edges_project_to_image_borders():
    cam = _cam()
    pts = np.array([[5.0, 5.0 * T30, 1.0], [5.0, -5.0 * T30, 1.0]])  # left edge (+y), right edge (-y)
    uv, _ = cam.project(pts, (0, 0, 0))
    np.testing.assert_allclose(uv[:, 0], [0.0, 640.0], atol=1e-9)
    np.testing.assert_allclose(uv[:, 1], [240.0, 240.0], atol=1e-9)
    inside = cam.in_image(uv, np.array([5.0, 5.0]))
    assert inside.tolist() == [True, False]  # image is [0, width)


def test_point_behind_camera():
    cam = _cam()
    uv, depth = cam.project(np.array([[-3.0, 0.0, 1.0], [0.0, 0.0, 1.0]]), (0, 0, 0))
    assert np.isnan(uv).all()
    assert (depth <= 0).all()
    assert not cam.in_image(uv, depth).any()
    assert not cam.fov_contains(np.array([-3.0, 0.0, 1.0]), (0, 0, 0))


def test_robot_and_mount_yaw_compose():
    cam = _cam(mount_yaw=math.radians(30))
    pose = (0.0, 0.0, math.radians(-30))
    uv, depth = cam.project(np.array([4.0, 0.0, 1.0]), pose)
    np.testing.assert_allclose(uv, [320.0, 240.0], atol=1e-9)
    assert depth == pytest.approx(4.0)
    # a point along world +y is 90 degrees to the left: outside the 60 degree FOV
    assert not cam.fov_contains(np.array([0.0, 4.0, 1.0]), pose)


def test_mount_offset_rotates_with_robot():
    cam = _cam(mount_x=0.5, mount_y=0.0, mount_z=1.2)
    pose = (1.0, 2.0, math.pi / 2)  # robot faces world +y, camera at (1, 2.5, 1.2)
    pc = cam.world_to_camera(np.array([1.0, 5.5, 1.2]), pose)
    np.testing.assert_allclose(pc, [0.0, 0.0, 3.0], atol=1e-12)
    pc = cam.world_to_camera(np.array([2.0, 5.5, 1.2]), pose)  # world +x is the robot's right -> camera +x
    np.testing.assert_allclose(pc, [1.0, 0.0, 3.0], atol=1e-12)


def test_image_v_grows_downward_and_u_to_the_right():
    cam = _cam(mount_z=1.0)
    uv, _ = cam.project(np.array([[5.0, 0.0, 0.5], [5.0, 0.0, 1.5], [5.0, -1.0, 1.0]]), (0, 0, 0))
    assert uv[0, 1] > 240.0 > uv[1, 1]
    assert uv[2, 0] > 320.0  # world -y is the robot's right -> image right
    fx = cam.fx
    assert uv[0, 1] == pytest.approx(240.0 + fx * 0.5 / 5.0)


def test_depth_is_forward_distance():
    cam = _cam(mount_yaw=math.radians(30))
    pts = np.array([[3.0, 1.0, 0.2], [3.0, -1.0, 1.7]])
    _, depth = _cam().project(pts, (0, 0, 0))
    np.testing.assert_allclose(depth, [3.0, 3.0])
    # for the yawed camera, depth = projection onto its axis
    axis = np.array([math.cos(math.radians(30)), math.sin(math.radians(30))])
    _, depth = cam.project(pts, (0, 0, 0))
    np.testing.assert_allclose(depth, pts[:, :2] @ axis)


def test_pitch_down():
    pitch = math.radians(10)
    cam = _cam(mount_z=1.0, mount_pitch=pitch)
    d = 5.0
    uv, depth = cam.project(np.array([d * math.cos(pitch), 0.0, 1.0 - d * math.sin(pitch)]), (0, 0, 0))
    np.testing.assert_allclose(uv, [320.0, 240.0], atol=1e-9)
    assert depth == pytest.approx(d)


def test_default_robot_cameras():
    left, right = default_robot_cameras()
    assert (left.width, left.height, left.hfov_deg) == (640, 480, 60.0)
    assert left.mount_yaw == pytest.approx(math.radians(30)) and right.mount_yaw == pytest.approx(
        -math.radians(30)
    )
    assert left.mount_z == pytest.approx(1.0) and right.mount_z == pytest.approx(1.0)
    # straight ahead of the robot is on the right border of the left camera, the left border of the right one
    p = np.array([5.0, 0.0, 1.0])
    assert left.project(p, (0, 0, 0))[0][0] == pytest.approx(640.0)
    assert right.project(p, (0, 0, 0))[0][0] == pytest.approx(0.0, abs=1e-9)
    assert left.fov_contains(np.array([5.0, 2.0, 1.0]), (0, 0, 0))
    assert not right.fov_contains(np.array([5.0, 2.0, 1.0]), (0, 0, 0))


def test_camera_validation():
    with pytest.raises(ValueError, match="width"):
        PinholeCamera(0, 480)
    with pytest.raises(ValueError, match="height"):
        PinholeCamera(640, -1)
    for bad in (0.0, 180.0, -5.0):
        with pytest.raises(ValueError, match="hfov_deg"):
            PinholeCamera(640, 480, hfov_deg=bad)
    with pytest.raises(ValueError, match="mount_pitch"):
        PinholeCamera(640, 480, mount_pitch=2.0)


# --- detector noise ----------------------------------------------------------------------------------


def test_noise_std_grows_with_distance():
    noise = _clean(pixel_std=2.0, pixel_std_per_m=0.5)
    n = 1500
    uv = _person_uv(n)
    vis = np.ones((n, 17), bool)
    stds = []
    for d in (2.0, 8.0):
        out = noise.apply(uv, np.full(n, d), vis, np.random.default_rng(0), image_size=(W, H))
        assert out.detected.all()
        stds.append(np.std(out.uv - uv))
    assert stds[0] == pytest.approx(3.0, rel=0.05)
    assert stds[1] == pytest.approx(6.0, rel=0.05)
    np.testing.assert_allclose(noise.pixel_sigma(np.array([2.0, 8.0])), [3.0, 6.0])


def test_zero_noise_gives_exact_projection():
    cam = _cam()
    pts = np.stack([np.full(17, 4.0), np.linspace(-0.2, 0.2, 17), np.linspace(0.1, 1.7, 17)], axis=-1)[None]
    uv, depth = cam.project(pts, (0, 0, 0))
    out = KeypointNoise.none().apply(
        uv, depth, cam.in_image(uv, depth), np.random.default_rng(3), image_size=cam
    )
    assert out.detected.all() and out.person_detected.all() and not out.false_positive.any()
    np.testing.assert_array_equal(out.uv, uv)
    np.testing.assert_array_equal(out.confidence, 1.0)


def test_reproducible_with_seed():
    noise = KeypointNoise(false_positive_rate=2.0)
    cam = _cam()
    uv = _person_uv(20)
    depth = np.linspace(1, 12, 20)
    vis = np.ones((20, 17), bool)
    a = noise.detect(uv, depth, vis, np.random.default_rng(7), cam)
    b = noise.detect(uv, depth, vis, np.random.default_rng(7), cam)
    c = noise.detect(uv, depth, vis, np.random.default_rng(8), cam)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert not np.array_equal(a.uv, c.uv, equal_nan=True)


def test_truncation_at_borders():
    uv = _person_uv(1)
    uv[0, 0] = [650.0, 240.0]  # outside right
    uv[0, 1] = [100.0, -0.5]  # outside top
    uv[0, 2] = [639.9, 479.9]  # inside corner
    out = KeypointNoise.none().apply(
        uv, np.full(1, 3.0), np.ones((1, 17), bool), np.random.default_rng(0), image_size=(W, H)
    )
    assert out.detected[0].tolist() == [False, False] + [True] * 15
    assert np.isnan(out.uv[0, :2]).all() and (out.confidence[0, :2] == 0).all()
    # with noise at the border, about half survive and none are reported outside
    n = 2000
    uv = _person_uv(n, u=639.0)
    out = _clean(pixel_std=2.0, pixel_std_per_m=0.0).apply(
        uv, np.full(n, 3.0), np.ones((n, 17), bool), np.random.default_rng(1), image_size=(W, H)
    )
    edge = out.detected[:, 8]  # offset 0 -> u = 639
    assert 0.6 < edge.mean() < 0.75  # P(N(639, 2) < 640) = 0.69
    assert (out.uv[out.detected][:, 0] < W).all()


def test_invisible_keypoints_and_missing_person():
    uv = _person_uv(2)
    vis = np.zeros((2, 17), bool)
    vis[0, :4] = True
    vis[1, :5] = True
    noise = KeypointNoise.none(min_keypoints=5)
    out = noise.apply(uv, np.full(2, 3.0), vis, np.random.default_rng(0), image_size=(W, H))
    assert out.person_detected.tolist() == [False, True]
    assert not out.detected[0].any()
    assert out.detected[1].tolist() == [True] * 5 + [False] * 12
    # a person with no visible keypoint is never detected, even with min_keypoints=0
    out = KeypointNoise.none().apply(
        uv, np.full(2, 3.0), np.zeros((2, 17), bool), np.random.default_rng(0), image_size=(W, H)
    )
    assert not out.person_detected.any()


def test_miss_rates_and_confidence_vs_distance():
    noise = KeypointNoise(false_positive_rate=0.0, min_keypoints=0)
    n = 4000
    uv = _person_uv(n)
    vis = np.ones((n, 17), bool)
    res = {}
    for d in (2.0, 8.0):
        out = noise.apply(uv, np.full(n, d), vis, np.random.default_rng(5), image_size=(W, H))
        person_rate = out.person_detected.mean()
        kp_rate = out.detected[out.person_detected].mean()
        res[d] = (person_rate, kp_rate, out.confidence[out.detected].mean())
        assert 0.0 <= out.confidence.min() and out.confidence.max() <= 1.0
    assert res[2.0][0] == pytest.approx(1 - 0.04, abs=0.01)
    assert res[8.0][0] == pytest.approx(1 - 0.10, abs=0.015)
    assert res[2.0][1] == pytest.approx(1 - 0.06, abs=0.01)
    assert res[8.0][1] == pytest.approx(1 - 0.18, abs=0.01)
    assert res[2.0][2] > res[8.0][2] + 0.1


def test_false_positive_statistics():
    noise = KeypointNoise(false_positive_rate=0.5)
    cam = _cam()
    rng = np.random.default_rng(11)
    counts = []
    for _ in range(3000):
        fp = noise.false_positives(rng, cam)
        counts.append(len(fp.uv))
        if len(fp.uv):
            assert fp.false_positive.all() and fp.person_detected.all()
            assert (fp.detected.sum(axis=1) >= noise.min_keypoints).all()
            pts = fp.uv[fp.detected]
            assert ((pts >= 0) & (pts < [W, H])).all()
            assert ((fp.confidence[fp.detected] >= 0.1) & (fp.confidence[fp.detected] <= 0.5)).all()
    counts = np.array(counts)
    assert counts.mean() == pytest.approx(0.5, abs=0.04)  # Poisson: std of the mean 0.013
    assert counts.var() == pytest.approx(0.5, abs=0.06)
    assert len(KeypointNoise.none().false_positives(rng, cam).uv) == 0


def test_detect_appends_false_positives():
    noise = KeypointNoise(false_positive_rate=20.0)
    out = noise.detect(
        _person_uv(2), np.full(2, 3.0), np.ones((2, 17), bool), np.random.default_rng(2), _cam()
    )
    assert out.uv.shape[1:] == (17, 2) and len(out.uv) > 2
    assert not out.false_positive[:2].any() and out.false_positive[2:].all()


def test_noise_validation():
    with pytest.raises(ValueError, match="pixel_std"):
        KeypointNoise(pixel_std=-1.0)
    with pytest.raises(ValueError, match="miss_prob"):
        KeypointNoise(miss_prob=1.5)
    with pytest.raises(ValueError, match="min_keypoints"):
        KeypointNoise(min_keypoints=18)
    with pytest.raises(ValueError, match="false_positive_rate"):
        KeypointNoise(false_positive_rate=float("nan"))
    with pytest.raises(ValueError, match="uv"):
        KeypointNoise().apply(
            np.zeros((1, 5, 2)),
            np.ones(1),
            np.ones((1, 5), bool),
            np.random.default_rng(0),
            image_size=(W, H),
        )


# --- occlusion ---------------------------------------------------------------------------------------


def test_occlusion_visible():
    img = np.full((H, W), 10.0)
    img[:, :100] = 3.0  # wall at 3 m on the left
    img[:, 100:200] = 4.9  # within tolerance of 5 m
    img[:, 200:300] = np.nan  # no return
    uv = np.array(
        [
            [50.0, 240.0],
            [150.0, 240.0],
            [250.0, 240.0],
            [400.0, 240.0],
            [700.0, 240.0],
            [np.nan, np.nan],
            [99.9, 10.0],
            [100.0, 10.0],
        ]
    )
    depth = np.array([5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0, 5.0])
    vis = occlusion_visible(uv, depth, img, tolerance=0.15)
    assert vis.tolist() == [False, True, True, True, False, False, False, True]
    # a keypoint in front of the wall is visible; with zero tolerance the 4.9 m surface hides 5.0 m
    assert occlusion_visible(np.array([50.0, 240.0]), np.array(2.0), img)
    assert not occlusion_visible(np.array([150.0, 240.0]), np.array(5.0), img, tolerance=0.0)
    assert not occlusion_visible(np.array([400.0, 240.0]), np.array(-1.0), img)
