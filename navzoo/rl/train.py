"""Joint training of robots and pedestrians with RLlib PPO (``python -m navzoo.rl.train``).

One PPO algorithm (RLlib's new API stack) with up to two policies, ``"robot"`` (every ``robot_*``
agent) and ``"human"`` (every ``human_*`` agent); which sides learn and what drives the others is a
:class:`~navzoo.rl.config.JointConfig` (``--config FILE`` and/or flags). Env runners are Ray actors,
i.e. separate processes (``--env-runners N``); the learner runs in the driver.

Ray: a local instance by default (``ray.init()`` bound to 127.0.0.1); ``--address HOST:PORT`` joins a
running cluster (``ray start --head`` on one node, ``ray start --address HEAD:PORT`` on the others)
and nothing else changes. Every node needs navzoo and the ``[ray]`` extra installed, same versions.

``--out DIR``: ``joint_config.yaml``, ``metrics.jsonl`` (the JSON line printed per iteration),
``checkpoints/iter_NNNNNN`` (``algo.save_to_path``; the last ``--keep`` are kept) and
``latest_checkpoint.txt``. A rerun with the same ``--out`` resumes from the latest checkpoint and runs
until ``--iterations`` in total. SIGINT (Ctrl-C) finishes the current iteration, saves and exits
with status 130; a second SIGINT stops at once.

Each iteration prints one JSON line: env steps sampled (iteration and lifetime), env steps/s over
the iteration (sampling and learning), per-policy mean episode return per agent, navzoo outcomes
(robot success / collision rate, wall time of one env step in the env runners), and per-policy
learner stats (losses, entropy, module
steps trained, and the L2 norm of the change of that policy's weights in the iteration, > 0 when
the policy was updated).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import shutil
import signal
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from navzoo.rl.config import HUMAN_MODES, ROBOT_MODES, JointConfig, policy_mapping_fn

__all__ = ["add_arguments", "build_algorithm", "init_ray", "main", "run", "run_cli"]

_LEARNER_KEYS = ("policy_loss", "vf_loss", "entropy", "mean_kl_loss", "curr_kl_coeff", "vf_explained_var",
                 "num_module_steps_trained", "module_train_batch_size_mean")


def _int_list(text: str) -> list[int]:
    try:
        values = [int(v) for v in text.split(",") if v.strip()]
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"expected comma-separated integers such as 128,128, got {text!r}") from exc
    if not values or any(v < 1 for v in values):
        raise argparse.ArgumentTypeError(f"expected positive integers, got {text!r}")
    return values


def _key_value(text: str) -> tuple[str, Any]:
    """A ``--set KEY=VALUE`` item (:func:`navzoo.envs.config.parse_override`: JSON values, else words)."""
    from navzoo.envs.config import parse_override

    try:
        return parse_override(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Arguments of ``navzoo train joint`` / ``python -m navzoo.rl.train``."""
    g = parser.add_argument_group("what is trained (overrides --config)")
    g.add_argument("--config", default=None, metavar="FILE", help="JointConfig YAML/JSON (see docs/scaling.md)")
    g.add_argument("--env", dest="env_id", default=None, help="scenario id (default navzoo/CircleCrossing-v0)")
    g.add_argument("--robots", choices=ROBOT_MODES, default=None, help="robots learn or are frozen (default learn)")
    g.add_argument("--humans", choices=HUMAN_MODES, default=None,
                   help="pedestrians learn, are frozen on a trained policy, or follow the crowd model (default learn)")
    g.add_argument("--n-robots", type=int, default=None)
    g.add_argument("--n-humans", type=int, default=None)
    g.add_argument("--robot-policy", default=None, help="frozen robots: baseline name or rllib:PATH (default orca)")
    g.add_argument("--human-policy", default=None, help="frozen pedestrians: rllib:PATH, or amp / amp:DIR (AMP bodies)")
    g.add_argument("--robot-init", default=None, metavar="DIR",
                   help="learning robots among learning AMP pedestrians start from this exported robot policy")
    g.add_argument("--set", dest="env_set", action="append", type=_key_value, default=[], metavar="KEY=VALUE",
                   help="NavConfig override, repeatable (e.g. --set time_limit=10 --set crowd_model=orca)")
    r = parser.add_argument_group("Ray")
    r.add_argument("--backend", choices=["ray"], default="ray", help="training backend (ray: RLlib PPO)")
    r.add_argument("--address", default=None,
                   help="Ray cluster to join, HOST:PORT of `ray start --head` (default: start a local instance)")
    r.add_argument("--env-runners", type=int, default=2, help="env runner processes (default 2; 0 = sample in the driver)")
    r.add_argument("--envs-per-runner", type=int, default=1)
    r.add_argument("--learner-threads", type=int, default=1,
                   help="torch threads of the learner in the driver (default 1: small MLPs on a shared CPU learn "
                        "several times faster than with one thread per core; env runners get 1 from Ray)")
    r.add_argument("--num-learners", type=int, default=0,
                   help="learner actors for data-parallel PPO updates (default 0: one learner in the driver); "
                        "each learns on --batch-size env steps, so an iteration samples num_learners x batch-size")
    r.add_argument("--gpus-per-learner", type=float, default=0.0,
                   help="GPUs of each learner (default 0: CPU); with --num-learners 0 the driver's learner")
    r.add_argument("--num-cpus", type=int, default=None,
                   help="local instance only: CPUs Ray may schedule (default max(cores, env runners + 1))")
    t = parser.add_argument_group("PPO")
    t.add_argument("--iterations", type=int, default=10, help="total training iterations (a resumed run continues to it)")
    t.add_argument("--batch-size", type=int, default=1000, help="env steps per iteration (train_batch_size_per_learner)")
    t.add_argument("--minibatch-size", type=int, default=250)
    t.add_argument("--epochs", type=int, default=4, help="SGD passes over each batch")
    t.add_argument("--lr", type=float, default=3e-4)
    t.add_argument("--gamma", type=float, default=0.99)
    t.add_argument("--hidden", type=_int_list, default=[128, 128], help="MLP widths (default 128,128)")
    t.add_argument("--seed", type=int, default=0)
    o = parser.add_argument_group("output")
    o.add_argument("--out", default="runs/joint", help="run folder (resumed if it holds a checkpoint)")
    o.add_argument("--fresh", action="store_true", help="ignore (delete) checkpoints in --out and start over")
    o.add_argument("--checkpoint-every", type=int, default=1, help="iterations between checkpoints (and at the end)")
    o.add_argument("--keep", type=int, default=2, help="checkpoints kept")
    o.add_argument("--print-config", action="store_true", help="print the resolved JointConfig as JSON and exit")


