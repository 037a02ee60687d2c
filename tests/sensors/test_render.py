"""Rendered camera images agree with PinholeCamera's geometry (bare PyBullet worlds and a navzoo env)."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

import navzoo
from navzoo import sim
from navzoo.sensors import (
    CameraImages,
    PinholeCamera,
    default_robot_cameras,
    egl_enabled,
    enable_egl,
    forget_egl,
    occlusion_visible,
    render_camera,
    render_robot_cameras,
)
from navzoo.sensors import render as render_mod

W, H = 160, 120
LEVEL = PinholeCamera(W, H, hfov_deg=60.0, mount_z=1.0)
ORIGIN = (0.0, 0.0, 0.0)


@pytest.fixture()
def client():
    cid = sim.connect()
    yield cid
    forget_egl(cid)
    sim.disconnect(cid)


def _box(cid: int, half, pos, yaw: float = 0.0, rgba=(0.8, 0.2, 0.2, 1.0)) -> int:
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=list(half), physicsClientId=cid)
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=list(half), rgbaColor=list(rgba), physicsClientId=cid)
    orn = p.getQuaternionFromEuler([0.0, 0.0, yaw])
    return p.createMultiBody(0, col, vis, basePosition=list(pos), baseOrientation=orn, physicsClientId=cid)


def _robot(cid: int, radius: float = 0.3, height: float = 0.4) -> int:
    col = p.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=height, physicsClientId=cid)
    vis = p.createVisualShape(
        p.GEOM_CYLINDER, radius=radius, length=height, rgbaColor=[0.15, 0.35, 0.85, 1.0], physicsClientId=cid
    )
    return p.createMultiBody(30.0, col, vis, basePosition=[0.0, 0.0, height / 2], physicsClientId=cid)


def _ray_truth(cid: int, cam: PinholeCamera, pose, far: float = 30.0) -> tuple[np.ndarray, np.ndarray]:
    """Body id and camera-frame depth at every pixel centre, by casting a ray through it."""
    rot, t = cam.extrinsics(pose)
    cols, rows = np.meshgrid(np.arange(cam.width) + 0.5, np.arange(cam.height) + 0.5)
    d = np.stack([(cols - cam.cx) / cam.fx, (rows - cam.cy) / cam.fy, np.ones_like(cols)], axis=-1).reshape(
        -1, 3
    )
    to = t + far * d @ rot
    frm = np.broadcast_to(t, to.shape)
    res = []
    for i in range(0, len(to), 10000):  # PyBullet takes at most 16384 rays per batch
        res += p.rayTestBatch(frm[i : i + 10000].tolist(), to[i : i + 10000].tolist(), physicsClientId=cid)
    seg = np.array([r[0] for r in res]).reshape(cam.height, cam.width)
    z = ((np.array([r[3] for r in res]) - t) @ rot.T)[:, 2].reshape(cam.height, cam.width)
    return seg, np.where(seg >= 0, z, np.inf)


def _boundary(seg: np.ndarray) -> np.ndarray:
    """Pixels with a 4-neighbour of another label."""
    out = np.zeros(seg.shape, dtype=bool)
    e = seg[1:, :] != seg[:-1, :]
    out[1:, :] |= e
    out[:-1, :] |= e
    e = seg[:, 1:] != seg[:, :-1]
    out[:, 1:] |= e
    out[:, :-1] |= e
    return out


def _check_against_truth(cid: int, cam: PinholeCamera, pose, img: CameraImages) -> None:
    seg, z = _ray_truth(cid, cam, pose)
    wrong = img.segmentation != seg
    # Pixels can only disagree where the true label changes between neighbouring pixels.
    assert not (wrong & ~_boundary(seg)).any()
    assert wrong.sum() <= 0.02 * _boundary(seg).sum() + 2
    inner = (seg >= 0) & ~_boundary(seg)
    err = np.abs(img.depth[inner] - z[inner])
    assert np.median(err) < 1e-3
    assert np.percentile(err, 95) < 5e-3
    assert np.isinf(img.depth[(seg < 0) & ~_boundary(seg)]).all()


# ------------------------------------------------------------------------------------ bare world
def test_box_silhouette_depth_and_background(client: int) -> None:
    half, centre = np.array([0.25, 0.5, 0.3]), np.array([3.0, 0.2, 1.1])
    box = _box(client, half, centre)
    img = render_camera(client, LEVEL, ORIGIN, renderer="tiny")
    assert img.rgb.shape == (H, W, 3) and img.rgb.dtype == np.uint8
    assert img.depth.shape == (H, W) and img.depth.dtype == np.float32
    assert img.segmentation.dtype == np.int32 and img.link.dtype == np.int32

    corners = centre + half * np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    uv, depth = LEVEL.project(corners, ORIGIN)
    assert (depth > 0).all()
    rows, cols = np.nonzero(img.segmentation == box)
    # Pixel (r, c) shows (u, v) = (c + 0.5, r + 0.5): the silhouette covers the pixel centres inside the
    # projected corners' bounding box (a box seen from outside: its silhouette's bounding box).
    expected = (
        math.ceil(uv[:, 0].min() - 0.5),
        math.floor(uv[:, 0].max() - 0.5),
        math.ceil(uv[:, 1].min() - 0.5),
        math.floor(uv[:, 1].max() - 0.5),
    )
    got = (cols.min(), cols.max(), rows.min(), rows.max())
    assert np.abs(np.subtract(got, expected)).max() <= 1, (got, expected)

    # The face towards the camera is at x = 2.75 and perpendicular to the optical axis.
    face_uv, face_depth = LEVEL.project(np.array([centre[0] - half[0], centre[1], centre[2]]), ORIGIN)
    r, c = int(face_uv[1]), int(face_uv[0])
    assert face_depth == pytest.approx(2.75)
    assert img.depth[r, c] == pytest.approx(2.75, abs=0.01)
    assert img.segmentation[r, c] == box and img.link[r, c] == -1
    # Background: nothing drawn there.
    bg = img.segmentation == -1
    assert bg.sum() > 0.5 * W * H
    assert np.isinf(img.depth[bg]).all() and (img.link[bg] == -1).all()
    assert np.isfinite(img.depth[~bg]).all()


def test_segmentation_and_depth_match_ray_casts_for_turned_tilted_camera(client: int) -> None:
    rng = np.random.default_rng(3)
    for _ in range(4):
        _box(
            client,
            rng.uniform(0.15, 0.6, 3),
            [rng.uniform(2, 6), rng.uniform(-2.5, 2.5), rng.uniform(0.3, 1.6)],
            rng.uniform(-3, 3),
        )
    cams = [
        PinholeCamera(
            W, H, hfov_deg=75.0, mount_x=0.2, mount_y=-0.1, mount_z=1.2, mount_yaw=0.35, mount_pitch=0.25
        ),
        PinholeCamera(W, H, hfov_deg=50.0, mount_z=0.6, mount_yaw=-0.3, mount_pitch=-0.2),
    ]
    pose = (-0.4, 0.3, -0.15)
    for cam in cams:
        img = render_camera(client, cam, pose, renderer="tiny")
        assert (img.segmentation >= 0).sum() > 500  # the boxes are in view
        _check_against_truth(client, cam, pose, img)


def test_point_on_optical_axis_lands_in_centre_pixel_of_tilted_camera(client: int) -> None:
    cam = PinholeCamera(W, H, hfov_deg=60.0, mount_z=1.5, mount_yaw=0.4, mount_pitch=0.3)
    pose = (1.0, -2.0, 0.7)
    rot, t = cam.extrinsics(pose)
    target = t + 4.0 * rot[2]  # 4 m along the optical axis
    box = _box(client, [0.05, 0.05, 0.05], target)
    img = render_camera(client, cam, pose, renderer="tiny")
    uv, depth = cam.project(target, pose)
    assert uv == pytest.approx([W / 2, H / 2])
    r, c = int(uv[1]), int(uv[0])
    assert img.segmentation[r, c] == box
    assert img.depth[r, c] == pytest.approx(depth - 0.05, abs=0.02)  # a face of the small cube


def test_link_image(client: int) -> None:
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=[0.2, 0.2, 0.2], physicsClientId=client)
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=[0.2, 0.2, 0.2], physicsClientId=client)
    body = p.createMultiBody(
        0,
        col,
        vis,
        basePosition=[3.0, -0.5, 1.0],
        linkMasses=[0.0],
        linkCollisionShapeIndices=[col],
        linkVisualShapeIndices=[vis],
        linkPositions=[[0.0, 1.0, 0.0]],
        linkOrientations=[[0, 0, 0, 1]],
        linkInertialFramePositions=[[0, 0, 0]],
        linkInertialFrameOrientations=[[0, 0, 0, 1]],
        linkParentIndices=[0],
        linkJointTypes=[p.JOINT_FIXED],
        linkJointAxis=[[0, 0, 1]],
        physicsClientId=client,
    )
    img = render_camera(client, LEVEL, ORIGIN)
    base_uv, _ = LEVEL.project(np.array([2.8, -0.5, 1.0]), ORIGIN)
    link_uv, _ = LEVEL.project(np.array([2.8, 0.5, 1.0]), ORIGIN)
    for uv, link in ((base_uv, -1), (link_uv, 0)):
        r, c = int(uv[1]), int(uv[0])
        assert img.segmentation[r, c] == body
        assert img.link[r, c] == link


def test_hidden_robot_body_does_not_occlude(client: int) -> None:
    robot = _robot(client)
    box = _box(client, [0.25, 0.5, 0.3], [1.5, 0.0, 0.3])
    cam = PinholeCamera(W, H, hfov_deg=60.0, mount_z=1.0, mount_pitch=0.9)  # looking down over the robot
    rgba_before = [d[7] for d in p.getVisualShapeData(robot, physicsClientId=client)]
    seen = render_camera(client, cam, ORIGIN)
    hidden = render_camera(client, cam, ORIGIN, hide_body_ids=[robot])
    assert (seen.segmentation == robot).sum() > 0.05 * W * H
    assert not (hidden.segmentation == robot).any()
    # Where the robot was, we now see what is behind it; the box is untouched.
    was_robot = seen.segmentation == robot
    assert (hidden.segmentation[was_robot] == -1).all() and np.isinf(hidden.depth[was_robot]).all()
    assert ((seen.segmentation == box) == (hidden.segmentation == box))[~was_robot].all()
    # The body's colours are restored, and an ordinary render sees it again.
    assert [d[7] for d in p.getVisualShapeData(robot, physicsClientId=client)] == rgba_before
    assert (render_camera(client, cam, ORIGIN).segmentation == robot).sum() == was_robot.sum()
    # A level camera inside the robot's own body does not see it (back faces are culled).
    inside = PinholeCamera(W, H, mount_z=0.3)
    assert not (render_camera(client, inside, ORIGIN).segmentation == robot).any()


def test_validation(client: int) -> None:
    with pytest.raises(ValueError, match="renderer"):
        render_camera(client, LEVEL, ORIGIN, renderer="opengl")
    with pytest.raises(ValueError, match="near"):
        render_camera(client, LEVEL, ORIGIN, near=0.0)
    with pytest.raises(ValueError, match="far"):
        render_camera(client, LEVEL, ORIGIN, near=1.0, far=1.0)
    with pytest.raises(ValueError, match="far"):
        render_camera(client, LEVEL, ORIGIN, far=math.inf)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        render_camera(client, LEVEL, (0.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        render_camera(client, LEVEL, (0.0, math.nan, 0.0))
    with pytest.raises(ValueError, match="whole number"):
        render_camera(client, PinholeCamera(160.5, 120), ORIGIN)
    with pytest.raises(TypeError, match="PinholeCamera"):
        render_camera(client, (160, 120), ORIGIN)
    with pytest.raises(ValueError, match="hide_body_ids"):
        render_camera(client, LEVEL, ORIGIN, hide_body_ids=[12345])
    with pytest.raises(ValueError, match="not connected"):
        render_camera(client + 1000, LEVEL, ORIGIN)


# ------------------------------------------------------------------------------------------- EGL
def test_egl_missing_raises_or_falls_back(client: int, monkeypatch: pytest.MonkeyPatch) -> None:
    assert not egl_enabled(client)
    with pytest.raises(RuntimeError, match="enable_egl"):
        render_camera(client, LEVEL, ORIGIN, renderer="egl")
    # No plugin module, or a plugin that does not load: False, and the client stays on TinyRenderer.
    with monkeypatch.context() as m:
        m.setattr(render_mod.importlib.util, "find_spec", lambda name: None)
        assert enable_egl(client) is False
    with monkeypatch.context() as m:
        m.setattr(render_mod.p, "loadPlugin", lambda *a, **k: -1)
        assert enable_egl(client) is False
    assert not egl_enabled(client)
    with pytest.raises(RuntimeError, match="enable_egl"):
        render_camera(client, LEVEL, ORIGIN, renderer="egl")
    # Too late once the world has bodies (EGL would not draw them): a warning, and TinyRenderer stays.
    _box(client, [0.3, 0.3, 0.3], [3.0, 0.0, 1.0])
    with pytest.warns(RuntimeWarning, match="bodies"):
        assert enable_egl(client) is False
    auto = render_camera(client, LEVEL, ORIGIN)
    assert np.array_equal(
        auto.segmentation, render_camera(client, LEVEL, ORIGIN, renderer="tiny").segmentation
    )
    _check_against_truth(client, LEVEL, ORIGIN, auto)


def test_egl_renders_with_the_same_geometry_where_available(client: int) -> None:
    if not enable_egl(client):  # before any body
        pytest.skip("EGL is not available on this machine")
    assert egl_enabled(client) and enable_egl(client)  # idempotent
    box = _box(client, [0.25, 0.5, 0.3], [1.5, 0.2, 0.3])
    robot = _robot(client)
    cam = PinholeCamera(W, H, hfov_deg=70.0, mount_z=1.0, mount_yaw=0.2, mount_pitch=0.9)
    egl = render_camera(client, cam, ORIGIN, renderer="egl", hide_body_ids=[robot])
    auto = render_camera(client, cam, ORIGIN, hide_body_ids=[robot])
    assert np.array_equal(auto.segmentation, egl.segmentation)
    assert box in egl.segmentation and robot not in egl.segmentation
    assert robot in render_camera(client, cam, ORIGIN).segmentation
    with pytest.raises(RuntimeError, match="EGL plugin"):
        render_camera(client, cam, ORIGIN, renderer="tiny")
    p.resetBasePositionAndOrientation(
        robot, [0.0, 0.0, -5.0], [0, 0, 0, 1], physicsClientId=client
    )  # out of the rays' way
    _check_against_truth(client, cam, ORIGIN, egl)
    forget_egl(client)
    assert not egl_enabled(client)


# -------------------------------------------------------------------------------------- navzoo env
@pytest.fixture(scope="module")
def lobby():
    env = navzoo.make("navzoo/Lobby-v0", raw=True, n_robots=2)
    # Robot 0 at (9, 6) facing +x; robot 1 ahead-right of it; person 0 ahead-left, person 1 behind the
    # pillar at (13, 4), the others out of the way.
    starts = np.array([[11.5, 6.6], [15.0, 3.0]] + [[x, 12.0] for x in range(5, 15)], dtype=float)
    env.reset(
        seed=0,
        options=dict(
            robot_starts=[[9.0, 6.0], [10.5, 4.8]],
            robot_goals=[[18.0, 9.0], [2.0, 9.0]],
            robot_yaws=[0.0, 0.0],
            human_starts=starts,
            human_goals=starts + [1.0, 0.0],
        ),
    )
    yield env
    env.close()


def _human_roots(env, idx) -> np.ndarray:
    return np.array(
        [p.getBasePositionAndOrientation(env.humans.ids[j], physicsClientId=env.client)[0] for j in idx]
    )


def test_robot_cameras_see_people_and_walls_hide_them(lobby) -> None:
    env = lobby
    cams = default_robot_cameras(W, H)
    left, right = render_robot_cameras(env, 0, cams)
    pose = (9.0, 6.0, 0.0)
    assert np.allclose([env.pos[0, 0], env.pos[0, 1], env.yaw[0]], pose)
    roots = _human_roots(env, [0, 1])
    visible_person, hidden_person = env.humans.ids[0], env.humans.ids[1]
    assert visible_person in left.segmentation
    assert env.robots.ids[0] not in left.segmentation and env.robots.ids[0] not in right.segmentation
    assert env.robots.ids[1] in right.segmentation  # hiding robot 0 leaves the robot sharing its shapes
    assert set(np.unique(left.segmentation)) & set(env.bodies.obstacle_ids)
    # Person 0's root is in the left camera's view and not occluded; person 1's root is in the right
    # camera's view, but the pillar in front of it hides it.
    assert cams[0].fov_contains(roots[0], pose) and cams[1].fov_contains(roots[1], pose)
    uv, depth = cams[0].project(roots[0], pose)
    assert occlusion_visible(uv, depth, left.depth)
    uv, depth = cams[1].project(roots[1], pose)
    assert not occlusion_visible(uv, depth, right.depth)
    assert hidden_person not in right.segmentation
    pillar = right.segmentation[int(uv[1]), int(uv[0])]
    assert pillar in env.bodies.obstacle_ids

    # Synthetic keypoints along pixel rays that hit a wall or obstacle: 1 m behind the surface they
    # are hidden, 0.5 m in front of it they are visible.
    rows, cols = np.nonzero(np.isin(right.segmentation, env.bodies.obstacle_ids) & np.isfinite(right.depth))
    pick = np.linspace(0, len(rows) - 1, 17).astype(int)
    r, c = rows[pick], cols[pick]
    rot, t = cams[1].extrinsics(pose)
    ray = np.stack(
        [(c + 0.5 - cams[1].cx) / cams[1].fx, (r + 0.5 - cams[1].cy) / cams[1].fy, np.ones(17)], axis=-1
    )
    surface = right.depth[r, c].astype(float)
    for offset, expect in ((1.0, False), (-0.5, True)):
        kp = t + ((surface + offset)[:, None] * ray) @ rot
        uv, depth = cams[1].project(kp, pose)
        assert np.allclose(uv, np.stack([c + 0.5, r + 0.5], axis=-1))
        assert (occlusion_visible(uv, depth, right.depth) == expect).all()


def test_render_robot_cameras_defaults_and_validation(lobby) -> None:
    env = lobby
    tilted = PinholeCamera(
        W, H, hfov_deg=90.0, mount_z=1.0, mount_pitch=1.0
    )  # sees its own robot unless hidden
    (img,) = render_robot_cameras(env, 0, [tilted])
    assert env.robots.ids[0] not in img.segmentation
    pose = (env.pos[0, 0], env.pos[0, 1], env.yaw[0])
    assert env.robots.ids[0] in render_camera(env.client, tilted, pose).segmentation
    with pytest.raises(ValueError, match="robot_index"):
        render_robot_cameras(env, 2, [tilted])
    with pytest.raises(TypeError, match="unexpected"):
        render_robot_cameras(env, 0, [tilted], hfov=3)
    with pytest.raises(TypeError, match="NavEnv"):
        render_robot_cameras(object(), 0)


# -------------------------------------------------------------------------- NavEnv with EGL (egl=True)
def test_prism_obj_has_outward_flat_normals() -> None:
    from navzoo.world.builder import _prism_mesh, prism_obj

    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]) - 0.5
    verts, idx = _prism_mesh(square, 2.0)
    text = prism_obj(verts, idx).splitlines()
    v = np.array([[float(t) for t in line.split()[1:]] for line in text if line.startswith("v ")])
    vn = np.array([[float(t) for t in line.split()[1:]] for line in text if line.startswith("vn ")])
    faces = [line for line in text if line.startswith("f ")]
    assert len(v) == 8 and len(faces) == len(vn) == len(idx) // 3 == 12
    np.testing.assert_allclose(np.linalg.norm(vn, axis=1), 1.0, atol=1e-6)
    for face, n in zip(faces, vn, strict=True):  # every normal points away from the prism's centre
        corners = [int(tok.split("//")[0]) - 1 for tok in face.split()[1:]]
        centre = v[corners].mean(axis=0) - np.array([0.0, 0.0, 1.0])
        assert float(centre @ n) > 0


def test_navenv_egl_draws_what_tinyrenderer_draws() -> None:
    """Polygon obstacles (OBJ visual meshes with egl=True) render alike with EGL and with TinyRenderer;
    with vertex-data meshes EGL would leave them out (0 pixels)."""
    from navzoo.world.scene import PolygonObstacle

    cam = default_robot_cameras(W, H)[0]
    views, polygons = {}, set()
    for egl in (False, True):
        env = navzoo.make(scene="cafe", raw=True, n_humans=0, egl=egl)
        if egl and not env.egl:
            env.close()
            pytest.skip("EGL is not available on this machine")
        polygons = {b for b, o in zip(env.bodies.obstacle_ids, env.scene.obstacles, strict=True)
                    if isinstance(o, PolygonObstacle)}
        env.reset(seed=2)
        views[egl] = [render_camera(env.client, cam, (env.pos[0, 0], env.pos[0, 1], env.yaw[0] + k * np.pi / 4),
                                    hide_body_ids=[env.robots.ids[0]]) for k in range(8)]
        assert egl_enabled(env.client) == egl
        client = env.client
        env.close()
        assert not egl_enabled(client)  # closing forgets the client's EGL record
    tiny_seg = np.stack([v.segmentation for v in views[False]])
    egl_seg = np.stack([v.segmentation for v in views[True]])
    on_polygons = np.isin(tiny_seg, list(polygons))
    assert on_polygons.sum() > 1000
    assert abs(int(np.isin(egl_seg, list(polygons)).sum()) - int(on_polygons.sum())) < 0.01 * on_polygons.sum()
    assert np.mean(tiny_seg == egl_seg) > 0.99
    tiny_d = np.stack([v.depth for v in views[False]])
    egl_d = np.stack([v.depth for v in views[True]])
    both = np.isfinite(tiny_d) & np.isfinite(egl_d)
    assert np.median(np.abs(tiny_d[both] - egl_d[both])) < 0.01


def test_navenv_egl_falls_back_with_a_warning(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(render_mod.importlib.util, "find_spec", lambda name: None)
    with pytest.warns(RuntimeWarning, match="EGL renderer is not available"):
        env = navzoo.make("navzoo/Home-v0", raw=True, n_humans=0, egl=True)
    assert env.egl is False and not egl_enabled(env.client)
    env.close()
    with pytest.raises(ValueError, match="egl must be a bool"):
        navzoo.make("navzoo/Home-v0", egl="yes")


def test_an_egl_plugin_that_ends_its_process_is_caught(client: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """Where the plugin exits the process (no EGL driver), the probe child dies instead of the caller."""
    monkeypatch.setattr(render_mod, "_EGL_WORKS", None)
    monkeypatch.setattr(render_mod, "_EGL_PROBE", "import os; print('failed to EGL with glad.'); os._exit(1)")
    monkeypatch.setattr(render_mod.importlib.util, "find_spec", lambda name: type("S", (), {"origin": "x.so"})())
    assert render_mod.egl_works() is False
    assert enable_egl(client) is False and not egl_enabled(client)
    monkeypatch.setattr(render_mod, "_EGL_PROBE", "raise SystemExit(0)")  # cached: not asked again
    assert render_mod.egl_works() is False
