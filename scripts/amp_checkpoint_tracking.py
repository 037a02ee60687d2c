"""Clip tracking (the paper's protocol) of AMP training checkpoints, to compare runs per sample.

With ``--protocol tracking_full`` the same clip tracking without ending a clip at its failure: every clip is
tracked for its whole duration, so the error means of controllers that fail early and late cover the same
seconds (the paper's protocol ends each clip at its failure, and then a controller that fails after one second
is scored on its first second only).

Or, with ``--protocol path3``, the training task's closed-loop check on stage-3 paths (curvy, with stops;
``navzoo.agents.amp.evaluate``: falls, path error; 32 patches x 60 s, seed 0; no obstacles for a policy
without obstacle rays, boxes and paired walkers for one with them, so compare like with like).

    python scripts/amp_checkpoint_tracking.py --out docs/results/amp_scratch_tracking.jsonl \\
        training/amp_scratch git:0ccd479:training/amp git:3ea0b4b:training/amp \\
        training/amp_scratch/policies/policy_00001059 training/amp_scratch/policies/policy_00001478

Or, with ``--protocol stance``, the split stance (docs/pedestrians_log.md, "Where the realism gap lies") of any
checkpoint, with or without obstacle rays: the whole clips are tracked as with ``tracking_full`` and the poses of
the standing bodies (15 keypoints, root-centred, heading-aligned, in spine lengths, as the realism metrics) are
compared with the clips': the mean walking pose (root speed 0.9 m/s and more) minus the clips' mean walking pose
for the right and left foot along the heading (``right_foot_fwd``, ``left_foot_fwd``; the shipped policy about
+0.70 / -0.51, the clips 0 by definition), their difference ``foot_split``, and the realism MMD of the tracking
poses against the clips (``tracking_mmd``, every control step).

With ``--export-dir DIR`` the sources are only exported, each to ``DIR/policy_<source>`` (characters other than
letters, digits, ``.``, ``_``, ``-`` replaced by ``_``), for the POLICY field of ``scripts/amp_target_ablation.py``:

    python scripts/amp_checkpoint_tracking.py --export-dir /tmp/lin git:3ea0b4b:training/amp
    # -> /tmp/lin/policy_git_3ea0b4b_training_amp

Each source is one of
- a training folder as committed (``name``, ``meta.json``, ``state.pt.part-*``): its checkpoint is exported;
- ``git:REV:FOLDER``: the same folder as it was at commit REV (earlier checkpoints of a run);
- an exported policy folder (``config.json`` + ``policy.pt``).

For every source one JSON line is appended to ``--out``: the checkpoint's iteration and samples, the protocol,
and its summary (tracking: ``navzoo.agents.amp.tracking.track_clips`` over all packaged locomotion clips, no
steering trim unless the policy's config has one). A source already in ``--out`` with the same protocol and
checkpoint (iteration) is skipped, so an interrupted run resumes.
Tracking runs on one torch thread (track_clips sees to it) and is deterministic on one kind of CPU; it takes
about 15-20 s per policy on a 2-core VM.
"""

from __future__ import annotations

import argparse
import json
import re
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from navzoo.agents.amp.checkpoint import join_split_checkpoint
from navzoo.agents.amp.evaluate import evaluate
from navzoo.agents.amp.tracking import track_clips
from navzoo.agents.amp.train import export_from_checkpoint


def _git_files(rev: str, folder: str) -> list[str]:
    out = subprocess.run(["git", "ls-tree", "--name-only", f"{rev}:{folder}"], check=True, capture_output=True, text=True)
    return out.stdout.split()


def _git_show(rev: str, path: str) -> bytes:
    return subprocess.run(["git", "show", f"{rev}:{path}"], check=True, capture_output=True).stdout


def _is_blend(path: Path) -> bool:
    """Whether ``path`` is a blend of exported policies (:mod:`navzoo.agents.amp.blend`)."""
    import json

    from navzoo.agents.amp.blend import BLEND_FORMAT

    try:
        return json.loads((path / "config.json").read_text()).get("format") == BLEND_FORMAT
    except (OSError, ValueError, AttributeError):
        return False


def materialise(source: str, work: Path) -> Path:
    """An exported policy folder for ``source`` (see the module doc)."""
    if source.startswith("git:"):
        try:
            _, rev, folder = source.split(":", 2)
        except ValueError:
            raise SystemExit(f"{source}: expected git:REV:FOLDER") from None
        files = [f for f in _git_files(rev, folder) if f.startswith("state.pt.part-") or f == "meta.json"]
        path = work / f"git_{rev}"
        path.mkdir(parents=True)
        for f in files:
            (path / f).write_bytes(_git_show(rev, f"{folder}/{f}"))
    else:
        path = Path(source)
        if (path / "config.json").exists() and ((path / "policy.pt").exists() or _is_blend(path)):
            return path
    try:
        ckpt = join_split_checkpoint(path, work / f"ckpt_{path.name}")
    except FileNotFoundError as e:
        raise SystemExit(f"{source}: neither an exported policy (config.json, policy.pt), a blend, nor a training folder "
                         f"({e})") from None
    return export_from_checkpoint(ckpt, work / f"policy_{path.name}")


