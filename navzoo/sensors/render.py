"""Render what a :class:`~navzoo.sensors.camera_model.PinholeCamera` sees in a PyBullet world.

:func:`render_camera` returns RGB, metric depth, body-id segmentation and link-index images whose pixels
follow the conventions of :mod:`navzoo.sensors.camera_model`: a world point that
:meth:`PinholeCamera.project` sends to pixel ``(u, v)`` appears at row ``floor(v)``, column ``floor(u)``,
and the depth image holds its camera-frame ``z`` (m), so the output can be fed straight into
:func:`~navzoo.sensors.camera_model.occlusion_visible`.

How the images are made:

* The view matrix is built from :meth:`PinholeCamera.extrinsics` (the OpenGL camera looks down its -z
  axis with y up, i.e. rows ``(x, -y, -z)`` of the optical frame) and the projection matrix from the
  intrinsics (``fx``, ``fy``, principal point at the image centre), not from
  ``computeProjectionMatrixFOV``, so both renderers agree with :meth:`PinholeCamera.project` exactly.
* PyBullet's TinyRenderer samples a pixel at its corner (column ``c`` at ``u = c``, row ``r`` at
  ``v = r + 1``) where OpenGL samples at the centre; the projection matrix is shifted by half a pixel for
  it, so with either renderer pixel ``(r, c)`` shows what lies at ``(u, v) = (c + 0.5, r + 0.5)``.
* Depth: PyBullet's non-linear depth buffer ``b`` in [0, 1] becomes
  ``far * near / (far - (far - near) * b)`` metres; pixels where nothing is drawn (nothing between the
  near and the far plane) are ``np.inf``.
* Segmentation: rendered with ``ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX`` and decoded into the body
  unique id (-1 for background) and the link index (-1 for a body's base *and* for background; look at
  the body id to tell them apart).
* Hidden bodies (``hide_body_ids``, e.g. the robot carrying the camera): their visual shapes are made
  fully transparent (alpha 0) for the duration of the render and their colours restored afterwards.
  Both renderers skip alpha-0 shapes entirely (no colour, depth or segmentation). Only the visual
  shapes are touched, so physics, ray tests and contacts are unaffected. With the default robot cameras
  (1.0 m high, level, above a 0.4 m tall robot) the robot's own body is outside the field of view
  anyway, and a camera inside a closed body does not see it (its faces point away from the camera and
  are culled), but a camera tilted down over the robot would see it without this.
* Renderers: ``"tiny"`` is PyBullet's CPU TinyRenderer, available everywhere. ``"egl"`` is the
  OpenGL renderer of PyBullet's ``eglRenderer`` plugin (headless; a GPU, or Mesa's software llvmpipe),
  which must be loaded with :func:`enable_egl` right after connecting, before any body is created: the
  plugin only draws bodies created after it was loaded, and from then on it handles every render of
  that client. ``"auto"`` (the default) is EGL on a client where :func:`enable_egl` succeeded and
  TinyRenderer elsewhere; ``"egl"`` on a client without EGL, or ``"tiny"`` on one with it, raises
  ``RuntimeError``. Which clients have EGL is recorded here by client id; PyBullet reuses the ids of
  disconnected clients, so call :func:`forget_egl` when disconnecting an EGL client. A NavEnv builds
  its world when it is constructed, so EGL cannot be enabled on ``env.client`` afterwards (it stays on
  TinyRenderer, with a warning): ask for it with ``NavConfig(egl=True)``, which loads the plugin as the
  env connects (and forgets it on ``close``). Limits of the EGL plugin measured with pybullet 3.2.7 and
  Mesa's llvmpipe: it does not draw visual shapes made from vertex data (``createVisualShape(GEOM_MESH,
  vertices=...)``; it prints "issue extracting mesh from COLLADA/STL file"), so with ``egl=True`` the
  world builder gives polygon obstacles OBJ files instead, and its depth is quantised (with near 0.05 m and far 30 m:
  errors of 0.4 mm at 2 m, 6 mm at 10 m and 4 cm at 20 m; TinyRenderer's: 0.07 mm at 10 m), so
  TinyRenderer is the reference and EGL a faster option (on the 2-core VM, 81 against 121 ms per
  640 x 480 image; ``scripts/bench_sensors.py``). Where the plugin exists but no EGL driver does, it
  ends the process on loading; :func:`egl_works` tries it in a child process first.
"""

from __future__ import annotations

import contextlib
import importlib.util
import math
import warnings
from collections.abc import Iterable, Iterator, Sequence
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np
import pybullet as p

