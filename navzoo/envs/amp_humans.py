"""Physics pedestrians of ``human_model="amp"``: free-base humanoids, their target trajectories and state.

The env owns one :class:`AmpHumans`. Each pedestrian is a :class:`~navzoo.agents.amp.sim.PhysicsHumanoids`
body in the env's PyBullet client (120 Hz physics, 30 Hz control, torque-limited joint motors) that
collides with the scene, the robots and the other pedestrians. Its action is the 28 joint PD targets in
[-1, 1]; its observation is the AMP controller's input: the body's self-observation, the next
``n_waypoints`` points (every ``waypoint_dt``) of its target trajectory in its heading frame, and 16
obstacle rays (walls, other people and robots as discs; :func:`~navzoo.agents.amp.features.obstacle_observation`).

Target trajectories come from the env's crowd model (social force or ORCA) following each person's A*
path: every ``replan_seconds`` the model is rolled out from the bodies' *actual* positions and
velocities for the horizon the controller looks ahead (plus one replanning period), the robots moving
at constant velocity. The trajectory therefore stays attached to the body and reacts to the crowd,
while the body's joints are left to the controller.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
import pybullet as p

from navzoo.agents.amp.features import (
    FEATURE_DIM,
    N_RAYS,
    STANCE_FREE_M,  # noqa: F401  (re-exported: the stance term's constants and foot_split live in features)
    STANCE_TAU_S,
    foot_split,
    heading,
    obstacle_observation,
    policy_observation,
    stance_penalty,
)
from navzoo.agents.amp.sim import ACTION_DIM, PhysicsHumanoids, actions_to_targets
from navzoo.agents.orca import OrcaParams, orca_velocities
from navzoo.agents.policy import preferred_velocity
from navzoo.agents.sfm import SocialForceParams, social_force_velocities
from navzoo.agents.target_paths import resample
from navzoo.world.geometry import segment_point_distance, segment_segment_distance

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

PHYSICS_HZ = 120
CONTROL_HZ = 30
N_WAYPOINTS = 10
WAYPOINT_DT = 0.5
OBS_DIM = FEATURE_DIM + 2 * N_WAYPOINTS + N_RAYS
ACT_DIM = ACTION_DIM
PLAN_DT = 0.1
# An articulated body swings its hands and feet beyond its 0.3 m disc, so physics pedestrians plan
# with room to spare: +0.1 m on the radius in the target rollouts and on the A* inflation. Measured on
# home/lobby/corridor/grocery (4 x 60 s, seed 0): falls per trip 0.20 -> 0.09, success 0.33 -> 0.40
# (margins 0 / 0.1 / 0.15 compared; docs/pedestrians.md).
PLAN_MARGIN = 0.1  # m
# Margin on the radius that walls see in the social-force rollouts (``wall_radius``). With 0.4 m a
# lone rollout that enters a 0.9 m door off its axis is held back by the jambs (tests/test_amp_targets.py),
# but over the 8 following scenes (200 s, device machine, scripts/amp_target_ablation.py) 0 or 0.05 m
# instead of 0.1 m gave no more successes and more map contacts (0.13 against 0.10 of trips), so walls
# keep the people's margin.
WALL_PLAN_MARGIN = PLAN_MARGIN  # m
# ... except in passages too narrow for it. A rollout disc whose wall radius leaves less than about
# 0.07 m on each side of a door stalls in front of it: the jambs' corners push back as hard as the goal
# pulls, so the target stops and the body with it (home scene, 0.9 m doors: a lone person stood at a door
# for 60-80 s, 3 and 7 of its 8 and 11 trips timed out). Near a stretch of its A* path with clearance c
# (within PASSAGE_REACH of the disc), the wall margin is therefore at most c - radius - DOOR_SLACK
# (0.9 m doors: 0.05 m; 1.0 m doors and wider keep the full 0.1 m). See graded_wall_radius.
# Following protocol, 4 seeds (device machine, docs/pedestrians_log.md "A graded wall margin"): success
# 0.551 -> 0.573 with social-force targets and 0.636 -> 0.659 with diffusion targets, higher in every
# seed; map contacts 0.054 -> 0.069 and 0.088 -> 0.100 of trips. GRADED_WALL_MARGIN = False turns it off.
GRADED_WALL_MARGIN = True
DOOR_SLACK = 0.1  # m
PASSAGE_REACH = 1.0  # m
# Diffusion plans are paced in time and do not see the bodies that block a person, so a blocked body
# falls behind its target, up to 2 s x walking pace by the next replan; the controller then lunges at a
# target 2 m away and falls (corridor, 6 people: first target point p99 2.1 m from the body with
# diffusion plans against 1.0 m with social-force rollouts, which start from the body and see the others).
# With diffusion plans the target's current point therefore runs at most LAG_LIMIT_S ahead of the point
# of the plan nearest to the body (progress_index). 0.15 s and 0.5 s both succeed less with social-force targets
# (0.630 and 0.641 per limit against 0.711, seeds 0-1, VM; docs/pedestrians_log.md "How far the target may lead the body").
LAG_LIMIT_S = 0.3
# Social-force and ORCA rollouts start from the body at every replan (2 s); without a limit their targets run
# by time alone. LAG_LIMIT_RULES = True holds them to the same LAG_LIMIT_S lead over the body as diffusion
# targets, so every target generator meets the controller under one rule (the paper's SFM+AMP against
# Diffusion+AMP comparison keeps the controller and changes only the generator). On since 2026-12-01
# (docs/pedestrians_log.md "One pacing rule for every target generator"): with the pass margin, social-force
# targets, success per limit 0.621 -> 0.660 over seeds 0-3 and 0.599 -> 0.678 over seeds 4-5 (higher in all
# six), per goal 0.674 -> 0.738 and 0.664 -> 0.750, trips off the path 0.124 -> 0.027, timeouts 0.241 ->
# 0.299, falls 0.014 -> 0.013. Before the pass margin it was level per limit (0.573 -> 0.579, section
# "Pacing social-force targets"). False: social-force and ORCA targets run by time between replans.
LAG_LIMIT_RULES = True
# A replan that new goals asked for starts the rollouts from bodies that may still walk the other way (a
# goal behind the person: the body turns around while its target already walks off). START_REPLAN_S > 0
# replans once more that long after such a replan, from the turned body; 0 = off. START_LAG = True holds a
# person's target to the LAG_LIMIT_S lead over its body during the first plan of each trip (from the new goal
# to the next regular replan). Both off: over 4 seeds (docs/pedestrians_log.md "Pacing social-force targets"),
# per-limit success 0.573 -> 0.533 (START_REPLAN_S 0.7) and 0.561 (START_LAG). START_LAG adds nothing while
# LAG_LIMIT_RULES is on (the default since 2026-12-01), which holds every plan, the first of a trip too.
START_REPLAN_S = 0.0
START_LAG = False
# An event replan (someone reached a goal, began to yield, was granted a door, or got a new A* path round a
# fallen body or a hidden waypoint) rolls the crowd out again from the bodies. EVENT_REPLAN_OWN = True gives new
# targets (and, with the diffusion crowd, newly sampled plans) only to the people of the event; the others keep
# theirs until the regular replan (every amp_replan_seconds, from the oldest plan), and the rollout still moves
# everyone so the new targets see them. False: every event re-rolls every person's target. On, diffusion targets
# lost 4.8 +- 1.1 (Intel seeds 4-7) and 4.6 +- 1.3 (AMD seeds 0-3) points per limit in the eight scenes, agent contacts
# doubled (docs/crowd_log.md, "The shipped fallen-body planning on the Intel device; event replans ...").
EVENT_REPLAN_OWN = False
# Diffusion crowd with physics bodies: the target rollout heads for each plan's point this far ahead, at the
# plan's pace but at most DIFFUSION_SPEED_CAP times the person's preferred speed (docs/crowd_log.md "Diffusion
# plans for physics bodies"). 0.8 s (as kinematic diffusion pedestrians look ahead) until 2026-12-01; 0.4 s
# keeps the targets closer to the plans: following protocol, diffusion targets, success per limit 0.696 ->
# 0.725 over seeds 0-3 and 0.714 -> 0.732 over held-out seeds 4-5, per goal 0.841 -> 0.859 and 0.856 ->
# 0.867, agent contacts per goal 0.092 -> 0.073, falls level; 1.6 s: 0.701 -> 0.630 over seeds 0-1
# (docs/crowd_log.md "A shorter lookahead for diffusion targets").
DIFFUSION_LOOKAHEAD_S = 0.4
# The cap was 1.3 until 2026-11-28. Targets faster than the person's own pace run away from a body that
# cannot keep up: over 4 seeds of the following protocol (device machine, docs/crowd_log.md "A speed cap of 1.0
# for diffusion targets", docs/results/diffusion_speed_cap/) caps of
# 1.3 / 1.15 / 1.0 / 0.9 gave success per goal 0.779 / 0.810 / 0.823 / 0.824, falls 0.023 / 0.012 / 0.006 /
# 0.004, agent contacts 0.170 / 0.102 / 0.060 / 0.028 and timeouts 0.094 / 0.117 / 0.146 / 0.158; on two
# seeds not used to choose (4, 5) 1.0 against 1.3: 0.834 / 0.808 against 0.715 / 0.771.
DIFFUSION_SPEED_CAP = 1.0
# Door turns (NavConfig.human_door_turns, on for AMP pedestrians): whether a person coming from a side of a door with
# no waiting spot (a door off a narrow passage) stops short of the door while it is held the other way, instead of
# taking it at once (agents.door_turns.DoorParams.no_room_waits). An option, off; crowd_log.md, "Door turns for the
# physics bodies".
DOOR_NO_ROOM_WAITS = False
# Door turns for AMP pedestrians: whether the way back to a waiting spot is refused only where it runs into a passage
# (agents.door_turns.DoorParams.spot_passage_only), not beside one piece of furniture: without it the home's kitchen
# door has no waiting spot on its living-room side (the dining table beside the way). An option, off; crowd_log.md,
# "A kitchen door with no waiting spot".
DOOR_SPOT_PASSAGE_ONLY = False
# Door turns for AMP pedestrians: a person counts as through a door only within this distance of the door's axis line
# (m; agents.door_turns.DoorParams.passed_lateral; 0 = anywhere beside it). Without it a person pushed aside to where
# the door's far side lies along the axis drops the door it has not crossed. An option, off (behind in the home's three
# runs where it acts, the doorway unchanged); crowd_log.md, "Through a door without crossing it".
DOOR_PASSED_LATERAL = 0.0
# Door turns for AMP pedestrians: a holder of a door still before it and further to the side of the door's axis than
# this times its distance before the door's centre (a slope) heads for the point 1 m before the centre on the axis first
# (agents.door_turns.DoorParams.line_up; 0 = off). Traced in the doorway (crowd_log.md, "Holders pressed against the
# wall beside the door"): holders that leave their waiting spot aim at the door's middle on a line that meets the wall
# beside the opening, and stand there, pressed against it. An option, off: slope 0.35 is level on successes in the
# doorway and the home with fewer map contacts, but behind held out (three door scenes, seeds 0-7, AMD VM: -3.3 +- 1.9
# points per limit, the warehouse aisles 0.736 -> 0.684).
DOOR_LINE_UP = 0.0
# With DOOR_PASS_WAITERS, the social-force target rollouts let a person who holds a door pass the people waiting for
# that door without their repulsion (DoorTurns.holder_waiter_pairs, the grants and waits frozen at the plan's time, as
# the door turns are in the rollouts). The waiting spots lie 1.0 m beside the door's lane on purpose, yet their people
# push the holders' rollouts aside and slow them: in the doorway the holders' rollouts walked at 0.40-0.46 m/s while
# their plans walked at 1.04-1.08 (crowd_log.md, "Holders pressed against the wall beside the door"). An option, off:
# on the AMD VM (seeds 0-7) ahead in the doorway and the home by about one standard error with either target generator
# (+3.5 +- 3.2 / +2.5 +- 2.3 points per limit), level held out with either (-0.1 +- 1.3 / -1.0 +- 1.0, seeds 0-7 /
# 0-3), more agent contacts in the doorway; on the Intel device that the bold rows come from (seeds 0-7) level with
# diffusion targets (-0.3 +- 2.4) and behind with social-force targets (-4.5 +- 3.3, the home) (crowd_log.md,
# "Holders that pass the people waiting for their door").
DOOR_PASS_WAITERS = False
# How long a door turn's grant lasts for AMP pedestrians without its holder getting through (s;
# agents.door_turns.DoorParams.grant_max_s, 10 s for every crowd). The holder then asks again, last in the queue.
# 4 s was tried (crowd_log.md, "Where the doorway's time goes"): on the Intel device the doorway was level with either
# target generator, the home ahead with diffusion targets only, the held-out door scenes level; it stays 10 s.
DOOR_GRANT_MAX_S = 10.0
# A grant that ends sooner when its holder does not come on (agents.door_turns.DoorParams.grant_stall_s: not
# 0.3 m closer to the door within this many seconds while someone else asks for the door; 0: off, as for the
# kinematic crowds): DOOR_GRANT_STALL_S for AMP pedestrians with social-force or ORCA targets (off: level on the AMD
# VM, behind on the Intel device), DIFFUSION_DOOR_GRANT_STALL_S with diffusion targets (3 s since 2026-12-07: ahead in
# the doorway and the home on both CPUs, +5.8 / +2.2 successes per run on the AMD VM and +2.0 / +4.8 on the Intel
# device, seeds 0-7; the held-out door scenes level; crowd_log.md, "Where the doorway's time goes").
DOOR_GRANT_STALL_S = 0.0
DIFFUSION_DOOR_GRANT_STALL_S = 3.0
# Door turns find the doors of a path with navzoo.envs.doors.path_doors, which checks for jambs on both sides at the
# path's narrowest point. A path that enters a door slantwise has that point up to 0.2 m off the jamb line, and the
# door is missed for that path (the doorway: 11 of 60 sampled paths; the bottleneck 12, the cluttered room 17, the
# home 6; docs/crowd_log.md "Doors that paths enter slantwise"). DOOR_JAMB_SEARCH > 0 looks for the jambs up to that
# far along the door's axis (path_doors' jamb_search). An option, off until measured on eight seeds of both scene sets.
DOOR_JAMB_SEARCH = 0.0
# DOOR_RUN_SCAN: when a path's narrowest point in a narrow stretch has no jambs on both sides (or gives no door axis:
# a path that hugs a jamb's corner on its way in has its narrowest point at the corner, outside the door), the
# stretch's other points are tried, narrowest first (path_doors' run_scan). In the doorway, 6 of the 29 paths planned
# through its door in 100 s of seed 0 got no door turn, and those people walked into the door against the queue
# (docs/crowd_log.md, "Doors missed at the jamb's corner"). DIFFUSION_DOOR_RUN_SCAN with diffusion targets (on since
# 2026-12-07: the doorway ahead on both CPUs, +10.0 / +6.0 successes per run on the Intel device / AMD VM, seeds 0-7, the
# home and the held-out door scenes level), DOOR_RUN_SCAN with the other target generators (off: with social-force
# targets level on the Intel device, more falls).
DOOR_RUN_SCAN = False
DIFFUSION_DOOR_RUN_SCAN = True
# Plans are sampled from each person's recent past, so a body that has stopped (a yield, a push, a jam at a door)
# gets slow plans; its target then creeps (the rollout toward a slow plan, slowed further by a jamb the body stands
# next to) and the controller does not walk toward a target that slow, least of all one behind it (a lone body
# follows a straight target at 0.3 m/s only 1 m in 11 s when the target starts 135 degrees off its heading, and from
# 0.45 m/s on goes 1 m within 4 s whatever the bearing: docs/pedestrians_log.md, "Slow targets").
# Bodies stood this way for tens of seconds beside door jambs with the door free. With STALL_WARP_S > 0, a person
# whose body has stood (planar speed under STALL_SPEED) for that long gets a rollout that walks its plan's path at
# no less than STALL_PACE x its preferred speed (the plan's time runs faster, by at most STALL_MAX_WARP; the
# plan's own pace is measured over its next STALL_PLAN_S), where the plan moves at all (STALL_MIN_PLAN_SPEED:
# plans slower than that are a wait, and stay one). 0 = off. Off: 1.0 s measured level over seeds 0-5 of the
# following protocol with diffusion targets (device machine; 0.752 per limit either way, the corridor +11 points, the
# home -10; over eight seeds of the ten held-out scenes +1.7 +- 1.2 points per limit, within noise;
# docs/crowd_log.md, "Bodies that stand at doors").
STALL_WARP_S = 0.0
STALL_SPEED = 0.15  # m/s
STALL_PACE = 0.6
STALL_MIN_PLAN_SPEED = 0.05  # m/s
STALL_PLAN_S = 2.0  # s
STALL_MAX_WARP = 4.0
# Not within STALL_NARROW_REACH (m) of a stretch of the person's A* path too narrow for the full wall margin (the
# graded wall margin's narrow points: doors under about 1.0 m); 0 = everywhere.
STALL_NARROW_REACH = 0.0
# Not where another person (or robot) stands within STALL_CLEAR_M (m, centre to centre) ahead of the person, within
# STALL_CLEAR_DEG of the direction to its plan's point STALL_PLAN_S ahead: a body that stands behind someone waits
# for them, and a faster target would walk it into them. 0 = everywhere.
STALL_CLEAR_M = 0.0
STALL_CLEAR_DEG = 60.0
# Diffusion targets hand over to the A* path near narrow doors: within DIFFUSION_DOOR_REACH (m) of a stretch of a
# person's A* path too narrow for the full wall margin (the doors of the keep-right rule: under about 1.0 m), the
# target rollout heads for the person's next A* waypoint at its preferred speed, as social-force targets do, instead
# of along the sampled plan (which, for a body that has stood, starts slowly). Door turns shape it there as they shape
# social-force targets. 0 = off. Off: at 1.5 m ahead in the doorway on the AMD VM and behind on the Intel device
# (seeds 0-7; successes per run +4.9 +- 3.0 and -5.2 +- 4.7), level in the home, behind in all four held-out scenes
# with such doors (docs/crowd_log.md, "Diffusion targets handed to the A* path near narrow doors").
DIFFUSION_DOOR_REACH = 0.0


# A physics body is pushed and swerves: it can pass a waypoint of its A* path farther than the
# tolerance and come within it of a later one. Following the strict order would then send its target
# back to the missed waypoint at every replan while the body, turning slowly, never reaches it
# (station: a pedestrian stood 40 s next to its path this way). Physics pedestrians therefore move on
# past any of the next WAYPOINT_LOOKAHEAD waypoints they come within the tolerance of.
WAYPOINT_LOOKAHEAD = 4
# A body that swerves around a group can pass its next waypoints by more than the tolerance, all of
# them: its target then heads back to a waypoint behind it (circle crossing: a person 1.2 m from its goal
# kept a waypoint at the circle's centre, 3 m behind it, and went back and forth for 20 s). With
# SKIP_PASSED_WAYPOINTS, physics pedestrians also move past every waypoint they are beyond, along the
# path, while they can see the next one (advance_waypoint's ``visible``). Off: over 4 seeds of the
# following protocol (device machine, docs/pedestrians_log.md "Skipping passed waypoints") success moved by
# -6.8 to +9.0 points per seed, pooled 0.573 -> 0.579 with social-force targets and 0.659 -> 0.653 with
# diffusion targets, with a few more falls: within what the seeds scatter. Held out, with the defaults of
# 2026-12-06 (device, seeds 0-7, docs/crowd_log.md "Skipping passed waypoints, held out"): level as well.
SKIP_PASSED_WAYPOINTS = False
# A body that comes within the tolerance of a waypoint in a door while still before the jamb (0.6 m reach, at an
# angle) moves on to the waypoint beyond the door, hidden from it behind the wall: its targets then pull it along the
# wall into the jamb (home trace; crowd_log.md "Through a door without crossing it; waypoints beyond a door moved on
# to out of sight": level in the doorway and the home with fewer agent contacts, the lobby behind on every seed). With
# WAYPOINT_ADVANCE_IN_SIGHT, physics pedestrians move on only to a waypoint they can see (a line of sight on the
# planning grid from the nearest free point, advance_waypoint's ``in_sight``); otherwise they keep the last one in
# sight, the one in the door. An option, off.
WAYPOINT_ADVANCE_IN_SIGHT = False
# How the social-force rollouts keep PLAN_MARGIN between people. False: on the radius, which also makes the
# social repulsion exp(2 x 0.1 / 0.3) = 1.95 times stronger at every distance; in the lobby (15 people,
# 60 s) the targets then move at 0.59 m/s where the kinematic social-force crowd walks at 0.87
# (scripts/amp_pace_probe.py). True: the bare radii for the social repulsion and a short-range push that
# holds the margin (SocialForceParams.keep_apart). Off: over 4 seeds of the following protocol (device
# machine, docs/pedestrians_log.md "Keeping people apart without slowing the crowd") success went 0.573 -> 0.611
# with social-force targets but falls 0.012 -> 0.039 and agent contacts 0.085 -> 0.218, and 0.659 -> 0.544
# with diffusion targets.
KEEP_APART = False
# m added to each person's radius when ORCA walks the rollouts toward diffusion plans (NavConfig.diffusion_walker
# "orca" or "hybrid"): ORCA lets two discs pass just touching, so this is half the room two passing bodies keep.
ORCA_ROLLOUT_MARGIN = PLAN_MARGIN
# PASS_MARGIN = True keeps PLAN_MARGIN only between people who pass one another: the rollouts use the bare
# radii, and a pair's contact distance grows by 2 x PLAN_MARGIN x min(1, relative speed / PASS_SPEED)
# (SocialForceParams.pass_margin). People walking in one direction together (a corridor's lane, a queue)
# keep close as kinematic ones do; people meeting or crossing keep the room their limbs need. On since
# 2026-12-01 (docs/pedestrians_log.md "A margin for passing only"): following protocol, social-force targets,
# success per limit 0.573 -> 0.621 over seeds 0-3 (higher in all four) and 0.537 -> 0.599 over seeds 4-5,
# falls 0.012 -> 0.014 and agent contacts 0.085 -> 0.127 of trips; diffusion targets 0.680 -> 0.696
# (seeds 0-3) and 0.693 -> 0.714 (4-5), agent contacts 0.049 -> 0.087 and 0.036 -> 0.059. False: the
# margin on the radius of every pair. KEEP_APART = True overrides both.
PASS_MARGIN = True
PASS_SPEED = 1.0  # m/s
# The wall potential strength of the social-force target rollouts (SocialForceParams.A_wall, the kinematic
# crowd's default 1.0), where NavConfig.amp_wall_strength is None. Kinematic crowds reach 15 % more goals over 18
# scenes with 0.3 (docs/crowd_models.md, "Softer walls"); the physics rows gain 4-13 points per limit with it and
# touch walls on about twice as many trips (docs/pedestrians_log.md, "Softer walls for the target rollouts").
SFM_A_WALL = 1.0
# Softer walls only where people meet: with SFM_WALL_NEAR_RANGE > 0 (m), a person of the rollouts who has another
# within that distance feels the walls with SFM_A_WALL_NEAR instead (SocialForceParams.wall_near_range). An option,
# off (docs/pedestrians_log.md, "Softer walls only where people meet"). With SFM_WALL_NEAR_RAMP > 0 (m) the softer walls
# phase in linearly from SFM_WALL_NEAR_RANGE + SFM_WALL_NEAR_RAMP down to SFM_WALL_NEAR_RANGE instead of switching
# (SocialForceParams.wall_near_ramp; 0 = the switch).
SFM_WALL_NEAR_RANGE = 0.0
SFM_A_WALL_NEAR = 0.3
SFM_WALL_NEAR_RAMP = 0.0
# Softer walls for the people whom the walls hold still: with SFM_WALL_STALL on, a person of the social-force rollouts
# who wants to walk (preferred speed above 0.3 m/s) but has gone slower than 0.3 of it for 1 s of the rollout's clock
# feels the walls with SFM_A_WALL_NEAR (NavConfig.amp_wall_near_strength) for the next 2 s of it (a StallSwitch of the
# diffusion crowd's hybrid walker, on the rollout's clock). In a gap a little wider than the body (the home's 0.8-0.9 m
# doors, the cluttered room's 0.6-0.8 m gaps) the walls' push on both sides balances the pull of the plan, so the
# rollout, and with it the target, stands while the plan walks on: a person alone stands there for tens of seconds
# (docs/crowd_log.md, "One person alone"). An option, off.
SFM_WALL_STALL = False
# The keep-right gain of the social-force target rollouts (SocialForceParams.side_bias): a share of the push from
# someone ahead that turns a person to its right, so that people meeting head-on pass left shoulder to left shoulder.
# 0.4 since 2026-12-06 (before: 0.1, the kinematic crowd's own): lanes form earlier in counterflow, and success rose by
# 4.3 points per limit with diffusion targets and 3.6 with social-force targets on the protocol scenes, at more trips
# off their path (docs/crowd_log.md, "Keeping right"). NavConfig.amp_side_bias overrides.
SFM_SIDE_BIAS = 0.4
# ... except near narrow doors: within SFM_SIDE_NARROW_REACH (m) of a narrow point of its A* path (a stretch too
# narrow for the default wall margin WALL_PLAN_MARGIN, whatever NavConfig.amp_wall_margin is: the graded wall margin's
# narrow points at that margin, doors under about 1.0 m), a person of the
# rollouts keeps right with SFM_SIDE_BIAS_NARROW instead. In a door too narrow to pass in, a sidestep only takes
# people into the jambs (the home, whose people meet in its 0.9 m doors, lost with the gain 0.4 everywhere: 0.357 ->
# 0.230 per limit with diffusion targets; 0.344 with this rule). Default since 2026-12-06 (0 = off): success per limit
# +1.1 +- 0.5 points with diffusion targets (8 seeds), +1.0 +- 0.8 held out, level with social-force targets, which
# fall and touch walls and people less (docs/crowd_log.md, "Keeping right except near narrow doors").
# NavConfig.amp_side_narrow_reach / amp_side_bias_narrow override.
SFM_SIDE_NARROW_REACH = 1.5
SFM_SIDE_BIAS_NARROW = 0.1
# Bodies touch obstacles mostly at exposed corners (door jambs, shelf ends: 65 % of the wall-contact events of
# social-force + AMP in six protocol scenes, seed 0), with the pelvis 0.29 m from the corner while its target keeps
# 0.45 m: a body following a target round a corner cuts it (scripts/amp_wall_contact_links.py). CORNER_MARGIN > 0 (m)
# lets those corners push the target rollouts sideways as walls do at that much more margin (corner_steer), so
# targets swing wide and centre in doors without being braked. 0 = off; NavConfig.amp_corner_margin overrides.
# 0.15 m: wall-contact trips 8.8 -> 4.0 %, success 0.701 -> 0.620 (VM, seed 0; docs/pedestrians_log.md, "Corner steering
# in the target rollouts"), the same trade as a wider wall margin.
CORNER_MARGIN = 0.0
CORNER_REACH = 1.0  # m: corners further than this from a rollout disc are not looked at
# The controller steers toward the next 5 s of its target (10 points), so round a corner it heads for points
# behind the corner and cuts it. SIGHT_CLEARANCE > 0 (m) shows it only the points it can see: a target point
# whose straight line from the pelvis passes closer to an obstacle than SIGHT_CLEARANCE (or than the pelvis and
# the point themselves are, when nearer), and every later one, are replaced by the straight continuation of the
# points before it (sight_waypoints). 0 = off; NavConfig.amp_sight_clearance overrides.
SIGHT_CLEARANCE = 0.0
SIGHT_SLACK = 0.02  # m: how much closer than pelvis and point a line must pass to count as hidden
SIGHT_REACH = 0.0  # m: only points this close to the pelvis can be hidden (later ones follow the first hidden); 0 = all


# Social force turns a disc toward a new direction as fast as its relaxation allows: at a trip's
# start it can head back the other way within a second, faster than a walking body turns, and the
# body falls behind its target. The target rollouts of rule-based crowds therefore turn a moving
# disc's heading by at most TARGET_TURN_RATE (rad/s) and slow it down in sharp turns (limit_turn);
# 0 = off. 2 rad/s measured best (scripts/amp_target_ablation.py, docs/pedestrians.md: following
# success 0.33 -> 0.40 over two seeds; 1, 3 and 4 rad/s no gain). Diffusion-planned targets are left
# as they were measured (not ablated yet).
TARGET_TURN_RATE = 2.0
# Social force speeds a disc up to its preferred speed within about a second (relaxation 0.5 s); a body
# that stood or slowed (a yield, a new goal behind it, a push) speeds up more slowly and falls behind its
# target in time while it stays on the target's path. With TARGET_ACCEL > 0 the target rollouts of
# rule-based crowds raise a disc's speed by at most that much (m/s^2) from the body's speed at the replan
# (limit_accel; slowing down is not limited); DIFFUSION_TARGET_ACCEL does the same for the rollouts toward
# diffusion plans. Off: 0.8 m/s^2 cut falls with social-force targets (0.049 -> 0.028 of trips) but left
# success within the seed spread (0.423 -> 0.431 over 3 seeds; diffusion 0.527 -> 0.543), docs/pedestrians.md.
TARGET_ACCEL = 0.0
DIFFUSION_TARGET_ACCEL = 0.0
# The social-force (and ORCA) rollouts of physics pedestrians may go as fast as human_max_speed (2 m/s)
# when forces push them. With TARGET_SPEED_CAP > 0 they go at most that times the person's preferred speed,
# as DIFFUSION_SPEED_CAP holds the rollouts toward diffusion plans; 0 = off (human_max_speed only). Off: 1.0
# left per-limit success level over 4 seeds (0.573 -> 0.575; docs/pedestrians_log.md "Pacing social-force targets").
TARGET_SPEED_CAP = 0.0
# A physics pedestrian that yields in a bottleneck can hold its wait until the person it yielded to has
# passed it, for at most this many more seconds (navzoo.agents.yielding, YieldParams.hold_max; 0 = off).
# Off: 6 s measured worse on the following protocol (success 0.406 -> 0.353 at seed 0, 0.395 -> 0.338 at
# seed 1, more timeouts in the open scenes, the home and doorway no better; scripts/device_yield_hold_ablation.sh,
# docs/pedestrians.md).
YIELD_HOLD_S = 0.0


def limit_turn(v_prev: np.ndarray, v_new: np.ndarray, max_angle: float, moving: float = 0.1,
               min_speed: float = 0.2) -> np.ndarray:
    """Velocities ``v_new`` (N, 2) whose heading turned at most ``max_angle`` (rad) from ``v_prev``.

    Only discs moving faster than ``moving`` (m/s) before and after are limited; a limited one keeps
    ``v_new``'s speed times (1 + cos a) / 2 for the wanted turn a (a U-turn slows it to ``min_speed``).
    """
    sp_prev = np.linalg.norm(v_prev, axis=1)
    sp_new = np.linalg.norm(v_new, axis=1)
    h_prev = np.arctan2(v_prev[:, 1], v_prev[:, 0])
    want = np.arctan2(v_new[:, 1], v_new[:, 0]) - h_prev
    want = (want + np.pi) % (2.0 * np.pi) - np.pi
    limit = (sp_prev > moving) & (sp_new > moving) & (np.abs(want) > max_angle)
    if not limit.any():
        return v_new
    out = v_new.copy()
    h = h_prev[limit] + np.sign(want[limit]) * max_angle
    speed = np.maximum(min_speed, sp_new[limit] * 0.5 * (1.0 + np.cos(want[limit])))
    out[limit] = speed[:, None] * np.stack([np.cos(h), np.sin(h)], axis=1)
    return out


def limit_accel(v_prev: np.ndarray, v_new: np.ndarray, max_dv: float) -> np.ndarray:
    """Velocities ``v_new`` (N, 2) whose speed rose by at most ``max_dv`` (m/s) above ``v_prev``'s; the
    direction is ``v_new``'s, and slowing down is not limited."""
    sp_prev = np.linalg.norm(v_prev, axis=1)
    sp_new = np.linalg.norm(v_new, axis=1)
    cap = sp_prev + max_dv
    fast = sp_new > cap
    if not fast.any():
        return v_new
    out = v_new.copy()
    out[fast] *= (cap[fast] / sp_new[fast])[:, None]
    return out