def joint_config_from_args(args: argparse.Namespace) -> JointConfig:
    """The JointConfig of ``--config`` with the flags applied on top, validated."""
    cfg = JointConfig.load(args.config) if args.config else JointConfig()
    for name in ("env_id", "robots", "humans", "n_robots", "n_humans", "robot_policy", "human_policy", "robot_init"):
        value = getattr(args, name, None)
        if value is not None:
            setattr(cfg, name, value)
    for key, value in getattr(args, "env_set", []) or []:
        cfg.env[key] = value
    return cfg.validate()


def init_ray(address: str | None = None, num_cpus: int | None = None, env_runners: int = 0,
             learners: int = 0) -> None:
    """Connect to ``address`` or start a local Ray instance on 127.0.0.1 (no usage reporting)."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    import ray

    if ray.is_initialized():
        return
    if address:
        ray.init(address=address, log_to_driver=True)
        return
    cpus = num_cpus if num_cpus is not None else max(os.cpu_count() or 1, env_runners + learners + 1)
    with _loopback_only():
        ray.init(num_cpus=cpus, include_dashboard=False, _node_ip_address="127.0.0.1", log_to_driver=True)


@contextlib.contextmanager
def _loopback_only():
    """While starting a local single-node instance, keep it on 127.0.0.1 (loopback traffic only).

    On Linux Ray replaces 127.0.0.1 by the machine's outward address (``resolve_ip_for_localhost``)
    so that other nodes could join; a local instance needs no such address. Ray's switch for
    single-node platforms (``RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER=0``, what it does on macOS) keeps
    127.0.0.1. It is set (in the environment the instance's processes inherit, and in the already
    imported constants) only while the instance starts, and restored afterwards.
    """
    var = "RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"
    old_env = os.environ.get(var)
    os.environ[var] = "0"
    try:
        from ray._private import ray_constants
    except ImportError:  # another Ray layout: it keeps its default address
        ray_constants = None
    old_const = getattr(ray_constants, "ENABLE_RAY_CLUSTER", None)
    if ray_constants is not None and old_const is not None:
        ray_constants.ENABLE_RAY_CLUSTER = False
    try:
        yield
    finally:
        if old_env is None:
            os.environ.pop(var, None)
        else:
            os.environ[var] = old_env
        if ray_constants is not None and old_const is not None:
            ray_constants.ENABLE_RAY_CLUSTER = old_const


def build_config(cfg: JointConfig, args: argparse.Namespace):
    """The RLlib ``PPOConfig`` of a joint config and the PPO flags."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec

    from navzoo.rl.rllib_env import ENV_NAME, NavzooMetrics, register

    register()
    policies = cfg.learning_policies
    model = {"fcnet_hiddens": list(args.hidden), "fcnet_activation": "tanh", "vf_share_layers": False}
    return (
        PPOConfig()
        .environment(ENV_NAME, env_config=cfg.to_dict())
        .framework("torch")
        .env_runners(
            num_env_runners=args.env_runners,
            num_envs_per_env_runner=args.envs_per_runner,
            num_cpus_per_env_runner=1,
            rollout_fragment_length="auto",
            create_local_env_runner=args.env_runners == 0,
            sample_timeout_s=600.0,
        )
        .learners(num_learners=getattr(args, "num_learners", 0),
                  num_gpus_per_learner=getattr(args, "gpus_per_learner", 0.0))
        .multi_agent(policies=set(policies), policy_mapping_fn=policy_mapping_fn, policies_to_train=list(policies))
        .rl_module(rl_module_spec=MultiRLModuleSpec(
            rl_module_specs={pid: RLModuleSpec(model_config=dict(model)) for pid in policies}))
        .training(
            train_batch_size_per_learner=args.batch_size,
            minibatch_size=min(args.minibatch_size, args.batch_size),
            num_epochs=args.epochs,
            lr=args.lr,
            gamma=args.gamma,
        )
        .callbacks(NavzooMetrics)
        .debugging(seed=args.seed)
        .reporting(metrics_num_episodes_for_smoothing=20)
    )


