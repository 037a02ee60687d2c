"""Monoloco network plumbing, humanoid COCO keypoints, the camera pipeline and the perception wrapper."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import torch

import navzoo
from navzoo.perception.body_keypoints import humanoid_keypoints, humanoid_pose
from navzoo.perception.dataset import sample_targets
from navzoo.perception.monoloco import (
    INPUT_DIM,
    MonolocoEstimator,
    MonolocoNet,
    decode_outputs,
    keypoint_features,
    laplace_loss,
    load_estimator,
    save_model,
)
from navzoo.perception.pipeline import RobotPerception, observe_camera, people_ground_truth
from navzoo.sensors import COCO_KEYPOINTS, KeypointNoise, PinholeCamera, default_robot_cameras

KP = {n: k for k, n in enumerate(COCO_KEYPOINTS)}


@pytest.fixture(scope="module")
def line_env():
    """An open room: robot at (-3, 0) facing +x, person 0 at 2 m ahead, person 1 right behind them at 4 m."""
    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=2)
    env.reset(seed=0, options={"robot_starts": [[-3.0, 0.0]], "robot_goals": [[3.0, 3.0]], "robot_yaws": [0.0],
                               "human_starts": [[-1.0, 0.0], [1.0, 0.0]],
                               "human_goals": [[-1.0, 6.0], [1.0, -6.0]]})
    yield env
    env.close()


def test_keypoints_follow_the_body(line_env):
    env = line_env
    ids = env.humans.ids
    kp = humanoid_keypoints(env.client, ids)
    pelvis, yaw = humanoid_pose(env.client, ids)
    assert kp.shape == (2, 17, 3)
    np.testing.assert_allclose(yaw, env.yaw[1:], atol=1e-6)
    for h in range(2):
        c, s = math.cos(yaw[h]), math.sin(yaw[h])
        rel = kp[h, :, :2] - pelvis[h, :2]
        fwd, left = rel @ [c, s], rel @ [-s, c]
        assert fwd[KP["nose"]] > 0.05                                 # the nose looks forward
        assert left[KP["left_eye"]] > 0 > left[KP["right_eye"]]      # COCO left = the person's left
        assert left[KP["left_shoulder"]] > 0.1 > -0.1 > left[KP["right_shoulder"]]
        z = kp[h, :, 2]
        assert z[KP["nose"]] > z[KP["left_shoulder"]] > z[KP["left_hip"]] > z[KP["left_knee"]] > z[KP["left_ankle"]]
        assert 1.4 < z[KP["nose"]] < 1.7 and 0.0 <= min(z[KP["left_ankle"]], z[KP["right_ankle"]]) < 0.15


def test_features_do_not_depend_on_resolution():
    cam = PinholeCamera(640, 480, 60.0)
    small = replace(cam, width=320, height=240)
    pts = np.array([[[4.0, 0.3 * k - 2.0, 0.1 * k] for k in range(17)]])
    uv, _ = cam.project(pts, (0, 0, 0))
    uv2, _ = small.project(pts, (0, 0, 0))
    det = np.ones((1, 17), bool)
    det[0, 3] = False
    f1, f2 = keypoint_features(uv, det, cam), keypoint_features(uv2, det, small)
    assert f1.shape == (1, INPUT_DIM)
    np.testing.assert_allclose(f1, f2, atol=1e-6)
    assert f1[0, 6] == 0 and f1[0, 7] == 0 and f1[0, 34 + 3] == 0 and f1[0, 34] == 1


def test_exact_outputs_decode_to_the_true_pelvis_and_heading(line_env):
    """Targets built by the dataset, fed back as network outputs, give back the simulator's state."""
    env = line_env
    gt = people_ground_truth(env)
    for cam in default_robot_cameras():
        pose = np.array([env.pos[0, 0], env.pos[0, 1], env.yaw[0]])
        tg = sample_targets(gt, gt["index"], cam, pose)
        out = np.stack([tg["distance"], np.zeros(2), tg["xi"], tg["eta"], np.sin(tg["allocentric"]),
                        np.cos(tg["allocentric"])], axis=1)
        est = decode_outputs(out, cam, pose)
        np.testing.assert_allclose(est.position_world, gt["pelvis"], atol=1e-9)
        np.testing.assert_allclose(np.cos(est.yaw_world - gt["yaw"]), 1.0, atol=1e-9)
        np.testing.assert_allclose(est.distance_std, math.sqrt(2) * est.distance)  # b = e^0 = 1


