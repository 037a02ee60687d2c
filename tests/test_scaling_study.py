"""Scaling study (runtime scaling and parallel training): tiny budgets, resume, plots, CLI, bad arguments."""

from __future__ import annotations

import argparse
import json

import pytest
import torch

from navzoo.agents.scaling_study import (
    PARALLEL_KEY,
    ModelSize,
    add_arguments,
    main,
    parallel_training,
    plot_parallel,
    plot_runtime,
    read_jsonl,
    run_cli,
    runtime_scaling,
    write_jsonl,
)
from navzoo.envs.registry import make_raw

TINY = ModelSize(features_dim=16, heads=2, blocks=1, net_arch=(16,))
PNG_MAGIC = b"\x89PNG"


pytestmark = pytest.mark.usefixtures("one_torch_thread")


def _peds_in(env_id: str) -> int:
    env = make_raw(env_id)
    try:
        return sum(a.startswith("human_") for a in env.possible_agents)
    finally:
        env.close()


@pytest.fixture(scope="module")
def runtime_rows(tmp_path_factory) -> tuple[list[dict], object]:
    torch.set_num_threads(1)
    out = tmp_path_factory.mktemp("runtime") / "runtime.jsonl"
    rows = runtime_scaling("peds", [1, 2], "home", 1.0, "cpu", workers=0, out=out)
    rows += runtime_scaling("infer", [1, 2], "navzoo/Home-v0", 1.0, "cpu", workers=1, out=out)
    return rows, out


def test_runtime_peds_and_infer_rows(runtime_rows):
    rows, out = runtime_rows
    peds = _peds_in("navzoo/Home-v0")
    assert peds > 0
    assert [(r["mode"], r["n_envs"]) for r in rows] == [("peds", 1), ("peds", 2), ("infer", 1), ("infer", 2)]
    for r in rows:
        assert r["scene"] == "navzoo/Home-v0" and r["device"] == "cpu"
        assert r["env_steps"] > 0 and r["env_steps"] % r["n_envs"] == 0
        assert r["wall_s"] >= 0.9 and r["env_steps_per_s"] > 0
        assert r["agent_steps_per_s"] == pytest.approx(r["env_steps_per_s"] * r["agents_per_env"], rel=1e-3)
        assert r["machine"]["cpu_count"] >= 1 and r["machine"]["torch"] == torch.__version__
    for r in rows[:2]:  # pedestrians only: n_robots=0 is supported
        assert r["robots_per_env"] == 0 and r["agents_per_env"] == peds and r["workers"] == 0
        assert "n_robots=0" in r["note"]
    for r in rows[2:]:
        assert r["robots_per_env"] == 1 and r["agents_per_env"] == peds + 1 and r["workers"] == 1
        assert 0 < r["policy_fraction"] <= 1 and r["model"] == ModelSize().to_dict()
    assert read_jsonl(out) == rows  # appended as measured


def test_runtime_peds_in_worker_processes():
    (row,) = runtime_scaling("peds", [2], "home", 1.0, "cpu", workers=2, steps=5, warmup_steps=1)
    assert row["workers"] == 2 and row["env_steps"] == 10 and row["env_steps_per_s"] > 0
    assert len(row["worker_env_steps_per_s"]) == 2


def test_runtime_peds_worker_failure_is_reported(monkeypatch):
    import navzoo.envs.registry as registry

    def broken(*args, **kwargs):
        raise OSError("no pybullet today")

    monkeypatch.setattr(registry, "make", broken)  # the forked workers inherit the patch
    with pytest.raises(RuntimeError, match="no pybullet today"):
        runtime_scaling("peds", [2], "home", 1.0, "cpu", workers=2, steps=2)


def test_runtime_train_mode(tmp_path):
    (row,) = runtime_scaling("train", [1], "navzoo/CircleCrossing-v0", 3.0, "cpu", workers=0, model=TINY,
                             n_steps=8, n_epochs=1)
    assert row["mode"] == "train" and row["env_steps_per_s"] > 0 and row["env_steps"] > 0
    assert row["agents_per_env"] == 1 + _peds_in("navzoo/CircleCrossing-v0")
    assert row["agent_steps_per_s"] == pytest.approx(row["env_steps_per_s"] * row["agents_per_env"], rel=1e-3)
    assert row["rollouts"] == 4 and row["env_steps_per_s_incl_setup"] > 0  # whole rollouts, updates included
    assert row["rate_source"].startswith("steady state over rollouts 2..4") and row["env_steps"] == 3 * 8


