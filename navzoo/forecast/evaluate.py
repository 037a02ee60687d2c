"""Forecast accuracy of every registered forecaster on ETH/UCY-format data: ``navzoo eval forecast``.

Forecasters are created per fold by factories kept in a registry, so another model (the diffusion
model) is added with one call and then appears as another key of the result::

    from navzoo.forecast.evaluate import register_forecaster
    register_forecaster("diffusion", lambda ctx: MyModel.load(...))  # ctx: ForecastContext

A factory receives a :class:`ForecastContext` (split, held-out scene, the fold's training files,
seed) and returns an object with ``predict(batch, n_samples) -> (N, S, H, 2)`` in the batch's frame
(:class:`navzoo.forecast.baselines.Forecaster`). Built in: ``constant_velocity`` and ``sfm``.

Protocol: windows of 8 observed + 12 future steps with their neighbours, agent-centric
(:mod:`navzoo.forecast.data`); ``--split val`` tests on ``val/<scene>_val.txt`` (one fold, trained on
the ``train`` files), ``--split loo`` tests on each scene's ``all_data`` with the other scenes'
``all_data`` as the fold's training files. A learned model under ``loo`` needs one model per fold,
trained without the fold's scene: ``--loo-models DIR`` gives the diffusion forecaster ``DIR/<scene>/``
for the fold of ``<scene>`` (``navzoo train diffusion --split loo --test-scene <scene> --export
DIR/<scene>``); a model whose ``config.json`` does not say it was trained without that scene is
refused. ``--out`` is rewritten after every scene and resumed from (see :func:`run_cli`). Per scene:
minADE and minFDE over ``--samples`` samples (m, averaged over windows); ``average``: the unweighted
mean over scenes (the usual ETH/UCY convention). Every model sees exactly the same windows.

Maps (``--maps opentraj``; default ``none``): windows of a scene with an OpenTraj obstacle map in its world
frame (``biwi_eth``; :mod:`navzoo.forecast.scene_maps`) carry the occupancy crop around the person, which
a map-aware model (the shipped diffusion model) reads; the other scenes' windows say "no map". For
scenes with a map the result also gives each model's ``obstacle_rate``: the share of its predicted points
(every sample and step) on an occupied cell of the crop, next to the real futures' own rate
(``ground_truth_obstacle_rate``). ``--maps none`` gives every window "no map"; the obstacle rates are
still scored where the map files are found, so the two settings can be compared. The default is
``none`` because the shipped model, whose map input was learned from simulated crowds at 0.4 s steps,
forecasts ``biwi_eth`` (0.667 s steps) worse with its real map (docs/crowd.md, "The ETH obstacle map").
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "ForecastContext",
    "ForecasterFactory",
    "register_forecaster",
    "unregister_forecaster",
    "forecaster_names",
    "make_forecaster",
    "score",
    "evaluate_forecasts",
    "loo_model_dir",
    "format_table",
    "add_arguments",
    "run_cli",
]


@dataclass(frozen=True)
class ForecastContext:
    """What a forecaster factory knows about the fold it is made for.

    Attributes:
        data_dir: The ETH/UCY folder evaluated.
        split: ``"val"`` or ``"loo"``.
        test_scene: The held-out scene of a ``"loo"`` fold; None for ``"val"``.
        train_files: Scene -> file of the fold's training data (a trained model must not have seen
            the test files; e.g. pick the checkpoint trained without ``test_scene``).
        seed: Seed for stochastic forecasters.
        loo_models: Folder of per-fold models (``<loo_models>/<test_scene>/``) for ``"loo"``, or None.
    """

    data_dir: Path
    split: str
    test_scene: str | None
    train_files: Mapping[str, Path] = field(default_factory=dict)
    seed: int = 0
    loo_models: Path | None = None


ForecasterFactory = Callable[[ForecastContext], Any]
_REGISTRY: dict[str, ForecasterFactory] = {}


def register_forecaster(name: str, factory: ForecasterFactory, overwrite: bool = False) -> None:
    """Add a forecaster under ``name`` (the key it gets in the results).

    Raises:
        ValueError: If the name is empty or taken (and ``overwrite`` is False), or factory is not callable.
    """
    if not isinstance(name, str) or not name or "," in name:
        raise ValueError(f"forecaster name must be a non-empty string without commas, got {name!r}")
    if not callable(factory):
        raise ValueError(f"factory for {name!r} must be callable, got {type(factory).__name__}")
    if name in _REGISTRY and not overwrite:
        raise ValueError(f"forecaster {name!r} is already registered (pass overwrite=True to replace it)")
    _REGISTRY[name] = factory


def unregister_forecaster(name: str) -> None:
    """Remove a registered forecaster.

    Raises:
        ValueError: If ``name`` is not registered.
    """
    if name not in _REGISTRY:
        raise ValueError(f"unknown forecaster {name!r}; registered: {forecaster_names()}")
    del _REGISTRY[name]


def forecaster_names() -> list[str]:
    """Registered forecaster names, in registration order."""
    return list(_REGISTRY)


def make_forecaster(name: str, context: ForecastContext) -> Any:
    """Build the forecaster ``name`` for a fold.

    Raises:
        ValueError: If ``name`` is not registered.
    """
    if name not in _REGISTRY:
        raise ValueError(f"unknown forecaster {name!r}; registered: {forecaster_names()}")
    return _REGISTRY[name](context)


def _constant_velocity(context: ForecastContext) -> Any:
    from navzoo.forecast.baselines import ConstantVelocity

    return ConstantVelocity()


def _sfm(context: ForecastContext) -> Any:
    from navzoo.forecast.baselines import SocialForceForecaster

    return SocialForceForecaster(seed=context.seed)


def _diffusion(context: ForecastContext) -> Any:
    import os

    from navzoo.agents.diffusion.forecaster import MODEL_ENV, DiffusionForecaster

    if context.split == "loo" and context.loo_models is not None:
        return DiffusionForecaster(loo_model_dir(context.loo_models, context.test_scene), seed=context.seed)
    if context.split == "loo" and not os.environ.get(MODEL_ENV):
        raise ValueError(
            "the shipped diffusion model was trained on the train part of all five scenes, so it has seen every "
            "leave-one-scene-out test scene; train one per held-out scene (navzoo train diffusion --split loo "
            f"--test-scene {context.test_scene} --export DIR/{context.test_scene}) and pass --loo-models DIR")
    return DiffusionForecaster(seed=context.seed)


def loo_model_dir(root: str | Path, test_scene: str | None) -> Path:
    """``<root>/<test_scene>``, the exported model of one leave-one-scene-out fold, after checking that its
    ``config.json`` records a ``loo`` training without ``test_scene``.

    Raises:
        FileNotFoundError: If the folder or its ``config.json`` is missing.
        ValueError: If the model was not trained on the ``loo`` split with ``test_scene`` held out.
    """
    folder = Path(root) / str(test_scene)
    cfg_path = folder / "config.json"
    if not cfg_path.is_file():
        raise FileNotFoundError(f"no model for the leave-one-scene-out fold of {test_scene!r}: {cfg_path} does not "
                                f"exist (navzoo train diffusion --split loo --test-scene {test_scene} --export {folder})")
    try:
        data = json.loads(cfg_path.read_text()).get("data") or {}
    except (json.JSONDecodeError, AttributeError) as exc:
        raise ValueError(f"{cfg_path} is not a model config: {exc}") from exc
    if data.get("split") != "loo" or data.get("test_scene") != test_scene:
        raise ValueError(f"{folder} was trained on split {data.get('split')!r} with test scene "
                         f"{data.get('test_scene')!r}; the fold of {test_scene!r} needs a model trained with "
                         f"--split loo --test-scene {test_scene}")
    seen = {k.split("@")[0] for k in (data.get("train_windows") or {})} | set(data.get("val_windows") or {})
    if test_scene in seen:
        raise ValueError(f"{folder} saw {test_scene!r} in training or validation ({cfg_path})")
    return folder


register_forecaster("constant_velocity", _constant_velocity)
register_forecaster("sfm", _sfm)
register_forecaster("diffusion", _diffusion)


def score(forecaster: Any, batch: Mapping[str, Any], n_samples: int) -> dict[str, float]:
    """``{"min_ade", "min_fde"}`` (m, mean over windows) of one forecaster on one batch, plus
    ``obstacle_rate`` where the batch carries scoring crops (``obstacle_map``, see :func:`evaluate_forecasts`).

    Raises:
        ValueError: If the prediction does not have shape (N, n_samples, H, 2).
    """
    from navzoo.forecast.metrics import min_ade, min_fde

    fut = np.asarray(batch["fut"])
    pred = np.asarray(forecaster.predict(batch, n_samples))
    expected = (fut.shape[0], n_samples, *fut.shape[1:])
    if pred.shape != expected:
        raise ValueError(f"{type(forecaster).__name__}.predict returned shape {pred.shape}, expected {expected}")
    out = {"min_ade": float(min_ade(pred, fut).mean()), "min_fde": float(min_fde(pred, fut).mean())}
    if "obstacle_map" in batch:
        out["obstacle_rate"] = _obstacle_rate(pred, batch["obstacle_map"])
    return out


def _obstacle_rate(points: np.ndarray, crops: np.ndarray) -> float:
    from navzoo.forecast.map_eval import obstacle_hits

    hit, inside = obstacle_hits(points, crops)
    return float(hit.sum() / max(int(inside.sum()), 1))


def _has_maps(batch: Mapping[str, Any]) -> bool:
    return "map" in batch and bool(np.asarray(batch.get("has_map", [])).size) and bool(np.all(batch["has_map"]))


def _even_subset(n: int, max_windows: int | None) -> np.ndarray:
    if not max_windows or n <= max_windows:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max_windows).round().astype(np.int64))


def evaluate_forecasts(
    data_dir: str | Path | None = None,
    split: str = "val",
    samples: int = 20,
    models: Sequence[str] | None = None,
    scenes: Sequence[str] | None = None,
    max_windows: int | None = None,
    seed: int = 0,
    k_neighbors: int = 16,
    radius: float = 10.0,
    progress: Callable[[str], None] | None = None,
    maps: str = "none",
    map_dir: str | Path | None = None,
    loo_models: str | Path | None = None,
    resume_from: Mapping[str, Any] | None = None,
    on_scene: Callable[[dict[str, Any]], None] | None = None,
) -> dict[str, Any]:
    """Evaluate forecasters on a split; see the module doc for the protocol.

    Args:
        data_dir: ETH/UCY folder (default: the shared ``eth_ucy``).
        split: ``"val"`` or ``"loo"``.
        samples: Samples per window S (min over samples).
        models: Forecaster names (default: all registered; under ``"loo"`` without
            ``$NAVZOO_DIFFUSION_MODEL`` the diffusion model is left out, as it saw every scene).
        scenes: Only these test scenes (default: all of the split).
        max_windows: At most this many windows per scene, evenly spaced over the file (same windows
            for every model); None or 0 for all.
        seed: Passed to the factories.
        k_neighbors: Neighbour slots per window.
        radius: Neighbour radius (m).
        progress: Called with a line of text after each scene and model.
        maps: ``"opentraj"``: occupancy crops for scenes with an OpenTraj map (module doc); ``"none"``.
        map_dir: OpenTraj folder; default the ``opentraj`` folder beside ``data_dir`` if there is one, else
            :func:`navzoo.forecast.scene_maps.default_map_dir`.
        loo_models: ``"loo"`` only: folder with one exported diffusion model per held-out scene
            (``<loo_models>/<scene>/``, checked by :func:`loo_model_dir`); the diffusion model is then
            evaluated by default.
        resume_from: The result of an earlier, interrupted run (as ``on_scene`` received it). When its
            ``"config"`` equals this run's, a scene found in it with every requested model is not
            evaluated again; otherwise it is ignored.
        on_scene: Called after every scene with the result so far (the same keys, over the scenes done),
            e.g. to write it to a file, so a long evaluation loses nothing when it is stopped.

    Returns:
        ``{<model>: {"min_ade", "min_fde"} (mean over scenes), "scenes": {scene: {"windows", "dt", "map",
        "seconds": {<model>: s}, <model>: {"min_ade", "min_fde"[, "obstacle_rate"]}[,
        "ground_truth_obstacle_rate"]}}, "config": {...}}`` (obstacle rates for scenes whose map is found).

    Raises:
        ValueError: On an unknown split, model, scene or maps option, or ``samples < 1``.
        FileNotFoundError: If a scene with an OpenTraj map is evaluated with ``maps="opentraj"`` and the
            map's files are not in ``map_dir``.
    """
    from navzoo.forecast.data import default_data_dir, discover, load_windows, split_files, subset
    from navzoo.forecast.scene_maps import OPENTRAJ_MAPS, attach_maps, default_map_dir

    if samples < 1:
        raise ValueError(f"samples must be >= 1, got {samples!r}")
    if maps not in ("opentraj", "none"):
        raise ValueError(f"unknown maps option {maps!r}; expected 'opentraj' or 'none'")
    root = Path(data_dir) if data_dir is not None else default_data_dir()
    if map_dir is None:
        map_dir = root.parent / "opentraj" if (root.parent / "opentraj").is_dir() else default_map_dir()
    map_dir = Path(map_dir)
    names = list(models) if models else forecaster_names()
    if loo_models is not None and split != "loo":
        raise ValueError(f"loo_models is for split 'loo' (one model per held-out scene), got split {split!r}")
    if not models and split == "loo" and loo_models is None and not os.environ.get("NAVZOO_DIFFUSION_MODEL"):
        names = [n for n in names if n != "diffusion"]  # the shipped model saw every scene (see _diffusion)
    for name in names:
        if name not in _REGISTRY:
            raise ValueError(f"unknown forecaster {name!r}; registered: {forecaster_names()}")
    files = discover(root)
    if split == "val":
        train, test = split_files(root, "val")
        folds = [(None, train, test)]
    elif split == "loo":
        folds = []
        for scene in files["all"]:
            train, test = split_files(root, "loo", scene)
            folds.append((scene, train, test))
    else:
        raise ValueError(f"unknown split {split!r}; expected 'val' or 'loo'")
    available = sorted({s for _, _, test in folds for s in test})
    if scenes:
        unknown = sorted(set(scenes) - set(available))
        if unknown:
            raise ValueError(f"unknown scene(s) {unknown} for split {split!r}; scenes: {available}")

    config = {"data": str(root), "split": split, "samples": samples, "obs_len": 8, "pred_len": 12,
              "k_neighbors": k_neighbors, "radius": radius, "max_windows": max_windows or None,
              "seed": seed, "average": "unweighted mean over scenes", "maps": maps,
              "map_dir": str(map_dir) if maps == "opentraj" else None,
              "loo_models": None if loo_models is None else str(loo_models)}
    done = (resume_from.get("scenes") or {}) if resume_from and resume_from.get("config") == config else {}
    per_scene: dict[str, dict[str, Any]] = {}
    for held_out, train, test in folds:
        chosen = {s: p for s, p in test.items() if not scenes or s in scenes}
        for scene in list(chosen):
            earlier = done.get(scene)
            if earlier is not None and all(name in earlier for name in names):
                per_scene[scene] = dict(earlier)
                del chosen[scene]
                if progress:
                    progress(f"{scene}: kept from the earlier run")
        if not chosen:
            continue
        context = ForecastContext(data_dir=root, split=split, test_scene=held_out, train_files=train, seed=seed,
                                  loo_models=None if loo_models is None else Path(loo_models))
        forecasters = {name: make_forecaster(name, context) for name in names}
        for scene, path in chosen.items():
            batch = load_windows(path, k_neighbors=k_neighbors, radius=radius)
            map_found = scene in OPENTRAJ_MAPS and (map_dir / OPENTRAJ_MAPS[scene]).is_dir()
            if maps == "opentraj" and scene in OPENTRAJ_MAPS and not map_found:
                raise FileNotFoundError(f"scene {scene!r} has an OpenTraj map, but {map_dir / OPENTRAJ_MAPS[scene]} "
                                        "does not exist; pass --map-dir (the OpenTraj folder) or --maps none")
            if map_found:
                with_map = attach_maps(batch, scene, map_dir)
                batch = with_map if maps == "opentraj" else dict(batch)
                batch["obstacle_map"] = with_map["map"]  # scoring only; the models read map / has_map
            total = int(batch["hist"].shape[0])
            batch = subset(batch, _even_subset(total, max_windows))
            n = int(batch["hist"].shape[0])
            if n == 0:
                raise ValueError(f"scene {scene!r} ({path}) has no window of 20 consecutive frames")
            entry: dict[str, Any] = {"windows": n, "windows_total": total, "dt": float(batch["dt"][0]),
                                     "map": _has_maps(batch), "seconds": {}}
            if "obstacle_map" in batch:
                entry["ground_truth_obstacle_rate"] = _obstacle_rate(np.asarray(batch["fut"])[:, None],
                                                                     batch["obstacle_map"])
            for name, model in forecasters.items():
                t0 = time.perf_counter()
                entry[name] = score(model, batch, samples)
                entry["seconds"][name] = round(time.perf_counter() - t0, 3)
                if progress:
                    progress(f"{scene}: {name} minADE {entry[name]['min_ade']:.3f} minFDE "
                             f"{entry[name]['min_fde']:.3f} ({n} windows, {entry['seconds'][name]:.1f} s)")
            per_scene[scene] = entry
            if on_scene is not None:
                on_scene(_assemble(names, per_scene, config))
    return _assemble(names, per_scene, config)


def _assemble(names: Sequence[str], per_scene: Mapping[str, Mapping[str, Any]], config: Mapping[str, Any]
              ) -> dict[str, Any]:
    """The result of :func:`evaluate_forecasts` over the scenes in ``per_scene``, in the folds' order."""
    result: dict[str, Any] = {}
    for name in names:
        result[name] = {key: float(np.mean([per_scene[s][name][key] for s in per_scene]))
                        for key in ("min_ade", "min_fde")}
    result["scenes"] = dict(per_scene)
    result["config"] = dict(config)
    return result


