"""Success against wall contacts of the following protocol, one point per setting: where each target setting sits.

Reads result files of ``scripts/amp_target_ablation.py`` (one JSON row per scene run) and, for each setting, pools
each seed's scene runs (trips counted together) into a success rate per time limit and a share of trips with a map
(wall) contact, then draws the mean over the seeds with its standard error on both axes, one panel per scene set::

    python scripts/plot_success_contacts.py --title "diffusion + AMP" --seeds 0,1,2,3 \\
        --setting "default=docs/results/diffusion_sight/fis_s012345_device.jsonl;docs/results/heldout_2026-12-03/diffusion_s*_device.jsonl" \\
        --setting "wall margin 0.2=docs/results/wall_margin/dm2_s*.jsonl" \\
        --paper 88.67,2.40 --out /tmp/success_contacts.png

``--setting LABEL=GLOB[;GLOB...]`` (repeatable) names one setting and its files; each setting's files must hold one
row per scene and seed (``scripts/ablation_scene_weighted.py``'s rule). ``--scenes`` takes panels joined by ``/``
(default ``protocol/heldout``: the 8 scenes of the protocol and the 10 held out), each ``protocol``, ``heldout`` or
scene names joined by commas (:func:`navzoo.benchmark.pedestrians.scene_names`, which refuses unknown names).
``--paper SUCCESS,MAP`` (percent) marks the paper's row in the first panel, whose scenes it compares with. Prints one JSON line per setting and panel (``seeds`` the seeds found, ``success`` and
``map_contact`` mean and standard error over them, in percent). A setting without rows of a panel's scenes on the
chosen seeds is an error that names it. The plot in docs/ has its own command under it (docs/pedestrians_log.md, "Choosing
the wall settings").
"""

from __future__ import annotations

import argparse
import importlib.util
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from navzoo.benchmark.pedestrians import goal_trip_rates, scene_names

_SPEC = importlib.util.spec_from_file_location("ablation_scene_weighted",
                                               Path(__file__).resolve().parent / "ablation_scene_weighted.py")
_weighted = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(_weighted)


def parse_setting(text: str) -> tuple[str, list[str]]:
    label, eq, globs = text.partition("=")
    patterns = [g for g in globs.split(";") if g]
    if not eq or not label or not patterns:
        raise ValueError(f"--setting takes LABEL=GLOB[;GLOB...], got {text!r}")
    return label, patterns


def point(rows: dict[tuple[str, int], dict], seeds: Sequence[int] | None) -> dict:
    """Per seed, the pooled success per limit and map-contact share of ``rows`` ((scene, seed) -> row); their mean and
    standard error over the seeds (percent)."""
    found = sorted({k for _, k in rows if seeds is None or k in seeds})
    if not found:
        raise ValueError("no rows on the chosen seeds")
    per_seed = [goal_trip_rates([r for (_, k), r in rows.items() if k == seed]) for seed in found]
    out: dict = {"seeds": found, "trips": int(sum(p["trips"] for p in per_seed))}
    for key, name in (("success_rate", "success"), ("map_collision_rate", "map_contact")):
        v = 100.0 * np.array([p[key] for p in per_seed])
        se = float(v.std(ddof=1) / np.sqrt(len(v))) if len(v) > 1 else 0.0
        out[name] = [round(float(v.mean()), 2), round(se, 2)]
    return out


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--setting", action="append", required=True, metavar="LABEL=GLOB[;GLOB...]")
    ap.add_argument("--scenes", default="protocol/heldout", help="panels joined by '/'")
    ap.add_argument("--seeds", default=None, help="seeds to pool, e.g. 0,1,2,3 (default: all found per setting)")
    ap.add_argument("--paper", default=None, metavar="SUCCESS,MAP", help="the paper's row, percent (first panel)")
    ap.add_argument("--title", default="")
    ap.add_argument("--out", default=None, help="PNG to draw")
    args = ap.parse_args(argv)
    try:
        settings = [parse_setting(s) for s in args.setting]
        panels = [(p, scene_names(p)) for p in args.scenes.split("/")]
        seeds = None if args.seeds is None else [int(s) for s in args.seeds.split(",")]
        paper = None if args.paper is None else [float(x) for x in args.paper.split(",")]
        if paper is not None and len(paper) != 2:
            raise ValueError(f"--paper takes SUCCESS,MAP in percent, got {args.paper!r}")
    except ValueError as e:
        ap.error(str(e))
    points: dict[tuple[str, str], dict] = {}
    for label, patterns in settings:
        for name, scenes in panels:
            try:
                p = point(_weighted.load(patterns, scenes), seeds)
            except (ValueError, SystemExit) as e:
                raise SystemExit(f"setting {label!r}, scenes {name!r}: {e}") from None
            points[(label, name)] = p
            print(json.dumps({"setting": label, "scenes": name, **p}))
    if args.out:
        draw(points, settings, panels, paper, args.title, args.out)
    return 0


def draw(points: dict, settings: list, panels: list, paper: list[float] | None, title: str, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.4), squeeze=False)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, (name, scenes) in zip(axes[0], panels, strict=True):
        for i, (label, _) in enumerate(settings):
            p = points[(label, name)]
            (x, dx), (y, dy) = p["map_contact"], p["success"]
            ax.errorbar(x, y, xerr=dx, yerr=dy, fmt="o", color=colors[i % len(colors)], capsize=3,
                        label=f"{label} (seeds {','.join(map(str, p['seeds']))})")
        if paper is not None and name == panels[0][0]:
            ax.plot(paper[1], paper[0], "k*", markersize=12, label="paper")
        ax.set_title(f"{title}: {name} ({len(scenes)} scenes)" if title else f"{name} ({len(scenes)} scenes)")
        ax.set_xlabel("trips with a wall contact (%)")
        ax.set_ylabel("success per time limit (%)")
        ax.grid(alpha=0.3)
    axes[0][0].legend(fontsize=7, loc="best")
    fig.tight_layout()
    Path(out).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    raise SystemExit(main())
