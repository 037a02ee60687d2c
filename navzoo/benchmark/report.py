"""Reports of a benchmark run directory: Markdown and CSV tables, an HTML page with plots, JSON.

``navzoo report DIR`` reads ``DIR/episodes.jsonl`` (written by :mod:`navzoo.benchmark.runner`) and writes
into ``DIR/report``:

* ``report.md``: mean ± 95 % CI (Student t over episodes; pooled where METRICS.md pools) of the headline
  metrics per method x scene group x crowd level, one table for all scenes and one per group;
* ``groups.csv`` / ``cells.csv``: every metric (mean and CI half-width) per method x group x level and per
  method x scene x crowd x level;
* ``report.json``: the same numbers (``--json`` prints it);
* ``report.html`` with ``plots/``: metric bars per method, success per scene group, density sweeps of
  success / collision / navigation time, trajectory overlays of the saved episodes (every method's path in
  the same episode on one plot) and links to the videos.

Outcome flags are reported as rates under their METRICS.md names (``success_rate``, ``collision_rate``,
``timeout_rate``, ``human_collision_rate``, ...); every other metric keeps its
:func:`navzoo.benchmark.metrics.episode_metrics` name (``nav_time_s``, ``path_length_m``,
``discomfort_frequency``, ...). ``nav_time_s`` is the mean over successful episodes (the time limit when
there is none) and ``discomfort_frequency`` is pooled over all steps, as :func:`aggregate_episodes` does.
"""

from __future__ import annotations

import argparse
import csv
import html
import json
import math
import re
import sys
from collections import defaultdict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "HEADLINE",
    "SCENE_GROUPS",
    "build_report",
    "scene_group",
    "summarize",
]

# Scene name -> group, for the tables (procedural scenes: by prefix; anything else: "other").
SCENE_GROUPS: dict[str, tuple[str, ...]] = {
    "homes": ("apartment", "home", "kitchen", "studio_flat", "cluttered_room"),
    "offices": ("office_cubicles", "office_floor", "office_open", "lobby", "cafe"),
    "institutions": ("hospital_corridor", "school_corridor", "lecture_hall", "library_stacks", "museum_hall",
                     "waiting_room", "campus_plaza"),
    "retail": ("convenience_store", "grocery", "shopping_mall", "warehouse_aisles"),
    "transport": ("airport_gate", "station", "train_platform", "parking_garage"),
    "primitives": ("bottleneck", "corridor", "doorway", "l_corridor", "t_junction", "two_doors", "x_junction"),
    "crowdnav": ("circle_crossing", "square_crossing"),
}
_GROUP_OF = {scene: group for group, scenes in SCENE_GROUPS.items() for scene in scenes}
GROUP_ORDER = (*SCENE_GROUPS, "procedural", "recorded", "other")

# Outcome flags of episode_metrics -> their rate names.
RATE_NAMES = {
    "success": "success_rate",
    "collision": "collision_rate",
    "human_collision": "human_collision_rate",
    "obstacle_collision": "obstacle_collision_rate",
    "robot_collision": "robot_collision_rate",
    "timeout": "timeout_rate",
    "stuck": "stuck_rate",
    "swept_human_collision": "swept_human_collision_rate",
    "swept_obstacle_collision": "swept_obstacle_collision_rate",
}
# Numeric record fields that describe the episode, not its outcome.
_NOT_METRICS = ("episode", "seed", "density", "n_humans", "dt", "free_area_m2")

# The columns of the Markdown tables: (metric, header, decimals).
HEADLINE: tuple[tuple[str, str, int], ...] = (
    ("success_rate", "success", 2),
    ("collision_rate", "collision", 2),
    ("timeout_rate", "timeout", 2),
    ("nav_time_s", "nav time (s)", 1),
    ("path_length_m", "path (m)", 1),
    ("spl", "SPL", 2),
    ("min_distance_m", "min dist (m)", 2),
    ("discomfort_frequency", "discomfort", 3),
    ("intrusion_time_ratio", "intrusion", 3),
    ("mean_jerk", "jerk (m/s³)", 1),
)
# Physics pedestrians (env human_model "amp"): people who fell during an episode, mean per episode. The column
# appears only where the records hold it, so reports of kinematic crowds keep their columns.
FALLEN_COLUMN = ("people_fallen", "people fallen", 2)
MAX_TRAJECTORY_PLOTS = 48


def _columns(rows: Sequence[Mapping[str, Any]]) -> tuple[tuple[str, str, int], ...]:
    """The table columns: :data:`HEADLINE`, and the fallen people where any row holds them."""
    return HEADLINE + ((FALLEN_COLUMN,) if any(FALLEN_COLUMN[0] in r for r in rows) else ())


