"""The navzoo ParallelEnv: robots and pedestrians as agents of one PyBullet world."""

from __future__ import annotations

import time
import warnings
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pybullet as p
from gymnasium import spaces
from pettingzoo import ParallelEnv

from navzoo import sim
from navzoo.agents.door_turns import DoorParams, DoorTurns
from navzoo.agents.humanoid import HumanoidBodies
from navzoo.agents.policy import preferred_velocity
from navzoo.agents.robot import RobotBodies, command_velocity, wrap_angle
from navzoo.agents.yielding import TurnTaking, YieldParams
from navzoo.envs import amp_humans
from navzoo.envs import observations as obs_terms
from navzoo.envs.amp_humans import PLAN_MARGIN as AMP_PLAN_MARGIN
from navzoo.envs.amp_humans import WAYPOINT_LOOKAHEAD, AmpHumans, advance_waypoint
from navzoo.envs.amp_humans import YIELD_HOLD_S as AMP_YIELD_HOLD_S
from navzoo.envs.config import NavConfig
from navzoo.envs.doors import door_entries, path_doors
from navzoo.envs.fallen import FALLEN_BODY_RADIUS, FALLEN_GOAL_TRIES, FALLEN_RESTAMP_M, path_passes
from navzoo.envs.fallen import footprint_points as fallen_footprint_points
from navzoo.envs.fallen import stamp as stamp_fallen
from navzoo.envs.rewards import TERMS, RewardParams, navigation_reward
from navzoo.envs.subgoal import RobotGuide
from navzoo.world.builder import GROUP_ROBOT, GROUP_STATIC, build_scene
from navzoo.world.geometry import ray_segment_distances, swept_circle_hits_segments
from navzoo.world.library import get_scene
from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner
from navzoo.world.scene import Scene, load_scene
from navzoo.world.tasks import TaskSampler

# Swept tests use this slack: ORCA-like controllers drive exactly onto the boundary of the
# collision disc, and floating-point round-off must not turn a graze at 0.6 m into a collision.
COLLISION_TOLERANCE = 1e-4  # m
# NavConfig.human_replan_blocked: a pedestrian whose next waypoint has been out of its line of sight this long
# plans a new A* path from where it is, at most once per REPLAN_EVERY_S.
REPLAN_HIDDEN_S = 1.0
REPLAN_EVERY_S = 2.0

RESET_OPTIONS = ("robot_starts", "robot_goals", "robot_yaws", "human_starts", "human_goals")


