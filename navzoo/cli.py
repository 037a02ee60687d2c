"""The ``navzoo`` command line: demo, scene library, benchmark and report, throughput."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path


def _int_list(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers such as 5,20,64, got {text!r}") from exc
    if not values or any(v < 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected non-negative integers, got {text!r}")
    return values


def build_parser() -> argparse.ArgumentParser:
    from navzoo import __version__

    parser = argparse.ArgumentParser(
        prog="navzoo",
        description="navzoo: multi-agent human-aware robot navigation on PyBullet (PettingZoo).",
    )
    parser.add_argument("--version", action="version", version=f"navzoo {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    demo = sub.add_parser("demo", help="run a baseline robot in a crowd; write video, trajectory plot and metrics")
    demo.add_argument("--scene", default=None, help="scene name (see `navzoo scenes`) or a scene file; default lobby")
    demo.add_argument("--out", default="runs/demo", help="output folder (default runs/demo)")
    demo.add_argument("--seed", type=int, default=0)
    from navzoo.agents.baselines import policy_names

    demo.add_argument("--policy", default="orca",
                      help=f"baseline robot controller: {', '.join(policy_names())} (default orca; case, '_' and '-' "
                           "do not matter: pure_pursuit is pure-pursuit)")
    demo.add_argument("--humans", type=int, default=None, help="number of pedestrians (default: the scene's)")
    demo.add_argument("--no-video", action="store_true", help="skip the video")
    demo.add_argument("--json", action="store_true", help="print the metrics as one JSON object on stdout")

    scenes = sub.add_parser("scenes", help="list the scene library with sizes and free area")
    scenes.add_argument("--json", action="store_true")

    motions = sub.add_parser("motions", help="the reference motion library of the pedestrian body controller")
    msub = motions.add_subparsers(dest="motions_command", metavar="ACTION")
    convert = msub.add_parser("convert", help="convert the mocap in ../shared/data/mocap into the packaged library")
    from navzoo.agents.motion_convert import add_arguments as add_convert_arguments

    add_convert_arguments(convert)
    msub.add_parser("list", help="list the clips of the packaged library").add_argument("--json", action="store_true")

    tracks = sub.add_parser("tracks", help="the packaged ETH/UCY recordings of the replay crowd")
    trsub = tracks.add_subparsers(dest="tracks_command", metavar="ACTION")
    tconv = trsub.add_parser("convert", help="convert ../shared/data/trajectories/eth_ucy into navzoo/assets/tracks")
    tconv.add_argument("--data", default=None, help="ETH/UCY folder with all_data/ (default: the shared data folder)")
    tconv.add_argument("--out", default=None, help="output folder (default: the package's assets/tracks)")
    tconv.add_argument("--maps", default=None, help="OpenTraj folder with the scenes' wall lines (map.xml; default: "
                       "the opentraj folder beside --data; 'none': convert without walls)")

    train = sub.add_parser("train", help="train a model of navzoo")
    tsub = train.add_subparsers(dest="train_command", metavar="MODEL")
    from navzoo.agents.amp.train import add_arguments as add_amp_arguments

    add_amp_arguments(tsub.add_parser("amp", help="the AMP pedestrian controller (resumable; see docs/amp_learner.md and docs/pedestrians.md)"))
    from navzoo.agents.amp.steering import add_arguments as add_trim_arguments

    add_trim_arguments(tsub.add_parser(
        "amp-trim", help="calibrate an AMP policy's steering trim on open-ground paths (see docs/pedestrians.md)"))
    avg = tsub.add_parser(
        "amp-average", help="average exported AMP policies fine-tuned from one checkpoint into one (a model soup)")
    avg.add_argument("policies", nargs="+", metavar="POLICY_DIR", help="exported AMP policy folders (two or more)")
    avg.add_argument("--weights", default=None, metavar="W1,W2,...", help="averaging weights (default: equal)")
    avg.add_argument("--out", required=True, help="folder of the averaged policy (config.json + policy.pt)")
    blend = tsub.add_parser(
        "amp-blend", help="blend exported AMP policies in action space: the weighted mean of their PD targets")
    blend.add_argument("policies", nargs="+", metavar="POLICY_DIR", help="exported AMP policy folders (two or more)")
    blend.add_argument("--weights", default=None, metavar="W1,W2,...", help="blending weights (default: equal)")
    blend.add_argument("--out", required=True, help="folder of the blend (a config.json naming its components)")
    from navzoo.agents.diffusion.train import add_arguments as add_diffusion_arguments

    add_diffusion_arguments(tsub.add_parser(
        "diffusion", help="the trajectory diffusion model on ETH/UCY (resumable; see docs/crowd.md)"))
    from navzoo.agents.robot_train import add_arguments as add_robot_arguments

    add_robot_arguments(tsub.add_parser(
        "robot", help="the transformer PPO robot policy on station/home/grocery (resumable; see docs/training.md)"))
    from navzoo.rl.train import add_arguments as add_joint_arguments

    add_joint_arguments(tsub.add_parser(
        "joint", help="robots and pedestrians learning together (or one side frozen) with Ray RLlib; "
        "--address joins a cluster (see docs/scaling.md)"))
    from navzoo.perception.train import add_arguments as add_perception_arguments

    add_perception_arguments(tsub.add_parser(
        "perception", help="the Monoloco keypoint network on data from navzoo scenes (resumable; see docs/perception.md)"))

    ev = sub.add_parser("eval", help="evaluate a component of navzoo")
    esub = ev.add_subparsers(dest="eval_command", metavar="WHAT")
    from navzoo.benchmark.pedestrians import add_arguments as add_ped_arguments

    add_ped_arguments(esub.add_parser(
        "pedestrians", help="AMP pedestrians: clip tracking, trajectory following, motion realism, throughput"))
    from navzoo.forecast.evaluate import add_arguments as add_forecast_arguments

    add_forecast_arguments(esub.add_parser("forecast", help="minADE/minFDE of trajectory forecasters on ETH/UCY files"))
    from navzoo.benchmark.crowd_eval import add_arguments as add_crowd_eval_arguments

    add_crowd_eval_arguments(esub.add_parser(
        "crowd", help="closed-loop crowds: realism vs ETH/UCY, pedestrian reliability table, replan and step cost"))
    from navzoo.benchmark.matched_realism import add_arguments as add_matched_arguments

    add_matched_arguments(esub.add_parser(
        "crowd-matched", help="crowds walking the recorded people's starts and goals in their open scenes, vs the real tracks"))
    from navzoo.perception.evaluate import add_arguments as add_perception_eval_arguments

    add_perception_eval_arguments(esub.add_parser(
        "perception", help="robot perception of people: localisation, detection, tracking, navigation, cost"))

    bench = sub.add_parser(
        "benchmark", help="run robot policies over scenes x crowds x densities x episodes (parallel, resumable)",
        description="Run robot policies over scenes x crowd models x crowd levels x episodes in worker processes; "
        "every episode is appended to OUT/episodes.jsonl at once, a rerun with the same --out resumes. "
        "See docs/benchmarks.md.")
    from navzoo.benchmark.runner import add_arguments as add_benchmark_arguments

    add_benchmark_arguments(bench)
    report = sub.add_parser("report", help="tables (md, csv), HTML page with plots and JSON of a benchmark run")
    from navzoo.benchmark.report import add_arguments as add_report_arguments

    add_report_arguments(report)

    scaling = sub.add_parser("scaling", help="robot-training studies: runtime scaling and parallel training (docs/training.md)")
    from navzoo.agents.scaling_study import add_arguments as add_scaling_arguments

    add_scaling_arguments(scaling)

    speed = sub.add_parser("speed", help="env throughput with kinematic crowds and its overhead over PyBullet")
    speed.add_argument("--humans", type=_int_list, default=[5, 20, 64], help="crowd sizes (default 5,20,64)")
    speed.add_argument("--steps", type=int, default=200)
    speed.add_argument("--repeats", type=int, default=3)
    speed.add_argument("--scene", default="station")
    speed.add_argument("--crowd", default="sfm", choices=["sfm", "orca", "orca_rvo2"])
    speed.add_argument("--json", action="store_true")
    return parser


def _source_trims(paths: list[str]) -> list[str]:
    """``"DIR has 0.025 rad"`` for each exported AMP policy of ``paths`` whose config carries a steering trim."""
    out = []
    for p in paths:
        try:
            trim = json.loads((Path(p) / "config.json").read_text()).get("steering_trim")
        except (OSError, ValueError):
            continue
        if isinstance(trim, dict) and trim.get("rad"):
            out.append(f"{p} has {trim['rad']} rad")
    return out


def _weights(text: str | None) -> list[float] | None:
    """``--weights W1,W2,...`` as floats (None: equal weights); a ValueError names a bad entry."""
    return None if text is None else [float(x) for x in text.split(",")]


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 0
    try:
        if args.command == "demo":
            return _demo(args)
        if args.command == "scenes":
            return _scenes(args)
        if args.command == "speed":
            return _speed(args)
        if args.command == "scaling":
            from navzoo.agents.scaling_study import run_cli as run_scaling_cli

            return run_scaling_cli(args, parser.error)
        if args.command == "benchmark":
            from navzoo.benchmark.runner import run_cli as run_benchmark_cli

            return run_benchmark_cli(args)
        if args.command == "report":
            from navzoo.benchmark.report import run_cli as run_report_cli

            return run_report_cli(args)
        if args.command == "motions":
            return _motions(args, parser)
        if args.command == "tracks":
            if args.tracks_command != "convert":
                parser.parse_args(["tracks", "--help"])
                return 2
            from navzoo.agents.replay import convert_tracks

            for path in convert_tracks(args.data, args.out, args.maps):
                print(path)
            return 0
        if args.command == "train":
            return _train(args, parser)
        if args.command == "eval":
            if args.eval_command == "pedestrians":
                from navzoo.benchmark.pedestrians import run_cli

                return run_cli(args)
            if args.eval_command == "forecast":
                from navzoo.forecast.evaluate import run_cli as run_forecast_cli

                return run_forecast_cli(args)
            if args.eval_command == "crowd":
                from navzoo.benchmark.crowd_eval import run_cli as run_crowd_cli

                return run_crowd_cli(args)
            if args.eval_command == "crowd-matched":
                from navzoo.benchmark.matched_realism import run_cli as run_matched_cli

                return run_matched_cli(args)
            if args.eval_command == "perception":
                from navzoo.perception.evaluate import run_cli as run_perception_cli

                return run_perception_cli(args, parser.error)
            parser.parse_args(["eval", "--help"])
            return 2
    except (ValueError, TypeError, FileNotFoundError, OSError) as exc:
        print(f"navzoo {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"navzoo {args.command}: interrupted", file=sys.stderr)
        return 130
    parser.error(f"unknown command {args.command!r}")
    return 2


def _demo(args: argparse.Namespace) -> int:
    from navzoo.demo import DEFAULT_SCENE, run_demo

    metrics = run_demo(
        scene=args.scene or DEFAULT_SCENE, out=args.out, seed=args.seed, policy=args.policy,
        n_humans=args.humans, video=not args.no_video, progress=not args.json,
    )
    if args.json:
        print(json.dumps(metrics))
        return 0
    for r in metrics["robots"]:
        print(f"{metrics['scene']}: {r['agent']} {r['event']} after {r['steps']} steps "
              f"(path {r['path_length_m']:.1f} m, min gap to people {r['min_person_distance_m']:.2f} m)")
    for name, path in metrics["files"].items():
        if path:
            print(f"  {name:16s} {path}")
    return 0


def _scenes(args: argparse.Namespace) -> int:
    from navzoo.world.library import list_scenes, scene_info

    infos = [scene_info(n) for n in list_scenes()]
    if args.json:
        print(json.dumps({"scenes": infos}))
        return 0
    print(f"{'scene':18s} {'size (m)':>12s} {'free m2':>9s} {'obstacles':>9s} {'people':>6s}  protocol")
    for i in infos:
        w, h = i["size_m"]
        proto = i["protocol"] if isinstance(i["protocol"], str) else i["protocol"].get("type", "")
        print(f"{i['name']:18s} {w:5.1f} x {h:4.1f} {i['free_area_m2']:9.1f} {i['n_obstacles']:9d} {i['default_humans']:6d}  {proto}")
    return 0


def _motions(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    if args.motions_command == "convert":
        from navzoo.agents.motion_convert import format_summary, run

        summary = run(args)
        print(json.dumps(summary) if args.json else format_summary(summary))
        return 0
    if args.motions_command == "list":
        from navzoo.agents.motion_lib import MotionLibrary

        lib = MotionLibrary.load()
        rows = [{"clip": n, "duration_s": lib.duration(i), "speed_mps": lib.speed(i), "tags": list(lib.tags(i))}
                for i, n in enumerate(lib.clip_names())]
        if args.json:
            print(json.dumps({"clips": rows}))
        else:
            for r in rows:
                print(f"{r['clip']:28s} {r['duration_s']:6.2f} s {r['speed_mps']:5.2f} m/s  {','.join(r['tags'])}")
        return 0
    parser.parse_args(["motions", "--help"])
    return 2


def _train(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    if args.train_command == "amp":
        import dataclasses

        from navzoo.agents.amp.train import TrainArgs, run

        targs = TrainArgs(**{f.name: getattr(args, f.name) for f in dataclasses.fields(TrainArgs)})
        result = run(targs)
        print(json.dumps(result, default=str) if args.json else result)
        return 0
    if args.train_command == "amp-trim":
        from navzoo.agents.amp.steering import run as run_trim

        return run_trim(args)
    if args.train_command == "amp-average":
        from navzoo.agents.amp.checkpoint import CheckpointError, average_policies

        try:
            out = average_policies(args.policies, args.out, _weights(args.weights))
        except (ValueError, CheckpointError) as e:
            parser.error(f"train amp-average: {e}")
        print(json.dumps({"policy": str(out), "averaged_from": json.loads((out / "config.json").read_text())["averaged_from"]}))
        trims = _source_trims(args.policies)
        if trims:  # the average carries none: say so, or it would walk untrimmed unnoticed
            print(f"note: the average has no steering trim, though {', '.join(trims)} "
                  f"(calibrate one for it: navzoo train amp-trim --policy {out})", file=sys.stderr)
        return 0
    if args.train_command == "amp-blend":
        from navzoo.agents.amp.blend import write_blend
        from navzoo.agents.amp.checkpoint import CheckpointError

        try:
            cfg_path = write_blend(args.policies, args.out, _weights(args.weights))
        except (ValueError, CheckpointError) as e:
            parser.error(f"train amp-blend: {e}")
        print(json.dumps({"policy": str(cfg_path.parent),
                          "components": json.loads(cfg_path.read_text())["components"]}))
        return 0
    if args.train_command == "diffusion":
        from navzoo.agents.diffusion.train import run_cli as run_diffusion

        return run_diffusion(args)
    if args.train_command == "robot":
        from navzoo.agents.robot_train import run_cli as run_robot

        return run_robot(args, parser.error)
    if args.train_command == "joint":
        from navzoo.rl.train import run_cli as run_joint

        return run_joint(args, parser.error)
    if args.train_command == "perception":
        from navzoo.perception.train import run_cli as run_perception

        return run_perception(args, parser.error)
    parser.parse_args(["train", "--help"])
    return 2


def _speed(args: argparse.Namespace) -> int:
    from navzoo.benchmark.speed import run

    result = run(args.humans, steps=args.steps, repeats=args.repeats, scene=args.scene, crowd=args.crowd)
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"machine: {result['machine']}")
    print(f"{'humans':>6s} {'env steps/s':>12s} {'agent steps/s':>14s} {'step ms':>8s} {'physics ms':>10s} "
          f"{'physics frac':>12s} {'bare PyBullet ms':>16s} {'overhead':>8s}")
    for r in result["results"]:
        print(f"{r['humans']:6d} {r['env_steps_per_s']:12.1f} {r['agent_steps_per_s']:14.1f} {r['env_step_ms']:8.2f} "
              f"{r['physics_ms_in_env']:10.2f} {r['physics_fraction']:12.2f} {r['bare_physics_ms']:16.2f} "
              f"{r['overhead_ratio']:8.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