def test_parallel_study_and_plots(tmp_path, runtime_rows):
    out = tmp_path / "parallel.jsonl"
    rows = parallel_training([1, 2], [64], 32, "home", "cpu", workers=0, model=TINY, n_steps=16, n_epochs=1,
                             out=out)
    assert [(r["robots"], r["batch_size"]) for r in rows] == [(1, 16), (2, 32)]  # capped at n_steps x robots
    assert [r["iterations"] for r in rows] == [2, 2]  # fixed simulator steps: same iterations, R x the data
    for r in rows:
        assert r["timesteps"] == 32 * r["robots"] and r["stop_reason"] == "total_steps"
        assert r["iteration_s_median"] > 0
        assert r["time_to_target_updates_s_extrapolated"] == pytest.approx(r["iteration_s_median"] * 5000, rel=1e-3)
        assert "ep_rew_mean" in r and "success_rate" in r and "extrapolated" in r["note"]
    assert read_jsonl(out) == rows
    png = plot_parallel(rows, tmp_path / "parallel.png")
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == PNG_MAGIC
    png = plot_runtime(runtime_rows[0], tmp_path / "runtime.png")
    assert png.stat().st_size > 1000 and png.read_bytes()[:4] == PNG_MAGIC


def test_batch_sizes_capped_to_the_same_run_train_once(tmp_path, monkeypatch, capsys):
    import navzoo.agents.scaling_study as study

    trained = []
    real = study._train_quiet
    monkeypatch.setattr(study, "_train_quiet", lambda targs: trained.append(targs.batch_size) or real(targs))
    out = tmp_path / "par.jsonl"
    kw = dict(workers=0, model=TINY, n_steps=16, n_epochs=1, out=out, resume=True)
    # R = 1: a rollout of 16 steps caps both 64 and 512 at 16, so they are one run
    first, copy = parallel_training([1], [64, 512], 32, "home", "cpu", **kw)
    assert trained == [16]
    assert first["batch_size"] == copy["batch_size"] == 16 and "same_run_as_batch_size_requested" not in first
    assert copy["batch_size_requested"] == 512 and copy["same_run_as_batch_size_requested"] == 64
    assert copy["iteration_s_all"] == first["iteration_s_all"] and copy["ep_rew_mean"] == first["ep_rew_mean"]
    assert "measured once" in copy["note"] and "not trained again" in capsys.readouterr().err
    # resumed with one more capped size: copied from the file, still no training
    (more,) = parallel_training([1], [64, 512, 1024], 32, "home", "cpu", **kw)
    assert trained == [16] and more["batch_size_requested"] == 1024
    assert more["same_run_as_batch_size_requested"] == 64
    assert [r["batch_size_requested"] for r in read_jsonl(out)] == [64, 512, 1024]


def test_parallel_run_cut_off_continues_from_its_checkpoint(tmp_path, capsys):
    runs, out = tmp_path / "runs", tmp_path / "par.jsonl"
    kw = dict(workers=0, model=TINY, n_steps=16, n_epochs=1, out=out, resume=True, runs_dir=runs)
    # a wall limit that ends the run at its first chance: no row yet, a checkpoint to go on from
    assert parallel_training([1], [64], 64, "home", "cpu", time_limit_s=1e-3, **kw) == []
    assert "run the same command again to continue it" in capsys.readouterr().err
    (run_dir,) = runs.iterdir()
    ckpts = list((run_dir / "checkpoints").glob("step_*.pt"))
    assert ckpts and not out.exists()
    first = int(ckpts[0].stem.split("_")[1])
    assert first < 64
    (row,) = parallel_training([1], [64], 64, "home", "cpu", **kw)  # the same configuration: continues
    assert row["timesteps"] == 64 and row["stop_reason"] == "total_steps"
    assert row["iterations"] == 4 and row["iteration_s_median"] > 0
    assert read_jsonl(out) == [row]
    assert parallel_training([1], [64], 64, "home", "cpu", **kw) == []  # finished: skipped


def test_ctrl_c_stops_the_whole_parallel_study(tmp_path, monkeypatch):
    import navzoo.agents.scaling_study as study

    calls = []

    def interrupted(targs):  # what robot_train returns after Ctrl-C: checkpoint saved, reason "interrupted"
        calls.append(targs.n_envs)
        return {"timesteps": 16, "reason": "interrupted", "elapsed_s": 0.1}

    monkeypatch.setattr(study, "_train_quiet", interrupted)
    for runs_dir in (None, tmp_path / "runs"):
        with pytest.raises(KeyboardInterrupt):
            parallel_training([1, 2], [64], 64, "home", "cpu", workers=0, model=TINY, n_steps=16, n_epochs=1,
                              out=tmp_path / "par.jsonl", runs_dir=runs_dir)
    assert calls == [1, 1]  # the R = 2 runs never started
    assert not (tmp_path / "par.jsonl").exists()  # and no row of an unfinished run


