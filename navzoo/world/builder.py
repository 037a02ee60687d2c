"""Create the static PyBullet bodies of a scene (ground + obstacles) in an explicit physics client.

Collision groups (bit masks for ``p.setCollisionFilterGroupMask``):

* bit 0 ``GROUP_STATIC = 1``: the static scene (ground and obstacles),
* bit 1 ``GROUP_ROBOT = 2``: robots,
* bit 2 ``GROUP_HUMAN = 4``: pedestrians.

Two bodies collide when ``(group_a & mask_b) and (group_b & mask_a)``. Static bodies use group
``GROUP_STATIC`` and mask ``MASK_ALL`` (0xFFFF), so what touches the scene is decided by the dynamic
bodies' own masks (e.g. a robot with mask ``GROUP_STATIC | GROUP_ROBOT | GROUP_HUMAN``).
"""

from __future__ import annotations

import atexit
import hashlib
import shutil
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pybullet as p

from navzoo.world import geometry as geo
from navzoo.world.scene import (
    BoxObstacle,
    CircleObstacle,
    Obstacle,
    PolygonObstacle,
    Scene,
    WallObstacle,
)

__all__ = [
    "COLORS",
    "GROUP_HUMAN",
    "GROUP_ROBOT",
    "GROUP_STATIC",
    "MASK_ALL",
    "SceneBodies",
    "build_scene",
]

GROUP_STATIC = 1
GROUP_ROBOT = 2
GROUP_HUMAN = 4
MASK_ALL = 0xFFFF

#: RGBA colour per obstacle type.
COLORS: dict[str, tuple[float, float, float, float]] = {
    "wall": (0.78, 0.78, 0.80, 1.0),
    "box": (0.62, 0.45, 0.30, 1.0),
    "polygon": (0.55, 0.40, 0.28, 1.0),
    "circle": (0.70, 0.70, 0.66, 1.0),
    "ground": (0.92, 0.92, 0.90, 1.0),
}


@dataclass
class SceneBodies:
    """PyBullet ids of a built scene.

    Attributes:
        client_id: the physics client the bodies live in.
        obstacle_ids: one body id per ``scene.obstacles`` entry, in the same order.
        ground_id: the ground body, or None when built with ``ground=False``.
    """

    client_id: int
    obstacle_ids: list[int] = field(default_factory=list)
    ground_id: int | None = None

    @property
    def body_ids(self) -> list[int]:
        """All static bodies (ground first, when present)."""
        return ([self.ground_id] if self.ground_id is not None else []) + list(self.obstacle_ids)

    def remove(self) -> None:
        """Delete every body from the client."""
        for body in self.body_ids:
            p.removeBody(body, physicsClientId=self.client_id)
        self.obstacle_ids = []
        self.ground_id = None


def _prism_mesh(poly: np.ndarray, height: float) -> tuple[list[list[float]], list[int]]:
    """Closed triangle mesh (vertices, indices) of a polygon extruded from z = 0 to z = height.

    Vertices are centred on the polygon's centroid-ish mean so the body position carries the offset.
    """
    k = poly.shape[0]
    tris = geo.triangulate_polygon(poly)  # counter-clockwise triangles
    verts = np.concatenate([np.c_[poly, np.zeros(k)], np.c_[poly, np.full(k, height)]])
    idx: list[int] = []
    for a, b, c in tris.tolist():
        idx += [c, b, a]  # bottom cap, facing down
        idx += [a + k, b + k, c + k]  # top cap, facing up
    ccw = geo.polygon_area(poly) > 0
    for i in range(k):
        j = (i + 1) % k
        if ccw:
            idx += [i, j, j + k, i, j + k, i + k]  # outward-facing sides
        else:
            idx += [j, i, i + k, j, i + k, j + k]
    return verts.tolist(), idx


_MESH_DIR: Path | None = None


def _mesh_dir() -> Path:
    """A per-process folder for OBJ files of polygon prisms, removed at exit."""
    global _MESH_DIR
    if _MESH_DIR is None:
        _MESH_DIR = Path(tempfile.mkdtemp(prefix="navzoo_meshes_"))
        atexit.register(shutil.rmtree, _MESH_DIR, True)
    return _MESH_DIR