def stall_warp(plan_speed: np.ndarray, v_pref: np.ndarray, pace: float | None = None,
               min_speed: float | None = None, max_warp: float | None = None) -> np.ndarray:
    """How much faster than their plans' own pace stalled people walk their plans (STALL_WARP_S): the factor that
    brings a plan's pace ``plan_speed`` (m/s) up to ``pace`` x ``v_pref``, between 1 and ``max_warp``; 1 where the
    plan is slower than ``min_speed`` (a wait) or already as fast. Defaults: the module's STALL_* constants."""
    pace = STALL_PACE if pace is None else pace
    min_speed = STALL_MIN_PLAN_SPEED if min_speed is None else min_speed
    max_warp = STALL_MAX_WARP if max_warp is None else max_warp
    plan_speed = np.asarray(plan_speed, dtype=float)
    want = pace * np.asarray(v_pref, dtype=float) / np.maximum(plan_speed, 1e-9)
    return np.where(plan_speed > min_speed, np.clip(want, 1.0, max_warp), 1.0)


def near_narrow(points: list[np.ndarray], pos: np.ndarray, reach: float) -> np.ndarray:
    """(P,) whether each person's position ``pos`` (P, 2) lies within ``reach`` m of one of its narrow points
    (``points[j]``: (K_j, 2), :func:`narrow_points`; none: False)."""
    return np.array([len(pts) > 0 and bool((np.linalg.norm(np.asarray(pts) - p, axis=1) < reach).any())
                     for pts, p in zip(points, pos, strict=True)], dtype=bool)


