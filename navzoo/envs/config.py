"""Configuration of a navzoo world: one frozen, validated dataclass.

``NavConfig.from_dict`` rejects unknown keys with the list of valid ones, so a typo in a YAML file or
a keyword argument never silently falls back to a default.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

from navzoo.agents.robot import RobotSpec

CrowdModel = Literal["sfm", "orca", "orca_rvo2", "diffusion", "replay"]
CROWD_MODELS = ("sfm", "orca", "orca_rvo2", "diffusion", "replay")
_DEFAULT_SCENE = "circle_crossing"
HumanModel = Literal["kinematic", "amp"]
AMP_CONTROL_HZ = 30  # control rate of the AMP pedestrian controller (its training rate)


@dataclass(frozen=True)
class NavConfig:
    """Everything that defines a navzoo environment.

    Attributes:
        scene: scene name from the library (``navzoo scenes``) or a path to a YAML/JSON scene file.
        n_robots: number of robots (agents ``robot_0..``); 0 = a pedestrian-only world (the episode
            then ends at the time limit only).
        n_humans: number of pedestrians (agents ``human_0..``); ``None`` = the scene's default.
        robot: robot model and limits.
        human_model: pedestrian body controller; ``"kinematic"`` (root follows the planar command,
            joints play a walk cycle) or ``"amp"`` (free-base physics humanoids; a pedestrian's action
            is its 28 joint PD targets, its observation the AMP controller's input, and its target
            trajectory comes from ``crowd_model`` rolled out from the body's actual state every
            ``amp_replan_seconds``; needs ``dt`` a multiple of 1/30 s, ``navzoo.make`` uses 1/30 s;
            see docs/pedestrians.md).
        crowd_model: rule-based trajectory generator of frozen pedestrians: ``"sfm"`` (social
            force), ``"orca"`` (navzoo's ORCA), ``"orca_rvo2"`` (ORCA with RVO2's exact
            semantics, as CrowdNav's pedestrians) or ``"diffusion"`` (paths sampled every 2 s from the
            trajectory diffusion model trained on ETH/UCY, guided toward A* waypoints and away from
            people and walls; :mod:`navzoo.agents.diffusion.crowd`, docs/crowd.md) or ``"replay"``
            (real ETH/UCY tracks played back unchanged in the recording's open scene: people do not
            react to robots, pedestrian actions are ignored; kinematic bodies only;
            :mod:`navzoo.agents.replay`, docs/crowd.md "Replay crowd").
        diffusion_model: ``crowd_model="diffusion"``: directory of an exported model (None =
            ``$NAVZOO_DIFFUSION_MODEL`` if set, else the shipped ``policies/trajectory_diffusion``).
        diffusion_samples: ``crowd_model="diffusion"``: futures sampled per person and plan (the one
            of lowest guidance cost is walked).
        diffusion_walker: ``crowd_model="diffusion"``: what carries each kinematic body along its plan
            between the plans' points and keeps it off the others and the walls: ``"sfm"`` (social force, as the
            rule-based crowd) or ``"orca"`` (ORCA with short horizons,
            :data:`navzoo.agents.diffusion.crowd.ORCA_WALKER`: smoother and faster in crowds, docs/crowd.md
            "An ORCA walker") or ``"hybrid"`` (that ORCA, and social force for the people it holds still,
            :class:`navzoo.agents.diffusion.crowd.StallSwitch`: no jams in doors, docs/crowd.md "A hybrid walker").
            With physics (AMP) bodies it walks their target rollouts toward the plans the same way (``"hybrid"``:
            a switch of its own in every rollout; docs/crowd_log.md, "Walkers for the physics bodies' targets").
        replay_scene: ``crowd_model="replay"``: the recording to play (``"eth"``, ``"univ"``,
            ``"zara1"``, ``"zara3"``, ``"uni_examples"``; ``"hotel"``, ``"zara2"`` where their files
            exist). ``None`` = taken from ``scene="replay_<recording>"``. With the default ``scene``,
            ``scene`` becomes ``"replay_<recording>"``; any other scene is an error.
        replay_start: ``crowd_model="replay"``: recording time (s) shown at env time 0; the episode
            plays ``[replay_start, replay_start + time_limit]``.
        humans_see_robots: whether pedestrians react to robots (off = CrowdNav's invisible robot).
        human_yielding: turn-taking in bottlenecks: a pedestrian stuck face to face with another
            steps back and waits (:mod:`navzoo.agents.yielding`), so opposite flows through a door
            do not freeze. Works with every crowd model, for kinematic and AMP pedestrians; off in the
            CrowdNav presets, whose pedestrians are RVO2's as published.
        human_door_turns: door turns in doors that take one person at a time: a pedestrian near the
            next door of its path asks for it and waits beside it while people come through the other
            way; those going the same way follow each other through (:mod:`navzoo.agents.door_turns`).
            Works with every crowd model but the replay, for kinematic and AMP pedestrians. ``None``
            (the default) = on for AMP pedestrians (since 2026-12-06; docs/crowd_log.md, "Door turns for
            the physics bodies"), off for kinematic ones; ``True`` / ``False`` for both.
        human_radius: pedestrians' disc radius for collisions and observations (m).
        human_body_contacts: also count PyBullet contacts between a robot and a humanoid's limbs
            as collisions (a walking humanoid's hands and feet reach up to ~0.1 m beyond a 0.3 m
            disc). Off = the disc model alone, as CrowdNav (the CrowdNav presets turn it off).
        human_fallen_obstacles: physics (AMP) pedestrians that fall become obstacles in the other
            pedestrians' A* paths, stamped where they come to rest, and the people whose path passes a
            fallen body plan around it (:mod:`navzoo.envs.fallen`); on by default since 2026-12-06 (off
            before: people walked into bodies lying on the floor and fell over them, in cascades). Kinematic
            pedestrians never fall.
        human_fallen_wait: with ``human_fallen_obstacles``: a standing physics pedestrian whose path passes a
            fallen body and who finds no way round it (bodies across a corridor or in a door) stops and waits,
            its target trajectory standing still, until a later stamp (a new fall, or a body that moved) opens a
            way; a new goal with no path from where the person stands is drawn again (up to
            ``FALLEN_GOAL_TRIES`` times) before it waits. Off (the default): such a person keeps its old path and
            walks on into the bodies. Level in the eight scenes (AMD seeds 0-3: -0.1 +- 0.1 / +0.4 +- 0.9 points
            per limit with diffusion / social-force targets; held out -0.2 +- 0.1 / -0.7 +- 1.3); a traced corridor
            run fell 2 times instead of 7. On the Intel device (seeds 0-7) -0.7 +- 0.3 / -0.7 +- 0.9 points: a
            fifth fewer falls for more timeouts, so it stays off (docs/crowd_log.md, "People walk into the pile").
        human_fallen_redraw: with ``human_fallen_obstacles``: a new goal that no path round the fallen bodies
            reaches is drawn again (up to ``FALLEN_GOAL_TRIES`` times, as ``human_fallen_wait`` draws, without
            the waiting), and a person left with none walks the A* path of the bare scene (on into the bodies, as
            a person with no way round keeps its old path) instead of a straight line at its goal. Off: such a
            person walks straight at the goal, through walls (a home run with a body in the bedroom's door: a
            person pressed into the kitchen's wall toward a bedroom goal for 112 s). On the AMD VM (seeds 0-7)
            +0.4 +- 0.15 points per limit with diffusion targets (the home +3.0 successes per run), level with
            social-force targets; on the Intel device (the bold rows' CPU) level with diffusion targets
            (+0.04 +- 0.04) and +0.5 +- 0.2 with social-force targets (the home +3.6 successes per run). On by
            default since 2026-12-08; it acts only after a fall, so runs without one are unchanged
            (docs/crowd_log.md, "Goals cut off by a fallen body").
        human_door_entries: physics (AMP) pedestrians' A* paths cross each door on its axis, from an
            entry point 0.7 m before it to an exit point 0.7 m after it (:mod:`navzoo.envs.doors`);
            off by default.
        human_replan_blocked: pedestrians whose next waypoint has been out of their line of sight for
            ``REPLAN_HIDDEN_S`` (the crowd pushed them off their A* path, e.g. round a table's corner, where
            the straight pull toward the waypoint holds them against the corner) plan a new A* path from
            where they are, at most every ``REPLAN_EVERY_S`` (:meth:`NavEnv._replan_blocked_humans`):
            ``"amp"`` for physics pedestrians, ``"all"`` for kinematic ones too, ``"off"`` (the default).
        human_contact_penalty: kinematic pedestrians (crowd or learning ones) get the collision
            reward (-20) on the step a contact begins: with a robot (the robot's swept collision test
            or PyBullet contact) or with another pedestrian (discs overlapping). They are not taken
            out of the episode; ``info["contact"]`` names what they touched (``"robot"``,
            ``"human"`` or ``""``). Off = pedestrians' only cost for contact is the proximity term.
        human_speed: (min, max) preferred walking speed, sampled per person (m/s).
        human_at_goal: what a pedestrian does on reaching its goal: ``"new_goal"`` (walk on to a
            newly sampled goal, a continuous crowd) or ``"stop"`` (stay there, as in CrowdNav's
            test episodes).
        human_max_speed: speed that a human action of norm 1 maps to (m/s).
        dt: control period (s).
        physics_substeps: PyBullet steps per control step (``human_model="amp"``: fixed by the
            humanoids' 120 Hz physics, this field is ignored).
        amp_replan_seconds: ``human_model="amp"``: period of the target trajectory rollouts (s). 1.0 cuts path
            error by a quarter and agent contacts by a fifth in every pool measured, but success is level on the
            headline pool (Intel seeds 0-7: -0.6 +- 1.1 / +0.6 +- 1.1 points per limit with diffusion / social-force
            targets) and diffusion targets cost up to 1.6 times the run time; so 2.0 stays the default
            (docs/crowd_log.md, "Replanning every second on all eight Intel seeds").
        amp_progress_reward: ``human_model="amp"``: weight of a progress term added to the pedestrians'
            task reward: the body's speed toward the next waypoint of its path, as a share of its
            preferred speed, clipped to [-1, 1] (0 for fallen or arrived people;
            ``info["reward/path_progress"]``). 0 (default) = the paper's reward, whose tracking term
            follows targets replanned from the body every ``amp_replan_seconds`` and so does not pay for
            reaching the goal (docs/pedestrians_log.md, "Run 26").
        amp_wall_strength: ``human_model="amp"``: wall potential strength (``SocialForceParams.A_wall``) of the
            social-force rollouts that make the bodies' target trajectories (social-force targets, and the rollouts
            toward diffusion plans); None (default) = ``navzoo.envs.amp_humans.SFM_A_WALL`` (1.0, the kinematic
            crowd's own). 0.3 lets the targets pass nearer walls: more goals, about twice the wall contacts
            (docs/pedestrians_log.md, "Softer walls for the target rollouts").
        amp_wall_near_range: ``human_model="amp"``: with > 0 (m), a person of those target rollouts who has another
            person within this distance (centre to centre) feels the walls with ``amp_wall_near_strength`` instead:
            softer walls only where people meet (``SocialForceParams.wall_near_range``); 0 = off. None (default) =
            ``navzoo.envs.amp_humans.SFM_WALL_NEAR_RANGE`` (0, off).
        amp_wall_near_strength: that softer wall strength (``SocialForceParams.A_wall_near``); None (default) =
            ``amp_humans.SFM_A_WALL_NEAR`` (0.3).
        amp_wall_near_ramp: with > 0 (m), those softer walls phase in linearly from ``amp_wall_near_range`` + this
            distance down to ``amp_wall_near_range`` instead of switching (``SocialForceParams.wall_near_ramp``);
            None (default) = ``amp_humans.SFM_WALL_NEAR_RAMP`` (0, a switch). Range 1.5 with ramp 1.0 measured in
            docs/pedestrians_log.md, "A ramp instead of a switch".
        amp_wall_margin: ``human_model="amp"``: margin (m) added to a person's radius for the walls of those
            social-force target rollouts (the graded wall margin still shrinks it in narrow passages); None (default) =
            ``navzoo.envs.amp_humans.WALL_PLAN_MARGIN`` (0.1). 0.2 cuts the trips with a wall contact by a third and
            costs success (docs/pedestrians_log.md, "A wider wall margin for the target rollouts").
        amp_corner_margin: ``human_model="amp"``: extra margin (m) that the exposed corners of obstacles (door jambs,
            shelf corners: ``Scene.exposed_corners``) keep from a person in those target rollouts, as a sideways push
            only, so a target swings wide round a corner and centres in a door without being braked; None (default) =
            ``navzoo.envs.amp_humans.CORNER_MARGIN`` (0, off). 0.15 halves the trips with a wall contact and costs
            success as a wider wall margin does (docs/pedestrians_log.md, "Corner steering in the target rollouts").
        amp_side_bias: ``human_model="amp"``: the keep-right gain of those social-force target rollouts
            (``SocialForceParams.side_bias``: a share of the push from someone ahead that turns a person to its right,
            so people meeting head-on pass left shoulder to left shoulder); None (default) =
            ``navzoo.envs.amp_humans.SFM_SIDE_BIAS`` (0.4 since 2026-12-06; 0.1, the kinematic crowd's own, before:
            docs/crowd_log.md, "Keeping right").
        amp_side_narrow_reach: ``human_model="amp"``: within this distance (m) of a narrow point of its A* path (a door
            too narrow for the default wall margin of those rollouts, under about 1.0 m, whatever ``amp_wall_margin``
            is), a person of the target rollouts keeps right with ``amp_side_bias_narrow`` instead of
            ``amp_side_bias``; 0 = off. None (default) =
            ``navzoo.envs.amp_humans.SFM_SIDE_NARROW_REACH`` (1.5 since 2026-12-06; docs/crowd_log.md, "Keeping right
            except near narrow doors").
        amp_side_bias_narrow: that keep-right gain near narrow doors; None (default) =
            ``amp_humans.SFM_SIDE_BIAS_NARROW`` (0.1).
        amp_sight_clearance: ``human_model="amp"``: the controller sees only the target points that a straight line
            from the pelvis reaches with this clearance (m) from obstacles; the points behind a corner are shown
            continued straight, so the body walks past the corner before it turns
            (``navzoo.envs.amp_humans.sight_waypoints``); None (default) = ``amp_humans.SIGHT_CLEARANCE`` (0, off)
            (docs/pedestrians_log.md, "Target points in sight of the body").
        crowd_wall_strength: wall potential strength (``SocialForceParams.A_wall``) of the social force that moves
            the kinematic crowd (``crowd_model`` "sfm", and the bodies of the "diffusion" crowd between its plans) when
            it runs on :class:`navzoo.agents.crowd.CrowdPolicy` without parameters of its own. 1.0 (default) =
            ``SocialForceParams``' own; 0.3 lets people through narrow scenes, nearer the walls
            (docs/crowd_models.md, "Softer walls").
        crowd_wall_near_range: with > 0 (m), a person of that crowd who has another person within this distance
            (centre to centre) feels the walls with ``crowd_wall_near_strength`` instead: softer walls only where
            people meet (``SocialForceParams.wall_near_range``). 0 (default) = off.
        crowd_wall_near_strength: that softer wall strength (``SocialForceParams.A_wall_near``), default 0.3.
        crowd_wall_near_ramp: with > 0 (m), the softer walls phase in linearly from ``crowd_wall_near_range`` +
            this distance to ``crowd_wall_near_range`` instead of switching (``SocialForceParams.wall_near_ramp``).
        amp_stance_reward: ``human_model="amp"``: weight of a stance term added to the pedestrians' task
            reward: minus the excess over ``navzoo.agents.amp.features.STANCE_FREE_M`` (0.1 m) of the
            absolute running mean (time constant ``features.STANCE_TAU_S``, 1 s) of the right foot's fore-aft
            lead over the left foot in the body's heading frame, in metres (``info["reward/stance"]``, logged
            whatever the weight; the mean starts at 0 at each reset). Walking alternates the feet, so the mean stays near 0 (the reference clips: 0.069 m on
            average); a split stance (one foot kept ahead, docs/pedestrians_log.md, "Where the realism gap
            lies") holds it at about 0.5 m. 0 (default) = the paper's reward.
        amp_wall_contact_reward: ``human_model="amp"``: weight of a wall-contact term added to the pedestrians'
            task reward: -1 while any link of the body touches a scene obstacle (the contact of the step's last
            physics step, the one ``info["map_contact"]`` reports), else 0 (``info["reward/wall_contact"]``, logged
            whatever the weight). For training the controller to keep its hands and feet off walls and furniture
            (docs/pedestrians_log.md, "A wall-contact term for training"). 0 (default) = the paper's reward.
        time_limit: episode length (s); ``None`` = the scene's own limit.
        goal_tolerance: a robot reaches its goal when closer than this (m); ``None`` = robot radius
            (CrowdNav's rule, as the paper's reward).
        min_goal_distance: minimum start-goal distance of sampled tasks (m).
        robot_subgoal: ``None`` = robots observe their goal (the paper, CrowdNav); a distance ``L`` (m)
            = robots observe a subgoal instead, the farthest point of their A* path within ``L`` m and in
            line of sight (:mod:`navzoo.envs.subgoal`; for multi-room scenes). Goal reaching, metrics
            and the goal reward still use the real goal.
        robot_progress: distance behind the reward's progress term ``3.2 (d_{t-1} - d_t)`` for robots:
            ``"euclidean"`` (the paper) or ``"geodesic"`` (shortest path through the free space, so a
            detour around a wall is not punished; :mod:`navzoo.envs.subgoal`).
        wall_proximity: the reward's proximity term penalises being closer than 0.9 m (edge to edge)
            to people and robots; ``None`` = the same 0.9 m for walls and obstacles (the paper), a
            number = that distance for walls and obstacles instead (m; 0 = walls only count for
            collisions). In a home or a store most of a shortest path runs within 0.9 m of a wall, where
            the paper's reward gives no progress term at all.
        collision_reward: the reward on the step a robot's collision begins (the paper: -20, as the
            goal's +20); a finite number <= 0.
        proximity_scale: slope of the reward's proximity term, ``scale x (d_obs - 0.9)`` within 0.9 m
            (the paper: 0.5; per metre, per step); a finite number >= 0.
        k_neighbors: people/robots in each observation (K).
        history: past steps per neighbour (T).
        sensor_range: neighbours farther than this are masked out (m).
        map_size: side of the local occupancy crop (m).
        map_cells: cells per side of the local occupancy crop.
        scan_rays: rays of a planar range scan of the static scene in each robot and kinematic
            pedestrian observation (key ``"scan"``); 0 = no scan (the default, the paper's
            observation). Ray ``i`` points ``2 pi i / scan_rays`` counter-clockwise from the heading;
            each entry is the distance from the agent's centre to the first wall or obstacle edge along
            the ray, divided by ``scan_range`` (1 = nothing within range). Exact line geometry, so it
            resolves clearances finer than the occupancy crop's cells (0.15 m by default).
        scan_range: range of the scan (m).
        flat_obs: flatten the Dict observation into one Box (for simple learners).
        path_spacing: spacing of A* waypoints (m).
        path_clearance: extra inflation beyond the agent's radius when planning (m), so that paths
            keep a natural distance from walls and corners (falls back to the bare radius where a
            passage is too narrow for it).
        waypoint_tolerance: a pedestrian moves on to its next waypoint within this distance (m).
        grid_resolution: occupancy grid cell size (m).
        max_episode_steps_override: hard cap on steps, mainly for tests; ``None`` = from time limit.
        egl: load PyBullet's EGL renderer on the env's client (robot cameras then render with OpenGL: a
            GPU, or Mesa's llvmpipe on CPU; polygon obstacles get OBJ visual meshes, which EGL needs).
            Falls back to TinyRenderer with a warning where EGL is not available.
    """

    scene: str = "circle_crossing"
    n_robots: int = 1
    n_humans: int | None = None
    robot: RobotSpec = field(default_factory=RobotSpec)
    human_model: HumanModel = "kinematic"
    crowd_model: CrowdModel = "sfm"
    diffusion_model: str | None = None
    diffusion_samples: int = 4
    diffusion_walker: str = "sfm"
    replay_scene: str | None = None
    replay_start: float = 0.0
    humans_see_robots: bool = True
    human_yielding: bool = True
    human_door_turns: bool | None = None
    human_radius: float = 0.3
    human_body_contacts: bool = True
    human_contact_penalty: bool = True
    human_fallen_obstacles: bool = True
    human_fallen_wait: bool = False
    human_fallen_redraw: bool = True
    human_door_entries: bool = False
    human_replan_blocked: Literal["amp", "all", "off"] = "off"
    human_speed: tuple[float, float] = (1.0, 1.4)
    human_at_goal: Literal["new_goal", "stop"] = "new_goal"
    human_max_speed: float = 2.0
    dt: float = 0.1
    physics_substeps: int = 2
    amp_replan_seconds: float = 2.0
    amp_progress_reward: float = 0.0
    amp_stance_reward: float = 0.0
    amp_wall_contact_reward: float = 0.0
    amp_wall_strength: float | None = None
    amp_wall_near_range: float | None = None
    amp_wall_near_strength: float | None = None
    amp_wall_near_ramp: float | None = None
    amp_wall_margin: float | None = None
    amp_corner_margin: float | None = None
    amp_side_bias: float | None = None
    amp_side_narrow_reach: float | None = None
    amp_side_bias_narrow: float | None = None
    amp_sight_clearance: float | None = None
    crowd_wall_strength: float = 1.0
    crowd_wall_near_range: float = 0.0
    crowd_wall_near_strength: float = 0.3
    crowd_wall_near_ramp: float = 0.0
    time_limit: float | None = None
    goal_tolerance: float | None = None
    min_goal_distance: float = 3.0
    robot_subgoal: float | None = None
    robot_progress: Literal["euclidean", "geodesic"] = "euclidean"
    wall_proximity: float | None = None
    collision_reward: float = -20.0
    proximity_scale: float = 0.5
    k_neighbors: int = 6
    history: int = 8
    sensor_range: float = 6.0
    map_size: float = 4.8
    map_cells: int = 32
    scan_rays: int = 0
    scan_range: float = 4.0
    flat_obs: bool = False
    path_spacing: float = 0.5
    path_clearance: float = 0.2
    waypoint_tolerance: float = 0.6
    grid_resolution: float = 0.1
    max_episode_steps_override: int | None = None
    egl: bool = False

    def __post_init__(self) -> None:
        def bad(name: str, expected: str) -> ValueError:
            got = getattr(self, name)
            hint = ""
            if isinstance(got, bool) and expected.startswith("'"):
                # YAML 1.1 reads unquoted off/on/yes/no as booleans
                hint = " (in YAML, quote words such as 'off': unquoted off/on/yes/no are read as booleans)"
            return ValueError(f"NavConfig.{name} must be {expected}, got {got!r}{hint}")

        if not isinstance(self.scene, str) or not self.scene:
            raise bad("scene", "a scene name or a path to a scene file")
        if not _is_int(self.n_robots) or self.n_robots < 0:
            raise bad("n_robots", "an integer >= 0")
        if self.n_robots == 0 and self.n_humans == 0:
            raise ValueError("NavConfig needs at least one agent: n_robots and n_humans are both 0")
        if self.n_humans is not None and (not _is_int(self.n_humans) or self.n_humans < 0):
            raise bad("n_humans", "None or an integer >= 0")
        if not isinstance(self.robot, RobotSpec):
            raise bad("robot", "a RobotSpec")
        if self.human_model not in ("kinematic", "amp"):
            raise bad("human_model", "'kinematic' or 'amp'")
        if self.human_model == "amp" and _is_pos(self.dt):
            k = self.dt * AMP_CONTROL_HZ
            if abs(k - round(k)) > 1e-6 or round(k) < 1:
                raise ValueError(f"NavConfig.dt must be a multiple of 1/{AMP_CONTROL_HZ} s with human_model='amp' "
                                 f"(the AMP controller's rate), got {self.dt!r}; use dt=1/{AMP_CONTROL_HZ}")
        if not _is_pos(self.amp_replan_seconds):
            raise bad("amp_replan_seconds", "a finite number > 0")
        for name in ("amp_progress_reward", "amp_stance_reward", "amp_wall_contact_reward"):  # the optional reward terms
            w = getattr(self, name)
            if isinstance(w, bool) or not isinstance(w, int | float) or not math.isfinite(w) or w < 0:
                raise bad(name, "a finite number >= 0")
        # the wall settings of the physics pedestrians' target rollouts (amp_*, None = amp_humans' constants) and of
        # the kinematic crowd (crowd_*): strengths > 0, ranges and ramps >= 0
        for prefix, none in (("amp", "None or "), ("crowd", "")):
            for suffix, ok, expected in (("strength", _is_pos, "> 0"), ("near_strength", _is_pos, "> 0"),
                                         ("near_range", _is_non_negative, ">= 0 (0 = off)"),
                                         ("near_ramp", _is_non_negative, ">= 0 (0 = a switch)")):
                name = f"{prefix}_wall_{suffix}"
                value = getattr(self, name)
                if not ((none and value is None) or ok(value)):
                    raise bad(name, f"{none}a finite number {expected}")
        # the other target-rollout settings: None (the amp_humans constant) or a finite number >= 0
        for name in ("amp_wall_margin", "amp_corner_margin", "amp_side_bias", "amp_side_narrow_reach",
                     "amp_side_bias_narrow", "amp_sight_clearance"):
            if not (getattr(self, name) is None or _is_non_negative(getattr(self, name))):
                raise bad(name, "None or a finite number >= 0")
        if self.crowd_model not in CROWD_MODELS:
            raise bad("crowd_model", "'sfm', 'orca', 'orca_rvo2', 'diffusion' or 'replay'")
        self._validate_replay()
        if self.diffusion_model is not None and (not isinstance(self.diffusion_model, str) or not self.diffusion_model):
            raise bad("diffusion_model", "None or a path to an exported trajectory diffusion model")
        if not _is_int(self.diffusion_samples) or self.diffusion_samples < 1:
            raise bad("diffusion_samples", "an integer >= 1")
        if self.diffusion_walker not in ("sfm", "orca", "hybrid"):
            raise bad("diffusion_walker", "'sfm', 'orca' or 'hybrid'")
        if not isinstance(self.humans_see_robots, bool):
            raise bad("humans_see_robots", "a bool")
        if not isinstance(self.human_yielding, bool):
            raise bad("human_yielding", "a bool")
        if self.human_door_turns is not None and not isinstance(self.human_door_turns, bool):
            raise bad("human_door_turns", "a bool or None (on for AMP pedestrians only)")
        if self.human_replan_blocked not in ("amp", "all", "off"):
            raise bad("human_replan_blocked", "'amp', 'all' or 'off'")
        if self.human_at_goal not in ("new_goal", "stop"):
            raise bad("human_at_goal", "'new_goal' or 'stop'")
        if not isinstance(self.human_body_contacts, bool):
            raise bad("human_body_contacts", "a bool")
        if not isinstance(self.human_contact_penalty, bool):
            raise bad("human_contact_penalty", "a bool")
        if not isinstance(self.human_fallen_obstacles, bool):
            raise bad("human_fallen_obstacles", "a bool")
        if not isinstance(self.human_fallen_wait, bool):
            raise bad("human_fallen_wait", "a bool")
        if not isinstance(self.human_fallen_redraw, bool):
            raise bad("human_fallen_redraw", "a bool")
        if not isinstance(self.human_door_entries, bool):
            raise bad("human_door_entries", "a bool")
        if not _is_int(self.scan_rays) or self.scan_rays < 0:
            raise bad("scan_rays", "an integer >= 0 (0 = no range scan)")
        if not _is_pos(self.scan_range):
            raise bad("scan_range", "a finite number > 0")
        for name in ("human_radius", "human_max_speed", "dt", "min_goal_distance", "sensor_range", "map_size",
                     "path_spacing", "waypoint_tolerance", "grid_resolution"):
            if not _is_pos(getattr(self, name)):
                raise bad(name, "a finite number > 0")
        lo_hi = self.human_speed
        if (not isinstance(lo_hi, (tuple, list)) or len(lo_hi) != 2 or not all(_is_pos(v) for v in lo_hi)
                or lo_hi[0] > lo_hi[1] or lo_hi[1] > self.human_max_speed):
            raise bad("human_speed", f"(min, max) with 0 < min <= max <= human_max_speed={self.human_max_speed}")
        object.__setattr__(self, "human_speed", (float(lo_hi[0]), float(lo_hi[1])))
        for name in ("physics_substeps", "k_neighbors", "history", "map_cells"):
            if not _is_int(getattr(self, name)) or getattr(self, name) < 1:
                raise bad(name, "an integer >= 1")
        if not (_is_pos(self.path_clearance) or self.path_clearance == 0):
            raise bad("path_clearance", "a finite number >= 0")
        if self.time_limit is not None and not _is_pos(self.time_limit):
            raise bad("time_limit", "None or a finite number > 0")
        if self.robot_subgoal is not None and not _is_pos(self.robot_subgoal):
            raise bad("robot_subgoal", "None or a finite number > 0 (m)")
        if self.robot_progress not in ("euclidean", "geodesic"):
            raise bad("robot_progress", "'euclidean' or 'geodesic'")
        if self.wall_proximity is not None and (isinstance(self.wall_proximity, bool) or not (
                _is_pos(self.wall_proximity) or self.wall_proximity == 0)):
            raise bad("wall_proximity", "None or a finite number >= 0 (m)")
        if not (_is_num(self.collision_reward) and self.collision_reward <= 0):
            raise bad("collision_reward", "a finite number <= 0")
        if not (_is_num(self.proximity_scale) and self.proximity_scale >= 0):
            raise bad("proximity_scale", "a finite number >= 0")
        if self.goal_tolerance is not None and not _is_pos(self.goal_tolerance):
            raise bad("goal_tolerance", "None or a finite number > 0")
        if self.max_episode_steps_override is not None and (
            not _is_int(self.max_episode_steps_override) or self.max_episode_steps_override < 1
        ):
            raise bad("max_episode_steps_override", "None or an integer >= 1")
        if not isinstance(self.flat_obs, bool):
            raise bad("flat_obs", "a bool")
        if not isinstance(self.egl, bool):
            raise bad("egl", "a bool")

    def _validate_replay(self) -> None:
        from navzoo.agents.replay import SCENE_PREFIX, canonical_recording, load_recording

        if not (_is_pos(self.replay_start) or self.replay_start == 0) or isinstance(self.replay_start, bool):
            raise ValueError(f"NavConfig.replay_start must be a finite number >= 0 (seconds into the recording), "
                             f"got {self.replay_start!r}")
        object.__setattr__(self, "replay_start", float(self.replay_start))
        if self.crowd_model != "replay":
            if self.replay_scene is not None:
                raise ValueError(f"NavConfig.replay_scene={self.replay_scene!r} is only used with crowd_model='replay', "
                                 f"got crowd_model={self.crowd_model!r}; set replay_scene=None (the open scene "
                                 f"'{SCENE_PREFIX}<recording>' works with every crowd model)")
            return
        if self.human_model != "kinematic":
            raise ValueError("crowd_model='replay' plays recorded tracks on kinematic bodies only; human_model="
                             f"{self.human_model!r} is not supported (physics humanoids cannot follow a recorded "
                             "track exactly); use human_model='kinematic'")
        from_scene = self.scene[len(SCENE_PREFIX):] if self.scene.startswith(SCENE_PREFIX) else None
        if self.replay_scene is None and from_scene is None:
            raise ValueError("crowd_model='replay' needs a recording: replay_scene='eth' (or 'univ', 'zara1', ...) "
                             "or scene='replay_<recording>'")
        if self.replay_scene is not None and not isinstance(self.replay_scene, str):
            raise ValueError(f"NavConfig.replay_scene must be None or a recording name, got {self.replay_scene!r}")
        name = canonical_recording(self.replay_scene if self.replay_scene is not None else from_scene)
        if from_scene is not None and canonical_recording(from_scene) != name:
            raise ValueError(f"NavConfig.scene={self.scene!r} does not match replay_scene={self.replay_scene!r}; "
                             f"use scene='{SCENE_PREFIX}{name}' (or leave scene at its default)")
        if from_scene is None and self.scene != _DEFAULT_SCENE:
            raise ValueError(f"crowd_model='replay' plays recording {name!r} in its own open scene "
                             f"'{SCENE_PREFIX}{name}', got scene={self.scene!r}; use scene='{SCENE_PREFIX}{name}' "
                             "(or leave scene at its default)")
        object.__setattr__(self, "replay_scene", name)
        object.__setattr__(self, "scene", f"{SCENE_PREFIX}{name}")
        rec = load_recording(name)
        if self.replay_start >= rec.duration:
            raise ValueError(f"NavConfig.replay_start={self.replay_start:g} s is beyond the end of recording "
                             f"{name!r} ({rec.stem}, {rec.duration:.1f} s long); use 0 <= replay_start < "
                             f"{rec.duration:.1f}")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> NavConfig:
        """Build a config from plain data (e.g. YAML), rejecting unknown keys by name."""
        if not isinstance(data, dict):
            raise TypeError(f"NavConfig.from_dict expects a dict, got {type(data).__name__}")
        valid = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(data) - valid)
        if unknown:
            raise ValueError(f"unknown NavConfig key(s) {unknown}; valid keys: {sorted(valid)}")
        kwargs = dict(data)
        if isinstance(kwargs.get("robot"), dict):
            rvalid = {f.name for f in dataclasses.fields(RobotSpec)}
            runknown = sorted(set(kwargs["robot"]) - rvalid)
            if runknown:
                raise ValueError(f"unknown RobotSpec key(s) {runknown}; valid keys: {sorted(rvalid)}")
            kwargs["robot"] = RobotSpec(**kwargs["robot"])
        if isinstance(kwargs.get("human_speed"), list):
            kwargs["human_speed"] = tuple(kwargs["human_speed"])
        return cls(**kwargs)

    @property
    def door_turns(self) -> bool:
        """Whether door turns are on: ``human_door_turns``, or with ``None`` whether the pedestrians are AMP bodies."""
        return self.human_model == "amp" if self.human_door_turns is None else self.human_door_turns

    def replace(self, **changes: Any) -> NavConfig:
        """A copy with some fields changed (validated like a new config)."""
        valid = {f.name for f in dataclasses.fields(self)}
        unknown = sorted(set(changes) - valid)
        if unknown:
            raise ValueError(f"unknown NavConfig key(s) {unknown}; valid keys: {sorted(valid)}")
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _is_pos(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0


def _is_non_negative(v: Any) -> bool:
    return _is_num(v) and v >= 0


def parse_override(item: str) -> tuple[str, Any]:
    """One command-line ``--set KEY=VALUE`` item as ``(key, value)``: the value is read as JSON (numbers,
    ``true``/``false``, ``null``, lists), else kept as a string, so words such as ``off`` stay words.
    ``ValueError`` names an item without ``=`` or with an empty key. The key and value are checked by NavConfig."""
    import json

    if not isinstance(item, str) or "=" not in item:
        raise ValueError(f"--set takes KEY=VALUE (a NavConfig field), got {item!r}")
    key, text = item.split("=", 1)
    key = key.strip()
    if not key:
        raise ValueError(f"--set takes KEY=VALUE (a NavConfig field), got an empty KEY in {item!r}")
    try:
        return key, json.loads(text)
    except json.JSONDecodeError:
        return key, text


def parse_overrides(items: Any) -> dict[str, Any]:
    """``["KEY=VALUE", ...]`` (command-line ``--set`` options) as a dict, each item read by
    :func:`parse_override`. The keys are checked by NavConfig."""
    out: dict[str, Any] = {}
    for item in items or []:
        key, value = parse_override(item)
        out[key] = value
    return out