def scene_group(scene: str) -> str:
    """The group of a scene name: homes, offices, institutions, retail, transport, primitives, crowdnav,
    procedural (``procedural_*``), recorded (the ETH/UCY replay scenes ``replay_*``) or other."""
    if scene in _GROUP_OF:
        return _GROUP_OF[scene]
    if scene.startswith("procedural_"):
        return "procedural"
    if scene.startswith("replay_"):
        return "recorded"
    return "other"


# ---------------------------------------------------------------------------------------------------------
# Aggregation
# ---------------------------------------------------------------------------------------------------------


def _metric_record(rec: Mapping[str, Any]) -> dict[str, Any]:
    """A record's metrics only, flags renamed to rates, None (nan/inf in JSON) as nan."""
    out = {}
    for k, v in rec.items():
        if k in _NOT_METRICS or isinstance(v, (str, list, dict)):
            continue
        if v is None:
            v = float("nan")
        out[RATE_NAMES.get(k, k)] = v
    return out


def _level_parts(level: str) -> tuple[str, float] | None:
    """``("d", 0.15)`` for ``d0.15``, ``("n", 10.0)`` for ``n10``, None otherwise (``default``)."""
    m = re.fullmatch(r"([dn])(\d+(?:\.\d*)?(?:e[-+]?\d+)?)", level)
    return (m.group(1), float(m.group(2))) if m else None


def _level_sort_key(level: str) -> tuple[int, float]:
    parts = _level_parts(level)
    if parts is None:
        return (2, 0.0)
    return (0 if parts[0] == "d" else 1, parts[1])


def summarize(records: Sequence[Mapping[str, Any]], by: Sequence[str],
              methods: Sequence[str] | None = None) -> list[dict[str, Any]]:
    """Aggregate episode records grouped by the fields ``by`` (e.g. ``("method", "group", "crowd", "level")``).

    Each row: the ``by`` fields, ``n_episodes``, ``density`` and ``n_humans`` (their means over the rows'
    episodes), every metric's mean under its name, and ``ci95`` / ``n`` dicts (95 % CI half-width and the
    number of finite values) per metric. Rows are sorted by the ``by`` fields: methods in the order of
    ``methods`` (default: by name), groups in :data:`GROUP_ORDER`, levels by their number.
    """
    from navzoo.benchmark.metrics import aggregate_episodes

    groups: dict[tuple, list[Mapping[str, Any]]] = defaultdict(list)
    for r in records:
        groups[tuple(r.get(k) if k != "group" else r.get("group") or scene_group(r["scene"]) for k in by)].append(r)
    rows = []
    for key, recs in groups.items():
        agg = aggregate_episodes([_metric_record(r) for r in recs])
        row: dict[str, Any] = dict(zip(by, key, strict=True))
        row["n_episodes"] = agg["n_episodes"]
        row["density"] = float(np.mean([r.get("density") or 0.0 for r in recs]))
        row["n_humans"] = float(np.mean([r.get("n_humans") or 0 for r in recs]))
        row["ci95"], row["n"] = {}, {}
        for name, ci in agg["metrics"].items():
            row[name] = ci["mean"]
            row["ci95"][name] = ci["half_width"]
            row["n"][name] = ci["n"]
        rows.append(row)

    def sort_key(row: Mapping[str, Any]) -> tuple:
        parts: list[Any] = []
        for k in by:
            v = row[k]
            if k == "group":
                parts.append(GROUP_ORDER.index(v) if v in GROUP_ORDER else len(GROUP_ORDER))
            elif k == "method" and methods is not None:
                parts.append(list(methods).index(v) if v in methods else len(methods))
            elif k == "level":
                parts.append(_level_sort_key(v))
            else:
                parts.append(str(v))
        return tuple(parts)

    return sorted(rows, key=sort_key)