def prism_obj(verts: list[list[float]], idx: list[int]) -> str:
    """Wavefront OBJ text of a triangle mesh, with one flat normal per face (for PyBullet's EGL renderer)."""
    v = np.asarray(verts, dtype=np.float64)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in v]
    faces = []
    for t in range(0, len(idx), 3):
        a, b, c = idx[t:t + 3]
        n = np.cross(v[b] - v[a], v[c] - v[a])
        n = n / max(float(np.linalg.norm(n)), 1e-12)
        lines.append(f"vn {n[0]:.6f} {n[1]:.6f} {n[2]:.6f}")
        k = t // 3 + 1
        faces.append(f"f {a + 1}//{k} {b + 1}//{k} {c + 1}//{k}")
    return "\n".join(lines + faces) + "\n"


def _visual_mesh(verts: list[list[float]], idx: list[int], rgba: tuple[float, ...], client_id: int,
                 as_file: bool) -> int:
    if not as_file:
        return p.createVisualShape(p.GEOM_MESH, vertices=verts, indices=idx, rgbaColor=rgba,
                                   physicsClientId=client_id)
    text = prism_obj(verts, idx)
    path = _mesh_dir() / f"prism_{hashlib.sha1(text.encode()).hexdigest()[:16]}.obj"
    if not path.is_file():
        tmp = path.with_suffix(".tmp")
        tmp.write_text(text)
        tmp.replace(path)
    return p.createVisualShape(p.GEOM_MESH, fileName=str(path), rgbaColor=rgba, physicsClientId=client_id)


def _add_polygon(obs: PolygonObstacle, client_id: int, rgba: tuple[float, ...], mesh_files: bool = False) -> int:
    """A polygon prism: one convex hull when convex, otherwise one convex prism per ear-clipping triangle
    as links of a single fixed multibody (convex pieces collide robustly with every dynamic shape, unlike a
    concave triangle mesh), with the whole prism as the visual mesh of the base."""
    poly = obs.polygon()
    center = poly.mean(axis=0)
    local = poly - center
    verts, idx = _prism_mesh(local, obs.height)
    vis = _visual_mesh(verts, idx, rgba, client_id, mesh_files)
    if _is_convex(local):
        col = p.createCollisionShape(p.GEOM_MESH, vertices=verts, physicsClientId=client_id)
        return p.createMultiBody(0.0, col, vis, [center[0], center[1], 0.0], physicsClientId=client_id)
    tris = geo.triangulate_polygon(local)
    pieces = []
    for tri in tris:
        pts = local[tri]
        pverts = np.concatenate([np.c_[pts, np.zeros(3)], np.c_[pts, np.full(3, obs.height)]]).tolist()
        pieces.append(p.createCollisionShape(p.GEOM_MESH, vertices=pverts, physicsClientId=client_id))
    n_links = len(pieces) - 1
    return p.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=pieces[0],
        baseVisualShapeIndex=vis,
        basePosition=[center[0], center[1], 0.0],
        linkMasses=[0.0] * n_links,
        linkCollisionShapeIndices=pieces[1:],
        linkVisualShapeIndices=[-1] * n_links,
        linkPositions=[[0.0, 0.0, 0.0]] * n_links,
        linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * n_links,
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * n_links,
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * n_links,
        linkParentIndices=[0] * n_links,
        linkJointTypes=[p.JOINT_FIXED] * n_links,
        linkJointAxis=[[0.0, 0.0, 1.0]] * n_links,
        physicsClientId=client_id,
    )


def _is_convex(poly: np.ndarray) -> bool:
    d1 = poly - np.roll(poly, 1, axis=0)
    d2 = np.roll(poly, -1, axis=0) - poly
    cross = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    return bool(np.all(cross >= -1e-12) or np.all(cross <= 1e-12))