from navzoo.sensors.camera_model import PinholeCamera, default_robot_cameras
from navzoo.sim import quiet

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

__all__ = [
    "RENDERERS",
    "CameraImages",
    "egl_enabled",
    "egl_works",
    "enable_egl",
    "forget_egl",
    "hidden_bodies",
    "projection_matrix",
    "render_camera",
    "render_robot_cameras",
    "robot_pose",
    "view_matrix",
]

RENDERERS: tuple[str, ...] = ("auto", "tiny", "egl")
"""Accepted values of ``renderer``."""

_LINK_SHIFT = 24
_ID_MASK = (1 << _LINK_SHIFT) - 1
_EGL_PLUGINS: dict[int, int] = {}  # physics client id -> plugin id of its loaded eglRenderer


class CameraImages(NamedTuple):
    """What one camera sees.

    Attributes:
        rgb: (H, W, 3) uint8 colour image.
        depth: (H, W) float32 metric depth (m): the camera-frame z (along the optical axis, not along
            the ray) of the surface seen in each pixel, ``np.inf`` where nothing lies between the near
            and the far plane.
        segmentation: (H, W) int32 PyBullet body unique id seen in each pixel, -1 for background.
        link: (H, W) int32 link index seen in each pixel, -1 for a body's base and for background.
    """

    rgb: np.ndarray
    depth: np.ndarray
    segmentation: np.ndarray
    link: np.ndarray


# ----------------------------------------------------------------------------------------------- EGL
def _check_client(client: int) -> int:
    try:
        cid = int(client)
    except (TypeError, ValueError):
        raise ValueError(f"client must be a PyBullet physics client id (int), got {client!r}") from None
    if cid != client or not p.isConnected(physicsClientId=cid):
        raise ValueError(f"PyBullet client {client!r} is not connected")
    return cid


_EGL_PROBE = """
import importlib.util, sys
import pybullet as p
spec = importlib.util.find_spec("eglRenderer")
if spec is None or not spec.origin:
    sys.exit(3)
cid = p.connect(p.DIRECT)
if p.loadPlugin(spec.origin, "_eglRendererPlugin", physicsClientId=cid) < 0:
    sys.exit(4)
p.getCameraImage(8, 8, renderer=p.ER_BULLET_HARDWARE_OPENGL, physicsClientId=cid)
print("navzoo-egl-ok")
"""
_EGL_WORKS: bool | None = None


def egl_works() -> bool:
    """Whether PyBullet's EGL plugin can render on this machine, tried once per process in a child process.

    The plugin does not fail gracefully everywhere: where its module exists but no EGL driver does
    (measured on the H100 device machine, whose image has no ``libEGL``), loading it prints "failed to
    EGL with glad." and ends the whole process. So the first call loads it in a short-lived Python child
    (about 0.5 s) and caches the answer; :func:`enable_egl` asks here before loading it in this process.
    """
    global _EGL_WORKS
    if _EGL_WORKS is None:
        import subprocess
        import sys

        try:
            spec = importlib.util.find_spec("eglRenderer")
        except (ImportError, ValueError):
            spec = None
        if spec is None or not spec.origin:
            _EGL_WORKS = False
        else:
            try:
                run = subprocess.run([sys.executable, "-c", _EGL_PROBE], capture_output=True, text=True, timeout=60)
                _EGL_WORKS = run.returncode == 0 and "navzoo-egl-ok" in run.stdout
            except (OSError, subprocess.TimeoutExpired):
                _EGL_WORKS = False
    return _EGL_WORKS


def enable_egl(client: int) -> bool:
    """Load PyBullet's ``eglRenderer`` plugin on a client, for ``renderer="egl"`` / ``"auto"``.

    Call it right after connecting, before any body exists: the plugin only draws bodies created after
    it was loaded, and once loaded it handles every ``getCameraImage`` of the client (TinyRenderer is no
    longer reachable there; unloading it does not bring TinyRenderer back, and loading it again after
    ``unloadPlugin`` crashes pybullet 3.2.7). A client that already holds bodies is therefore left alone:
    a ``RuntimeWarning`` and False.

    Safe where EGL is missing: the plugin module not being installed, the plugin failing to load (tried
    first in a child process, :func:`egl_works`, because on some machines it ends the process), or a
    test render failing all return False and leave the client on TinyRenderer. Calling it again on a
    client that has EGL returns True. The plugin's driver report (printed from C code) is silenced.

    Args:
        client: PyBullet physics client id.

    Returns:
        Whether EGL rendering is on for the client now.
    """
    cid = _check_client(client)
    if cid in _EGL_PLUGINS:
        return True
    n_bodies = p.getNumBodies(physicsClientId=cid)
    if n_bodies > 0:
        warnings.warn(
            f"enable_egl: client {cid} already holds {n_bodies} bodies, which the EGL renderer would not "
            "draw; EGL must be enabled right after connecting. Staying on TinyRenderer.",
            RuntimeWarning,
            stacklevel=2,
        )
        return False
    try:
        spec = importlib.util.find_spec("eglRenderer")
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.origin or not egl_works():
        return False
    try:
        with quiet():
            plugin = p.loadPlugin(spec.origin, "_eglRendererPlugin", physicsClientId=cid)
    except p.error:
        return False
    if plugin < 0:
        return False
    try:  # the plugin can load and still have no usable OpenGL context
        with quiet():
            p.getCameraImage(8, 8, renderer=p.ER_BULLET_HARDWARE_OPENGL, physicsClientId=cid)
    except p.error:
        return False  # (not unloaded: see above; the client has no working renderer now)
    _EGL_PLUGINS[cid] = plugin
    return True