def build_algorithm(cfg: JointConfig, args: argparse.Namespace):
    return build_config(cfg, args).build_algo()


def _runner_where(runner: Any) -> dict[str, Any]:
    import ray

    return {"pid": os.getpid(), "node_id": ray.get_runtime_context().get_node_id()}


def cluster_info(algo) -> dict[str, Any]:
    """Nodes of the Ray cluster and where each env runner process lives (pid, node)."""
    import ray

    nodes = [n for n in ray.nodes() if n.get("Alive")]
    driver_node = ray.get_runtime_context().get_node_id()
    remote = algo.config.num_env_runners > 0
    runners = algo.env_runner_group.foreach_env_runner(_runner_where, local_env_runner=not remote)
    return {
        "ray_version": ray.__version__,
        "nodes": len(nodes),
        "cluster_cpus": sum(float(n.get("Resources", {}).get("CPU", 0)) for n in nodes),
        "node_ips": sorted({n.get("NodeManagerAddress") for n in nodes}),
        "driver": {"pid": os.getpid(), "node_id": driver_node},
        "env_runners": runners,
        "env_runners_on_other_nodes": sum(r["node_id"] != driver_node for r in runners),
    }


def _weights(algo, policies: Sequence[str]) -> dict[str, Any]:
    import numpy as np

    state = algo.learner_group.get_weights(module_ids=list(policies))
    return {pid: {k: np.array(v, copy=True) for k, v in state[pid].items()} for pid in policies}