def blocked_ahead(pos: np.ndarray, heading_to: np.ndarray, others: np.ndarray, reach: float,
                  half_angle_deg: float) -> np.ndarray:
    """(P,) whether someone of ``others`` (M, 2) stands within ``reach`` m of each position ``pos`` (P, 2), inside
    ``half_angle_deg`` of the direction ``heading_to`` (P, 2, any length; zero length: nobody counts as ahead).
    Points that coincide with the person itself (itself among ``others``) are skipped."""
    pos = np.asarray(pos, dtype=float).reshape(-1, 2)
    d = np.asarray(heading_to, dtype=float).reshape(-1, 2)
    others = np.asarray(others, dtype=float).reshape(-1, 2)
    if not len(pos) or not len(others):
        return np.zeros(len(pos), dtype=bool)
    rel = others[None] - pos[:, None]  # (P, M, 2)
    dist = np.linalg.norm(rel, axis=2)
    norm = np.linalg.norm(d, axis=1)
    cos = np.einsum("pmk,pk->pm", rel, d) / np.maximum(dist * norm[:, None], 1e-12)
    ahead = (dist > 1e-6) & (dist < reach) & (cos >= np.cos(np.radians(half_angle_deg))) & (norm[:, None] > 1e-9)
    return ahead.any(axis=1)