def forget_egl(client: int) -> None:
    """Drop this module's record that a client id has EGL; call it when disconnecting such a client.

    The record is kept by client id, and PyBullet reuses the ids of disconnected clients: without this,
    a new client with the same id would be taken for an EGL one (``"auto"`` would pick EGL's pixel
    convention and ``"egl"`` would silently get TinyRenderer). Nothing happens for other ids.

    Args:
        client: PyBullet physics client id.
    """
    _EGL_PLUGINS.pop(int(client), None)


def egl_enabled(client: int) -> bool:
    """Whether :func:`enable_egl` has loaded EGL on this client id (and it has not been forgotten).

    Args:
        client: PyBullet physics client id.

    Returns:
        True when ``renderer="auto"`` uses EGL on the client.
    """
    return int(client) in _EGL_PLUGINS


# ---------------------------------------------------------------------------------------- matrices
def _pose(robot_pose: Any) -> np.ndarray:
    try:
        pose = np.asarray(robot_pose, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"robot_pose must be (x, y, yaw), got {robot_pose!r}") from None
    if pose.shape != (3,):
        raise ValueError(f"robot_pose must have shape (3,) = (x, y, yaw), got shape {pose.shape}")
    if not np.isfinite(pose).all():
        raise ValueError(f"robot_pose must be finite, got {pose.tolist()}")
    return pose


def _image_size(camera: PinholeCamera) -> tuple[int, int]:
    if not isinstance(camera, PinholeCamera):
        raise TypeError(f"camera must be a PinholeCamera, got {type(camera).__name__}")
    w, h = camera.width, camera.height
    if int(w) != w or int(h) != h:
        raise ValueError(f"a rendered camera needs a whole number of pixels, got {w!r} x {h!r}")
    return int(w), int(h)


def _check_planes(near: float, far: float) -> tuple[float, float]:
    near_f, far_f = float(near), float(far)
    if not (math.isfinite(near_f) and near_f > 0.0):
        raise ValueError(f"near must be a finite distance > 0 (m), got {near!r}")
    if not (math.isfinite(far_f) and far_f > near_f):
        raise ValueError(f"far must be finite and > near = {near_f} (m), got {far!r}")
    return near_f, far_f


def view_matrix(camera: PinholeCamera, robot_pose: np.ndarray | Sequence[float]) -> np.ndarray:
    """The OpenGL view matrix of a robot camera (world to eye coordinates, eye looking down -z, y up).

    Args:
        camera: The camera.
        robot_pose: ``(x, y, yaw)`` of the robot in the world.

    Returns:
        (4, 4) float matrix (row-major; PyBullet wants ``m.T.ravel()``, column-major).
    """
    rot, t = camera.extrinsics(_pose(robot_pose))
    rot_gl = np.stack([rot[0], -rot[1], -rot[2]])
    view = np.eye(4)
    view[:3, :3] = rot_gl
    view[:3, 3] = -rot_gl @ t
    return view


