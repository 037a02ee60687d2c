"""scripts/device_slim_tree.sh: moves what a device call does not need out of the tree and back, losing nothing."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _run(repo: Path, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "scripts/device_slim_tree.sh", *args], cwd=repo, capture_output=True, text=True)


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_out_keeps_the_named_paths_and_back_restores_everything(tmp_path: Path) -> None:
    repo = tmp_path / "repo"
    (repo / "scripts").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "device_slim_tree.sh", repo / "scripts")
    files = ["training/run_a/state.pt.part-aa", "training/run_a/policies/policy_00000010/policy.pt",
             "training/run_b/meta.json", "training/run_b/policies/p/policy.pt", "policies/amp/policy.pt",
             "policies/other/model.pt", "policies/README.md", "docs/x.md", "benchmarks/r/e.jsonl", "navzoo/a.py"]
    for i, f in enumerate(files):
        (repo / f).parent.mkdir(parents=True, exist_ok=True)
        (repo / f).write_text(f"content {i}\n")
    subprocess.run(["git", "init", "-q"], cwd=repo, check=True)
    subprocess.run(["git", "add", "."], cwd=repo, check=True)
    stash = tmp_path / ".device_stash"

    out = _run(repo, "out", "training/run_a", "policies/amp/")
    assert out.returncode == 0, out.stderr
    present = {f for f in files if (repo / f).exists()}
    assert present == {"training/run_a/state.pt.part-aa", "policies/amp/policy.pt", "policies/README.md", "navzoo/a.py"}
    assert (stash / "training/run_b/meta.json").exists() and (stash / "docs/x.md").exists()
    # a kept training folder's exported policies are not needed to train: they leave too
    assert (stash / "training/run_a/policies/policy_00000010/policy.pt").exists()
    again = _run(repo, "out")
    assert again.returncode == 1 and "run 'back' first" in again.stderr

    back = _run(repo, "back")
    assert back.returncode == 0, back.stderr
    for i, f in enumerate(files):
        assert (repo / f).read_text() == f"content {i}\n", f
    assert not stash.exists()
    assert _run(repo, "back").returncode == 1  # nothing to put back
    bad = _run(repo, "out", "no/such/path")
    assert bad.returncode == 1 and "no/such/path" in bad.stderr and not stash.exists()


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_back_moves_nothing_when_a_stashed_path_was_made_again(tmp_path: Path) -> None:
    """Results copied into docs/ while it is stashed: ``back`` names the clash and leaves both sides whole."""
    repo = tmp_path / "repo"
    (repo / "scripts").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "device_slim_tree.sh", repo / "scripts")
    files = ["training/run_b/meta.json", "policies/other/model.pt", "docs/x.md", "benchmarks/r/e.jsonl"]
    for f in files:
        (repo / f).parent.mkdir(parents=True, exist_ok=True)
        (repo / f).write_text(f)
    subprocess.run(["git", "init", "-q"], cwd=repo, check=True)
    stash = tmp_path / ".device_stash"
    assert _run(repo, "out").returncode == 0
    (repo / "docs/results").mkdir(parents=True)
    (repo / "docs/results/new.jsonl").write_text("new")
    back = _run(repo, "back")
    assert back.returncode == 1 and "docs" in back.stderr and "nothing moved" in back.stderr
    assert all((stash / f).read_text() == f for f in files)  # the stash is whole
    assert not (repo / "training/run_b").exists() and (repo / "docs/results/new.jsonl").read_text() == "new"
    shutil.move(repo / "docs/results/new.jsonl", tmp_path / "new.jsonl")
    shutil.rmtree(repo / "docs")
    assert _run(repo, "back").returncode == 0
    assert all((repo / f).read_text() == f for f in files) and not stash.exists()
