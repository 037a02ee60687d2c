"""The steering trim of exported AMP policies (navzoo.agents.amp.steering, AmpPolicy.steering_trim)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import torch

from navzoo.agents.amp.checkpoint import (
    CheckpointError,
    export_policy_files,
    load_policy,
    rotate_waypoints,
    waypoint_layout,
)
from navzoo.agents.amp.features import FEATURE_DIM, N_RAYS
from navzoo.agents.amp.networks import Actor
from navzoo.agents.amp.normalizer import RunningMeanStd
from navzoo.agents.amp.steering import main, parse_trims, refine_minimum

OBS = FEATURE_DIM + 20 + N_RAYS


def _policy(tmp_path: Path, **extra) -> Path:
    torch.manual_seed(0)
    actor = Actor(OBS, 28, [16], "relu")
    return export_policy_files(tmp_path / "pol", actor, RunningMeanStd(OBS, clip=5.0),
                               {"obs_dim": OBS, "act_dim": 28, "actor_hidden": [16], "activation": "relu", **extra})


def test_rotate_waypoints_turns_only_the_target_points() -> None:
    obs = np.random.default_rng(0).normal(size=(3, OBS)).astype(np.float32)
    obs[:, FEATURE_DIM:FEATURE_DIM + 2] = [1.0, 0.0]  # first point straight ahead
    out = rotate_waypoints(obs, FEATURE_DIM, 10, np.pi / 2)
    np.testing.assert_allclose(out[:, FEATURE_DIM:FEATURE_DIM + 2], [[0.0, 1.0]] * 3, atol=1e-6)  # now to the left
    np.testing.assert_array_equal(out[:, :FEATURE_DIM], obs[:, :FEATURE_DIM])
    np.testing.assert_array_equal(out[:, FEATURE_DIM + 20:], obs[:, FEATURE_DIM + 20:])
    norms = np.linalg.norm(obs[:, FEATURE_DIM:FEATURE_DIM + 20].reshape(3, 10, 2), axis=-1)
    np.testing.assert_allclose(np.linalg.norm(out[:, FEATURE_DIM:FEATURE_DIM + 20].reshape(3, 10, 2), axis=-1),
                               norms, rtol=1e-6)
    assert obs[0, FEATURE_DIM] == 1.0  # the input is not modified


def test_waypoint_layout() -> None:
    assert waypoint_layout(FEATURE_DIM + 20) == (FEATURE_DIM, 10)
    assert waypoint_layout(OBS) == (FEATURE_DIM, 10)
    assert waypoint_layout(50, {"steering_trim": {"waypoint_start": 4, "n_waypoints": 3}}) == (4, 3)
    with pytest.raises(ValueError, match="77 columns"):
        waypoint_layout(77)


def test_trimmed_policy_acts_as_the_untrimmed_one_on_turned_targets(tmp_path: Path) -> None:
    plain = load_policy(_policy(tmp_path))
    assert plain.steering_trim == 0.0
    cfg_path = tmp_path / "pol" / "config.json"
    cfg = json.loads(cfg_path.read_text())
    cfg["steering_trim"] = {"rad": 0.2}
    cfg_path.write_text(json.dumps(cfg))
    trimmed = load_policy(tmp_path / "pol")
    assert trimmed.steering_trim == 0.2
    obs = np.random.default_rng(1).normal(size=(5, OBS)).astype(np.float32)
    np.testing.assert_allclose(trimmed(obs), plain(rotate_waypoints(obs, FEATURE_DIM, 10, 0.2)), atol=1e-6)
    assert not np.allclose(trimmed(obs), plain(obs), atol=1e-4)  # the trim changes the actions
    np.testing.assert_allclose(trimmed(obs[0]), trimmed(obs)[0], atol=1e-6)  # unbatched input too


@pytest.mark.parametrize("trim, match", [
    ({"rad": 0.9}, "within"), ({"rad": float("nan")}, "finite"), ({"rad": "left"}, "could not convert"),
    (0.1, "an object"), ({"rad": 0.1, "waypoint_start": 130, "n_waypoints": 10}, "outside"),
])
def test_bad_trims_are_rejected_naming_the_config(tmp_path: Path, trim, match) -> None:
    _policy(tmp_path)
    cfg_path = tmp_path / "pol" / "config.json"
    cfg = json.loads(cfg_path.read_text())
    cfg["steering_trim"] = trim
    cfg_path.write_text(json.dumps(cfg))
    with pytest.raises(CheckpointError, match=rf"config\.json: .*{match}"):
        load_policy(tmp_path / "pol")


def test_parse_trims_and_refine() -> None:
    assert parse_trims("-0.1:0.1:0.05") == [-0.1, -0.05, 0.0, 0.05, 0.1]
    assert parse_trims("0.2,0,0.1") == [0.0, 0.1, 0.2]
    for bad in ("0:0.1:0", "0.1:0:0.05", "a,b", "0.6", ""):
        with pytest.raises(ValueError, match="trims must"):
            parse_trims(bad)
    trims = [0.0, 0.05, 0.1, 0.15, 0.2]
    errors = [(t - 0.12) ** 2 + 0.1 for t in trims]
    assert refine_minimum(trims, errors) == pytest.approx(0.12)
    assert refine_minimum(trims, [0.1, 0.2, 0.3, 0.4, 0.5]) == 0.0  # minimum at the edge: the grid point


def test_calibration_writes_a_trim_that_loads(tmp_path: Path, capsys) -> None:
    """The CLI on a copy of the shipped policy, two trims, a tiny budget: the trim of least path error
    is written with its calibration; the weights are untouched."""
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir

    pol = tmp_path / "amp"
    shutil.copytree(default_policy_dir(), pol, ignore=shutil.ignore_patterns("*.md"))
    cfg_before = json.loads((pol / "config.json").read_text())
    assert main(["--policy", str(pol), "--trims", "0,0.3", "--people", "1", "--seconds", "3", "--json", "--write"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["trims"] == [0.0, 0.3] and len(result["path_error_m"]) == 2 and result["scene"] == "campus_plaza"
    assert result["path_error_m"][0] != result["path_error_m"][1]  # the trim reached the workers' policy
    assert result["rad"] == [0.0, 0.3][int(np.argmin(result["path_error_m"]))]
    cfg = json.loads((pol / "config.json").read_text())
    assert cfg["weights_sha256"] == cfg_before["weights_sha256"]
    assert cfg["steering_trim"]["rad"] == result["rad"]
    assert cfg["steering_trim"]["calibration"]["path_error_m"] == result["path_error_m"]
    assert "--write" in cfg["steering_trim"]["calibration"]["command"]
    assert cfg["steering_trim"]["off_for_crowd_models"] == cfg_before["steering_trim"]["off_for_crowd_models"]
    assert load_policy(pol).steering_trim == result["rad"]
    # refused before anything runs: a trim beyond the limit, an evaluation scene
    assert main(["--policy", str(pol), "--trims", "0:1:0.5"]) == 2
    assert main(["--policy", str(pol), "--scene", "station"]) == 2
    assert "outside the evaluation's scenes" in capsys.readouterr().err


def test_pedestrian_policy_can_override_the_trim(tmp_path: Path) -> None:
    from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy

    pol = _policy(tmp_path)
    assert AmpPedestrianPolicy(pol).policy.steering_trim == 0.0
    assert AmpPedestrianPolicy(pol, steering_trim=0.1).policy.steering_trim == 0.1
    for bad in (0.7, float("inf")):
        with pytest.raises(ValueError, match="steering_trim must be finite"):
            AmpPedestrianPolicy(pol, steering_trim=bad)


def test_config_trim_is_not_applied_to_the_crowd_models_it_names(tmp_path: Path) -> None:
    """A config trim is off in the crowds its list names and on in the others (the shipped average lists
    none since its trim was measured on diffusion targets too); an explicit trim applies everywhere; a
    malformed list is refused naming the config."""
    from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy
    from navzoo.envs.nav_env import NavEnv

    listed = AmpPedestrianPolicy(_policy(tmp_path / "a", steering_trim={"rad": 0.1, "off_for_crowd_models": ["diffusion"]}))
    shipped = AmpPedestrianPolicy()
    trim = shipped.policy.steering_trim
    assert trim > 0 and shipped.policy.config["steering_trim"]["off_for_crowd_models"] == []
    envs = {m: NavEnv(scene="lobby", n_robots=0, n_humans=1, human_model="amp", crowd_model=m)
            for m in ("diffusion", "sfm")}
    for model, want in (("diffusion", 0.0), ("sfm", 0.1), ("diffusion", 0.0)):
        listed.reset(envs[model])
        assert listed.policy.steering_trim == want, model
    for model in ("diffusion", "sfm"):
        shipped.reset(envs[model])
        assert shipped.policy.steering_trim == trim, model
    explicit = AmpPedestrianPolicy(steering_trim=0.05)
    explicit.reset(envs["diffusion"])
    assert explicit.policy.steering_trim == 0.05
    for env in envs.values():
        env.close()
    pol = _policy(tmp_path / "b", steering_trim={"rad": 0.1, "off_for_crowd_models": "diffusion"})
    with pytest.raises(ValueError, match="off_for_crowd_models must be a list"):
        AmpPedestrianPolicy(pol)


def test_tracking_takes_a_trim_override() -> None:
    """``track_clips(steering_trim=...)`` (``--steering-trim``) changes what the policy does."""
    from navzoo.agents.amp.tracking import track_clips

    a = track_clips(clips=[0], max_seconds=1.0, steering_trim=0.0)
    b = track_clips(clips=[0], max_seconds=1.0, steering_trim=0.3)
    assert a["mean_pos_error_m"] != b["mean_pos_error_m"]
    with pytest.raises(ValueError, match="steering_trim must be finite"):
        track_clips(clips=[0], max_seconds=1.0, steering_trim=0.9)