def narrow_points(path: np.ndarray, clearance, below: float, spacing: float = 0.05) -> tuple[np.ndarray, np.ndarray]:
    """Points of the polyline ``path`` (L, 2), every ``spacing`` m, whose clearance is below ``below``.

    ``clearance`` maps points (M, 2) to their distance from the nearest wall (``Scene.clearance``).
    Returns the points (K, 2) and their clearances (K,); K = 0 where the whole path is wider.
    """
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(path) < 2:
        pts = path
    else:
        seg = np.diff(path, axis=0)
        length = np.linalg.norm(seg, axis=1)
        pts = [path[:1]]
        for a, d, n in zip(path[:-1], seg, np.maximum(1, np.ceil(length / spacing)).astype(int), strict=True):
            pts.append(a + d * (np.arange(1, n + 1) / n)[:, None])
        pts = np.concatenate(pts)
    c = np.asarray(clearance(pts), dtype=float) if len(pts) else np.zeros(0)
    keep = c < below
    return pts[keep], c[keep]


def graded_wall_radius(pos: np.ndarray, radius: np.ndarray, margin: float, narrow: list[tuple[np.ndarray, np.ndarray]],
                       slack: float = DOOR_SLACK, reach: float = PASSAGE_REACH) -> np.ndarray:
    """Wall radius (H,) of each rollout disc: ``radius + margin``, the margin cut to leave ``slack`` on
    each side of the narrowest stretch of the disc's path within ``reach`` of it.

    Args:
        pos: (H, 2) disc positions.
        radius: (H,) bare radii.
        margin: the wall margin where there is room.
        narrow: per disc, the narrow points of its path and their clearances (:func:`narrow_points`).
    """
    cut = np.full(len(radius), float(margin))
    for j, (pts, c) in enumerate(narrow):
        if len(pts):
            near = np.linalg.norm(pts - pos[j], axis=1) < reach
            if near.any():
                cut[j] = min(margin, max(0.0, float(c[near].min()) - float(radius[j]) - slack))
    return np.asarray(radius, dtype=float) + cut