def test_laplace_loss_is_smallest_at_the_true_distance():
    d = torch.tensor([5.0])
    vals = [float(laplace_loss(torch.tensor([m]), torch.tensor([-2.0]), d)) for m in (4.0, 4.9, 5.0, 5.1, 6.0)]
    assert np.argmin(vals) == 2
    # For a fixed error the best log b is log |1 - mu/d|.
    lb = torch.linspace(-5, 1, 601)
    loss = torch.abs(1 - torch.tensor(4.0) / d) * torch.exp(-lb) + lb
    assert abs(float(lb[torch.argmin(loss)]) - math.log(0.2)) < 0.02


def test_save_load_round_trip_and_rejections(tmp_path):
    net = MonolocoNet()
    save_model(net, tmp_path / "m", {"note": "test"})
    est = load_estimator(tmp_path / "m")
    x = np.random.default_rng(0).normal(size=(4, INPUT_DIM)).astype(np.float32)
    np.testing.assert_allclose(est.raw(x), MonolocoEstimator(net).raw(x), atol=1e-6)
    assert est.meta["note"] == "test"
    save_model(net, tmp_path / "h", half=True)
    half = load_estimator(tmp_path / "h")
    assert half.meta["dtype"] == "float16"
    assert (tmp_path / "h" / "model.pt").stat().st_size < 0.6 * (tmp_path / "m" / "model.pt").stat().st_size
    np.testing.assert_allclose(half.raw(x), est.raw(x), atol=2e-2, rtol=2e-2)
    with pytest.raises(ValueError, match=r"\(N, 51\)"):
        est.raw(np.zeros((2, 50), np.float32))
    with pytest.raises(FileNotFoundError, match="no Monoloco model"):
        load_estimator(tmp_path / "missing")
    w = tmp_path / "m" / "model.pt"
    w.write_bytes(w.read_bytes()[:-7] + b"garbage")
    with pytest.raises(ValueError, match="sha256"):
        load_estimator(tmp_path / "m")


def test_camera_sees_the_near_person_and_not_the_one_behind(line_env):
    env = line_env
    gt = people_ground_truth(env)
    rng = np.random.default_rng(0)
    cam = PinholeCamera(320, 240, 60.0, mount_z=1.0, name="front")  # straight ahead
    o = observe_camera(env, 0, cam, KeypointNoise.none(), rng, gt, occlusion="render", occlusion_downscale=1)
    assert set(o.in_view_people.tolist()) == {0, 1}
    assert 0 in o.person.tolist()
    near = o.detected[o.person.tolist().index(0)]
    # Person 0 faces +y (to the robot's left): its left side faces the camera, its right side is hidden
    # by its own body; the ankles are below the image's lower edge at 2 m.
    assert near[[KP["left_shoulder"], KP["left_hip"], KP["nose"], KP["left_knee"]]].all()
    assert not near[[KP["right_shoulder"], KP["right_hip"], KP["left_ankle"], KP["right_ankle"]]].any()
    # Person 1 stands right behind person 0: most of its keypoints are hidden by them.
    o_none = observe_camera(env, 0, cam, KeypointNoise.none(), rng, gt, occlusion="none")
    far_all = o_none.detected[o_none.person.tolist().index(1)].sum()
    far_vis = o.detected[o.person.tolist().index(1)].sum() if 1 in o.person.tolist() else 0
    assert far_all == 17 and far_vis < 10