def _delta(before: dict[str, Any], after: dict[str, Any]) -> float:
    import numpy as np

    return float(math.sqrt(sum(float(np.sum((after[k].astype(np.float64) - before[k]) ** 2)) for k in before)))


def _num(x: Any) -> float | int | None:
    try:
        import numpy as np

        if hasattr(x, "item"):
            x = x.item()
        if isinstance(x, bool | int):
            return int(x)
        x = float(x)
        return None if not np.isfinite(x) else round(x, 6)
    except (TypeError, ValueError):
        return None


def summarize(result: dict[str, Any], policies: Sequence[str], deltas: dict[str, float], iteration: int,
              wall_s: float) -> dict[str, Any]:
    """One JSON-able line of an RLlib result."""
    er = result.get("env_runners", {}) or {}
    steps = int(er.get("num_env_steps_sampled", 0) or 0)
    agent_returns = er.get("agent_episode_returns_mean", {}) or {}
    line: dict[str, Any] = {
        "iteration": iteration,
        "env_steps_sampled": steps,
        "env_steps_sampled_lifetime": int(er.get("num_env_steps_sampled_lifetime", 0) or 0),
        "agent_steps_sampled": {pid: int((er.get("num_module_steps_sampled", {}) or {}).get(pid, 0) or 0)
                                for pid in policies},
        "iteration_s": round(wall_s, 3),
        "env_steps_per_s": round(steps / wall_s, 2) if wall_s > 0 else None,
        "episodes": int(er.get("num_episodes", 0) or 0),
        "episode_len_mean": _num(er.get("episode_len_mean")),
        "reward_mean": {},
        "learner": {},
    }
    for pid in policies:
        per_agent = [v for a, v in agent_returns.items() if policy_mapping_fn(a) == pid and _num(v) is not None]
        line["reward_mean"][pid] = round(sum(per_agent) / len(per_agent), 4) if per_agent else None
        stats = (result.get("learners", {}) or {}).get(pid, {}) or {}
        line["learner"][pid] = {k: _num(stats[k]) for k in _LEARNER_KEYS if k in stats}
        line["learner"][pid]["weights_delta_l2"] = round(deltas.get(pid, 0.0), 6)
    line["navzoo"] = {k.split("/", 1)[1]: _num(v) for k, v in er.items() if isinstance(k, str) and k.startswith("navzoo/")}
    return line


class _Stop:
    """SIGINT: first one asks to stop after the iteration (and save), the second one interrupts."""

    def __init__(self) -> None:
        self.requested = False
        self._old: Any = None

    def __enter__(self) -> _Stop:
        try:
            self._old = signal.signal(signal.SIGINT, self._handle)
        except ValueError:  # not the main thread
            self._old = None
        return self

    def _handle(self, signum, frame) -> None:
        if self.requested:
            raise KeyboardInterrupt
        self.requested = True
        print("navzoo.rl.train: SIGINT, saving after this iteration (again to abort)", file=sys.stderr, flush=True)

    def __exit__(self, *exc) -> None:
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)


def _latest(out: Path) -> Path | None:
    f = out / "latest_checkpoint.txt"
    if f.is_file():
        p = out / f.read_text().strip()
        if p.is_dir():
            return p
    return None