def _metric_names(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    names: list[str] = [m for m, _, _ in HEADLINE]
    for r in rows:
        for k in r.get("ci95", {}):
            if k not in names:
                names.append(k)
    return [n for n in names if any(n in r for r in rows)]


# ---------------------------------------------------------------------------------------------------------
# Formatting
# ---------------------------------------------------------------------------------------------------------


def _fmt(mean: Any, ci: Any, decimals: int) -> str:
    if mean is None or not isinstance(mean, (int, float)) or not math.isfinite(mean):
        return "–"
    s = f"{mean:.{decimals}f}"
    if ci is not None and isinstance(ci, (int, float)) and math.isfinite(ci):
        s += f" ± {ci:.{decimals}f}"
    return s


def _cell(row: Mapping[str, Any], metric: str, decimals: int) -> str:
    """A table cell; navigation time without any success is the time limit, marked as such."""
    if metric == "nav_time_s" and row.get("n", {}).get(metric) == 0:
        return _fmt(row.get(metric), None, decimals) + " (limit)"
    return _fmt(row.get(metric), row.get("ci95", {}).get(metric), decimals)


def level_text(level: str) -> str:
    """A crowd level for people: ``0.15 /m²``, ``5 people`` or ``default`` (each scene's own number)."""
    parts = _level_parts(level)
    if parts is None:
        return level
    return f"{level[1:]} /m²" if parts[0] == "d" else f"{level[1:]} people"


def _md_table(rows: Sequence[Mapping[str, Any]], first: Sequence[tuple[str, str]]) -> list[str]:
    columns = _columns(rows)
    head = [h for _, h in first] + ["n"] + [h for _, h, _ in columns]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = []
        for k, _ in first:
            cells.append(level_text(r[k]) if k == "level" else str(r[k]))
        cells.append(str(r["n_episodes"]))
        cells += [_cell(r, m, d) for m, _, d in columns]
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def _html_table(rows: Sequence[Mapping[str, Any]], first: Sequence[tuple[str, str]]) -> str:
    columns = _columns(rows)
    head = [h for _, h in first] + ["n"] + [h for _, h, _ in columns]
    out = ["<table><thead><tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in head) + "</tr></thead><tbody>"]
    for r in rows:
        cells = [level_text(r[k]) if k == "level" else str(r[k]) for k, _ in first]
        cells.append(str(r["n_episodes"]))
        cells += [_cell(r, m, d) for m, _, d in columns]
        out.append("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in cells) + "</tr>")
    out.append("</tbody></table>")
    return "\n".join(out)


def _write_csv(path: Path, rows: Sequence[Mapping[str, Any]], keys: Sequence[str], metrics: Sequence[str]) -> None:
    with open(path, "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow([*keys, "n_episodes", "density", "n_humans", *[c for m in metrics for c in (m, f"{m}_ci95")]])
        for r in rows:
            vals = []
            for m in metrics:
                vals += [_csv_num(r.get(m)), _csv_num(r.get("ci95", {}).get(m))]
            w.writerow([*[r[k] for k in keys], r["n_episodes"], _csv_num(r["density"]), _csv_num(r["n_humans"]), *vals])


def _csv_num(v: Any) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return ""
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def _json_ready(obj: Any) -> Any:
    if isinstance(obj, Mapping):
        return {str(k): _json_ready(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_json_ready(v) for v in obj]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(float(obj)) else None
    return obj


# ---------------------------------------------------------------------------------------------------------
# Plots
# ---------------------------------------------------------------------------------------------------------


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _yerr(means: np.ndarray, cis: np.ndarray, rate: bool) -> np.ndarray:
    """Whiskers (2, n): the CI half-width, clipped to [0, 1] for rates (a Wald interval can leave it)."""
    cis = np.where(np.isfinite(cis), cis, 0.0)
    if not rate:
        return np.stack([cis, cis])
    m = np.nan_to_num(means)
    return np.stack([np.minimum(cis, m), np.minimum(cis, np.maximum(1.0 - m, 0.0))])


def _method_colors(methods: Sequence[str]) -> dict[str, Any]:
    plt = _plt()
    cmap = plt.get_cmap("tab10")
    return {m: cmap(i % 10) for i, m in enumerate(methods)}


def _plot_metric_bars(rows: Sequence[Mapping[str, Any]], methods: Sequence[str], path: Path) -> None:
    """Bars per method (all scenes and levels pooled) with 95 % CI whiskers."""
    plt = _plt()
    panels = [("success_rate", "success rate"), ("collision_rate", "collision rate"), ("timeout_rate", "timeout rate"),
              ("nav_time_s", "navigation time (s)"), ("spl", "SPL"), ("min_distance_m", "min distance to people (m)"),
              ("discomfort_frequency", "discomfort frequency"), ("path_length_m", "path length (m)"),
              ("mean_jerk", "mean jerk (m/s³)")]
    by_method = {r["method"]: r for r in rows}
    colors = _method_colors(methods)
    fig, axes = plt.subplots(3, 3, figsize=(12, 9))
    for ax, (m, title) in zip(axes.flat, panels, strict=True):
        means = [by_method[x].get(m, np.nan) if x in by_method else np.nan for x in methods]
        cis = [by_method[x].get("ci95", {}).get(m, np.nan) if x in by_method else np.nan for x in methods]
        means = np.array([np.nan if v is None else v for v in means], dtype=float)
        cis = np.array([0.0 if v is None or not np.isfinite(v) else v for v in cis], dtype=float)
        ax.bar(range(len(methods)), np.nan_to_num(means), yerr=_yerr(means, cis, m.endswith("_rate")), capsize=3,
               color=[colors[x] for x in methods], edgecolor="black", linewidth=0.5)
        ax.set_xticks(range(len(methods)), methods, rotation=30, ha="right", fontsize=8)
        ax.set_title(title, fontsize=10)
        if m.endswith("_rate"):
            ax.set_ylim(0, 1.05)
        ax.grid(axis="y", alpha=0.3)
    fig.suptitle("All scenes and crowd levels (mean ± 95 % CI)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _plot_group_bars(rows: Sequence[Mapping[str, Any]], methods: Sequence[str], path: Path) -> None:
    """Success and collision rate per scene group, one bar per method."""
    plt = _plt()
    groups = [g for g in GROUP_ORDER if any(r["group"] == g for r in rows)]
    colors = _method_colors(methods)
    idx = {(r["method"], r["group"]): r for r in rows}
    fig, axes = plt.subplots(1, 2, figsize=(max(8, 1.6 * len(groups) * 2), 4), squeeze=False)
    width = 0.8 / max(1, len(methods))
    for ax, (metric, title) in zip(axes[0], (("success_rate", "success rate"), ("collision_rate", "collision rate")),
                                   strict=True):
        for k, m in enumerate(methods):
            ys = [idx[(m, g)].get(metric, np.nan) if (m, g) in idx else np.nan for g in groups]
            es = [idx[(m, g)].get("ci95", {}).get(metric) if (m, g) in idx else None for g in groups]
            ys = np.array([np.nan if v is None else v for v in ys], dtype=float)
            es = np.array([0.0 if v is None or not np.isfinite(v) else v for v in es], dtype=float)
            ax.bar(np.arange(len(groups)) + (k - (len(methods) - 1) / 2) * width, np.nan_to_num(ys), width,
                   yerr=_yerr(ys, es, True),
                   capsize=2, color=colors[m], label=m, edgecolor="black", linewidth=0.4)
        ax.set_xticks(range(len(groups)), groups, rotation=20, ha="right")
        ax.set_ylim(0, 1.05)
        ax.set_title(f"{title} per scene group")
        ax.grid(axis="y", alpha=0.3)
    fig.legend(*axes[0][0].get_legend_handles_labels(), loc="lower center", ncol=min(len(methods), 6), fontsize=8)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _plot_density_sweep(rows: Sequence[Mapping[str, Any]], methods: Sequence[str], crowd: str, path: Path) -> None:
    """Success, collision and navigation time against the crowd level, one line per method."""
    plt = _plt()
    colors = _method_colors(methods)
    counts = all(r["level"].startswith("n") for r in rows)
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
    for ax, (metric, title) in zip(axes, (("success_rate", "success rate"), ("collision_rate", "collision rate"),
                                          ("nav_time_s", "navigation time (s)")), strict=True):
        for m in methods:
            rs = sorted((r for r in rows if r["method"] == m), key=lambda r: r["n_humans"] if counts else r["density"])
            if not rs:
                continue
            x = [r["n_humans"] if counts else r["density"] for r in rs]
            y = np.array([np.nan if r.get(metric) is None else r.get(metric) for r in rs], dtype=float)
            e = np.array([np.nan if r.get("ci95", {}).get(metric) is None else r["ci95"][metric] for r in rs],
                         dtype=float)
            ax.errorbar(x, y, yerr=_yerr(y, e, metric.endswith("_rate")), marker="o", capsize=3, color=colors[m],
                        label=m)
        ax.set_xlabel("people per scene" if counts else "people per m² of free space")
        ax.set_title(title)
        if metric.endswith("_rate"):
            ax.set_ylim(-0.02, 1.02)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"Crowd level sweep, all scenes ({crowd} crowd)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def _plot_overlay(scene: str, trajs: Sequence[tuple[str, Mapping[str, Any]]], colors: Mapping[str, Any],
                  title: str, path: Path) -> None:
    """Every method's robot path in one episode over the scene; the people of the first method faintly."""
    plt = _plt()
    from navzoo.world.library import get_scene
    from navzoo.world.plot import plot_scene

    sc = get_scene(scene)
    w, h = sc.size
    fig, ax = plt.subplots(figsize=(7, max(3.0, 7 * h / max(w, 1e-9))))
    plot_scene(sc, ax=ax, show_regions=False, show_waypoints=False, title=title)
    _, first = trajs[0]
    hp = np.asarray(first["human_pos"], dtype=np.float64)
    present = first.get("human_present")
    if present is not None and np.shape(present) == hp.shape[:2]:  # replayed people: not where they are parked
        hp = np.where(np.asarray(present, dtype=bool)[..., None], hp, np.nan)
    for j in range(hp.shape[1] if hp.ndim == 3 else 0):
        ax.plot(hp[:, j, 0], hp[:, j, 1], color="tab:gray", lw=0.7, alpha=0.45,
                label=f"people ({first['method']} episode; ● start)" if j == 0 else None)
        seen = np.flatnonzero(np.isfinite(hp[:, j, 0]))
        if seen.size:
            ax.plot(hp[seen[0], j, 0], hp[seen[0], j, 1], "o", color="tab:gray", ms=3, alpha=0.6)
    for method, d in trajs:
        rp = np.asarray(d["robot_pos"])
        ax.plot(rp[:, 0], rp[:, 1], color=colors[method], lw=1.8, label=f"{method}: {d['event']}")
        ax.plot(rp[-1, 0], rp[-1, 1], "o", color=colors[method], ms=5)
    start, goal = np.asarray(first["start"]), np.asarray(first["goal"])
    ax.plot(*start, "s", color="black", ms=7, label="start")
    ax.plot(*goal, "*", color="tab:green", ms=14, label="goal")
    ax.legend(fontsize=7, loc="best")
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _trajectory_overlays(run: Path, records: Sequence[Mapping[str, Any]], methods: Sequence[str],
                         plots: Path) -> list[dict[str, str]]:
    from navzoo.benchmark.runner import _safe_name, artifact_path

    episodes: dict[tuple, list[Mapping[str, Any]]] = defaultdict(list)
    for r in records:
        if (run / "trajectories" / artifact_path(r, ".npz")).is_file():
            episodes[(r["scene"], r["crowd"], r["level"], int(r["episode"]))].append(r)
    colors = _method_colors(methods)
    out = []
    order = sorted(episodes, key=lambda k: (GROUP_ORDER.index(scene_group(k[0])), k[0], k[1],
                                            _level_sort_key(k[2]), k[3]))
    # one overlay per cell first (episode 0), then further episodes while there is room
    order = sorted(order, key=lambda k: k[3])[:MAX_TRAJECTORY_PLOTS]
    order.sort(key=lambda k: (GROUP_ORDER.index(scene_group(k[0])), k[0], k[1], _level_sort_key(k[2]), k[3]))
    for scene, crowd, level, ep in order:
        recs = sorted(episodes[(scene, crowd, level, ep)], key=lambda r: methods.index(r["method"]))
        trajs = []
        for r in recs:
            with np.load(run / "trajectories" / artifact_path(r, ".npz")) as z:
                trajs.append((r["method"], {k: z[k] for k in ("robot_pos", "human_pos", "start", "goal")}
                              | {"human_present": z["human_present"] if "human_present" in z.files else None}
                              | {"event": str(z["event"]), "method": r["method"]}))
        name = _safe_name(f"traj_{scene}_{crowd}_{level}_ep{ep:04d}") + ".png"  # rllib:PATH crowds hold slashes
        title = f"{scene}, {crowd}, {level_text(level)}, episode {ep} (seed {recs[0]['seed']})"
        _plot_overlay(scene, trajs, colors, title, plots / name)
        out.append({"file": f"plots/{name}", "title": title})
    return out


# ---------------------------------------------------------------------------------------------------------
# The report
# ---------------------------------------------------------------------------------------------------------


def _reference_rows(run_doc: Mapping[str, Any], overall: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """A protocol's published numbers next to the measured ones."""
    name = (run_doc.get("spec") or {}).get("protocol")
    if not name:
        return []
    from navzoo.benchmark.protocols import PROTOCOLS

    proto = PROTOCOLS.get(name)
    if proto is None:
        return []
    rows = []
    for method, ref in proto.reference.items():
        for r in overall:
            if r["method"] == method:
                for metric, value in ref.items():
                    rows.append({"method": method, "crowd": r["crowd"], "level": r["level"], "metric": metric,
                                 "published": value, "measured": r.get(metric),
                                 "ci95": r.get("ci95", {}).get(metric)})
    return rows


def build_report(run_dir: str | Path, out: str | Path | None = None, plots: bool = True) -> dict[str, Any]:
    """Write the report of a run directory and return its JSON content (see the module docstring).

    Raises:
        FileNotFoundError: no ``episodes.jsonl`` in ``run_dir``.
        ValueError: it holds no finished episode.
    """
    from navzoo.benchmark.runner import (
        EPISODES_FILE,
        RUN_FILE,
        _safe_name,
        artifact_path,
        load_episodes,
        load_errors,
    )

    run = Path(run_dir)
    if not (run / EPISODES_FILE).is_file():
        raise FileNotFoundError(f"{run} is not a benchmark run directory (no {EPISODES_FILE}); "
                                "run `navzoo benchmark --out DIR` first")
    records = load_episodes(run)
    if not records:
        raise ValueError(f"{run / EPISODES_FILE} holds no finished episode")
    for r in records:
        r.setdefault("group", scene_group(r["scene"]))
    run_doc: dict[str, Any] = {}
    if (run / RUN_FILE).is_file():
        run_doc = json.loads((run / RUN_FILE).read_text(encoding="utf-8"))
    spec_methods = (run_doc.get("spec") or {}).get("methods") or []
    methods = [m for m in spec_methods if any(r["method"] == m for r in records)]
    methods += sorted({r["method"] for r in records} - set(methods))
    out_dir = Path(out) if out is not None else run / "report"
    out_dir.mkdir(parents=True, exist_ok=True)

    overall = summarize(records, ("method", "crowd", "level"), methods)
    by_method = summarize(records, ("method",), methods)
    groups = summarize(records, ("method", "group", "crowd", "level"), methods)
    groups_pooled = summarize(records, ("method", "group"), methods)
    cells = summarize(records, ("method", "scene", "group", "crowd", "level"), methods)
    metrics = _metric_names(cells)
    errors = [{k: v for k, v in e.items() if k != "traceback"} for e in load_errors(run)]
    sessions = run_doc.get("sessions", [])
    wall = sum(float(s.get("wall_s") or 0.0) for s in sessions)
    n_run = sum(int(s.get("episodes_run") or 0) + int(s.get("errors") or 0) for s in sessions)

    # Tables
    _write_csv(out_dir / "groups.csv", groups, ("method", "group", "crowd", "level"), metrics)
    _write_csv(out_dir / "cells.csv", cells, ("method", "scene", "group", "crowd", "level"), metrics)
    _write_csv(out_dir / "overall.csv", overall, ("method", "crowd", "level"), metrics)

    # Plots
    figures: list[dict[str, str]] = []
    overlays: list[dict[str, str]] = []
    if plots:
        pdir = out_dir / "plots"
        pdir.mkdir(exist_ok=True)
        _plot_metric_bars(by_method, methods, pdir / "metric_bars.png")
        figures.append({"file": "plots/metric_bars.png", "title": "Metrics per method (all scenes and levels)"})
        _plot_group_bars(groups_pooled, methods, pdir / "group_bars.png")
        figures.append({"file": "plots/group_bars.png", "title": "Success and collision per scene group"})
        for crowd in sorted({r["crowd"] for r in overall}):
            name = _safe_name(f"density_sweep_{crowd}") + ".png"
            _plot_density_sweep([r for r in overall if r["crowd"] == crowd], methods, crowd, pdir / name)
            figures.append({"file": f"plots/{name}", "title": f"Crowd level sweep ({crowd} crowd)"})
        overlays = _trajectory_overlays(run, records, methods, pdir)

    videos = []
    for r in sorted(records, key=lambda r: (r["scene"], r["crowd"], _level_sort_key(r["level"]), r["episode"],
                                            methods.index(r["method"]))):
        mp4 = run / "videos" / artifact_path(r, ".mp4")
        if mp4.is_file():
            poster = mp4.with_suffix(".png")
            videos.append({"method": r["method"], "scene": r["scene"], "crowd": r["crowd"], "level": r["level"],
                           "episode": r["episode"], "event": r["event"], "video": _rel(mp4, out_dir),
                           "poster": _rel(poster, out_dir) if poster.is_file() else None})

    spec = run_doc.get("spec", {})
    result = {
        "run": str(run),
        "spec": spec,
        "machine": run_doc.get("machine"),
        "merged_from": run_doc.get("merged_from"),
        "sessions": sessions,
        "wall_s": wall,
        "episodes_per_hour": 3600.0 * n_run / wall if wall > 0 else None,
        "n_episodes": len(records),
        "episodes_total": run_doc.get("episodes_total"),
        "n_errors": len(errors),
        "errors": errors,
        "methods": methods,
        "metric_names": metrics,
        "thresholds": run_doc.get("thresholds"),
        "overall": by_method,
        "levels": overall,
        "groups": groups,
        "cells": cells,
        "reference": _reference_rows(run_doc, overall),
        "figures": figures,
        "trajectory_plots": overlays,
        "videos": videos,
    }
    result = _json_ready(result)
    files = {"markdown": out_dir / "report.md", "html": out_dir / "report.html", "json": out_dir / "report.json",
             "groups_csv": out_dir / "groups.csv", "cells_csv": out_dir / "cells.csv",
             "overall_csv": out_dir / "overall.csv"}
    result["files"] = {k: str(v) for k, v in files.items()}
    files["markdown"].write_text(_markdown(result), encoding="utf-8")
    files["html"].write_text(_html(result), encoding="utf-8")
    files["json"].write_text(json.dumps(result, indent=1, allow_nan=False) + "\n", encoding="utf-8")
    return result


def _rel(path: Path, start: Path) -> str:
    import os

    return Path(os.path.relpath(path, start)).as_posix()


def _machine_text(machine: Mapping[str, Any]) -> str:
    commit = (machine.get("git_commit") or "")[:10]
    return (f"{machine.get('cpu')}, {machine.get('cores')} cores, Python {machine.get('python')}"
            + (f", navzoo {commit}{' (dirty)' if machine.get('git_dirty') else ''}" if commit else ""))


def _run_lines(res: Mapping[str, Any]) -> list[str]:
    spec, machine = res.get("spec") or {}, res.get("machine") or {}
    lines = []
    if spec:
        if spec.get("density"):
            lv = "density " + ", ".join(f"{d:g}" for d in spec["density"]) + " people/m²"
        elif spec.get("humans"):
            lv = ", ".join(str(n) for n in spec["humans"]) + " people"
        else:
            lv = "the scenes' default people"
        crowds = spec.get("crowd") or []
        if "replay" in crowds:  # the replay crowd brings its own people (runner.REPLAY_LEVEL)
            lv = "the recorded people" if len(crowds) == 1 else f"{lv} (replay: the recorded people)"
        ns, nm = len(spec.get("scenes", [])), len(spec.get("methods", []))
        lines.append(f"{ns} scene{'s' * (ns != 1)} × {nm} method{'s' * (nm != 1)} × crowd "
                     f"{', '.join(spec.get('crowd', []))} × {lv} × {spec.get('episodes')} episodes, seed "
                     f"{spec.get('seed')}" + (f", protocol {spec['protocol']}" if spec.get("protocol") else ""))
    if machine:
        lines.append(f"machine: {_machine_text(machine)}")
    for src in res.get("merged_from") or []:
        lines.append(f"merged from {src.get('run')}: {', '.join(src.get('methods') or [])}"
                     + (f" (machine: {_machine_text(src['machine'])})" if src.get("machine") else ""))
    if res.get("wall_s"):
        eph = res.get("episodes_per_hour")
        lines.append(f"wall time {res['wall_s'] / 3600:.2f} h over {len(res.get('sessions', []))} session(s)"
                     + (f", {eph:.0f} episodes/h" if eph else ""))
    lines.append(f"episodes: {res['n_episodes']} finished" + (f" of {res['episodes_total']}" if res.get("episodes_total")
                                                               else "") + f", {res['n_errors']} failed")
    return lines


def _markdown(res: Mapping[str, Any]) -> str:
    md = ["# Benchmark report", ""]
    md += [f"- {line}" for line in _run_lines(res)]
    md += ["", "Mean ± 95 % confidence interval over episodes (Student t); navigation time over successful "
           "episodes only; discomfort = share of steps closer than 0.2 m, pooled. Metric definitions: "
           "docs/metrics.md.", ""]
    if res.get("reference"):
        md += ["## Published reference", "", "| method | metric | published | measured |", "|---|---|---|---|"]
        for r in res["reference"]:
            md.append(f"| {r['method']} | {r['metric']} | {r['published']} | {_fmt(r['measured'], r['ci95'], 3)} |")
        md.append("")
    md += ["## All scenes", ""]
    md += _md_table(res["levels"], (("method", "method"), ("crowd", "crowd"), ("level", "people")))
    for group in GROUP_ORDER:
        rows = [r for r in res["groups"] if r["group"] == group]
        if not rows:
            continue
        scenes = sorted({c["scene"] for c in res["cells"] if c["group"] == group})
        md += ["", f"## {group} ({', '.join(scenes)})", ""]
        md += _md_table(rows, (("method", "method"), ("crowd", "crowd"), ("level", "people")))
    if res.get("errors"):
        md += ["", "## Failed episodes", "", "| method | scene | crowd | people | episode | seed | error |",
               "|---|---|---|---|---|---|---|"]
        for e in res["errors"][:100]:
            msg = str(e.get("message", "")).replace("|", "\\|").replace("\n", " ")[:160]
            md.append(f"| {e['method']} | {e['scene']} | {e['crowd']} | {level_text(e['level'])} | {e['episode']} | "
                      f"{e['seed']} | {e.get('type')}: {msg} |")
    md += ["", "Per-scene numbers: `cells.csv`; every metric: `groups.csv`, `report.json`; plots: `report.html`.", ""]
    return "\n".join(md)


_CSS = """body{font-family:system-ui,sans-serif;margin:2em;max-width:1400px;color:#222}
table{border-collapse:collapse;margin:0.5em 0 1.5em;font-size:13px}th,td{border:1px solid #ccc;padding:3px 7px;
text-align:right}th{background:#f0f0f0}td:nth-child(-n+3){text-align:left}img{max-width:100%;border:1px solid #ddd}
.grid{display:flex;flex-wrap:wrap;gap:12px}.grid figure{margin:0;width:440px}figcaption{font-size:12px;color:#555}
code{background:#f4f4f4;padding:1px 3px}"""


def _html(res: Mapping[str, Any]) -> str:
    e = html.escape
    parts = ["<!doctype html><html><head><meta charset='utf-8'><title>navzoo benchmark report</title>",
             f"<style>{_CSS}</style></head><body><h1>navzoo benchmark report</h1><ul>"]
    parts += [f"<li>{e(line)}</li>" for line in _run_lines(res)]
    parts.append("</ul><p>Mean ± 95 % confidence interval over episodes. Tables as CSV: "
                 "<a href='overall.csv'>overall.csv</a>, <a href='groups.csv'>groups.csv</a>, "
                 "<a href='cells.csv'>cells.csv</a>; all numbers: <a href='report.json'>report.json</a>.</p>")
    if res.get("reference"):
        parts.append("<h2>Published reference</h2><table><tr><th>method</th><th>metric</th><th>published</th>"
                     "<th>measured</th></tr>")
        for r in res["reference"]:
            parts.append(f"<tr><td>{e(r['method'])}</td><td>{e(r['metric'])}</td><td>{r['published']}</td>"
                         f"<td>{e(_fmt(r['measured'], r['ci95'], 3))}</td></tr>")
        parts.append("</table>")
    parts.append("<h2>All scenes</h2>")
    parts.append(_html_table(res["levels"], (("method", "method"), ("crowd", "crowd"), ("level", "people"))))
    for fig in res.get("figures", []):
        parts.append(f"<figure><img src='{e(fig['file'])}' alt='{e(fig['title'])}'>"
                     f"<figcaption>{e(fig['title'])}</figcaption></figure>")
    for group in GROUP_ORDER:
        rows = [r for r in res["groups"] if r["group"] == group]
        if rows:
            scenes = sorted({c["scene"] for c in res["cells"] if c["group"] == group})
            parts.append(f"<h2>{e(group)}</h2><p>{e(', '.join(scenes))}</p>")
            parts.append(_html_table(rows, (("method", "method"), ("crowd", "crowd"), ("level", "people"))))
    if res.get("trajectory_plots"):
        parts.append("<h2>Trajectories</h2><p>Every method in the same episode (same start, goal and crowd "
                     "seed); people's paths of the first method in orange.</p><div class='grid'>")
        for fig in res["trajectory_plots"]:
            parts.append(f"<figure><a href='{e(fig['file'])}'><img src='{e(fig['file'])}' alt='{e(fig['title'])}'>"
                         f"</a><figcaption>{e(fig['title'])}</figcaption></figure>")
        parts.append("</div>")
    if res.get("videos"):
        parts.append("<h2>Videos</h2><p>Top-down, MPEG-4 (<code>mp4v</code>; a browser may download it rather "
                     "than play it: VLC or mpv play it). The picture is the last frame.</p><div class='grid'>")
        for v in res["videos"]:
            cap = f"{v['method']} on {v['scene']}, {v['crowd']}, {level_text(v['level'])}, episode {v['episode']}: " \
                  f"{v['event']}"
            img = f"<img src='{e(v['poster'])}' alt='{e(cap)}'>" if v.get("poster") else e(cap)
            parts.append(f"<figure><a href='{e(v['video'])}'>{img}</a><figcaption><a href='{e(v['video'])}'>"
                         f"{e(cap)}</a></figcaption></figure>")
        parts.append("</div>")
    if res.get("errors"):
        parts.append("<h2>Failed episodes</h2><table><tr><th>method</th><th>scene</th><th>crowd</th><th>people</th>"
                     "<th>episode</th><th>seed</th><th>error</th></tr>")
        for x in res["errors"][:200]:
            parts.append(f"<tr><td>{e(x['method'])}</td><td>{e(x['scene'])}</td><td>{e(x['crowd'])}</td>"
                         f"<td>{e(level_text(x['level']))}</td><td>{x['episode']}</td><td>{x['seed']}</td>"
                         f"<td style='text-align:left'>{e(str(x.get('type')))}: {e(str(x.get('message'))[:300])}</td></tr>")
        parts.append("</table>")
    parts.append("</body></html>")
    return "\n".join(parts)


# ---------------------------------------------------------------------------------------------------------
# Command line (``navzoo report``)
# ---------------------------------------------------------------------------------------------------------


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("run_dir", metavar="DIR", nargs="+",
                        help="a run directory of `navzoo benchmark`; several (run directories or folders with a "
                             "committed episodes.jsonl.gz) are merged into OUT/merged_run first, e.g. a new method's "
                             "run next to benchmarks/full_sfm (same scenes, levels, seed)")
    parser.add_argument("--out", default=None, help="report folder (default DIR/report; required with several DIRs)")
    parser.add_argument("--no-plots", action="store_true", help="tables only")
    parser.add_argument("--json", action="store_true",
                        help="print the numbers as one JSON object: per method (overall), per crowd level, scene "
                             "group and cell, every metric under its name with ci95")


def run_cli(args: argparse.Namespace) -> int:
    run_dir, out = args.run_dir, args.out
    if isinstance(run_dir, (list, tuple)):
        if len(run_dir) > 1:
            if out is None:
                raise ValueError("navzoo report with several run directories needs --out (the merged run and "
                                 "its report go there)")
            from navzoo.benchmark.runner import merge_runs

            merge_runs(run_dir, Path(out) / "merged_run")
            run_dir = Path(out) / "merged_run"
        else:
            run_dir = run_dir[0]
    res = build_report(run_dir, out, plots=not args.no_plots)
    if args.json:
        print(json.dumps(res, allow_nan=False))
        return 0
    print(Path(res["files"]["markdown"]).read_text(encoding="utf-8"))
    print(f"report: {res['files']['html']} (tables: {res['files']['markdown']}, {res['files']['groups_csv']})",
          file=sys.stderr)
    return 0