def corner_steer(pos: np.ndarray, pref: np.ndarray, corners: np.ndarray, wall_radius: np.ndarray, margin: float,
                 a_wall: float, b_wall: float, tau: float, reach: float = CORNER_REACH) -> np.ndarray:
    """Preferred velocities (H, 2) with the sideways push of exposed ``corners`` (K, 2) added.

    Each corner within ``reach`` of a disc pushes it, away from the corner, with what the social force's wall
    potential adds when the disc's wall radius grows by ``margin``:
    ``(a_wall / b_wall) * (exp((r + margin - d) / b_wall) - exp((r - d) / b_wall))`` at distance ``d``; only the
    part across the disc's preferred direction is kept, and it enters the preferred velocity times ``tau``, as the
    social force's driving term ``(pref - v) / tau`` reads it; the result keeps the preferred speed (a corner turns
    the preferred direction: it neither brakes nor hurries). Discs standing still (zero ``pref``) are left
    alone; ``margin`` 0 changes nothing. Between two jambs the pushes cancel on the door's middle line and point to
    it elsewhere."""
    pref = np.asarray(pref, dtype=float)
    if margin <= 0.0 or not len(corners) or not len(pos):
        return pref
    rel = pos[:, None, :] - corners[None, :, :]  # (H, K, 2) from corner to disc
    d = np.linalg.norm(rel, axis=2)
    r = np.asarray(wall_radius, dtype=float)[:, None]
    near = (d < reach) & (d > 1e-9)
    e1 = np.exp(np.minimum((r + margin - d) / b_wall, 50.0))
    e0 = np.exp(np.minimum((r - d) / b_wall, 50.0))
    mag = np.where(near, (a_wall / b_wall) * (e1 - e0), 0.0)
    push = (mag / np.maximum(d, 1e-9))[:, :, None] * rel  # (H, K, 2)
    force = push.sum(axis=1)
    speed = np.linalg.norm(pref, axis=1, keepdims=True)
    u = pref / np.maximum(speed, 1e-9)
    side = force - np.sum(force * u, axis=1, keepdims=True) * u
    turned = pref + tau * side
    turned *= speed / np.maximum(np.linalg.norm(turned, axis=1, keepdims=True), 1e-9)  # the same pace
    return np.where(speed > 1e-9, turned, pref)


def sight_waypoints(pos: np.ndarray, wps: np.ndarray, segments: np.ndarray, clearance: float,
                    slack: float | None = None, reach: float | None = None) -> np.ndarray:
    """The target points (H, K, 2) that bodies at ``pos`` (H, 2) can see, the hidden ones continued straight.

    Point ``j`` of a body is hidden when the straight line from ``pos`` to it passes closer to a wall
    ``segment`` than ``min(clearance, d(pos), d(point)) - slack`` (``d``: distance to the nearest segment), so a
    body walking along a wall still sees the points along it. From the first hidden point ``f >= 1`` on, the
    points are replaced by ``wps[f-1] + m * step`` (m = 1, 2, ...), ``step`` the last visible stretch
    (``wps[f-1] - wps[f-2]``, or ``wps[0] - pos`` for ``f = 1``): the body walks on past the corner before it
    turns. When the first point is hidden, all are left as they are (nothing to continue from); ``clearance`` 0
    changes nothing."""
    wps = np.asarray(wps, dtype=float)
    if clearance <= 0.0 or not len(segments) or not len(pos):
        return wps
    slack = SIGHT_SLACK if slack is None else slack
    reach = SIGHT_REACH if reach is None else reach
    K = wps.shape[1]
    seg = np.asarray(segments, dtype=float)
    s_lo, s_hi = seg.min(axis=1), seg.max(axis=1)  # (S, 2) bounding boxes of the segments
    out = wps.copy()
    for i in range(len(pos)):
        pts = np.concatenate([pos[i:i + 1], wps[i]])
        lo, hi = pts.min(axis=0) - clearance, pts.max(axis=0) + clearance
        near = seg[np.all((s_hi >= lo) & (s_lo <= hi), axis=1)]  # only segments a line could pass that close to
        if not len(near):
            continue
        chords = np.stack([np.repeat(pos[i:i + 1], K, axis=0), wps[i]], axis=1)  # (K, 2, 2)
        d_chord = segment_segment_distance(chords, near).min(axis=1)
        d_ends = segment_point_distance(near, pts).min(axis=1)  # pelvis, then the K points
        hidden = d_chord < np.minimum(np.minimum(clearance, d_ends[0]), d_ends[1:]) - slack
        if reach > 0.0:
            hidden &= np.linalg.norm(wps[i] - pos[i], axis=1) <= reach
        if hidden[0] or not hidden.any():
            continue
        f = int(np.argmax(hidden))
        step = wps[i, f - 1] - (wps[i, f - 2] if f >= 2 else pos[i])
        out[i, f:] = wps[i, f - 1] + step * np.arange(1, K - f + 1)[:, None]
    return out


def passed(path: np.ndarray, k: int, pos: np.ndarray) -> bool:
    """Whether ``pos`` lies beyond waypoint ``k`` of ``path`` along the path's direction there (the
    direction from waypoint ``k - 1``, or ``k`` itself for the first, to waypoint ``k + 1``)."""
    d = path[min(k + 1, len(path) - 1)] - path[max(k - 1, 0)]
    return bool(np.dot(pos - path[k], d) > 0.0)


def advance_waypoint(path: np.ndarray, k: int, pos: np.ndarray, tol: float, lookahead: int = 0,
                     visible: Callable[[np.ndarray, np.ndarray], bool] | None = None,
                     in_sight: Callable[[np.ndarray, np.ndarray], bool] | None = None) -> int:
    """Index of the waypoint to head for next: past the farthest of ``path[k .. k + lookahead]``
    within ``tol`` of ``pos``, then past every following one within ``tol`` (``lookahead=0``: the
    strict order of kinematic pedestrians). With ``visible`` (and ``lookahead > 0``), also past every
    waypoint that ``pos`` has :func:`passed` while ``visible(pos, next waypoint)`` holds (a line of sight
    on the planning grid). With ``in_sight``, the index moves on only as far as the last waypoint for which
    ``in_sight(pos, waypoint)`` holds (it never goes back below ``k``). Never beyond the path's last point."""
    k0 = k
    k = _advance_waypoint(path, k, pos, tol, lookahead, visible)
    if in_sight is not None:
        while k > k0 and not in_sight(pos, path[k]):
            k -= 1
    return k