class NavEnv(ParallelEnv):
    """Crowd navigation in PyBullet: every robot and every pedestrian is an agent.

    ## Description
    Robots (differential-drive or holonomic bases, real PyBullet bodies) navigate to goals through a
    scene of walls and furniture among pedestrians (15-body humanoids). Each agent has a goal and an
    A* path on the scene's occupancy grid; pedestrians that reach their goal get a new one.

    ## Agents
    ``robot_0 .. robot_{R-1}``, then ``human_0 .. human_{H-1}``. Robots leave ``agents`` when they
    reach their goal or collide; pedestrians stay until the episode ends. The episode ends for
    everyone when no robot is left or at the time limit.

    With ``crowd_model="replay"`` (:mod:`navzoo.agents.replay`) the pedestrians replay recorded
    ETH/UCY tracks: they stay in ``agents`` (a stable list) but their actions are ignored and their
    rewards are 0; a slot whose person has not appeared yet or has left is absent
    (``env.human_active[j]`` False, ``info["active"]``): parked far outside the scene, left out of
    observations, collisions, clearances and rendering.

    ## Action space
    ``Box(-1, 1, (2,), float32)`` for every agent; finite values outside [-1, 1] are clipped and
    counted in ``info[agent]["action_clipped"]``.

    | agent | kinematics | a[0] | a[1] |
    |---|---|---|---|
    | robot | diff_drive | v / max_speed (m/s) | omega / max_turn_rate (rad/s) |
    | robot | holonomic | v_x / max_speed, world frame | v_y / max_speed, world frame |
    | human | kinematic | forward speed / human_max_speed, own frame | leftward speed / human_max_speed |

    Commands are rate-limited by the robot's acceleration limits; holonomic and human commands are
    capped to a norm of 1.

    ## Observation space
    ``Dict`` (or, with ``flat_obs=True``, the same entries flattened into one Box in the Dict's sorted
    key order: agents, agents_mask, goal, map, velocity):

    | key | shape | content (agent frame: x forward, y left) |
    |---|---|---|
    | goal | (5,) | x_g, y_g (m), d_g (m), sin theta_g, cos theta_g |
    | velocity | (3,) | v_x, v_y (m/s), omega (rad/s) |
    | agents | (K, T, 7) | K nearest others over T steps: x, y, u, v, cos theta, sin theta, radius |
    | agents_mask | (K, T) | 1 where the entry is a real, observed agent |
    | map | (C, C) | local occupancy crop, 1 = occupied, agent at the centre, heading along columns |

    ## Rewards
    Robots: the paper's r_nav + r_omega (see :mod:`navzoo.envs.rewards`), each term in
    ``info[agent]["reward/<term>"]``. Pedestrians: the same r_nav with their own goal (no omega
    term); a pedestrian that reaches its goal gets +20 and a new goal, and a kinematic one gets the
    collision term (``collision_reward``, -20) when a contact with a robot or a person begins (``human_contact_penalty``).

    ## Starting state
    Sampled from the scene's spawn/goal regions or its protocol (circle/square crossing) by a seeded
    sampler: free, reachable, at least ``min_goal_distance`` apart, not overlapping.
    ``reset(options=...)`` accepts explicit ``robot_starts``, ``robot_goals``, ``robot_yaws``,
    ``human_starts``, ``human_goals`` arrays.

    ## Episode end
    Termination (robots): goal reached (distance < goal tolerance), or collision with a person, an
    obstacle or another robot (swept motion within the step, plus PyBullet contacts), or a NaN
    physics state (``info["nan_state"]``). Truncation: the time limit.

    ## Arguments
    ``NavEnv(config=NavConfig(...), render_mode=None | "rgb_array" | "human", render_view=
    "topdown" | "camera" | "both", **config_overrides)``.

    ## Version history
    v0: initial release.
    """

    metadata = {
        "name": "navzoo_nav_v0",
        "render_modes": ["rgb_array", "human"],
        "render_fps": 10,
        "is_parallelizable": True,
    }

    def __init__(
        self,
        config: NavConfig | None = None,
        render_mode: str | None = None,
        render_view: str = "topdown",
        **overrides: Any,
    ) -> None:
        cfg = config if config is not None else NavConfig()
        if not isinstance(cfg, NavConfig):
            raise TypeError(f"config must be a NavConfig, got {type(cfg).__name__}")
        if overrides:
            cfg = cfg.replace(**overrides)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        if render_view not in ("topdown", "camera", "both"):
            raise ValueError(f"render_view must be 'topdown', 'camera' or 'both', got {render_view!r}")
        self.config = cfg
        self.render_mode = render_mode
        self.render_view = render_view
        self.scene: Scene = _resolve_scene(cfg.scene)
        self.n_robots = cfg.n_robots
        self.time_limit = cfg.time_limit if cfg.time_limit is not None else float(self.scene.time_limit)
        self.max_steps = cfg.max_episode_steps_override or max(1, int(round(self.time_limit / cfg.dt)))
        # crowd_model="replay": recorded ETH/UCY people in fixed slots (navzoo.agents.replay); by
        # default as many slots as people present at once in the played window.
        self.replay = None
        if cfg.crowd_model == "replay":
            from navzoo.agents.replay import ReplayCrowd

            self.replay = ReplayCrowd(cfg.replay_scene, cfg.replay_start, cfg.dt, self.max_steps, cfg.n_humans)
            self.n_humans = self.replay.n_slots
            if self.n_robots == 0 and self.n_humans == 0:
                raise ValueError(f"no agent at all: n_robots=0 and nobody walks in recording {cfg.replay_scene!r} "
                                 f"between {cfg.replay_start:g} s and {cfg.replay_start + self.time_limit:g} s")
        else:
            self.n_humans = cfg.n_humans if cfg.n_humans is not None else int(self.scene.default_humans)
        self.n_total = self.n_robots + self.n_humans
        self.possible_agents = [f"robot_{i}" for i in range(self.n_robots)] + [f"human_{j}" for j in range(self.n_humans)]
        self._index = {a: i for i, a in enumerate(self.possible_agents)}
        self.agents: list[str] = []
        self.goal_tolerance = cfg.goal_tolerance if cfg.goal_tolerance is not None else cfg.robot.radius
        self.reward_params = RewardParams(wall_proximity_distance=cfg.wall_proximity,
                                          collision_reward=float(cfg.collision_reward),
                                          proximity_scale=float(cfg.proximity_scale))

        # Static world: grid, planners (one A* for robots and people, per radius), task sampler.
        self.grid = OccupancyGrid.from_scene(self.scene, resolution=cfg.grid_resolution)
        self.segments = self.scene.wall_segments(include_bounds=True)  # the scene edge is a wall too
        # The obstacle owning each wall edge (each scene-edge side is a wall of its own): crowd
        # models push people once per obstacle, from its nearest point.
        owner = np.array(self.scene.wall_segment_owner(include_bounds=True))
        edge = owner < 0
        owner[edge] = owner.max(initial=-1) + 1 + np.arange(int(edge.sum()))
        self.segment_groups = owner
        self._planners: dict[float, AStarPlanner] = {}
        self.radius = np.array([cfg.robot.radius] * self.n_robots + [cfg.human_radius] * self.n_humans)
        self.is_robot = np.arange(self.n_total) < self.n_robots
        # Robots' global planner (subgoals, geodesic progress), when the config asks for either.
        self.robot_guide: RobotGuide | None = None
        if self.n_robots and (cfg.robot_subgoal is not None or cfg.robot_progress == "geodesic"):
            self.robot_guide = RobotGuide(self.grid, self.radius[: self.n_robots], cfg.robot_subgoal or 3.0,
                                          clearance=cfg.path_clearance, spacing=cfg.path_spacing,
                                          planners=self._planners)
        # Set by navzoo.perception.PerceptionWrapper: {robot index: (positions, velocities, radii)} of the
        # people each robot perceives, read by the privileged baselines instead of the true people.
        self.perceived_people: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._samplers = {
            "robot": TaskSampler(self.scene, self.grid, cfg.robot.radius),
            "human": TaskSampler(self.scene, self.grid, cfg.human_radius),
        }

        # Spaces: built once, the same object returned on every call.
        self._obs_space = self._build_observation_space()
        self._act_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        self.observation_spaces = {a: self._obs_space for a in self.possible_agents}
        self.action_spaces = {a: self._act_space for a in self.possible_agents}
        if cfg.human_model == "amp" and self.n_humans > 0:
            from navzoo.envs import amp_humans

            h_obs = spaces.Box(-np.inf, np.inf, shape=(amp_humans.OBS_DIM,), dtype=np.float32)
            h_act = spaces.Box(-1.0, 1.0, shape=(amp_humans.ACT_DIM,), dtype=np.float32)
            for a in self.possible_agents[self.n_robots:]:
                self.observation_spaces[a] = h_obs
                self.action_spaces[a] = h_act

        # PyBullet world: one client per env, bodies built once and moved on reset (physics pedestrians: rebuilt).
        self.client = sim.connect(gui=(render_mode == "human"))
        # Cameras render with EGL only if its plugin is loaded before the first body exists.
        self.egl = False
        if cfg.egl:
            from navzoo.sensors.render import enable_egl

            self.egl = enable_egl(self.client)
            if not self.egl:
                warnings.warn("NavConfig.egl: PyBullet's EGL renderer is not available here (no eglRenderer "
                              "plugin or no OpenGL context); cameras use TinyRenderer", RuntimeWarning, stacklevel=2)
        self.diffusion = None
        if cfg.crowd_model == "diffusion" and self.n_humans > 0:
            from navzoo.agents.diffusion.crowd import DiffusionCrowd

            self.diffusion = DiffusionCrowd(cfg.diffusion_model, n_samples=cfg.diffusion_samples)
        self._build_world()

        self._seeded = False
        self._needs_reset = True
        self._world_stepped = False  # stepped since the world was built (reset rebuilds physics worlds then)
        self.physics_time = 0.0  # seconds spent in stepSimulation, cumulative (for `navzoo speed`)
        self._viewer_window = None

    def _build_world(self) -> None:
        """The PyBullet content of the env's client: the scene's bodies, the robots, the pedestrians' bodies, and
        the state that ``reset`` restores. Called once by ``__init__``, and by ``reset`` after
        ``p.resetSimulation`` in worlds of physics pedestrians (see :meth:`reset`)."""
        cfg = self.config
        p.setGravity(0, 0, -9.81, physicsClientId=self.client)
        p.setTimeStep(cfg.dt / cfg.physics_substeps, physicsClientId=self.client)
        if self.egl:
            from navzoo.sensors.render import quiet

            # The EGL plugin reports, from C, every collision-only mesh piece (the convex parts of a
            # concave polygon) that it cannot draw; they have no visual shape and are not drawn anyway.
            with quiet():
                self.bodies = build_scene(self.scene, self.client, mesh_files=True)
        else:
            self.bodies = build_scene(self.scene, self.client)
        # PyBullet pairs collide when *either* body's group matches the other's mask (filter mode
        # OR), so the scene's bodies must leave the kinematic humans out of their mask: scripted
        # people do not collide with the scene or each other, only with robots.
        for body in self.bodies.body_ids:
            for link in range(-1, p.getNumJoints(body, physicsClientId=self.client)):
                p.setCollisionFilterGroupMask(body, link, GROUP_STATIC, GROUP_STATIC | GROUP_ROBOT,
                                              physicsClientId=self.client)
        self.robots = RobotBodies(self.client, cfg.robot, self.n_robots)
        self.amp: AmpHumans | None = None
        if cfg.human_model == "amp" and self.n_humans > 0:
            self.amp = AmpHumans(self)  # sets the client's time step to 1/120 s
            human_ids = self.amp.ids
        else:
            self.humans = HumanoidBodies(self.client, self.n_humans)
            human_ids = self.humans.ids
        self._body_kind: dict[int, str] = {}
        for b in self.bodies.obstacle_ids:
            self._body_kind[b] = "obstacle"
        for b in self.robots.ids:
            self._body_kind[b] = "robot"
        for b in human_ids:
            self._body_kind[b] = "human"
        self._human_index = {b: j for j, b in enumerate(human_ids)}
        self._saved_state = p.saveState(physicsClientId=self.client)

    # ------------------------------------------------------------------ spaces
    def _build_observation_space(self) -> spaces.Space:
        cfg = self.config
        k, t, c = cfg.k_neighbors, cfg.history, cfg.map_cells
        B, V = obs_terms.POS_BOUND, obs_terms.VEL_BOUND
        G = obs_terms.GOAL_BOUND
        f32 = np.float32
        goal = spaces.Box(np.array([-G, -G, 0, -1, -1], f32), np.array([G, G, 1.5 * G, 1, 1], f32), dtype=f32)
        vel = spaces.Box(-V, V, shape=(3,), dtype=f32)
        lo = np.broadcast_to(np.array([-B, -B, -V, -V, -1, -1, 0], f32), (k, t, 7)).copy()
        hi = np.broadcast_to(np.array([B, B, V, V, 1, 1, 2.0], f32), (k, t, 7)).copy()
        agents = spaces.Box(lo, hi, dtype=f32)
        mask = spaces.Box(0.0, 1.0, shape=(k, t), dtype=f32)
        local_map = spaces.Box(0.0, 1.0, shape=(c, c), dtype=f32)
        entries = {"goal": goal, "velocity": vel, "agents": agents, "agents_mask": mask, "map": local_map}
        if cfg.scan_rays:
            entries["scan"] = spaces.Box(0.0, 1.0, shape=(cfg.scan_rays,), dtype=f32)
        self._dict_space = spaces.Dict(entries)
        if cfg.flat_obs:
            return spaces.flatten_space(self._dict_space)
        return self._dict_space

    def observation_space(self, agent: str) -> spaces.Space:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space:
        return self.action_spaces[agent]

    # ------------------------------------------------------------------ reset
    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None or not self._seeded:
            ss = np.random.SeedSequence(seed)
            task_ss, crowd_ss, self_ss = ss.spawn(3)
            self.rng_tasks = np.random.default_rng(task_ss)
            self.rng_crowd = np.random.default_rng(crowd_ss)
            self.np_random = np.random.default_rng(self_ss)
            self._seeded = True
        options = dict(options or {})
        unknown = sorted(set(options) - set(RESET_OPTIONS))
        if unknown:
            # PettingZoo's conformance test passes an arbitrary option, so unknown keys are reported,
            # not fatal; malformed values of known keys are errors.
            gymnasium.logger.warn(f"ignoring unknown reset option(s) {unknown}; valid options: {list(RESET_OPTIONS)}")
        cfg = self.config
        if self.amp is not None and self._world_stepped:
            # Physics pedestrians: restoreState puts every body back, but PyBullet's broadphase keeps its order of
            # overlapping pairs, the order in which the solver meets contacts, so an episode would depend on the
            # episodes before it in this world. A rebuilt world (a few hundredths of a second) is a fresh one, so an
            # episode depends on its seed alone (docs/env.md, "Reproducibility"). Body ids come back the same.
            p.resetSimulation(physicsClientId=self.client)
            self._build_world()
        self._world_stepped = False
        p.restoreState(self._saved_state, physicsClientId=self.client)
        for i in range(self.n_robots):
            self.robots.restore(i)

        R, H, N = self.n_robots, self.n_humans, self.n_total
        rp = self.replay
        if rp is not None:
            given = sorted({"human_starts", "human_goals"} & set(options))
            if given:
                raise ValueError(f"reset option(s) {given} cannot be used with crowd_model='replay': the people "
                                 "follow the recording")
            # Robots start clear of the people present at t=0 (0.5 m beyond touching).
            act0 = rp.active[0]
            h_start, h_goal = rp.pos[0].copy(), rp.goal[0].copy()
            r_start, r_goal = self._sample_or_take(
                options, "robot", R, (h_start[act0], np.full(int(act0.sum()), cfg.human_radius + 0.5), h_goal[act0]))
        else:
            r_start, r_goal = self._sample_or_take(options, "robot", R, None)
            h_start, h_goal = self._sample_or_take(options, "human", H, (r_start, self.radius[:R], r_goal))
        self.pos = np.concatenate([r_start, h_start]).reshape(N, 2).astype(np.float64)
        self.goal = np.concatenate([r_goal, h_goal]).reshape(N, 2).astype(np.float64)
        self.vel = np.zeros((N, 2))
        self.omega = np.zeros(N)
        self.cmd = np.zeros((R, 2))
        self._fallen_grid: OccupancyGrid | None = None  # the grid with fallen bodies (human_fallen_obstacles)
        self._fallen_planners: dict[float, AStarPlanner] = {}
        self._fallen_points = np.zeros((0, 2))
        self._fallen_stamped: dict[int, np.ndarray] = {}  # pedestrian -> its root and key bodies (K+1, 2) when stamped
        self._fallen_replanned = np.zeros(H, dtype=bool)  # who got a path round a fallen body since the last step
        # human_fallen_wait: who stands and waits because fallen bodies block every way to its goal
        self.human_waiting_fallen = np.zeros(H, dtype=bool)
        self._wp_hidden = np.zeros(N)  # seconds each agent's current waypoint has been out of its sight
        self._last_replan = np.full(N, -np.inf)  # sim time of each pedestrian's last blocked-path replan
        # Replayed people walk their recorded track: their "path" is the track's last point.
        self.paths: list[np.ndarray] = [
            self._plan(i, self.pos[i], self.goal[i]) if (rp is None or i < R) else self.goal[i][None].copy()
            for i in range(N)
        ]
        self.wp_index = np.zeros(N, dtype=int)
        self._advance_waypoints()
        yaws = np.array([_heading_along(path, start) for path, start in zip(self.paths, self.pos, strict=True)])
        if "robot_yaws" in options:
            yaws[:R] = _as_array(options["robot_yaws"], (R,), "robot_yaws")
        self.human_active = np.ones(H, dtype=bool)  # False = absent (replay: not yet appeared / left)
        self._human_continuing = np.ones(H, dtype=bool)  # present at the previous step too, on the same track
        if rp is not None:
            yaws[R:] = rp.yaw[0]
            self.vel[R:] = rp.vel[0]
            self.human_active = rp.active[0].copy()
        self.yaw = yaws
        lo, hi = cfg.human_speed
        self.v_pref = np.concatenate([np.full(R, cfg.robot.max_speed), self.rng_crowd.uniform(lo, hi, H)])
        self.alive = np.ones(N, dtype=bool)
        self.d_goal = np.linalg.norm(self.goal - self.pos, axis=1)
        self.shortest_path_length = np.array([_path_length(pth, s) for pth, s in zip(self.paths, self.pos, strict=True)])
        self.steps = 0
        self.perceived_people = None  # a PerceptionWrapper sets it again after its own reset
        self.sim_time = 0.0
        self.action_clips = np.zeros(N, dtype=int)
        self.events: dict[str, str] = {}
        self.goals_reached = np.zeros(N, dtype=int)
        self.arrived = np.zeros(N, dtype=bool)  # pedestrians done for good (human_at_goal="stop")
        # physics pedestrians may hold a yield until the other has passed (amp_humans.YIELD_HOLD_S; 0 = off)
        hold = YieldParams(hold_max=AMP_YIELD_HOLD_S) if cfg.human_model == "amp" else None
        self.turn_taking = TurnTaking(H, hold) if cfg.human_yielding and rp is None else None
        stall_s = amp_humans.DIFFUSION_DOOR_GRANT_STALL_S if cfg.crowd_model == "diffusion" else amp_humans.DOOR_GRANT_STALL_S
        door_params = DoorParams(no_room_waits=bool(amp_humans.DOOR_NO_ROOM_WAITS),
                                 spot_passage_only=bool(amp_humans.DOOR_SPOT_PASSAGE_ONLY),
                                 passed_lateral=float(amp_humans.DOOR_PASSED_LATERAL) or None,
                                 line_up=float(amp_humans.DOOR_LINE_UP) or None,
                                 grant_max_s=float(amp_humans.DOOR_GRANT_MAX_S),
                                 grant_stall_s=float(stall_s) or None) if cfg.human_model == "amp" else None
        self.door_turns = DoorTurns(H, self.grid.distance_at, door_params) if cfg.door_turns and rp is None else None
        self._door_paths: list[object] = [None] * H

        self.robots.reset(self.pos[:R], self.yaw[:R])
        self.robot_subgoals = self.goal[:R].copy()  # what the robots' goal features point at
        self.d_progress = self.d_goal[:R].copy()  # the distance behind the robots' progress reward
        if self.robot_guide is not None:
            self.robot_guide.reset(self.pos[:R], self.goal[:R])
            self._update_robot_guide(np.ones(R, dtype=bool))
        if self.diffusion is not None:
            self.diffusion.seed = int(self.rng_crowd.integers(2**31))
            self.diffusion.reset(self)
        self.human_fallen = np.zeros(H, dtype=bool)
        self._human_contact = np.zeros(H, dtype="<U5")  # what each pedestrian touched at the last step
        self._humans_hit: set[int] = set()
        self.human_map_contact = np.zeros(H, dtype=bool)
        self.human_agent_contact = np.zeros(H, dtype=bool)
        self.human_robot_contact = np.zeros(H, dtype=bool)
        self._update_door_turns()  # before the first AMP target rollout
        if self.amp is not None:
            self.amp.reset(self.pos[R:], self.yaw[R:])
        else:
            self.humans.reset(self.pos[R:], self.yaw[R:], self.rng_crowd.uniform(0, 1, H))
        T = cfg.history
        self.hist_pos = np.repeat(self.pos[None], T, axis=0)
        self.hist_vel = np.zeros((T, N, 2))
        self.hist_vel[-1] = self.vel
        self.hist_yaw = np.repeat(self.yaw[None], T, axis=0)
        self.hist_valid = np.zeros(T, dtype=bool)
        self.hist_valid[-1] = True
        self.hist_present = np.zeros((T, N), dtype=bool)  # per agent and step: in the world (not parked)
        self.hist_present[-1] = self.present
        self.trail: list[np.ndarray] = [self.pos.copy()]  # every step's positions, for rendering
        self.trail_present: list[np.ndarray] = [self.present.copy()]  # False also where a slot changed person

        self.agents = list(self.possible_agents)
        self._needs_reset = False
        obs = self._observations(self.agents)
        infos = {a: self._base_info(a) for a in self.agents}
        return obs, infos

    def _sample_or_take(self, options, kind, n, existing):
        starts_key, goals_key = f"{kind}_starts", f"{kind}_goals"
        if n == 0:
            return np.zeros((0, 2)), np.zeros((0, 2))
        if starts_key in options or goals_key in options:
            if starts_key not in options or goals_key not in options:
                raise ValueError(f"reset options {starts_key!r} and {goals_key!r} must be given together")
            starts = _as_array(options[starts_key], (n, 2), starts_key)
            goals = _as_array(options[goals_key], (n, 2), goals_key)
            return starts, goals
        ex_pos, ex_rad, ex_goal = existing if existing is not None else (None, None, None)
        return self._samplers[kind].sample(
            self.rng_tasks, n, kind, min_goal_dist=self.config.min_goal_distance,
            existing_positions=ex_pos, existing_radii=ex_rad, existing_goals=ex_goal,
        )

    def _planner(self, radius: float) -> AStarPlanner:
        if radius not in self._planners:
            self._planners[radius] = AStarPlanner(self.grid, radius)
        return self._planners[radius]

    def _fallen_planner(self, radius: float) -> AStarPlanner:
        if radius not in self._fallen_planners:
            self._fallen_planners[radius] = AStarPlanner(self._fallen_grid, radius)
        return self._fallen_planners[radius]

    def _planner_for(self, i: int):
        """Agent ``i``'s planner factory (radius -> AStarPlanner): pedestrians plan around fallen bodies
        once there are any (``human_fallen_obstacles``), robots on the bare scene grid."""
        return self._fallen_planner if i >= self.n_robots and self._fallen_grid is not None else self._planner

    def _plan(self, i: int, start: np.ndarray, goal: np.ndarray, fallback: bool = True,
              scene_grid: bool = False) -> np.ndarray | None:
        """Agent ``i``'s A* path from ``start`` to ``goal`` (pedestrians around fallen bodies when the
        config asks for it, or on the bare scene grid with ``scene_grid``); without a path, the goal alone,
        or None when ``fallback`` is False."""
        path = None
        clearance = self.config.path_clearance
        if self.config.human_model == "amp" and i >= self.n_robots:
            clearance += AMP_PLAN_MARGIN
        planner = self._planner if scene_grid else self._planner_for(i)
        bare = planner(float(self.radius[i]))
        if clearance > 0:
            padded = float(self.radius[i]) + clearance
            path = planner(padded).plan(start, goal, spacing=self.config.path_spacing)
            if path is None:  # a passage on the way is too narrow for the clearance: keep it where it fits
                path = bare.plan_graded(start, goal, clearance, spacing=self.config.path_spacing)
        if path is None:
            path = bare.plan(start, goal, spacing=self.config.path_spacing)
        if (path is None or len(path) == 0) and not fallback:
            return None
        if path is not None and len(path) and self.config.human_door_entries and self.config.human_model == "amp" \
                and i >= self.n_robots:
            path = door_entries(path, start, bare.grid, float(self.radius[i]))
        if path is None or len(path) == 0:
            # No grid path (e.g. explicit start/goal given inside an inflated area): walk straight.
            return np.asarray(goal, dtype=np.float64).reshape(1, 2)
        return np.asarray(path, dtype=np.float64)

    # ------------------------------------------------------------------ step
    def step(self, actions: dict[str, Any]):
        if self._needs_reset:
            raise RuntimeError("NavEnv.step() called before reset() (or after the episode ended); call reset() first")
        act = self._validate_actions(actions)
        self._world_stepped = True
        cfg = self.config
        R, dt = self.n_robots, cfg.dt
        acting = list(self.agents)
        acting_idx = np.array([self._index[a] for a in acting], dtype=int)
        prev_pos = self.pos.copy()
        d_goal_prev = self.d_goal.copy()

        # Pedestrians (kinematic): the action is a velocity in the person's frame.
        hum = np.arange(R, self.n_total)
        if self.amp is not None:
            self._human_blocked = np.zeros(hum.size, dtype=bool)
            a_h = act[hum]
            live_h = np.isin(hum, acting_idx)
            if hum.size:  # fallen (done) pedestrians keep their last targets
                sph0, rev0 = self.amp.bodies.targets
                self.amp.set_actions(a_h)
                if (~live_h).any():
                    sph1, rev1 = self.amp.bodies.targets
                    sph1[~live_h], rev1[~live_h] = sph0[~live_h], rev0[~live_h]
                    self.amp.bodies.apply_targets(sph1, rev1)
        elif self.replay is not None and hum.size:
            # Replayed people (crowd_model="replay") follow the recording; their actions are ignored.
            rp = self.replay
            k0, k1 = rp.step_index(self.steps), rp.step_index(self.steps + 1)
            cont = rp.active[k1] & (rp.track[k1] == rp.track[k0])
            new_yaw = rp.yaw[k1]
            self.omega[hum] = np.where(cont, wrap_angle(new_yaw - self.yaw[hum]) / dt, 0.0)
            self.pos[hum] = rp.pos[k1]
            self.vel[hum] = rp.vel[k1]
            self.yaw[hum] = new_yaw
            for j in np.flatnonzero(rp.track[k1] != rp.track[k0]):  # a slot changed person (or was parked)
                self.goal[R + j] = rp.goal[k1, j]
                self.paths[R + j] = rp.goal[k1, j][None].copy()
                self.wp_index[R + j] = 0
            self.human_active = rp.active[k1].copy()
            self._human_continuing = cont
            speed = np.linalg.norm(self.vel[hum], axis=1)
            self.humans.advance(speed, dt)
            self.humans.pose(self.pos[hum], self.yaw[hum], speed)
            self._human_blocked = np.zeros(hum.size, dtype=bool)
        elif hum.size:
            a_h = act[hum]
            norm = np.linalg.norm(a_h, axis=1, keepdims=True)
            a_h = np.where(norm > 1.0, a_h / np.maximum(norm, 1e-12), a_h)
            c, s = np.cos(self.yaw[hum]), np.sin(self.yaw[hum])
            v_world = cfg.human_max_speed * np.stack([c * a_h[:, 0] - s * a_h[:, 1], s * a_h[:, 0] + c * a_h[:, 1]], axis=1)
            new_pos = self.pos[hum] + v_world * dt
            # Scripted bodies do not collide with the scene in PyBullet, so a person whose step
            # would cut through a wall stays put (and the map collision is reported in info).
            blocked = self._swept_hits_walls(self.pos[hum], new_pos, np.full(hum.size, 0.5 * cfg.human_radius))
            new_pos[blocked] = self.pos[hum][blocked]
            v_world[blocked] = 0.0
            speed = np.linalg.norm(v_world, axis=1)
            # Heading turns toward the walking direction (at most 4 rad/s), held when standing.
            desired = np.where(speed > 0.05, np.arctan2(v_world[:, 1], v_world[:, 0]), self.yaw[hum])
            dyaw = np.clip(wrap_angle(desired - self.yaw[hum]), -4.0 * dt, 4.0 * dt)
            self.pos[hum] = new_pos
            self.vel[hum] = v_world
            self.omega[hum] = dyaw / dt
            self.yaw[hum] = wrap_angle(self.yaw[hum] + dyaw)
            self.humans.advance(speed, dt)
            self.humans.pose(self.pos[hum], self.yaw[hum], speed)
            self._human_blocked = blocked
        else:
            self._human_blocked = np.zeros(0, dtype=bool)

        # Robots: limited velocity commands, applied at every physics substep.
        robot_alive = self.alive[:R].copy()
        self.cmd, world = command_velocity(act[:R, :2], self.cmd, self.yaw[:R], cfg.robot, dt)
        world[~robot_alive] = 0.0
        t0 = time.perf_counter()
        if self.amp is not None:
            for _ in range(self.amp.control_steps):
                self.amp.control_step(lambda: self.robots.apply_velocity(world, robot_alive))
        else:
            for _ in range(cfg.physics_substeps):
                self.robots.apply_velocity(world, robot_alive)
                p.stepSimulation(physicsClientId=self.client)
        self.physics_time += time.perf_counter() - t0
        if self.amp is not None and hum.size:
            h_pos, h_yaw, h_vel, h_omega = self.amp.planar()
            self.pos[hum], self.yaw[hum], self.vel[hum], self.omega[hum] = h_pos, h_yaw, h_vel, h_omega
            self.amp.fallen |= self.amp.bodies.fallen()
            self.human_map_contact, self.human_agent_contact, self.human_robot_contact = self.amp.contacts()
            new_falls = np.flatnonzero(self.amp.fallen & ~self.human_fallen)
            self.human_fallen = self.amp.fallen.copy()
            if cfg.human_fallen_obstacles and (new_falls.size or self._fallen_moved()):
                self._fallen_replanned = self._avoid_fallen() | self._fallen_replanned
        r_pos, r_yaw, tilt = self.robots.read_state()
        nan_state = bool(~np.isfinite(r_pos[robot_alive]).all() or ~np.isfinite(r_yaw[robot_alive]).all())
        if not nan_state:
            for i in np.flatnonzero(robot_alive):
                if tilt[i]:
                    self.robots.straighten(i, r_pos[i], r_yaw[i])
                self.vel[i] = (r_pos[i] - prev_pos[i]) / dt
                self.omega[i] = wrap_angle(r_yaw[i] - self.yaw[i]) / dt
                self.pos[i] = r_pos[i]
                self.yaw[i] = r_yaw[i]

        # Events.
        coll_kind = self._robot_collisions(prev_pos, robot_alive) if not nan_state else {}
        self._advance_waypoints()
        blocked_replanned = self._replan_blocked_humans(dt)
        self.d_goal = np.linalg.norm(self.goal - self.pos, axis=1)
        reached = np.zeros(self.n_total, dtype=bool)
        reached[:R] = robot_alive & (self.d_goal[:R] < self.goal_tolerance)
        collided = np.zeros(self.n_total, dtype=bool)
        collided[list(coll_kind)] = True
        d_agents, d_walls = self._clearance_parts()
        human_contact_new = self._human_contacts(coll_kind, d_agents, hum)
        if human_contact_new is not None:
            collided[hum] = human_contact_new
        if cfg.wall_proximity is None:  # the paper: one clearance to everything
            d_obs, d_walls_reward = np.minimum(d_agents, d_walls), None
        else:
            d_obs, d_walls_reward = d_agents, d_walls
        human_reached = self._retarget_humans()
        reached[R:] = human_reached
        new_yields = np.zeros(hum.size, dtype=bool)
        if self.turn_taking is not None and hum.size:
            new_yields = self.turn_taking.update(
                self.sim_time + dt, dt, self.pos[hum], self.vel[hum], self.human_preferred_velocity(yielding=False),
                active=~self.human_fallen & ~self.arrived[hum],
            )
        new_doors = self._update_door_turns(self.sim_time + dt)
        if self.amp is not None and hum.size:
            amp_terms = self.amp.task_reward()
            self.amp.after_step(replan=human_reached | new_yields | self._fallen_replanned | blocked_replanned
                                | new_doors)
            self._fallen_replanned[:] = False
        # After a re-target a pedestrian's distance jumps to its new goal: that step earns the goal
        # reward, not a progress penalty, so its previous distance is taken as the new one.
        d_prev = np.where(human_reached_mask(self.n_total, R, human_reached), self.d_goal, d_goal_prev)
        d_now = self.d_goal
        if self.robot_guide is not None and R:
            d_prev, d_now = d_prev.copy(), d_now.copy()
            d_prev[:R] = self.d_progress
            self._update_robot_guide(robot_alive)
            d_now[:R] = self.d_progress
        rew, terms = navigation_reward(
            d_now, d_prev, d_obs, reached, collided, np.where(self.is_robot, self.omega, 0.0),
            self.reward_params, d_walls=d_walls_reward,
        )
        if self.amp is not None and hum.size:
            # Pedestrians' reward is the controller's task reward (r_tau + r_e + r_d); a learner adds
            # the style reward of its discriminator.
            rew[hum] = amp_terms["track"] + amp_terms["energy"] + amp_terms["direction"]
            if self.config.amp_progress_reward:
                amp_terms["path_progress"] = self._human_progress()
                rew[hum] += self.config.amp_progress_reward * amp_terms["path_progress"]
            if self.config.amp_stance_reward:
                rew[hum] += self.config.amp_stance_reward * amp_terms["stance"]
            amp_terms["wall_contact"] = -self.human_map_contact.astype(float)
            if self.config.amp_wall_contact_reward:
                rew[hum] += self.config.amp_wall_contact_reward * amp_terms["wall_contact"]
        if self.replay is not None and hum.size:  # replayed people do not act: nothing to reward
            rew[hum] = 0.0
            for name in TERMS:
                terms[name][hum] = 0.0

        # Bookkeeping: history, time.
        self.steps += 1
        self.sim_time += dt
        if self.diffusion is not None:
            self.diffusion.observe(self)
        self.hist_pos = np.roll(self.hist_pos, -1, axis=0)
        self.hist_vel = np.roll(self.hist_vel, -1, axis=0)
        self.hist_yaw = np.roll(self.hist_yaw, -1, axis=0)
        self.hist_valid = np.roll(self.hist_valid, -1)
        self.hist_pos[-1], self.hist_vel[-1], self.hist_yaw[-1], self.hist_valid[-1] = self.pos, self.vel, self.yaw, True
        self.hist_present = np.roll(self.hist_present, -1, axis=0)
        self.hist_present[:, R + np.flatnonzero(~self._human_continuing)] = False  # a new person: no past yet
        self.hist_present[-1] = self.present
        self.trail.append(self.pos.copy())
        self.trail_present.append(self.present & np.concatenate([np.ones(R, dtype=bool), self._human_continuing]))

        terminated = np.zeros(self.n_total, dtype=bool)
        terminated[:R] = robot_alive & (reached[:R] | collided[:R])
        if self.amp is not None:  # a pedestrian that fell is done (its body stays where it lies)
            terminated[hum] = self.human_fallen & np.isin(hum, acting_idx)
        if nan_state:
            terminated[acting_idx] = True
        time_up = self.steps >= self.max_steps
        robots_left = robot_alive & ~terminated[:R]
        end_all = time_up or (R > 0 and not robots_left.any())
        truncated = np.zeros(self.n_total, dtype=bool)
        if end_all:
            truncated[acting_idx] = ~terminated[acting_idx]

        for i in range(R):
            if robot_alive[i] and terminated[i]:
                self.alive[i] = False
                self.events[self.possible_agents[i]] = (
                    "goal" if reached[i] else f"collision_{coll_kind.get(i, 'obstacle')}" if collided[i] else "nan_state"
                )
        obs = self._observations(acting)
        rewards, infos, terminations, truncations = {}, {}, {}, {}
        for a, i in zip(acting, acting_idx, strict=True):
            rewards[a] = float(rew[i])
            terminations[a] = bool(terminated[i])
            truncations[a] = bool(truncated[i])
            info = self._base_info(a)
            for name in TERMS:
                info[f"reward/{name}"] = float(terms[name][i])
            if i < R:
                info["event"] = self.events.get(a, "timeout" if truncated[i] else "running")
                info["is_success"] = bool(reached[i])
                info["collision"] = coll_kind.get(int(i), "")
            else:
                info["goal_reached"] = bool(reached[i])
                info["contact"] = str(self._human_contact[i - R])
                info["map_blocked"] = bool(self._human_blocked[i - R]) if self.n_humans else False
                if self.replay is not None:
                    info["active"] = bool(self.human_active[i - R])
                if self.amp is not None:
                    j = i - R
                    info["fallen"] = bool(self.human_fallen[j])
                    info["map_contact"] = bool(self.human_map_contact[j])
                    info["agent_contact"] = bool(self.human_agent_contact[j])
                    info["robot_contact"] = bool(self.human_robot_contact[j])
                    for name in ("track", "energy", "direction", "path_progress", "stance", "wall_contact",
                                 "path_error"):
                        if name in amp_terms:
                            info[f"reward/{name}" if name != "path_error" else name] = float(amp_terms[name][j])
            if nan_state:
                info["nan_state"] = True
            infos[a] = info
        for i in range(R):
            if robot_alive[i] and terminated[i]:
                self.robots.remove(i)
        self.agents = [a for a in acting if not (terminations[a] or truncations[a])]
        if not self.agents:
            self._needs_reset = True
        if self.render_mode == "human":
            self.render()
        return obs, rewards, terminations, truncations, infos

    def _validate_actions(self, actions: dict[str, Any]) -> np.ndarray:
        if not isinstance(actions, dict):
            raise TypeError(f"actions must be a dict {{agent: action}}, got {type(actions).__name__}")
        width = max(self.action_spaces[a].shape[0] for a in self.possible_agents)
        out = np.zeros((self.n_total, width))
        live = set(self.agents)
        for agent in actions:
            if agent not in self._index:
                raise ValueError(f"unknown agent {agent!r} in actions; possible agents: {self.possible_agents}")
            if agent not in live:
                raise ValueError(f"agent {agent!r} is done (terminated or truncated) and cannot act; live agents: {self.agents}")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"missing actions for live agent(s) {missing}")
        for agent, a in actions.items():
            try:
                arr = np.asarray(a, dtype=np.float64)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"action of {agent!r} is not numeric: {a!r}") from exc
            shape = self.action_spaces[agent].shape
            if arr.shape != shape:
                raise ValueError(f"action of {agent!r} must have shape {shape}, got shape {arr.shape}")
            if not np.isfinite(arr).all():
                raise ValueError(f"action of {agent!r} contains NaN or inf: {arr.tolist()}")
            i = self._index[agent]
            clipped = np.clip(arr, -1.0, 1.0)
            if np.any(clipped != arr):
                self.action_clips[i] += 1
            out[i, : clipped.size] = clipped
        return out

    def _robot_collisions(self, prev_pos: np.ndarray, robot_alive: np.ndarray) -> dict[int, str]:
        """Collisions of each live robot during the step: swept discs and PyBullet contacts."""
        R = self.n_robots
        out: dict[int, str] = {}
        self._humans_hit = set()  # pedestrians (0-based) that a robot collided with in this step
        idx = np.flatnonzero(robot_alive)
        if idx.size == 0:
            return out
        rr = self.radius[idx]
        # People: the robot's motion relative to each person is a segment; test its distance to the
        # person's centre (CrowdNav's swept test, so fast robots cannot tunnel through people).
        # Absent (parked) people are left out; a person who just appeared is tested where they are.
        h = R + np.flatnonzero(self.human_active)
        if h.size:
            h_prev = np.where(self._human_continuing[h - R][:, None], prev_pos[h], self.pos[h])
            p0 = prev_pos[idx][:, None, :] - h_prev[None, :, :]
            p1 = self.pos[idx][:, None, :] - self.pos[h][None, :, :]
            dmin = _segment_origin_distance(p0, p1)
            hit = dmin < (rr[:, None] + self.radius[h][None, :]) - COLLISION_TOLERANCE
            for k, i in enumerate(idx):
                if hit[k].any():
                    out[int(i)] = "human"
            self._humans_hit.update(int(j) for j in h[hit.any(axis=0)] - R)
        # Other robots (both moving).
        if idx.size > 1:
            p0 = prev_pos[idx][:, None, :] - prev_pos[idx][None, :, :]
            p1 = self.pos[idx][:, None, :] - self.pos[idx][None, :, :]
            dmin = _segment_origin_distance(p0, p1)
            np.fill_diagonal(dmin, np.inf)
            hit = dmin < (rr[:, None] + rr[None, :]) - COLLISION_TOLERANCE
            for k, i in enumerate(idx):
                if hit[k].any() and int(i) not in out:
                    out[int(i)] = "robot"
        # Obstacles: the swept disc against every wall edge.
        if len(self.segments):
            hit = self._swept_hits_walls(prev_pos[idx], self.pos[idx], rr - COLLISION_TOLERANCE)
            for k, i in enumerate(idx):
                if hit[k] and int(i) not in out:
                    out[int(i)] = "obstacle"
        # PyBullet contacts (the bodies' real shapes: arms, furniture heights).
        for i in idx:
            if int(i) in out:
                continue
            for body in self.robots.contacts(int(i)):
                kind = self._body_kind.get(body)
                if kind == "human" and not self.config.human_body_contacts:
                    continue
                if kind == "human" and self._human_index.get(body) is not None and not self.human_active[self._human_index[body]]:
                    continue
                if kind is not None:
                    out[int(i)] = kind
                    if kind == "human" and self._human_index.get(body) is not None:
                        self._humans_hit.add(int(self._human_index[body]))
                    break
        return out

    def _human_contacts(self, coll_kind: dict[int, str], d_agents: np.ndarray, hum: np.ndarray) -> np.ndarray | None:
        """Kinematic pedestrians' contacts in this step (``NavConfig.human_contact_penalty``).

        Updates ``self._human_contact`` ("robot", "human" or "") and returns the (H,) mask of contacts
        that began in this step (they earn the collision reward), or None where the penalty does not
        apply (off, AMP bodies with their own reward, replayed people, no pedestrians).
        """
        if hum.size == 0:
            return None
        R = self.n_robots
        before = self._human_contact != ""
        now = np.full(hum.size, "", dtype="<U5")
        vis = self.alive[hum] & self.present[hum]
        now[vis & (d_agents[hum] < -COLLISION_TOLERANCE)] = "human"
        if any(kind == "human" for kind in coll_kind.values()):
            for j in self._humans_hit:
                now[j] = "robot"
        # Overlapping a live robot's disc counts too (the robot's test reports one kind per robot and
        # stops at the first: a robot that hit a wall while touching a person).
        if R:
            rob = np.flatnonzero(self.alive[:R] & self.present[:R])
            if rob.size:
                gap = (np.linalg.norm(self.pos[hum][:, None, :] - self.pos[rob][None, :, :], axis=2)
                       - self.radius[hum][:, None] - self.radius[rob][None, :])
                now[vis & (gap < -COLLISION_TOLERANCE).any(axis=1)] = "robot"
        self._human_contact = now
        if not self.config.human_contact_penalty or self.amp is not None or self.replay is not None:
            return None
        return (now != "") & ~before

    def _swept_hits_walls(self, p0: np.ndarray, p1: np.ndarray, radius: np.ndarray) -> np.ndarray:
        """Whether discs moving straight from p0 to p1 touch any wall edge (exact test).

        The exact segment test is only run for agents that could reach a wall in this step: the
        occupancy distance field and the distance to the scene's edge rule out the others cheaply.
        """
        out = np.zeros(len(p0), dtype=bool)
        if len(self.segments) == 0 or len(p0) == 0:
            return out
        xmin, ymin, xmax, ymax = self.scene.bounds
        reach = np.linalg.norm(p1 - p0, axis=1) + radius + 2.0 * self.grid.resolution
        to_edge = np.minimum.reduce([p0[:, 0] - xmin, xmax - p0[:, 0], p0[:, 1] - ymin, ymax - p0[:, 1]])
        near = (self.grid.distance_at(p0) <= reach) | (to_edge <= reach)
        if near.any():
            out[near] = swept_circle_hits_segments(p0[near], p1[near], radius[near], self.segments)
        return out

    def _update_robot_guide(self, which: np.ndarray) -> None:
        """Advance the robots' subgoals and progress distances (robots ``which``, a (R,) mask)."""
        guide, cfg = self.robot_guide, self.config
        idx = np.flatnonzero(which)
        if guide is None or idx.size == 0:
            return
        if cfg.robot_subgoal is not None:
            self.robot_subgoals[idx] = guide.subgoals(self.pos[idx], idx)
        if cfg.robot_progress == "geodesic":
            for i in idx:
                geo = guide.geodesic(int(i), self.pos[i])
                # Off the field (inside inflated space): fall back to the straight line for this step.
                self.d_progress[i] = geo if np.isfinite(geo) else self.d_goal[i]
        else:
            self.d_progress[idx] = self.d_goal[idx]

    def _clearance_parts(self) -> tuple[np.ndarray, np.ndarray]:
        """(to other live agents, to walls and obstacles): edge-to-edge clearances of every agent."""
        vis = self.alive & self.present
        d = np.linalg.norm(self.pos[:, None, :] - self.pos[None, :, :], axis=2) - self.radius[:, None] - self.radius[None, :]
        d[:, ~vis] = np.inf
        np.fill_diagonal(d, np.inf)
        d_agents = d.min(axis=1) if self.n_total > 1 else np.full(self.n_total, np.inf)
        d_map = self.grid.distance_at(self.pos) - self.radius
        return d_agents, d_map

    def _advance_waypoints(self) -> None:
        tol = self.config.waypoint_tolerance
        for i in range(self.n_total):
            amp = self.amp is not None and i >= self.n_robots
            self.wp_index[i] = advance_waypoint(self.paths[i], int(self.wp_index[i]), self.pos[i], tol,
                                                WAYPOINT_LOOKAHEAD if amp else 0,
                                                self.waypoint_visibility(i) if amp else None,
                                                self.waypoint_sight(i) if amp else None)

    def waypoint_visibility(self, i: int):
        """Line-of-sight test ``(a, b) -> bool`` on agent ``i``'s bare planning grid (pedestrians: around
        fallen bodies too, when planned so), with which physics pedestrians move past waypoints they have
        passed (:func:`~navzoo.envs.amp_humans.advance_waypoint`); None when that is off."""
        if not amp_humans.SKIP_PASSED_WAYPOINTS:
            return None
        planner = self._planner_for(i)(float(self.radius[i]))
        return planner.line_of_sight

    def waypoint_sight(self, i: int):
        """Line-of-sight test ``(pos, waypoint) -> bool`` from the nearest free point of agent ``i``'s planning
        grid (a position off it, or with no free point near, sees everything), with which physics pedestrians
        move on only to waypoints in sight (``amp_humans.WAYPOINT_ADVANCE_IN_SIGHT``); None when that is off."""
        if not amp_humans.WAYPOINT_ADVANCE_IN_SIGHT:
            return None
        planner = self._planner_for(i)(float(self.radius[i]))

        def sight(pos: np.ndarray, waypoint: np.ndarray) -> bool:
            return planner.sight_from(pos, waypoint) is not False

        return sight

    def _human_progress(self) -> np.ndarray:
        """(H,) each pedestrian's speed toward the next waypoint of its path, as a share of its preferred
        speed, clipped to [-1, 1]; 0 for fallen or arrived people (``NavConfig.amp_progress_reward``)."""
        h = np.arange(self.n_robots, self.n_total)
        wp = np.array([self.paths[i][min(int(self.wp_index[i]), len(self.paths[i]) - 1)] if len(self.paths[i])
                       else self.pos[i] for i in h]).reshape(-1, 2)
        to_wp = wp - self.pos[h]
        dist = np.linalg.norm(to_wp, axis=1)
        speed = np.einsum("ij,ij->i", self.vel[h], to_wp) / np.maximum(dist, 1e-9)
        out = np.clip(speed / np.maximum(self.v_pref[h], 1e-6), -1.0, 1.0)
        out[(dist <= 1e-6) | self.arrived[h] | self.human_fallen] = 0.0
        return out

    def human_preferred_velocity(self, yielding: bool = True, t: float | None = None,
                                 slow_radius: float = 0.5) -> np.ndarray:
        """(H, 2) pedestrians' preferred velocities: toward the next A* waypoint at their preferred
        speed, slowing down linearly within ``slow_radius`` of the goal, with turn-taking
        (``NavConfig.human_yielding``) and door turns (``NavConfig.human_door_turns``) applied at time ``t``
        (default: now) unless ``yielding`` is False."""
        h = np.arange(self.n_robots, self.n_total)
        pref = preferred_velocity(self.pos[h], self.next_waypoints()[h], self.goal[h], self.v_pref[h],
                                  slow_radius=slow_radius)
        return self.crowd_conventions(pref, self.sim_time if t is None else t) if yielding else pref

    def crowd_conventions(self, pref: np.ndarray, t: float, pos: np.ndarray | None = None,
                          v_pref: np.ndarray | None = None) -> np.ndarray:
        """(H, 2) preferred velocities ``pref`` with turn-taking (at time ``t``) and door turns (at positions
        ``pos``, default the pedestrians' own, walking to waiting spots at ``v_pref``, default theirs) applied,
        where the config turns them on; the one place every crowd (kinematic steps, AMP target rollouts) edits
        its preferred velocities for them."""
        h = np.arange(self.n_robots, self.n_total)
        if self.turn_taking is not None:
            pref = self.turn_taking.apply(t, pref)
        if self.door_turns is not None:
            pref = self.door_turns.apply(self.pos[h] if pos is None else pos, pref,
                                         self.v_pref[h] if v_pref is None else v_pref)
        return pref

    def _update_door_turns(self, t: float = 0.0) -> np.ndarray:
        """``NavConfig.human_door_turns``: the doors of every pedestrian path that changed since the last
        call, then the door requests and grants at time ``t``; returns (H,) who was granted a door now."""
        H = self.n_humans
        if self.door_turns is None or H == 0:
            return np.zeros(H, dtype=bool)
        R = self.n_robots
        amp = self.config.human_model == "amp"
        jambs = float(amp_humans.DOOR_JAMB_SEARCH) if amp else 0.0
        scan = amp and bool(amp_humans.DIFFUSION_DOOR_RUN_SCAN if self.config.crowd_model == "diffusion"
                            else amp_humans.DOOR_RUN_SCAN)
        for j in range(H):
            i = R + j
            if self._door_paths[j] is not self.paths[i]:
                self._door_paths[j] = self.paths[i]
                rest = self.paths[i][int(self.wp_index[i]):]
                self.door_turns.set_route(j, [(c, a) for c, a, _ in path_doors(rest, self.pos[i], self.grid, two_sided=True,
                                                                                    end_margin=0.7, jamb_search=jambs,
                                                                                    run_scan=scan)])
        return self.door_turns.update(t, self.pos[R:], ~self.arrived[R:] & ~self.human_fallen)

    def _fallen_lying(self) -> dict[int, np.ndarray]:
        """Each fallen pedestrian's root and key bodies where they lie now: index -> (K+1, 2)."""
        s = self.amp.state()
        return {int(j): np.concatenate([s["root_pos"][j, None, :2], s["key_pos"][j, :, :2]])
                for j in np.flatnonzero(self.human_fallen)}

    def _fallen_moved(self) -> bool:
        """Whether a fallen body has moved more than ``FALLEN_RESTAMP_M`` since it was stamped: a body is found
        fallen while it still slides and rolls, and comes to rest further on (a median 0.3-0.4 m in crowd runs)."""
        if not self._fallen_stamped:
            return False
        now = self._fallen_lying()
        return any(float(np.max(np.linalg.norm(now[j] - was, axis=1))) > FALLEN_RESTAMP_M
                   for j, was in self._fallen_stamped.items())

    def _path_passes_fallen(self, i: int) -> bool:
        """Whether agent ``i``'s remaining path comes near a stamped fallen body (within its radius, the body's
        half thickness and 0.1 m)."""
        near = float(self.radius[i]) + FALLEN_BODY_RADIUS + 0.1
        return path_passes(self.paths[i][self.wp_index[i]:], self.pos[i], self._fallen_points, near)

    def _avoid_fallen(self) -> np.ndarray:
        """Stamp the bodies of the fallen pedestrians, where they lie now, into the pedestrians' planning grid
        (a fresh copy of the bare grid) and plan again for the standing ones whose path passes them; returns
        (H,) whose path changed (:mod:`navzoo.envs.fallen`). Called on each new fall and whenever a fallen
        body has moved on from where it was stamped (:meth:`_fallen_moved`)."""
        R = self.n_robots
        lying = self._fallen_lying()
        pts = np.concatenate([fallen_footprint_points(xy[0], xy[1:]) for xy in lying.values()])
        self._fallen_points = pts
        self._fallen_stamped = lying
        self._fallen_grid = stamp_fallen(self.grid, pts)
        self._fallen_planners = {}
        changed = np.zeros(self.n_humans, dtype=bool)
        wait = self.config.human_fallen_wait
        self.human_waiting_fallen &= ~self.human_fallen
        for j in np.flatnonzero(~self.human_fallen & ~self.arrived[R:]):
            i = R + j
            if not self.human_waiting_fallen[j] and not self._path_passes_fallen(i):
                continue
            path = self._plan(i, self.pos[i], self.goal[i], fallback=False)
            if path is not None:  # a way round, or a waiting person's way is open again
                self.paths[i] = path
                self.wp_index[i] = 0
                changed[j] = True
                self.human_waiting_fallen[j] = False
            elif wait and not self.human_waiting_fallen[j]:  # no way round: stand and wait (targets stand still)
                self.human_waiting_fallen[j] = True
                changed[j] = True
            # else (human_fallen_wait off): keep the old path, which walks on into the bodies
        return changed

    def _replan_blocked_humans(self, dt: float) -> np.ndarray:
        """``NavConfig.human_replan_blocked``: pedestrians whose current waypoint has been out of their line
        of sight (on their bare planning grid, from the nearest free point) for ``REPLAN_HIDDEN_S`` plan a
        new A* path from where they are, at most once per ``REPLAN_EVERY_S``. Without it, a person the crowd
        pushed round a corner is pulled straight at a waypoint behind the corner and stays there (social
        force has no way round). Returns (H,) whose path changed (the physics pedestrians then roll out
        new targets at once)."""
        mode = self.config.human_replan_blocked
        changed = np.zeros(self.n_humans, dtype=bool)
        if mode == "off" or self.replay is not None or (mode == "amp" and self.amp is None):
            return changed
        R = self.n_robots
        fallen = self.human_fallen if self.amp is not None else np.zeros(self.n_humans, dtype=bool)
        for j in np.flatnonzero(~fallen & ~self.arrived[R:]):
            i = R + j
            path = self.paths[i]
            k = min(int(self.wp_index[i]), len(path) - 1)
            planner = self._planner_for(i)(float(self.radius[i]))
            if planner.sight_from(self.pos[i], path[k]):
                self._wp_hidden[i] = 0.0
                continue
            self._wp_hidden[i] += dt
            if self._wp_hidden[i] < REPLAN_HIDDEN_S or self.sim_time - self._last_replan[i] < REPLAN_EVERY_S:
                continue
            self._last_replan[i] = self.sim_time
            new = self._plan(i, self.pos[i], self.goal[i], fallback=False)
            if new is not None:  # else keep the path (no way from here on the grid)
                self.paths[i] = new
                self.wp_index[i] = 0
                self._wp_hidden[i] = 0.0
                changed[j] = True
                self.human_waiting_fallen[j] = False
        return changed

    def _retarget_humans(self) -> np.ndarray:
        """Give pedestrians that reached their goal a new goal and path; returns who reached."""
        R = self.n_robots
        reached = np.zeros(self.n_humans, dtype=bool)
        if self.replay is not None:  # replayed people leave the scene where their track ends
            return reached
        stop = self.config.human_at_goal == "stop"
        for j in range(self.n_humans):
            i = R + j
            if self.d_goal[i] < max(self.config.waypoint_tolerance, self.radius[i]) and not self.arrived[i]:
                reached[j] = True
                self.goals_reached[i] += 1
                if stop:  # stays at its goal for the rest of the episode
                    self.arrived[i] = True
                    continue
                goal = self._samplers["human"].sample_goal(self.rng_tasks, self.pos[i], "human",
                                                            min_goal_dist=self.config.min_goal_distance)
                path = None
                wait, redraw = self.config.human_fallen_wait, self.config.human_fallen_redraw
                cut = self._fallen_grid is not None and not self.human_fallen[j]
                if (wait or redraw) and cut:
                    # fallen bodies may cut the way to the goal: draw again, and wait (human_fallen_wait) or walk
                    # the scene's path (human_fallen_redraw) if none can be reached
                    for attempt in range(FALLEN_GOAL_TRIES):
                        path = self._plan(i, self.pos[i], goal, fallback=False)
                        if path is not None or attempt == FALLEN_GOAL_TRIES - 1:
                            break  # (the last goal tried is kept: no untried goal is drawn after the last try)
                        goal = self._samplers["human"].sample_goal(self.rng_tasks, self.pos[i], "human",
                                                                    min_goal_dist=self.config.min_goal_distance)
                    self.human_waiting_fallen[j] = path is None and wait
                self.goal[i] = goal
                if path is None:  # (human_fallen_redraw: on the bare scene grid, not straight through walls)
                    path = self._plan(i, self.pos[i], goal, scene_grid=redraw and cut and not wait)
                self.paths[i] = path
                self.wp_index[i] = 0
                self.d_goal[i] = float(np.linalg.norm(goal - self.pos[i]))
        return reached

    # ------------------------------------------------------------------ observations
    def _observations(self, agents: list[str]) -> dict[str, Any]:
        if not agents:
            return {}
        cfg = self.config
        out: dict[str, Any] = {}
        if self.amp is not None:
            humans = [a for a in agents if self._index[a] >= self.n_robots]
            if humans:
                h_obs = self.amp.observations()
                for a in humans:
                    out[a] = h_obs[self._index[a] - self.n_robots]
            agents = [a for a in agents if self._index[a] < self.n_robots]
            if not agents:
                return out
        idx = np.array([self._index[a] for a in agents], dtype=int)
        target = self.goal[idx]
        if self.config.robot_subgoal is not None:
            rob = idx < self.n_robots
            target = target.copy()
            target[rob] = self.robot_subgoals[idx[rob]]
        goal = obs_terms.goal_features(self.pos[idx], self.yaw[idx], target)
        vel = obs_terms.velocity_features(self.vel[idx], self.yaw[idx], self.omega[idx])
        feats, mask = obs_terms.neighbor_features(
            self.hist_pos, self.hist_vel, self.hist_yaw, self.hist_valid, self.radius, self.alive & self.present, idx,
            cfg.k_neighbors, cfg.sensor_range, hist_present=self.hist_present,
        )
        maps = self.grid.crop_many(self.pos[idx], self.yaw[idx], cfg.map_size, cfg.map_cells)
        scans = self.range_scan(idx) if cfg.scan_rays else None
        for n, a in enumerate(agents):
            o = {
                "goal": goal[n].astype(np.float32),
                "velocity": vel[n].astype(np.float32),
                "agents": feats[n],
                "agents_mask": mask[n],
                "map": maps[n].astype(np.float32),
            }
            if scans is not None:
                o["scan"] = scans[n]
            out[a] = spaces.flatten(self._dict_space, o).astype(np.float32) if cfg.flat_obs else o
        return out

    def range_scan(self, idx: np.ndarray, rays: int | None = None, scan_range: float | None = None) -> np.ndarray:
        """The ``"scan"`` observation of agents ``idx``: ``(len(idx), rays)`` float32 in [0, 1].

        Distances from each agent's centre to the static scene's edges (walls, obstacles, the scene
        bounds) along ``rays`` rays from its heading (ray ``i`` at ``2 pi i / rays``, counter-clockwise),
        over ``scan_range``; both default to the env's ``NavConfig.scan_rays`` / ``scan_range``.
        """
        rays = self.config.scan_rays if rays is None else int(rays)
        rng = self.config.scan_range if scan_range is None else float(scan_range)
        if rays < 1:
            raise ValueError(f"range_scan needs rays >= 1 (NavConfig.scan_rays is {self.config.scan_rays})")
        idx = np.asarray(idx, dtype=int).reshape(-1)
        rel = 2.0 * np.pi * np.arange(rays) / rays
        ang = self.yaw[idx][:, None] + rel[None, :]
        d = ray_segment_distances(self.pos[idx], ang, self.segments, rng)
        return (d / rng).astype(np.float32)

    def _base_info(self, agent: str) -> dict[str, Any]:
        i = self._index[agent]
        return {"action_clipped": int(self.action_clips[i]), "time": float(self.sim_time)}

    # ------------------------------------------------------------------ state for controllers
    def agent_index(self, agent: str) -> int:
        """Index of ``agent`` in the state arrays (robots first, then pedestrians)."""
        if agent not in self._index:
            raise KeyError(f"unknown agent {agent!r}; this env has {self.possible_agents}")
        return self._index[agent]

    @property
    def crowd_sfm_params(self):
        """The :class:`navzoo.agents.sfm.SocialForceParams` of the kinematic crowd's social force, from the config's
        ``crowd_wall_*`` fields (the defaults give ``SocialForceParams()``); used by a
        :class:`navzoo.agents.crowd.CrowdPolicy` made without parameters of its own."""
        from navzoo.agents.sfm import SocialForceParams

        c = self.config
        key = (c.crowd_wall_strength, c.crowd_wall_near_range, c.crowd_wall_near_strength, c.crowd_wall_near_ramp)
        if getattr(self, "_crowd_sfm", (None, None))[0] != key:
            near = {"wall_near_range": key[1], "A_wall_near": key[2], "wall_near_ramp": key[3]} if key[1] > 0 else {}
            self._crowd_sfm = (key, SocialForceParams(A_wall=key[0], **near))
        return self._crowd_sfm[1]

    @property
    def pedestrian_grid(self) -> OccupancyGrid:
        """The occupancy grid the pedestrians plan on: the scene grid with the fallen bodies stamped where they lie
        once any have fallen under ``human_fallen_obstacles`` (:meth:`_avoid_fallen`), else the scene grid
        (``grid``). Read-only: a new fall or a moved body replaces it."""
        return self._fallen_grid if self._fallen_grid is not None else self.grid

    @property
    def present(self) -> np.ndarray:
        """(N,) bool: agents in the world (robots always; pedestrians unless absent, see ``human_active``)."""
        return np.concatenate([np.ones(self.n_robots, dtype=bool), self.human_active])

    def next_waypoints(self) -> np.ndarray:
        """(N, 2) current A* waypoint of every agent (its goal once the path is used up)."""
        return np.stack([self.paths[i][min(self.wp_index[i], len(self.paths[i]) - 1)] for i in range(self.n_total)])

    def state_dict(self) -> dict[str, np.ndarray]:
        """A copy of the world's planar state arrays (for loggers, metrics and controllers)."""
        return {
            "pos": self.pos.copy(), "vel": self.vel.copy(), "yaw": self.yaw.copy(), "omega": self.omega.copy(),
            "goal": self.goal.copy(), "radius": self.radius.copy(), "alive": self.alive.copy(),
            "present": self.present, "time": np.array(self.sim_time),
        }

    # ------------------------------------------------------------------ render / close
    def render(self):
        from navzoo.envs.render import camera_view, draw_topdown

        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; pass render_mode='rgb_array' to NavEnv")
            return None
        if self.render_mode == "human":
            # The PyBullet GUI shows the world itself; keep the camera on the first robot.
            if self.n_robots:
                x, y = self.pos[0]
                p.resetDebugVisualizerCamera(8.0, 0.0, -60.0, [x, y, 0.0], physicsClientId=self.client)
            return None
        if self._needs_reset and not hasattr(self, "pos"):
            raise RuntimeError("render() called before reset()")
        views = []
        if self.render_view in ("topdown", "both"):
            views.append(draw_topdown(self))
        if self.render_view in ("camera", "both"):
            views.append(camera_view(self, height=views[0].shape[0] if views else 480))
        if len(views) == 1:
            return views[0]
        return np.concatenate(views, axis=1)

    # A PyBullet world cannot be pickled: a pickled env (SuperSuit and process pools copy envs this
    # way) is rebuilt from its config as a fresh env that needs reset(), with its own client.
    def __getstate__(self) -> dict[str, Any]:
        return {"config": self.config, "render_mode": self.render_mode, "render_view": self.render_view}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__init__(state["config"], render_mode=state["render_mode"], render_view=state["render_view"])

    def close(self) -> None:
        if getattr(self, "client", None) is not None:
            if getattr(self, "egl", False):
                from navzoo.sensors.render import forget_egl

                forget_egl(self.client)
            sim.disconnect(self.client)
            self.client = None

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:  # noqa: BLE001 - interpreter shutdown
            pass