def _add_box(center: tuple[float, float], size: tuple[float, float], yaw: float, height: float, client_id: int,
             rgba: tuple[float, ...]) -> int:
    half = [0.5 * size[0], 0.5 * size[1], 0.5 * height]
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, physicsClientId=client_id)
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=rgba, physicsClientId=client_id)
    quat = p.getQuaternionFromEuler([0.0, 0.0, yaw])
    return p.createMultiBody(0.0, col, vis, [center[0], center[1], 0.5 * height], quat, physicsClientId=client_id)


def _add_obstacle(obs: Obstacle, client_id: int, mesh_files: bool = False) -> int:
    rgba = COLORS[obs.type]
    if isinstance(obs, BoxObstacle):
        return _add_box(obs.center, obs.size, obs.yaw, obs.height, client_id, rgba)
    if isinstance(obs, WallObstacle):
        mid = (0.5 * (obs.start[0] + obs.end[0]), 0.5 * (obs.start[1] + obs.end[1]))
        yaw = float(np.arctan2(obs.end[1] - obs.start[1], obs.end[0] - obs.start[0]))
        return _add_box(mid, (obs.length, obs.thickness), yaw, obs.height, client_id, rgba)
    if isinstance(obs, CircleObstacle):
        col = p.createCollisionShape(p.GEOM_CYLINDER, radius=obs.radius, height=obs.height, physicsClientId=client_id)
        vis = p.createVisualShape(
            p.GEOM_CYLINDER, radius=obs.radius, length=obs.height, rgbaColor=rgba, physicsClientId=client_id
        )
        pos = [obs.center[0], obs.center[1], 0.5 * obs.height]
        return p.createMultiBody(0.0, col, vis, pos, physicsClientId=client_id)
    if isinstance(obs, PolygonObstacle):
        return _add_polygon(obs, client_id, rgba, mesh_files)
    raise TypeError(f"unsupported obstacle {obs!r}")  # pragma: no cover - Scene validates types


def _set_static_filter(body: int, client_id: int) -> None:
    for link in range(-1, p.getNumJoints(body, physicsClientId=client_id)):
        p.setCollisionFilterGroupMask(body, link, GROUP_STATIC, MASK_ALL, physicsClientId=client_id)


def build_scene(scene: Scene, client_id: int, ground: bool = True, mesh_files: bool = False) -> SceneBodies:
    """Create the scene's static bodies (mass 0) in physics client ``client_id``.

    Boxes and walls become ``GEOM_BOX`` bodies, circles ``GEOM_CYLINDER`` bodies, and polygons extruded
    prisms (see ``_add_polygon``); each obstacle stands on z = 0 with its height. The ground is an infinite
    ``GEOM_PLANE`` collision shape with a thin box visual covering the bounds. All get collision group
    ``GROUP_STATIC`` with mask ``MASK_ALL``.

    Args:
        scene: the scene to build.
        client_id: an open PyBullet client (the implicit default client is never used).
        ground: also create the ground plane.
        mesh_files: give polygon prisms their visual mesh as an OBJ file (in a per-process temporary
            folder) instead of vertex data; PyBullet's EGL renderer draws only the former.

    Returns:
        The created body ids.
    """
    bodies = SceneBodies(client_id=client_id)
    if ground:
        x0, y0, x1, y1 = scene.bounds
        col = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=client_id)
        half = [0.5 * (x1 - x0) + 1.0, 0.5 * (y1 - y0) + 1.0, 0.005]
        vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=half, visualFramePosition=[0, 0, -0.005], rgbaColor=COLORS["ground"],
            physicsClientId=client_id,
        )
        # The plane shape is infinite; the body sits at the bounds' centre only so the visual covers them.
        bodies.ground_id = p.createMultiBody(
            0.0, col, vis, [0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.0], physicsClientId=client_id
        )
        _set_static_filter(bodies.ground_id, client_id)
    for obs in scene.obstacles:
        body = _add_obstacle(obs, client_id, mesh_files)
        _set_static_filter(body, client_id)
        bodies.obstacle_ids.append(body)
    return bodies