def export_name(source: str) -> str:
    """The folder name of ``source``'s exported policy under ``--export-dir``: ``policy_`` and the source with every
    character other than letters, digits, ``.``, ``_`` and ``-`` replaced by ``_`` (``git:3ea0b4b:training/amp`` ->
    ``policy_git_3ea0b4b_training_amp``)."""
    return "policy_" + re.sub(r"[^A-Za-z0-9._-]", "_", source.strip("/"))


def export(source: str, export_dir: Path) -> Path:
    """``source`` (module doc) as an exported policy folder ``export_dir / export_name(source)``, kept; refuses to
    overwrite a folder that is there already."""
    dest = export_dir / export_name(source)
    if dest.exists():
        raise SystemExit(f"{dest} exists: remove it or choose another --export-dir")
    export_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=export_dir) as tmp:
        policy = materialise(source, Path(tmp))
        shutil.copytree(policy, dest)
    return dest


def stance(policy: Path, walk: float = 0.9) -> dict:
    """The ``stance`` protocol (module doc): whole-clip tracking, then the walking poses' foot bias and MMD, with the
    posture bias of ``scripts/amp_realism_by_speed.py`` (the realism study's own definition)."""
    import numpy as np

    from navzoo.agents.amp.tracking import load_motions
    from navzoo.benchmark import realism

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from amp_realism_by_speed import posture, reference_speeds  # the sibling script

    lib = load_motions(None)
    sink: list = []
    result = track_clips(policy, lib, stop_on_failure=False, pose_sink=sink)
    poses = np.concatenate([p for p, _ in sink])
    speeds = np.concatenate([v for _, v in sink])
    ref_poses, ref_speeds, _ = reference_speeds(lib)
    ref = realism.RealismReference.fit(ref_poses, seed=0)
    out = {k: result[k] for k in ("clip_success_rate", "mean_pos_error_m", "mean_rot_error_rad", "fall_rate")
           if k in result}
    out["walking_poses"] = int((speeds >= walk).sum())
    bias = posture(poses, speeds, ref_poses, ref_speeds, ref, walk).get("bias")  # None below 100 walking poses
    out["right_foot_fwd"] = bias["right_foot"][0] if bias else None
    out["left_foot_fwd"] = bias["left_foot"][0] if bias else None
    out["foot_split"] = out["right_foot_fwd"] - out["left_foot_fwd"] if bias else None
    out["tracking_mmd"] = float(realism.realism_metrics(poses, ref)["mmd"])
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sources", nargs="+")
    ap.add_argument("--out", help="JSON lines, appended; sources already there are skipped")
    ap.add_argument("--protocol", choices=("tracking", "tracking_full", "path3", "stance"), default="tracking")
    ap.add_argument("--export-dir", metavar="DIR",
                    help="only export: write each source's policy to DIR/policy_<name> (for other scripts' POLICY "
                         "arguments, e.g. scripts/amp_target_ablation.py) and print the folders; no protocol runs")
    args = ap.parse_args(argv)
    if args.export_dir:
        for source in args.sources:
            print(export(source, Path(args.export_dir)))
        return 0
    if not args.out:
        ap.error("--out is required unless --export-dir is given")
    out = Path(args.out)
    done = set()
    if out.exists():
        rows = [json.loads(line) for line in out.read_text().splitlines() if line.strip()]
        # a training folder holds another checkpoint after each run: a source is done per checkpoint
        done = {(row["source"], row.get("trained_iterations")) for row in rows
                if row.get("protocol", "tracking") == args.protocol}
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for source in args.sources:
            policy = materialise(source, Path(tmp) / str(len(list(Path(tmp).iterdir()))))
            config = json.loads((policy / "config.json").read_text())
            if (source, config.get("trained_iterations")) in done:
                print(f"{source} (iteration {config.get('trained_iterations')}): already in {out}", file=sys.stderr)
                continue
            if args.protocol in ("tracking", "tracking_full"):
                result = track_clips(policy, stop_on_failure=args.protocol == "tracking")
                shown = ("clip_success_rate", "mean_pos_error_m", "max_pos_error_m", "mean_rot_error_rad")
            elif args.protocol == "stance":
                result = stance(policy)
                shown = ("right_foot_fwd", "left_foot_fwd", "foot_split", "tracking_mmd", "clip_success_rate")
            else:
                result = evaluate(str(policy), envs=32, seconds=60.0, stage=3, seed=0)
                shown = ("episodes_ended", "falls", "mean_path_error_m", "reward_per_step")
            row = {"source": source, "protocol": args.protocol, "trained_iterations": config.get("trained_iterations"),
                   "trained_steps": config.get("trained_steps"), **result}
            row["policy_dir"] = str(policy) if not str(policy).startswith(tmp) else None
            with out.open("a") as f:
                f.write(json.dumps(row) + "\n")
            print(json.dumps({k: row[k] for k in ("source", "trained_steps", *shown)}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