def _advance_waypoint(path: np.ndarray, k: int, pos: np.ndarray, tol: float, lookahead: int,
                      visible: Callable[[np.ndarray, np.ndarray], bool] | None) -> int:
    last = len(path) - 1
    if lookahead > 0 and k < last:
        end = min(last, k + lookahead)
        near = np.flatnonzero(np.linalg.norm(path[k:end + 1] - pos, axis=1) < tol)
        if near.size:
            k = min(last, k + int(near[-1]) + 1)
    while k < last and (np.linalg.norm(path[k] - pos) < tol or (
            lookahead > 0 and visible is not None and passed(path, k, pos) and visible(pos, path[k + 1]))):
        k += 1
    return k


def progress_index(k_prev: np.ndarray, k_time: np.ndarray, paths: np.ndarray, pos: np.ndarray, lag: int,
                   k_min: np.ndarray | None = None) -> np.ndarray:
    """Current target index of each body: one step further than before, as time goes, but at most
    ``lag`` steps ahead of the point of its path nearest to the body (searched up to ``k_time``, and from ``k_min``
    on where given: the index the current path starts at, when earlier indices hold an earlier path).

    Args:
        k_prev: (H,) previous indices.
        k_time: (H,) the time-based indices (control steps since each plan).
        paths: (H, L, 2) target paths, one point per control step.
        pos: (H, 2) the bodies' positions.
        lag: the largest lead (control steps) of the target over the body's projection.
        k_min: (H,) the first index searched (default 0).
    """
    L = paths.shape[1]
    k_time = np.minimum(k_time, L - 1)
    d = np.linalg.norm(paths - pos[:, None, :], axis=2)
    j = np.arange(L)[None, :]
    searched = j <= k_time[:, None]
    if k_min is not None:
        searched &= j >= np.asarray(k_min)[:, None]
    d = np.where(searched, d, np.inf)
    k_near = np.argmin(d, axis=1)
    return np.minimum(np.minimum(k_prev + 1, k_time), k_near + lag)