def format_table(result: Mapping[str, Any]) -> str:
    """A Markdown table of minADE / minFDE per scene and model, with the average row."""
    names = [k for k in result if k not in ("scenes", "config")]
    head = "| scene | windows | " + " | ".join(f"{n} minADE / minFDE (m)" for n in names) + " |"
    rows = [head, "|" + "---|" * (len(names) + 2)]
    for scene, entry in result["scenes"].items():
        cells = " | ".join(f"{entry[n]['min_ade']:.3f} / {entry[n]['min_fde']:.3f}" for n in names)
        rows.append(f"| {scene} | {entry['windows']} | {cells} |")
    cells = " | ".join(f"**{result[n]['min_ade']:.3f} / {result[n]['min_fde']:.3f}**" for n in names)
    rows.append(f"| average | {sum(e['windows'] for e in result['scenes'].values())} | {cells} |")
    return "\n".join(rows)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``navzoo eval forecast``."""
    parser.add_argument("--data", default=None,
                        help="folder of ETH/UCY-format files (all_data/, train/, val/ or flat *.txt); "
                             "default ../shared/data/trajectories/eth_ucy")
    parser.add_argument("--split", default="val", choices=["val", "loo"],
                        help="val: the files' temporal split; loo: leave one scene out (default val)")
    parser.add_argument("--samples", type=int, default=20, help="samples per window for minADE/minFDE (default 20)")
    parser.add_argument("--models", default=None,
                        help="comma-separated forecasters (default: all registered, e.g. constant_velocity,sfm)")
    parser.add_argument("--scenes", default=None, help="comma-separated test scenes (default: all)")
    parser.add_argument("--max-windows", type=int, default=0,
                        help="at most this many windows per scene, evenly spaced (default 0: all)")
    parser.add_argument("--neighbors", type=int, default=16, help="neighbour slots per window (default 16)")
    parser.add_argument("--radius", type=float, default=10.0, help="neighbour radius in m (default 10)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--maps", default="none", choices=["opentraj", "none"],
                        help="opentraj: occupancy crops from the OpenTraj obstacle map where a scene has one in its "
                             "frame (biwi_eth) for map-aware models; none: no map for any window (default none)")
    parser.add_argument("--map-dir", default=None,
                        help="OpenTraj folder (default: 'opentraj' beside --data, else ../shared/data/trajectories/opentraj)")
    parser.add_argument("--loo-models", default=None,
                        help="with --split loo: folder of per-fold diffusion models, DIR/<scene>/ trained without "
                             "<scene> (navzoo train diffusion --split loo --test-scene <scene> --export DIR/<scene>)")
    parser.add_argument("--out", default=None, help="also write the JSON result to this file")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of a table")


def _read_partial(out: Path) -> dict[str, Any] | None:
    """The result of an interrupted run in ``out`` (written with ``"partial": true``), else None. A finished
    file is never reused; :func:`evaluate_forecasts` keeps a partial one's scenes only if its settings match."""
    if not out.is_file():
        return None
    try:
        earlier = json.loads(out.read_text())
    except json.JSONDecodeError:
        return None
    ok = isinstance(earlier, dict) and earlier.get("partial") and isinstance(earlier.get("scenes"), dict)
    return earlier if ok else None