def test_resume_skips_measured_rows(tmp_path, capsys):
    out = tmp_path / "rt.jsonl"
    (first,) = runtime_scaling("peds", [1], "home", 1.0, "cpu", workers=0, steps=3, out=out)
    assert runtime_scaling("peds", [1], "home", 1.0, "cpu", workers=0, steps=3, out=out, resume=True) == []
    assert "skipping peds n_envs=1" in capsys.readouterr().err
    new = runtime_scaling("peds", [1, 2], "home", 1.0, "cpu", workers=0, steps=3, out=out, resume=True)
    assert [r["n_envs"] for r in new] == [2]
    assert read_jsonl(out) == [first, *new]

    pout = tmp_path / "par.jsonl"
    done = dict(zip(PARALLEL_KEY, (1, 64, 64, 32, 6, "navzoo/Home-v0", "cpu", 0, 0), strict=True))
    del done["seed"]  # rows written before the study recorded its seed were trained with the default, 0
    write_jsonl([{"study": "parallel", **done}], pout)
    assert parallel_training([1], [64], 64, "home", "cpu", workers=0, out=pout, resume=True) == []  # no training
    assert len(read_jsonl(pout)) == 1
    # another seed is another run: trained, its row records the seed, and a resume then skips it
    (row,) = parallel_training([1], [64], 64, "home", "cpu", workers=0, out=pout, resume=True, seed=1,
                               model=TINY)
    assert row["seed"] == 1 and len(read_jsonl(pout)) == 2
    assert parallel_training([1], [64], 64, "home", "cpu", workers=0, out=pout, resume=True, seed=1) == []


@pytest.mark.parametrize(("call", "bad"), [
    (lambda: runtime_scaling("walk", [1], "home", 1.0, "cpu"), "'walk'"),
    (lambda: runtime_scaling("peds", [1, 0], "home", 1.0, "cpu"), "got 0"),
    (lambda: runtime_scaling("peds", [], "home", 1.0, "cpu"), "n_envs_list"),
    (lambda: runtime_scaling("peds", [1], "nowhere", 1.0, "cpu"), "'nowhere'"),
    (lambda: runtime_scaling("peds", [1], "home", 0.0, "cpu"), "got 0.0"),
    (lambda: runtime_scaling("infer", [1], "home", 1.0, "tpu"), "'tpu'"),
    (lambda: runtime_scaling("peds", [1], "home", 1.0, "cpu", workers=-1), "got -1"),
    (lambda: runtime_scaling("peds", [1], "home", 1.0, "cpu", resume=True), "resume needs an out file"),
    (lambda: parallel_training([1], [1], 64, "home", "cpu"), "got 1"),
    (lambda: parallel_training([-2], [64], 64, "home", "cpu"), "got -2"),
    (lambda: parallel_training([1], [64], 0, "home", "cpu"), "sim_steps"),
    (lambda: parallel_training([1], [64], 64, "navzoo/Mars-v0", "cpu"), "'navzoo/Mars-v0'"),
    (lambda: plot_runtime([], "x.png"), "no runtime rows"),
])
def test_invalid_arguments_name_the_bad_value(call, bad):
    with pytest.raises(ValueError) as err:
        call()
    assert bad in str(err.value)


@pytest.mark.parametrize(("argv", "bad"), [
    (["runtime", "--envs", "1,x", "--out", "o.jsonl"], "'1,x'"),
    (["runtime", "--envs", "1,0", "--out", "o.jsonl"], "got 0"),
    (["runtime", "--modes", "peds,fly", "--out", "o.jsonl"], "'fly'"),
    (["runtime", "--seconds", "-1", "--out", "o.jsonl"], "'-1'"),
    (["parallel", "--batch-sizes", "64,1", "--out", "o.jsonl"], "got 1"),
    (["parallel", "--robots", "", "--out", "o.jsonl"], "at least one"),
])
def test_cli_rejects_bad_lists(argv, bad, capsys):
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2 and bad in capsys.readouterr().err


def test_cli_rejects_unknown_scene(capsys):
    with pytest.raises(SystemExit):
        main(["runtime", "--modes", "peds", "--scene", "nowhere", "--out", "o.jsonl"])
    assert "'nowhere'" in capsys.readouterr().err
    args = add_arguments(argparse.ArgumentParser()).parse_args(["parallel", "--scene", "nowhere", "--out", "o"])
    with pytest.raises(ValueError, match="'nowhere'"):
        run_cli(args)


def test_cli_runtime_then_plot(tmp_path, capsys):
    out, png = tmp_path / "rt.jsonl", tmp_path / "rt.png"
    assert main(["runtime", "--modes", "peds", "--envs", "1,2", "--steps", "3", "--workers", "0",
                 "--out", str(out), "--plot", str(png)]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines() if x.startswith("{")]
    assert [x["n_envs"] for x in lines[:2]] == [1, 2] and lines[2] == {"plot": str(png)}
    assert png.read_bytes()[:4] == PNG_MAGIC
    assert main(["plot", "--runtime", str(out), "--out-dir", str(tmp_path / "figs")]) == 0
    assert (tmp_path / "figs" / "runtime.png").read_bytes()[:4] == PNG_MAGIC
    with pytest.raises(SystemExit):
        main(["plot", "--runtime", str(tmp_path / "missing.jsonl"), "--out-dir", str(tmp_path)])
    assert "missing.jsonl" in capsys.readouterr().err