class AmpHumans:
    """The physics pedestrians of one :class:`~navzoo.envs.nav_env.NavEnv`."""

    def __init__(self, env: NavEnv) -> None:
        self.env = env
        self.client = env.client
        self.n = env.n_humans
        self.control_steps = int(round(env.config.dt * CONTROL_HZ))
        self.replan_steps = max(1, int(round(env.config.amp_replan_seconds * CONTROL_HZ)))
        self.bodies = PhysicsHumanoids(self.client, self.n, physics_hz=PHYSICS_HZ, control_hz=CONTROL_HZ,
                                       pd_mode="motor")
        self.ids = list(self.bodies.ids)
        # The humanoids stand on their own box ground (full contact manifolds, see PhysicsHumanoids);
        # the scene's plane and the robots ignore that box, the humanoids ignore the plane.
        if env.bodies.ground_id is not None:
            self.bodies.exclude_collisions(env.bodies.ground_id)
        p.changeVisualShape(self.bodies.ground_id, -1, rgbaColor=[0, 0, 0, 0], physicsClientId=self.client)  # the scene's floor shows
        for r in env.robots.ids:
            for link in range(-1, p.getNumJoints(r, physicsClientId=self.client)):
                p.setCollisionFilterPair(r, self.bodies.ground_id, link, -1, 0, physicsClientId=self.client)
        self.horizon = env.config.amp_replan_seconds + N_WAYPOINTS * WAYPOINT_DT + 0.5
        self.path_len = int(round(self.horizon * CONTROL_HZ)) + 1
        self.stride = int(round(WAYPOINT_DT * CONTROL_HZ))
        self.paths = np.zeros((self.n, self.path_len, 2))
        self.t = 0  # control steps since reset
        self.plan_t = np.zeros(self.n, dtype=int)  # control step of each person's last plan
        self.extra_replan = -1  # control step of the replan that START_REPLAN_S asks for (-1: none)
        self.starting = np.zeros(self.n, dtype=bool)  # the current plan is the first of a trip (START_LAG)
        self._goals_seen = np.zeros(self.n, dtype=int)
        self.k_prog = np.zeros(self.n, dtype=int)  # index of each person's current target point
        self.lag_all = env.diffusion is not None or LAG_LIMIT_RULES  # every target held to LAG_LIMIT_S (progress_index)
        self.fallen = np.zeros(self.n, dtype=bool)
        # each pedestrian's touched pedestrians' and robots' PyBullet body ids in the last physics step (contacts())
        self.touched: list[set[int]] = [set() for _ in range(self.n)]
        self.still_s = np.zeros(self.n)  # how long each body has stood (speed < STALL_SPEED), for STALL_WARP_S
        self.stance = np.zeros(self.n)  # running mean of foot_split (STANCE_TAU_S), updated by task_reward
        wall = env.config.amp_wall_strength
        self.a_wall = float(SFM_A_WALL if wall is None else wall)  # A_wall of the target rollouts
        cfg = env.config
        # the SocialForceParams fields that every parameter set of the rollouts takes: NavConfig's, else the constant
        given = {"wall_near_range": (cfg.amp_wall_near_range, SFM_WALL_NEAR_RANGE),
                 "A_wall_near": (cfg.amp_wall_near_strength, SFM_A_WALL_NEAR),
                 "wall_near_ramp": (cfg.amp_wall_near_ramp, SFM_WALL_NEAR_RAMP),
                 "side_bias": (cfg.amp_side_bias, SFM_SIDE_BIAS)}
        self.sfm_fields = {"A_wall": self.a_wall, **{k: float(const if v is None else v) for k, (v, const) in given.items()}}
        self.sfm = SocialForceParams(**self.sfm_fields)
        self.sfm_keep = SocialForceParams(keep_apart=PLAN_MARGIN, **self.sfm_fields)
        # the keep-right gain near narrow doors (NavConfig.amp_side_narrow_reach / amp_side_bias_narrow)
        reach, narrow_bias = cfg.amp_side_narrow_reach, cfg.amp_side_bias_narrow
        self.side_narrow_reach = float(SFM_SIDE_NARROW_REACH if reach is None else reach)
        self.side_bias_narrow = float(SFM_SIDE_BIAS_NARROW if narrow_bias is None else narrow_bias)
        # margin on the radius that walls see in the social-force rollouts (NavConfig.amp_wall_margin)
        self.wall_margin = float(WALL_PLAN_MARGIN if cfg.amp_wall_margin is None else cfg.amp_wall_margin)
        # extra margin that exposed corners keep, as a sideways push (NavConfig.amp_corner_margin; CORNER_MARGIN)
        self.corner_margin = float(CORNER_MARGIN if cfg.amp_corner_margin is None else cfg.amp_corner_margin)
        self.corners = env.scene.exposed_corners() if self.corner_margin > 0.0 else np.zeros((0, 2))
        # target points hidden behind obstacles are shown continued straight (NavConfig.amp_sight_clearance)
        self.sight_clearance = float(SIGHT_CLEARANCE if cfg.amp_sight_clearance is None else cfg.amp_sight_clearance)
        model = env.config.crowd_model
        self.orca = OrcaParams(right_bias=0.0, one_step_safety=False) if model == "orca_rvo2" else OrcaParams()
        self._index = {b: j for j, b in enumerate(self.ids)}
        # per wall margin, per person: (the path, its narrow points), recomputed when the path changes (narrow_passages)
        self._narrow: dict[float, list[tuple[object, tuple[np.ndarray, np.ndarray]]]] = {}

    # ------------------------------------------------------------------ reset / state
    def reset(self, pos: np.ndarray, yaw: np.ndarray) -> None:
        if self.n == 0:
            return
        self.bodies.set_state(self.bodies.standing_state(pos, yaw))
        self.t = 0
        self.fallen[:] = False
        self.still_s[:] = 0.0
        self.stance[:] = 0.0  # the standing start has its feet side by side
        self.extra_replan = -1
        self._goals_seen[:] = -1  # the first plan after a reset starts every person's first trip
        self.plan_all()

    def state(self) -> dict[str, np.ndarray]:
        return self.bodies.read_state()

    def planar(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Root position (H, 2), heading (H,), planar velocity (H, 2) and yaw rate (H,)."""
        s = self.state()
        return s["root_pos"][:, :2].copy(), heading(s["root_quat"]), s["root_lin_vel"][:, :2].copy(), \
            s["root_ang_vel"][:, 2].copy()

    # ------------------------------------------------------------------ targets
    def target_now(self) -> np.ndarray:
        """(H, 2) the current point of every target trajectory."""
        k = np.minimum(self.k_prog, self.path_len - 1)
        return self.paths[np.arange(self.n), k]

    def waypoints(self) -> np.ndarray:
        """(H, K, 2) the next K target points, ``WAYPOINT_DT`` apart."""
        k = self.k_prog[:, None] + self.stride * np.arange(1, N_WAYPOINTS + 1)[None, :]
        return np.take_along_axis(self.paths, np.minimum(k, self.path_len - 1)[..., None], axis=1)

    def plan_all(self, who: np.ndarray | None = None) -> None:
        """Roll the crowd model out from the bodies' actual states: new target trajectories for all, or only for
        the people of ``who`` (indices among the pedestrians; the rollout still moves everyone)."""
        env = self.env
        R, N = env.n_robots, env.n_total
        h = np.arange(R, N)
        pos, _, vel, _ = self.planar()
        goal = env.goal[h].copy()
        v_pref = np.where(env.arrived[h] | self.fallen | env.human_waiting_fallen, 0.0, env.v_pref[h])
        wp_index = env.wp_index[h].copy()
        paths = [env.paths[i] for i in h]
        rad = env.radius[h] + PLAN_MARGIN  # an articulated body swings beyond its disc: plan with room to spare
        # keep apart: the room is held by a short-range push, the social repulsion is that of the bare discs
        # pass margin: the room only between people who pass one another (KEEP_APART, an option, comes first)
        if KEEP_APART:
            sf_rad, sf_params = env.radius[h], self.sfm_keep
        elif PASS_MARGIN:
            sf_rad, sf_params = env.radius[h], SocialForceParams(pass_margin=PLAN_MARGIN, pass_speed=PASS_SPEED,
                                                                 **self.sfm_fields)
        else:
            sf_rad, sf_params = rad, self.sfm
        social = env.config.crowd_model in ("sfm", "diffusion")
        graded = GRADED_WALL_MARGIN and self.wall_margin > 0.0 and social
        side_narrow = social and self.side_narrow_reach > 0.0 and self.side_bias_narrow != sf_params.side_bias
        narrow = self.narrow_passages(paths, env.radius[h]) if graded else None
        door_astar = env.diffusion is not None and DIFFUSION_DOOR_REACH > 0.0  # diffusion targets hand over near doors
        if side_narrow or door_astar:
            # the doors of the default wall margin, whatever amp_wall_margin is: the same doors under about 1.0 m
            door_points = [pts for pts, _ in self.narrow_passages(paths, env.radius[h], WALL_PLAN_MARGIN)]
        if side_narrow:  # the rollouts' parameters near narrow doors: another keep-right gain
            sf_narrow = replace(sf_params, side_bias=self.side_bias_narrow)
        wall_stall = None
        if SFM_WALL_STALL and env.config.crowd_model in ("sfm", "diffusion"):  # softer walls for who they hold still
            from navzoo.agents.diffusion.crowd import StallSwitch

            wall_stall = StallSwitch(self.n)
        wall_rad = env.radius[h] + self.wall_margin
        visible = [env.waypoint_visibility(i) for i in h]
        in_sight = [env.waypoint_sight(i) for i in h]
        vmax = np.full(self.n, env.config.human_max_speed)
        if TARGET_SPEED_CAP > 0.0 and env.diffusion is None:
            vmax = np.where(v_pref > 0.0, np.minimum(vmax, v_pref * TARGET_SPEED_CAP), vmax)
        robots = np.flatnonzero(env.alive[:R]) if env.config.humans_see_robots else np.zeros(0, dtype=int)
        r_pos, r_vel, r_rad = env.pos[robots], env.vel[robots], env.radius[robots]
        tol = env.config.waypoint_tolerance
        steps = int(np.ceil(self.horizon / PLAN_DT))
        diffusion = env.diffusion
        # what walks the rollouts toward diffusion plans (NavConfig.diffusion_walker): social force, or ORCA with
        # short horizons ("orca"), or that ORCA with social force for the people it holds still ("hybrid", a
        # StallSwitch of its own in every rollout, on the rollout's clock)
        walker = env.config.diffusion_walker if diffusion is not None else "sfm"
        switch = None
        if walker != "sfm":
            from navzoo.agents.diffusion.crowd import ORCA_WALKER, StallSwitch

            switch = StallSwitch(self.n) if walker == "hybrid" else None
            orca_rad = env.radius[h] + ORCA_ROLLOUT_MARGIN
            orca_max = np.concatenate([vmax, np.full(robots.size, env.config.robot.max_speed)])
        if diffusion is not None:
            # The sampled plans give the direction and pace (as for kinematic diffusion pedestrians);
            # social force rolls them out from the bodies, so bodies keep their distance.
            diffusion.plan_now(env, who)
            cap = np.minimum(vmax, v_pref * DIFFUSION_SPEED_CAP)[:, None]
            stalled = np.flatnonzero((self.still_s >= STALL_WARP_S) & (v_pref > 0.0)) if STALL_WARP_S > 0 \
                else np.zeros(0, dtype=int)
            if stalled.size:  # how much faster than its own pace each stalled person walks its plan
                t0 = env.sim_time
                later = diffusion._plans_at(t0 + STALL_PLAN_S)[stalled, 0]  # each plan's point STALL_PLAN_S ahead
                plan_speed = np.linalg.norm(later - diffusion._plans_at(t0)[stalled, 0], axis=1) / STALL_PLAN_S
                warp = stall_warp(plan_speed, v_pref[stalled])
                if STALL_NARROW_REACH > 0 and narrow is not None:  # not where the path passes a narrow door
                    near = near_narrow([narrow[j][0] for j in stalled], pos[stalled], STALL_NARROW_REACH)
                    warp = np.where(near, 1.0, warp)
                if STALL_CLEAR_M > 0:  # not where someone stands just ahead, toward the plan
                    others = np.concatenate([pos, r_pos]) if len(r_pos) else pos
                    warp = np.where(blocked_ahead(pos[stalled], later - pos[stalled], others, STALL_CLEAR_M, STALL_CLEAR_DEG),
                                    1.0, warp)
        def toward_waypoints(who, pos):  # people `who` head for their next A* waypoint at their preferred speed
            for j in who:  # advance along the A* path, as the env does for physics pedestrians
                wp_index[j] = advance_waypoint(paths[j], int(wp_index[j]), pos[j], tol, WAYPOINT_LOOKAHEAD, visible[j],
                                               in_sight[j])
            wp = np.stack([paths[j][min(wp_index[j], len(paths[j]) - 1)] for j in who])
            return preferred_velocity(pos[who], wp, goal[who], v_pref[who])

        # DOOR_PASS_WAITERS: door holders feel no push from the people waiting for their door
        ignore = env.door_turns.holder_waiter_pairs() if DOOR_PASS_WAITERS and env.door_turns is not None else None
        if ignore is not None and not ignore.any():
            ignore = None

        def social_force(pos, vel, pref, o_pos, wall_rad, softer=False):  # one social-force step of the rollout
            def step(params):
                if softer:  # SFM_WALL_STALL's rows: the walls of the "near" strength
                    params = replace(params, A_wall=params.A_wall_near)
                return social_force_velocities(pos, vel, pref, sf_rad, vmax, PLAN_DT, params, env.segments,
                                               others_pos=o_pos, others_vel=r_vel, others_radius=r_rad,
                                               segment_groups=env.segment_groups, wall_radius=wall_rad, ignore=ignore)
            v = step(sf_params)
            # each person's forces depend on its own gain only, and a step of PLAN_DT is one sub-step of the social force
            # (max_substep 0.1 s), so the rows of the step with the other gain are exact
            if side_narrow:
                near = near_narrow(door_points, pos, self.side_narrow_reach)
                if near.any():
                    v[near] = step(sf_narrow)[near]
            return v

        out = np.empty((self.n, steps + 1, 2))
        out[:, 0] = pos
        prev_vel = vel
        for k in range(steps):
            if diffusion is not None:
                look = DIFFUSION_LOOKAHEAD_S
                ahead = diffusion._plans_at(env.sim_time + k * PLAN_DT + look)[:, 0]
                pref = (ahead - pos) / look
                speed = np.linalg.norm(pref, axis=1, keepdims=True)
                pref = np.where(speed > cap, pref / np.maximum(speed, 1e-9) * cap, pref)
                pref[v_pref == 0.0] = 0.0
                if stalled.size:  # bodies that stand: along the plan's path at STALL_PACE x v_pref or more
                    ahead = diffusion._plans_at(env.sim_time + warp * (k * PLAN_DT + look))[stalled, np.arange(stalled.size)]
                    fast = (ahead - pos[stalled]) / look
                    speed = np.linalg.norm(fast, axis=1, keepdims=True)
                    pref[stalled] = np.where(speed > cap[stalled], fast / np.maximum(speed, 1e-9) * cap[stalled], fast)
                if door_astar:
                    near = np.flatnonzero(near_narrow(door_points, pos, DIFFUSION_DOOR_REACH) & (v_pref > 0.0))
                    if near.size:
                        pref[near] = toward_waypoints(near, pos)
            else:
                pref = toward_waypoints(np.arange(self.n), pos)
            # yields in progress shape the rollout ahead, and so do the door turns, at the rolled-out positions
            pref = env.crowd_conventions(pref, env.sim_time + k * PLAN_DT, pos, v_pref)
            o_pos = r_pos + (k * PLAN_DT) * r_vel
            if narrow is not None:
                wall_rad = graded_wall_radius(pos, env.radius[h], self.wall_margin, narrow)
            if env.config.crowd_model in ("sfm", "diffusion"):
                if len(self.corners):
                    pref = corner_steer(pos, pref, self.corners, wall_rad, self.corner_margin, self.a_wall,
                                        sf_params.B_wall, sf_params.tau)
                if walker == "sfm":
                    v_new = social_force(pos, vel, pref, o_pos, wall_rad)
                    if wall_stall is not None:  # the held rows of the same step again, with softer walls
                        use = wall_stall.update(k * PLAN_DT, PLAN_DT, v_new, pref)
                        if use.any():
                            v_new[use] = social_force(pos, vel, pref, o_pos, wall_rad, softer=True)[use]
                    vel = v_new
                else:
                    v_new = orca_velocities(np.concatenate([pos, o_pos]), np.concatenate([vel, r_vel]),
                                            np.concatenate([pref, r_vel]), np.concatenate([orca_rad, r_rad]),
                                            orca_max, PLAN_DT, ORCA_WALKER, env.segments, n_active=self.n)
                    use = switch.update(k * PLAN_DT, PLAN_DT, v_new, pref) if switch is not None else None
                    if use is not None and use.any():  # the hybrid: social force for those ORCA holds still
                        v_new[use] = social_force(pos, vel, pref, o_pos, wall_rad)[use]
                    vel = v_new
            else:
                vel = orca_velocities(np.concatenate([pos, o_pos]), np.concatenate([vel, r_vel]),
                                      np.concatenate([pref, r_vel]), np.concatenate([rad, r_rad]),
                                      np.concatenate([vmax, np.full(robots.size, env.config.robot.max_speed)]),
                                      PLAN_DT, self.orca, env.segments, n_active=self.n)
            if TARGET_TURN_RATE > 0.0 and diffusion is None:
                vel = limit_turn(prev_vel, vel, TARGET_TURN_RATE * PLAN_DT)
            accel = TARGET_ACCEL if diffusion is None else DIFFUSION_TARGET_ACCEL
            if accel > 0.0:
                vel = limit_accel(prev_vel, vel, accel * PLAN_DT)
            prev_vel = vel
            pos = pos + PLAN_DT * vel
            out[:, k + 1] = pos
        paths = resample(out, PLAN_DT, 1.0 / CONTROL_HZ, self.path_len)
        mine = np.arange(self.n) if who is None else np.asarray(who, dtype=int)
        self.paths[mine] = paths[mine]
        self.plan_t[mine] = self.t
        self.k_prog[mine] = 0
        goals = env.goals_reached[h]
        self.starting[mine] = goals[mine] != self._goals_seen[mine]
        self._goals_seen[mine] = goals[mine]

    def narrow_passages(self, paths: list[np.ndarray], radius: np.ndarray,
                        margin: float | None = None) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per person, the points of its A* path where a wall margin (``margin``, default the rollouts' own
        ``wall_margin``) must shrink (:func:`narrow_points`), recomputed only when its path changed."""
        margin = self.wall_margin if margin is None else float(margin)
        cache = self._narrow.setdefault(margin, [(None, (np.zeros((0, 2)), np.zeros(0)))] * self.n)
        out = []
        for j, path in enumerate(paths):
            key, value = cache[j]
            if key is not path:
                value = narrow_points(path, self.env.scene.clearance, float(radius[j]) + margin + DOOR_SLACK)
                cache[j] = (path, value)
            out.append(value)
        return out

    # ------------------------------------------------------------------ observation / action / step
    def observations(self) -> np.ndarray:
        """(H, OBS_DIM) float32: the AMP controller's input of every pedestrian."""
        s = self.state()
        env = self.env
        others = np.flatnonzero(env.alive | ~env.is_robot)  # live robots and every person (fallen ones lie there)
        own = np.full(env.n_total, -1)
        own[others] = np.arange(others.size)
        rays = obstacle_observation(s["root_pos"][:, :2], heading(s["root_quat"]), env.segments, env.pos[others],
                                    env.radius[others], self_disc=own[env.n_robots:])
        wps = self.waypoints()
        if self.sight_clearance > 0.0:
            wps = sight_waypoints(s["root_pos"][:, :2], wps, env.segments, self.sight_clearance)
        return policy_observation(s, wps, rays)

    def set_actions(self, actions: np.ndarray) -> None:
        sph, rev = actions_to_targets(np.clip(np.asarray(actions, dtype=np.float64), -1.0, 1.0))
        self.bodies.apply_targets(sph, rev)

    def control_step(self, before_substep) -> None:
        """One 30 Hz control step (4 physics steps); ``before_substep`` drives the robots."""
        self.bodies.step(before_substep)
        self.t += 1
        k_time = self.t - self.plan_t
        held = self.lag_all | (START_LAG & self.starting)  # whose target waits for the body
        if held.any() or STALL_WARP_S > 0:
            pos, _, vel, _ = self.planar()
            if STALL_WARP_S > 0:
                speed = np.linalg.norm(vel, axis=1)
                self.still_s = np.where(speed < STALL_SPEED, self.still_s + 1.0 / CONTROL_HZ, 0.0)
            if held.any():
                lead = progress_index(self.k_prog, k_time, self.paths, pos, int(round(LAG_LIMIT_S * CONTROL_HZ)))
                k_time = np.where(held, lead, k_time)
        self.k_prog = k_time

    def after_step(self, replan: bool | np.ndarray) -> None:
        """Falls are sticky; replan when due (or when asked, e.g. after new goals). ``replan`` is a bool, or (H,)
        bools naming the people of the events that ask for it: with ``EVENT_REPLAN_OWN`` only those get new
        targets (unless the regular replan is due, which replans everyone)."""
        self.fallen |= self.bodies.fallen()
        who = np.asarray(replan, dtype=bool)
        if who.ndim and who.shape != (self.n,):
            raise ValueError(f"replan must be a bool or ({self.n},) bools, got shape {who.shape}")
        asked = bool(who.any())
        extra = 0 <= self.extra_replan <= self.t
        if extra or self.t - int(self.plan_t.min()) >= self.replan_steps:
            self.plan_all()
        elif asked:
            self.plan_all(np.flatnonzero(who) if EVENT_REPLAN_OWN and who.ndim else None)
        else:
            return
        self.extra_replan = self.t + int(round(START_REPLAN_S * CONTROL_HZ)) if asked and START_REPLAN_S > 0 else -1

    def task_reward(self) -> dict[str, np.ndarray]:
        """The controller's task reward terms (the paper's r_tau, r_e, r_d with its alpha values), and
        ``stance``: minus the excess of the absolute running mean of :func:`foot_split` over ``STANCE_FREE_M``
        (``NavConfig.amp_stance_reward``).
        Call once per env step: it advances that running mean."""
        s = self.state()
        self.stance += min(1.0, self.control_steps / (CONTROL_HZ * STANCE_TAU_S)) * (foot_split(s) - self.stance)
        err2 = np.sum((s["root_pos"][:, :2] - self.target_now()) ** 2, axis=1)
        h = heading(s["root_quat"])
        u = np.cos(h) * s["root_lin_vel"][:, 0] + np.sin(h) * s["root_lin_vel"][:, 1]
        return {
            "track": np.exp(-2.0 * err2),
            "energy": -0.0005 * self.bodies.joint_power(),
            "direction": np.exp(np.minimum(0.0, u) / 1.8) - 1.0,
            "path_error": np.sqrt(err2),
            "stance": stance_penalty(self.stance),
        }

    def contacts(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(H,) bools: touching a scene obstacle; touching another pedestrian or a robot; touching a robot
        (last physics step). Also keeps which pedestrians and robots each one touched (``touched``, body ids)."""
        env = self.env
        map_hit = np.zeros(self.n, dtype=bool)
        agent_hit = np.zeros(self.n, dtype=bool)
        robot_hit = np.zeros(self.n, dtype=bool)
        self.touched = [set() for _ in range(self.n)]
        for j, body in enumerate(self.ids):
            for c in p.getContactPoints(bodyA=body, physicsClientId=self.client):
                kind = env._body_kind.get(c[2])
                if kind == "obstacle":
                    map_hit[j] = True
                elif kind in ("human", "robot") and c[2] != body:
                    agent_hit[j] = True
                    robot_hit[j] |= kind == "robot"
                    self.touched[j].add(c[2])
        return map_hit, agent_hit, robot_hit
