"""A planar (2D) lidar on the robot, cast with PyBullet's batched ray tests.

Frames follow :mod:`navzoo.sensors.camera_model`: a robot pose is ``(x, y, yaw)`` in the world, the robot
frame has x forward and y left, and ray angles are measured in the robot frame, counter-clockwise from
its x axis. The lidar sits at ``(mount_x, 0, height)`` in the robot frame and casts horizontal rays.

What the rays see, and why (PyBullet facts, measured with pybullet 3.2.7):

* Ray tests hit *collision* shapes, not visual ones, and return the first hit along each ray.
* A ray that starts inside a convex collision shape does not hit that shape. A lidar inside its own
  robot's body (the default: 0.3 m high at the centre of a 0.3 m radius, 0.4 m tall cylinder) therefore
  never sees it (but a ray that starts just inside a surface, within Bullet's margin, reports a hit at
  distance 0, so re-casting from just past a hit does not work). For other cases (a lidar mounted
  outside the body, concave bodies) ``ignore_body_ids``: every ray whose first hit is an ignored body is
  cast again with ``reportHitNumber = 0, 1, ...`` (PyBullet's all-hits mode) and keeps the nearest hit
  on any other body (at most :data:`MAX_HITS` hits per ray are examined).
* Collision filters apply to rays: PyBullet's ray has collision filter group :data:`RAY_GROUP` (= 1,
  Bullet's default filter; not settable) and mask ``collisionFilterMask`` (default all bits), and it hits
  a body only if ``body_group & ray_mask`` and ``RAY_GROUP & body_mask`` are both non-zero. The static
  scene and the robots have ``GROUP_STATIC`` (= 1) in their masks and are hit, and so are AMP
  pedestrians, but kinematic pedestrians (group ``GROUP_HUMAN``, mask ``GROUP_ROBOT``, see
  :mod:`navzoo.agents.humanoid`) are invisible to every ray test. ``reveal`` handles them: for the
  duration of the scan the listed bodies' masks get :data:`RAY_GROUP` added, then their
  ``(group, mask)`` is set back (PyBullet cannot read a filter, so the caller states it). No physics runs
  in between; a NavEnv rollout with scans at every step is identical to one without (tested).
  :func:`render_robot_lidar` does this for a NavEnv's kinematic pedestrians.
* ``min_range``: rays start ``min_range`` from the sensor, so nearer surfaces are not seen at all (as a
  real lidar's dead zone); ranges are still measured from the sensor. Rays that hit nothing read
  ``max_range`` with ``hit_body == -1``.
* Noise: ``noise_std > 0`` adds ``N(0, noise_std^2)`` to the range of every ray that hit something,
  clipped to ``[min_range, max_range]``. One standard normal is drawn per ray (whether it hit or not),
  so the draws depend only on the generator's state and ``n_rays``.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import pybullet as p

from navzoo.sensors.render import _check_client, _nav_env, _pose
from navzoo.sensors.render import robot_pose as _robot_pose
from navzoo.world.builder import GROUP_HUMAN, GROUP_ROBOT

__all__ = ["MAX_HITS", "RAY_GROUP", "Lidar2D", "LidarScan", "ray_visible", "render_robot_lidar"]

MAX_HITS = 16
"""Most hits examined along one ray whose first hit is in ``ignore_body_ids``."""

RAY_GROUP = 1
"""The collision filter group of PyBullet's ray tests (Bullet's ``DefaultFilter``): a body is hit only
when its collision mask has this bit."""

_BATCH = 16384  # rays per rayTestBatch call (PyBullet's limit for one batch)


class LidarScan(NamedTuple):
    """One lidar scan.

    Attributes:
        ranges: (n,) distance (m) from the sensor to the first surface along each ray, ``max_range``
            where nothing was hit.
        angles: (n,) ray directions (rad) in the robot frame, counter-clockwise from its x axis,
            increasing.
        hit_body: (n,) int PyBullet body unique id hit by each ray, -1 for no hit.
        origin: (2,) sensor position ``(mount_x, 0)`` in the robot frame (m).
    """

    ranges: np.ndarray
    angles: np.ndarray
    hit_body: np.ndarray
    origin: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        """(n,) bool, rays that hit something."""
        return self.hit_body >= 0

    def to_points(self) -> np.ndarray:
        """The hit points in the robot frame.

        Returns:
            (n, 2) float array ``origin + range * (cos(angle), sin(angle))``, NaN rows for rays that hit
            nothing.
        """
        pts = self.origin + self.ranges[:, None] * np.stack(
            [np.cos(self.angles), np.sin(self.angles)], axis=-1
        )
        return np.where(self.hit[:, None], pts, np.nan)


@contextlib.contextmanager
def ray_visible(client: int, reveal: Mapping[int, tuple[int, int]]) -> Iterator[None]:
    """Let PyBullet's ray tests hit bodies whose collision mask lacks :data:`RAY_GROUP`, inside the block.

    Every link of each body gets mask ``mask | RAY_GROUP`` on entry and ``(group, mask)`` back on exit
    (also after an exception). PyBullet has no getter for collision filters, so the caller states them.

    Args:
        client: PyBullet physics client id.
        reveal: body unique id -> its current ``(group, mask)`` (the same on all of its links).
    """
    done: list[tuple[int, int, int, int]] = []
    try:
        for body, (group, mask) in reveal.items():
            if mask & RAY_GROUP:
                continue
            for link in range(-1, p.getNumJoints(body, physicsClientId=client)):
                p.setCollisionFilterGroupMask(body, link, group, mask | RAY_GROUP, physicsClientId=client)
                done.append((body, link, group, mask))
        yield
    finally:
        for body, link, group, mask in reversed(done):
            with contextlib.suppress(p.error):
                p.setCollisionFilterGroupMask(body, link, group, mask, physicsClientId=client)


def _positive(name: str, value: Any, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    if not (math.isfinite(v) and (v >= 0.0 if allow_zero else v > 0.0)):
        raise ValueError(f"{name} must be a finite number {'>= 0' if allow_zero else '> 0'}, got {value!r}")
    return v


@dataclass(frozen=True)
class Lidar2D:
    """A planar lidar: ``n_rays`` horizontal rays spread over ``fov_deg`` (see the module docstring).

    With ``fov_deg = 360`` the rays are ``2 pi / n_rays`` apart starting at ``-pi`` (straight behind),
    without repeating the end; with a smaller field of view they span ``[-fov/2, +fov/2]`` inclusive,
    centred on the robot's heading. Angles increase (counter-clockwise), as a ROS ``LaserScan``.

    Attributes:
        n_rays: Number of rays (>= 1).
        fov_deg: Field of view (degrees, in (0, 360]).
        max_range: Maximum range (m, > min_range); rays that hit nothing read this.
        height: Height of the scan plane above the ground (m, >= 0).
        mount_x: Forward offset of the sensor in the robot frame (m).
        min_range: Dead zone (m, >= 0): rays start this far from the sensor.
        noise_std: Std of the Gaussian range noise (m, >= 0) on rays that hit something.
    """

    n_rays: int = 360
    fov_deg: float = 360.0
    max_range: float = 10.0
    height: float = 0.3
    mount_x: float = 0.0
    min_range: float = 0.0
    noise_std: float = 0.0

    def __post_init__(self) -> None:
        try:
            whole = not isinstance(self.n_rays, bool) and int(self.n_rays) == self.n_rays and self.n_rays >= 1
        except (TypeError, ValueError):
            whole = False
        if not whole:
            raise ValueError(f"n_rays must be an integer >= 1, got {self.n_rays!r}")
        fov = _positive("fov_deg", self.fov_deg)
        if fov > 360.0:
            raise ValueError(f"fov_deg must be in (0, 360] degrees, got {self.fov_deg!r}")
        _positive("max_range", self.max_range)
        _positive("height", self.height, allow_zero=True)
        _positive("min_range", self.min_range, allow_zero=True)
        _positive("noise_std", self.noise_std, allow_zero=True)
        if not math.isfinite(float(self.mount_x)):
            raise ValueError(f"mount_x must be finite, got {self.mount_x!r}")
        if self.min_range >= self.max_range:
            raise ValueError(f"min_range ({self.min_range!r}) must be < max_range ({self.max_range!r})")

    @property
    def angles(self) -> np.ndarray:
        """(n_rays,) ray angles (rad) in the robot frame, increasing."""
        n = int(self.n_rays)
        fov = math.radians(float(self.fov_deg))
        if self.fov_deg >= 360.0:
            return -math.pi + fov * np.arange(n) / n
        if n == 1:
            return np.zeros(1)
        return np.linspace(-fov / 2.0, fov / 2.0, n)

    def rays(self, robot_pose: np.ndarray | Sequence[float]) -> tuple[np.ndarray, np.ndarray]:
        """Sensor position and unit ray directions in the world.

        Args:
            robot_pose: ``(x, y, yaw)`` of the robot.

        Returns:
            ``(origin, directions)``: (3,) sensor position and (n_rays, 3) unit directions (m).
        """
        x, y, yaw = _pose(robot_pose)
        c, s = math.cos(yaw), math.sin(yaw)
        origin = np.array([x + c * self.mount_x, y + s * self.mount_x, float(self.height)])
        world = yaw + self.angles
        dirs = np.stack([np.cos(world), np.sin(world), np.zeros_like(world)], axis=-1)
        return origin, dirs

    def scan(
        self,
        client: int,
        robot_pose: np.ndarray | Sequence[float],
        rng: np.random.Generator | None = None,
        ignore_body_ids: Iterable[int] = (),
        *,
        reveal: Mapping[int, tuple[int, int]] | None = None,
    ) -> LidarScan:
        """Cast the rays from a robot pose.

        Args:
            client: PyBullet physics client id.
            robot_pose: ``(x, y, yaw)`` of the robot.
            rng: Source of the range noise; required when ``noise_std > 0``, unused otherwise.
            ignore_body_ids: Bodies the rays pass through (e.g. the robot's own body when the sensor is
                outside it).
            reveal: Bodies the ray tests would otherwise miss because of their collision filter (body id
                -> its current ``(group, mask)``), see :func:`ray_visible`.

        Returns:
            :class:`LidarScan`.

        Raises:
            ValueError: Bad client, pose, or ``noise_std > 0`` without ``rng``.
        """
        cid = _check_client(client)
        origin, dirs = self.rays(robot_pose)
        if self.noise_std > 0.0 and rng is None:
            raise ValueError("noise_std > 0 needs a numpy Generator: pass rng=np.random.default_rng(seed)")
        if rng is not None and not isinstance(rng, np.random.Generator):
            raise ValueError(f"rng must be a numpy.random.Generator, got {type(rng).__name__}")
        ignore = np.array(sorted({int(b) for b in ignore_body_ids}), dtype=np.int64)
        n = dirs.shape[0]
        lo, hi = float(self.min_range), float(self.max_range)
        frm = origin + lo * dirs
        to = origin + hi * dirs
        with ray_visible(cid, reveal or {}):
            body, frac = _cast(cid, frm, to)
            if ignore.size:
                # Rays whose first hit is ignored: go through all of their hits (PyBullet reports the
                # k-th with reportHitNumber=k, in no guaranteed order) and keep the nearest other one.
                todo = np.flatnonzero(np.isin(body, ignore))
                body[todo], frac[todo] = -1, 1.0
                for k in range(MAX_HITS):
                    if todo.size == 0:
                        break
                    hid, hfr = _cast(cid, frm[todo], to[todo], hit_number=k)
                    better = (hid >= 0) & ~np.isin(hid, ignore) & (hfr < frac[todo])
                    body[todo[better]], frac[todo[better]] = hid[better], hfr[better]
                    todo = todo[hid >= 0]
        ranges = np.where(body >= 0, lo + frac * (hi - lo), hi)
        if rng is not None and self.noise_std > 0.0:
            noise = rng.standard_normal(n) * float(self.noise_std)
            ranges = np.where(body >= 0, np.clip(ranges + noise, lo, hi), ranges)
        return LidarScan(ranges, self.angles, body, np.array([float(self.mount_x), 0.0]))


def _cast(
    client: int, frm: np.ndarray, to: np.ndarray, hit_number: int = -1
) -> tuple[np.ndarray, np.ndarray]:
    """Body id (-1: none) and hit fraction of each ray; the first hit, or the ``hit_number``-th one."""
    ids = np.empty(len(frm), dtype=np.int64)
    frac = np.empty(len(frm))
    extra = {} if hit_number < 0 else {"reportHitNumber": int(hit_number)}
    for i in range(0, len(frm), _BATCH):
        res = p.rayTestBatch(
            frm[i : i + _BATCH].tolist(), to[i : i + _BATCH].tolist(), physicsClientId=client, **extra
        )
        ids[i : i + len(res)] = [r[0] for r in res]
        frac[i : i + len(res)] = [r[2] for r in res]
    return ids, frac


def render_robot_lidar(
    env: Any, robot_index: int, lidar: Lidar2D | None = None, rng: np.random.Generator | None = None
) -> LidarScan:
    """Scan with a lidar on one robot of a NavEnv, from its current pose.

    The rays pass through the robot's own body and see walls, obstacles, other robots and pedestrians:
    kinematic pedestrians within reach (whose collision mask excludes ray tests) are revealed for the
    scan with :func:`ray_visible`, restoring their filter ``(GROUP_HUMAN, GROUP_ROBOT)`` (the one
    :class:`~navzoo.agents.humanoid.HumanoidBodies` sets); AMP pedestrians collide with the scene and are
    hit anyway.

    Args:
        env: A reset :class:`~navzoo.envs.nav_env.NavEnv` (or a wrapper of one).
        robot_index: Index of the robot, in ``[0, env.n_robots)``.
        lidar: The sensor; default ``Lidar2D()`` (360 rays, 10 m, 0.3 m high).
        rng: Source of range noise (needed when ``lidar.noise_std > 0``).

    Returns:
        :class:`LidarScan`.
    """
    base = _nav_env(env)
    pose = _robot_pose(base, robot_index)
    lidar = Lidar2D() if lidar is None else lidar
    if not isinstance(lidar, Lidar2D):
        raise TypeError(f"lidar must be a Lidar2D, got {type(lidar).__name__}")
    reveal: dict[int, tuple[int, int]] = {}
    if base.amp is None and base.n_humans > 0:
        origin, _ = lidar.rays(pose)
        # A person's collision shapes stay within ~1 m of their root: reveal only those in reach.
        near = np.linalg.norm(base.pos[base.n_robots :] - origin[:2], axis=1) < float(lidar.max_range) + 1.5
        reveal = {
            int(b): (GROUP_HUMAN, GROUP_ROBOT) for b, ok in zip(base.humans.ids, near, strict=True) if ok
        }
    return lidar.scan(
        base.client, pose, rng, ignore_body_ids=(base.robots.ids[int(robot_index)],), reveal=reveal
    )