def human_reached_mask(n_total: int, n_robots: int, human_reached: np.ndarray) -> np.ndarray:
    m = np.zeros(n_total, dtype=bool)
    m[n_robots:] = human_reached
    return m


def _segment_origin_distance(p0: np.ndarray, p1: np.ndarray) -> np.ndarray:
    """Distance from the origin to segments p0->p1 (arrays (..., 2))."""
    d = p1 - p0
    dd = np.sum(d * d, axis=-1)
    t = np.clip(-np.sum(p0 * d, axis=-1) / np.maximum(dd, 1e-12), 0.0, 1.0)
    closest = p0 + t[..., None] * d
    return np.linalg.norm(closest, axis=-1)


def _heading_along(path: np.ndarray, start: np.ndarray) -> float:
    for wp in path:
        d = wp - start
        if np.hypot(*d) > 1e-3:
            return float(np.arctan2(d[1], d[0]))
    return 0.0


def _path_length(path: np.ndarray, start: np.ndarray) -> float:
    pts = np.vstack([start[None], path])
    return float(np.linalg.norm(np.diff(pts, axis=0), axis=1).sum())


def _as_array(value: Any, shape: tuple[int, ...], name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=np.float64)
    if arr.shape != shape:
        raise ValueError(f"reset option {name!r} must have shape {shape}, got {arr.shape}")
    if not np.isfinite(arr).all():
        raise ValueError(f"reset option {name!r} contains NaN or inf")
    return arr


def _resolve_scene(scene: str) -> Scene:
    path = Path(scene)
    if path.suffix.lower() in (".yaml", ".yml", ".json") or path.exists():
        if not path.exists():
            raise ValueError(f"scene file {scene!r} does not exist")
        return load_scene(path)
    return get_scene(scene)