def projection_matrix(
    camera: PinholeCamera, near: float = 0.05, far: float = 30.0, *, corner_sampling: bool = False
) -> np.ndarray:
    """The OpenGL projection matrix of a pinhole camera's intrinsics.

    Args:
        camera: The camera.
        near: Near clipping plane (m, > 0).
        far: Far clipping plane (m, > near).
        corner_sampling: The rasteriser samples pixel (row ``r``, column ``c``) at window coordinates
            ``(c, height - 1 - r)`` instead of at the pixel centre (TinyRenderer does); the matrix then
            shifts the image by half a pixel so that the sample still shows ``(u, v) = (c + 0.5, r + 0.5)``.

    Returns:
        (4, 4) float matrix (row-major; PyBullet wants ``m.T.ravel()``, column-major).
    """
    w, h = _image_size(camera)
    near, far = _check_planes(near, far)
    proj = np.zeros((4, 4))
    proj[0, 0] = 2.0 * camera.fx / w
    proj[1, 1] = 2.0 * camera.fy / h
    if corner_sampling:
        # NDC x, y get -1/w, -1/h: window x = u - 0.5 and window y = (h - v) - 0.5.
        proj[0, 2] = 1.0 / w
        proj[1, 2] = 1.0 / h
    proj[2, 2] = -(far + near) / (far - near)
    proj[2, 3] = -2.0 * far * near / (far - near)
    proj[3, 2] = -1.0
    return proj


# ------------------------------------------------------------------------------------------ hiding
@contextlib.contextmanager
def hidden_bodies(client: int, body_ids: Iterable[int]) -> Iterator[None]:
    """Make bodies invisible to the renderers (alpha 0 on every visual shape) inside the block.

    Their RGBA colours are restored on exit, also after an exception. Only visual shapes change: the
    physics, contacts and ray tests do not see any difference.

    Args:
        client: PyBullet physics client id.
        body_ids: Body unique ids to hide (unknown ids raise ``ValueError``).
    """
    saved: list[tuple[int, int, int, list[float]]] = []
    ids = list(dict.fromkeys(int(b) for b in body_ids))
    for b in ids:
        try:
            p.getBodyInfo(b, physicsClientId=client)
        except p.error:
            raise ValueError(f"hide_body_ids: no body {b} in client {client}") from None
    try:
        for b in ids:
            shape_counts: dict[int, int] = {}
            for data in p.getVisualShapeData(b, physicsClientId=client):
                link = int(data[1])
                k = shape_counts.get(link, 0)
                shape_counts[link] = k + 1
                rgba = [float(c) for c in data[7]]
                saved.append((b, link, k, rgba))
                p.changeVisualShape(b, link, shapeIndex=k, rgbaColor=rgba[:3] + [0.0], physicsClientId=client)
        yield
    finally:
        for b, link, k, rgba in reversed(saved):
            with contextlib.suppress(p.error):
                p.changeVisualShape(b, link, shapeIndex=k, rgbaColor=rgba, physicsClientId=client)


# ----------------------------------------------------------------------------------------- render
def _resolve_renderer(client: int, renderer: str) -> bool:
    """True for EGL, False for TinyRenderer."""
    if renderer not in RENDERERS:
        raise ValueError(f"renderer must be one of {list(RENDERERS)}, got {renderer!r}")
    has_egl = client in _EGL_PLUGINS
    if renderer == "egl" and not has_egl:
        raise RuntimeError(
            f"renderer='egl' but EGL is not enabled on client {client}: call enable_egl(client) right after "
            "connecting (it returns False where EGL is unavailable), or use renderer='auto' or 'tiny'"
        )
    if renderer == "tiny" and has_egl:
        raise RuntimeError(
            f"renderer='tiny' but client {client} has the EGL plugin, which handles all of its renders; "
            "use renderer='auto' or 'egl' there"
        )
    return has_egl


def _render_one(
    client: int, camera: PinholeCamera, pose: np.ndarray, use_egl: bool, near: float, far: float
) -> CameraImages:
    w, h = _image_size(camera)
    view = view_matrix(camera, pose)
    proj = projection_matrix(camera, near, far, corner_sampling=not use_egl)
    _, _, rgba, buf, seg = p.getCameraImage(
        w,
        h,
        view.T.ravel().tolist(),
        proj.T.ravel().tolist(),
        renderer=p.ER_BULLET_HARDWARE_OPENGL if use_egl else p.ER_TINY_RENDERER,
        flags=p.ER_SEGMENTATION_MASK_OBJECT_AND_LINKINDEX,
        physicsClientId=client,
    )
    rgb = np.asarray(rgba, dtype=np.uint8).reshape(h, w, 4)[:, :, :3].copy()
    seg = np.asarray(seg, dtype=np.int64).reshape(h, w)
    buf = np.asarray(buf, dtype=np.float64).reshape(h, w)
    empty = (seg < 0) | (buf >= 1.0)
    with np.errstate(divide="ignore"):
        depth = far * near / (far - (far - near) * buf)
    depth = np.where(empty, np.inf, depth).astype(np.float32)
    body = np.where(empty, -1, seg & _ID_MASK).astype(np.int32)
    link = np.where(empty, -1, (seg >> _LINK_SHIFT) - 1).astype(np.int32)
    return CameraImages(rgb, depth, body, link)