def _names(text: str | None) -> list[str] | None:
    return [t.strip() for t in text.split(",") if t.strip()] if text else None


def run_cli(args: argparse.Namespace) -> int:
    """Run ``navzoo eval forecast`` from parsed arguments; prints the table or the JSON.

    With ``--out`` the result is written after every scene, with ``"partial": true`` until the end; a
    rerun with the same settings keeps the scenes of such a partial file (:func:`_read_partial`).
    """
    import sys

    out = Path(args.out) if args.out else None
    earlier = _read_partial(out) if out is not None else None

    def write(result: dict[str, Any], partial: bool) -> None:
        out.parent.mkdir(parents=True, exist_ok=True)  # type: ignore[union-attr]
        tmp = out.with_name(out.name + ".tmp")  # type: ignore[union-attr]
        tmp.write_text(json.dumps({**result, **({"partial": True} if partial else {})}, indent=2) + "\n")
        tmp.replace(out)  # type: ignore[arg-type]

    result = evaluate_forecasts(
        data_dir=args.data, split=args.split, samples=args.samples, models=_names(args.models),
        scenes=_names(args.scenes), max_windows=args.max_windows, seed=args.seed, k_neighbors=args.neighbors,
        radius=args.radius, progress=None if args.json else (lambda line: print(line, file=sys.stderr, flush=True)),
        maps=args.maps, map_dir=args.map_dir, loo_models=args.loo_models, resume_from=earlier,
        on_scene=None if out is None else (lambda r: write(r, True)),
    )
    if earlier is not None:
        kept = sorted(earlier["scenes"]) if earlier.get("config") == result["config"] else []
        print(f"resuming from {out}: kept {kept}" if kept else
              f"{out} held an interrupted run with other settings: evaluated again", file=sys.stderr, flush=True)
    text = json.dumps(result)
    if out is not None:
        write(result, False)
    print(text if args.json else format_table(result))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m navzoo.forecast.evaluate``: the same as ``navzoo eval forecast``."""
    parser = argparse.ArgumentParser(prog="navzoo eval forecast", description=__doc__.split("\n")[0])
    add_arguments(parser)
    return run_cli(parser.parse_args(argv))


if __name__ == "__main__":
    raise SystemExit(main())