def _save(algo, out: Path, iteration: int, keep: int) -> Path:
    ckdir = out / "checkpoints"
    path = ckdir / f"iter_{iteration:06d}"
    tmp = ckdir / f".tmp_iter_{iteration:06d}"
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.parent.mkdir(parents=True, exist_ok=True)
    algo.save_to_path(str(tmp.resolve()))
    (tmp / "navzoo_state.json").write_text(json.dumps({"iteration": iteration}))
    shutil.rmtree(path, ignore_errors=True)
    tmp.rename(path)
    (out / "latest_checkpoint.txt.tmp").write_text(str(path.relative_to(out)))
    (out / "latest_checkpoint.txt.tmp").replace(out / "latest_checkpoint.txt")
    old = sorted(p for p in ckdir.glob("iter_*") if p.is_dir())
    for p in old[:-max(1, keep)]:
        shutil.rmtree(p, ignore_errors=True)
    return path


def run(cfg: JointConfig, args: argparse.Namespace, emit: Callable[[dict[str, Any]], None] | None = None) -> dict[str, Any]:
    """Train; return the summary. Ray must be initialised (see :func:`init_ray`).

    ``emit`` receives the cluster line and each iteration's line (default: print as JSON).
    """
    if emit is None:
        def emit(d: dict[str, Any]) -> None:
            print(json.dumps(d), flush=True)
    out = Path(args.out)
    if args.fresh and out.exists():
        shutil.rmtree(out / "checkpoints", ignore_errors=True)
        for name in ("latest_checkpoint.txt", "metrics.jsonl"):
            (out / name).unlink(missing_ok=True)
    out.mkdir(parents=True, exist_ok=True)
    saved_cfg = out / "joint_config.yaml"
    latest = _latest(out)
    if latest is not None and saved_cfg.is_file():
        before = JointConfig.load(saved_cfg)
        if before.to_dict() != cfg.to_dict():
            raise ValueError(f"{out} holds a run of another joint config ({saved_cfg}: {before.to_dict()}); "
                             "use another --out, or --fresh to start over")
    cfg.save(saved_cfg)
    policies = cfg.learning_policies
    threads = getattr(args, "learner_threads", None)
    if threads:
        import torch

        torch.set_num_threads(threads)
    algo = build_algorithm(cfg, args)
    start = 0
    try:
        cluster = cluster_info(algo)
        emit({"cluster": cluster, "policies": policies})
        if latest is not None:
            algo.restore_from_path(str(latest.resolve()))
            state = json.loads((latest / "navzoo_state.json").read_text())
            start = int(state["iteration"])
            print(f"navzoo.rl.train: resumed from {latest} (iteration {start})", file=sys.stderr, flush=True)
        last: dict[str, Any] = {}
        it = start
        saved_at = start if latest is not None else -1
        interrupted = False
        with _Stop() as stop, (out / "metrics.jsonl").open("a") as log:
            while it < args.iterations and not stop.requested:
                w0 = _weights(algo, policies)
                t0 = time.perf_counter()
                result = algo.train()
                wall = time.perf_counter() - t0
                w1 = _weights(algo, policies)
                it += 1
                last = summarize(result, policies, {p: _delta(w0[p], w1[p]) for p in policies}, it, wall)
                log.write(json.dumps(last) + "\n")
                log.flush()
                emit(last)
                if it % max(1, args.checkpoint_every) == 0 or it >= args.iterations or stop.requested:
                    _save(algo, out, it, args.keep)
                    saved_at = it
            interrupted = stop.requested
        if saved_at != it:
            _save(algo, out, it, args.keep)
        return {"iterations": it, "resumed_from": start, "cluster": cluster, "interrupted": interrupted, "out": str(out),
                "checkpoint": str(_latest(out)), "last": last}
    finally:
        algo.stop()