def test_pipeline_and_wrapper_keep_the_ground_truth_format():
    from navzoo.perception.wrapper import PerceptionWrapper

    env = navzoo.make("navzoo/Lobby-v0", n_humans=6)
    gt_obs, _ = env.reset(seed=3)
    from navzoo.sensors import Lidar2D

    per = RobotPerception(estimator=MonolocoEstimator(MonolocoNet()), seed=0)  # untrained: format only
    with pytest.raises(TypeError, match="Lidar2D"):
        PerceptionWrapper(navzoo.make("navzoo/Lobby-v0", n_humans=6), per, lidar="yes")
    w = PerceptionWrapper(navzoo.make("navzoo/Lobby-v0", n_humans=6), per, images=True, lidar=Lidar2D(n_rays=90))
    obs, infos = w.reset(seed=3)
    space = w.observation_space("robot_0")
    assert space.contains(obs["robot_0"]) and space.contains(gt_obs["robot_0"])
    np.testing.assert_array_equal(obs["robot_0"]["goal"], gt_obs["robot_0"]["goal"])
    for _ in range(5):
        obs, r, te, tr, infos = w.step({"robot_0": np.array([0.3, 0.0], np.float32)})
        assert space.contains(obs["robot_0"])
        assert "perception/detections" in infos["robot_0"]
        scan, imgs = infos["robot_0"]["perception/lidar"], infos["robot_0"]["perception/images"]
        assert scan.ranges.shape == (90,) and len(imgs) == 2 and imgs[0].depth.shape == (480, 640)
    nav = w.unwrapped
    assert 0 in nav.perceived_people
    assert per.ms_per_robot_step()["total"] > 0
    env.close()
    w.close()


def test_baselines_use_perceived_people():
    """ORCA heads into a person it does not perceive, and avoids it when perceived (here: the truth)."""
    from navzoo.agents.baselines import make_policy

    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=1)
    env.reset(seed=0, options={"robot_starts": [[-2.0, 0.0]], "robot_goals": [[4.0, 0.0]], "robot_yaws": [0.0],
                               "human_starts": [[-1.0, 0.0]], "human_goals": [[-1.0, 0.1]]})
    pol = make_policy("orca")
    pol.reset(env)
    obs = {"robot_0": None}
    truth = pol.act(obs, env)["robot_0"]
    env.perceived_people = {0: (np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0))}
    blind = pol.act(obs, env)["robot_0"]
    env.perceived_people = {0: (env.pos[1:2].copy(), env.vel[1:2].copy(), env.radius[1:2].copy())}
    seen = pol.act(obs, env)["robot_0"]
    np.testing.assert_allclose(seen, truth, atol=1e-6)
    assert not np.allclose(blind, truth, atol=1e-3)
    env.close()


@pytest.mark.parametrize("goal, face", [((3.0, 0.0), {"left_ear", "right_ear"}),
                                        ((-6.0, 0.0), {"nose", "left_eye", "right_eye", "left_ear", "right_ear"}),
                                        ((-0.5, 6.0), {"nose", "left_eye", "left_ear"})])
def test_the_head_hides_the_face_keypoints_turned_away(goal, face):
    """Seen from behind only the ears, from the front the whole face, from the left side the left half."""
    env = navzoo.make("navzoo/CircleCrossing-v0", raw=True, n_humans=1)
    env.reset(seed=0, options={"robot_starts": [[-3.0, 0.0]], "robot_goals": [[3.0, 3.0]], "robot_yaws": [0.0],
                               "human_starts": [[-0.5, 0.0]], "human_goals": [list(goal)]})
    cam = PinholeCamera(640, 480, 60.0, mount_z=1.0)
    o = observe_camera(env, 0, cam, KeypointNoise.none(), np.random.default_rng(0), occlusion="render")
    seen = {COCO_KEYPOINTS[k] for k in range(5) if o.detected[0, k]}
    assert seen == face
    env.close()