def render_camera(
    client: int,
    camera: PinholeCamera,
    robot_pose: np.ndarray | Sequence[float],
    *,
    renderer: str = "auto",
    near: float = 0.05,
    far: float = 30.0,
    hide_body_ids: Iterable[int] = (),
) -> CameraImages:
    """Render one robot camera's RGB, depth and segmentation images (see the module docstring).

    Args:
        client: PyBullet physics client id.
        camera: The camera (its width and height must be whole numbers of pixels).
        robot_pose: ``(x, y, yaw)`` of the robot carrying the camera.
        renderer: ``"auto"`` (EGL where :func:`enable_egl` succeeded on the client, else TinyRenderer),
            ``"tiny"`` or ``"egl"`` (``RuntimeError`` where the client does not render that way).
        near: Near clipping plane (m, > 0): surfaces closer than this along the optical axis are not seen.
        far: Far clipping plane (m, > near): farther surfaces are background (depth ``inf``).
        hide_body_ids: Bodies not drawn (e.g. the robot's own body); see :func:`hidden_bodies`.

    Returns:
        :class:`CameraImages` ``(rgb, depth, segmentation, link)``.

    Raises:
        ValueError: Bad renderer name, clipping planes, pose, client or body id.
        RuntimeError: ``renderer="egl"`` on a client without EGL, ``"tiny"`` on one with it.
    """
    cid = _check_client(client)
    pose = _pose(robot_pose)
    near, far = _check_planes(near, far)
    _image_size(camera)
    use_egl = _resolve_renderer(cid, renderer)
    with hidden_bodies(cid, hide_body_ids):
        return _render_one(cid, camera, pose, use_egl, near, far)


def _nav_env(env: Any) -> NavEnv:
    base = getattr(env, "unwrapped", env)
    if not (hasattr(base, "client") and hasattr(base, "robots")):
        raise TypeError(f"expected a navzoo NavEnv (or a wrapper of one), got {type(env).__name__}")
    if base.client is None:
        raise RuntimeError("the env is closed")
    if getattr(base, "pos", None) is None:
        raise RuntimeError("the env has not been reset: call env.reset() first")
    return base


def robot_pose(env: Any, robot_index: int) -> np.ndarray:
    """``(x, y, yaw)`` of robot ``robot_index`` of a (reset) NavEnv.

    Args:
        env: A :class:`~navzoo.envs.nav_env.NavEnv` or a wrapper of one.
        robot_index: Index of the robot, in ``[0, env.n_robots)``.

    Returns:
        (3,) float array.
    """
    base = _nav_env(env)
    i = int(robot_index)
    if i != robot_index or not 0 <= i < base.n_robots:
        raise ValueError(f"robot_index must be an integer in [0, {base.n_robots}), got {robot_index!r}")
    return np.array([base.pos[i, 0], base.pos[i, 1], base.yaw[i]], dtype=float)


def render_robot_cameras(
    env: Any, robot_index: int, cameras: Sequence[PinholeCamera] | None = None, **kw: Any
) -> list[CameraImages]:
    """Render the cameras of one robot of a NavEnv, from its current pose, without its own body.

    Args:
        env: A reset :class:`~navzoo.envs.nav_env.NavEnv` (or a wrapper of one).
        robot_index: Index of the robot, in ``[0, env.n_robots)``.
        cameras: The robot's cameras; default :func:`default_robot_cameras` (two 640x480, 60 degree
            cameras at +-30 degrees).
        **kw: ``renderer``, ``near``, ``far`` and ``hide_body_ids`` (extra bodies to hide; the robot's
            own body always is) for :func:`render_camera`.

    Returns:
        One :class:`CameraImages` per camera, in order.
    """
    base = _nav_env(env)
    pose = robot_pose(base, robot_index)
    cams = list(default_robot_cameras() if cameras is None else cameras)
    unknown = sorted(set(kw) - {"renderer", "near", "far", "hide_body_ids"})
    if unknown:
        raise TypeError(f"unexpected keyword argument(s) {unknown}")
    renderer = kw.get("renderer", "auto")
    near, far = _check_planes(kw.get("near", 0.05), kw.get("far", 30.0))
    hide = [base.robots.ids[int(robot_index)], *kw.get("hide_body_ids", ())]
    for cam in cams:
        _image_size(cam)
    use_egl = _resolve_renderer(base.client, renderer)
    with hidden_bodies(base.client, hide):
        return [_render_one(base.client, cam, pose, use_egl, near, far) for cam in cams]
