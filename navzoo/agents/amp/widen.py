"""Grow a training checkpoint's policy input to a longer observation (new inputs appended at the end).

    python -m navzoo.agents.amp.widen SRC_CKPT_DIR DST_ROOT --obs-dim 141 [--export POLICY_DIR]

SRC_CKPT_DIR is a checkpoint directory (``ckpt_*``) or a committed training folder whose state is split in
``state.pt.part-*`` files (e.g. ``training/amp_stance``). ``--export`` also writes the widened checkpoint's
deterministic policy (:func:`navzoo.agents.amp.train.export_from_checkpoint`): a policy that takes the wider
observation and ignores the new inputs, i.e. where a resumed run with them starts (docs/pedestrians_log.md, "The
stance run before its obstacle stage").

Used to add the obstacle rays (16 inputs) to a policy trained without them, instead of training from
scratch: the actor's and critic's first-layer weights get zero columns for the new inputs (so the
widened networks compute exactly what they did), the observation normaliser starts the new inputs at
mean 0 / variance 1, and the Adam moments of those columns start at zero. Everything else (other
layers, discriminator, replay, optimiser steps, RNG, counters) is copied. The env-side arrays are
dropped, so the resumed run starts from freshly reset envs.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Any

import torch

from navzoo.agents.amp import checkpoint as ckpt


def _pad_cols(t: torch.Tensor, old: int, new: int) -> torch.Tensor:
    out = torch.zeros((*t.shape[:-1], new), dtype=t.dtype)
    out[..., :old] = t
    return out


def _widen_net(sd: dict[str, torch.Tensor], old: int, new: int) -> tuple[dict[str, torch.Tensor], list[str]]:
    """Zero-pad every 2-D weight whose input width is ``old`` (the first layer); returns the names."""
    out, names = {}, []
    for k, v in sd.items():
        if v.ndim == 2 and v.shape[1] == old and k.endswith("weight"):
            out[k] = _pad_cols(v, old, new)
            names.append(k)
        else:
            out[k] = v
    if len(names) != 1:
        raise ckpt.CheckpointError(f"expected one first-layer weight of input width {old}, found {names}")
    return out, names


def _widen_opt(opt: dict[str, Any], old: int, new: int) -> dict[str, Any]:
    state = {}
    for idx, st in opt["state"].items():
        st = dict(st)
        for key in ("exp_avg", "exp_avg_sq"):
            v = st.get(key)
            if isinstance(v, torch.Tensor) and v.ndim == 2 and v.shape[1] == old:
                st[key] = _pad_cols(v, old, new)
        state[idx] = st
    return {**opt, "state": state}


def widen_checkpoint(src: str | Path, dst_root: str | Path, obs_dim: int) -> Path:
    tensors, meta = ckpt.load_checkpoint(src)
    old = int(meta["dims"]["obs_dim"])
    if obs_dim <= old:
        raise ValueError(f"new obs_dim {obs_dim} must exceed the checkpoint's {old}")
    t = dict(tensors)
    t["actor"], _ = _widen_net(tensors["actor"], old, obs_dim)
    t["critic"], _ = _widen_net(tensors["critic"], old, obs_dim)
    t["actor_opt"] = _widen_opt(tensors["actor_opt"], old, obs_dim)
    t["critic_opt"] = _widen_opt(tensors["critic_opt"], old, obs_dim)
    norm = dict(tensors["obs_norm"])
    norm["mean"] = torch.cat([norm["mean"], torch.zeros(obs_dim - old, dtype=norm["mean"].dtype)])
    norm["var"] = torch.cat([norm["var"], torch.ones(obs_dim - old, dtype=norm["var"].dtype)])
    t["obs_norm"] = norm
    t["learner"] = {k: v for k, v in tensors["learner"].items() if k not in ("obs", "ep_return", "ep_len")}
    t["env"] = {}
    new_meta = {k: v for k, v in meta.items() if k not in ("format", "version", "iteration", "state_sha256")}
    new_meta["dims"] = {**meta["dims"], "obs_dim": obs_dim}
    new_meta.pop("env_state", None)
    new_meta["widened_from"] = {"obs_dim": old, "checkpoint": Path(src).name}
    return ckpt.save_checkpoint(dst_root, int(meta["iteration"]), t, new_meta)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("src")
    parser.add_argument("dst_root")
    parser.add_argument("--obs-dim", type=int, required=True)
    parser.add_argument("--export", default=None, metavar="POLICY_DIR",
                        help="also export the widened checkpoint's policy here")
    args = parser.parse_args(argv)
    src = Path(args.src)
    with tempfile.TemporaryDirectory() as tmp:
        if not (src / ckpt.STATE_FILE).is_file() and any(src.glob(f"{ckpt.STATE_FILE}.part-*")):
            src = ckpt.join_split_checkpoint(src, Path(tmp) / src.name)  # a committed training folder
        out = widen_checkpoint(src, args.dst_root, args.obs_dim)
    print(out)
    if args.export:
        from navzoo.agents.amp.train import export_from_checkpoint

        print(export_from_checkpoint(out, args.export))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