def run_cli(args: argparse.Namespace, error: Callable[[str], None] | None = None) -> int:
    """Entry point of ``navzoo train joint`` (``args`` from :func:`add_arguments`)."""
    def fail(msg: str) -> int:
        if error is not None:
            error(msg)
        print(f"navzoo train joint: error: {msg}", file=sys.stderr)
        return 2

    for name, low in (("env_runners", 0), ("envs_per_runner", 1), ("learner_threads", 1), ("iterations", 1), ("batch_size", 1),
                      ("minibatch_size", 1), ("epochs", 1), ("checkpoint_every", 1), ("keep", 1)):
        if getattr(args, name) < low:
            return fail(f"--{name.replace('_', '-')} must be >= {low}, got {getattr(args, name)}")
    if args.num_learners < 0:
        return fail(f"--num-learners must be >= 0, got {args.num_learners}")
    if not (args.gpus_per_learner >= 0 and math.isfinite(args.gpus_per_learner)):
        return fail(f"--gpus-per-learner must be a number >= 0, got {args.gpus_per_learner}")
    if args.address and args.num_cpus is not None:
        return fail("--num-cpus applies to a local Ray instance only; a cluster's nodes declare their CPUs at `ray start`")
    try:
        cfg = joint_config_from_args(args)
    except (ValueError, TypeError, FileNotFoundError) as exc:
        return fail(str(exc))
    if args.print_config:
        print(json.dumps(cfg.to_dict()))
        return 0
    if cfg.humans == "learn" and cfg.nav_config().human_model == "amp":
        return _run_amp_joint(cfg, args, fail)
    try:
        import ray  # noqa: F401
        import ray.rllib  # noqa: F401
    except ImportError:
        return fail("Ray RLlib is not installed: pip install 'navzoo[ray]' (see docs/scaling.md)")
    init_ray(args.address, args.num_cpus, args.env_runners, args.num_learners)
    try:
        summary = run(cfg, args)
    finally:
        import ray

        ray.shutdown()
    print(json.dumps({"done": summary}), flush=True)
    return 130 if summary["interrupted"] else 0


def _run_amp_joint(cfg: JointConfig, args: argparse.Namespace, fail: Callable[[str], int]) -> int:
    """AMP pedestrians learning among frozen or learning robots: the AMP learner with its discriminator
    (:mod:`navzoo.rl.amp_joint`), in this process; learning robots are SB3 PPO with the transformer, from
    ``robot_init`` (``--robot-init``) or fresh, at ``--lr``. ``--iterations`` x ``--batch-size`` pedestrian
    steps are trained; ``--envs-per-runner`` env copies; the Ray flags do not apply."""
    from navzoo.rl.amp_joint import AmpJointArgs, train

    nav = cfg.nav_config()
    if nav.n_humans is None:
        return fail(f"{cfg.env_id} has no fixed pedestrian count: give --n-humans for AMP pedestrians that learn")
    env = {k: v for k, v in cfg.env.items() if k not in ("human_model", "dt", "flat_obs")}
    jargs = AmpJointArgs(out=args.out, env_id=cfg.env_id, n_envs=args.envs_per_runner, n_humans=int(nav.n_humans),
                         n_robots=int(nav.n_robots), robot_policy=cfg.robot_policy,
                         steps=int(args.iterations) * int(args.batch_size), seed=int(args.seed), env=env,
                         robot_learn=None if cfg.robots == "frozen" else {
                             "init_from": cfg.robot_init, "lr": float(args.lr),
                             "forward_only": bool(cfg.robot_init) and _forward_only(cfg.robot_init)})
    try:
        summary = train(jargs)
    except (ValueError, FileNotFoundError) as exc:
        return fail(str(exc))
    print(json.dumps({"done": summary}, default=str), flush=True)
    return 130 if summary.get("interrupted") else 0


def _forward_only(policy_dir: str) -> bool:
    """Whether an exported robot policy commands speeds in [0, 1] only (trained with ``--forward-only``)."""
    cfg = json.loads((Path(policy_dir) / "config.json").read_text())
    return float(cfg["action"]["low"][0]) >= 0.0


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m navzoo.rl.train",
        description="Joint training of robots and pedestrians with RLlib PPO on a local Ray instance or a cluster "
        "(docs/scaling.md).")
    add_arguments(parser)
    return run_cli(parser.parse_args(argv), parser.error)


if __name__ == "__main__":
    sys.exit(main())
