"""scripts/amp_rotation_phase_floor.py and scripts/amp_motor_gain_probe.py: measurements behind docs/pedestrians.md."""

from __future__ import annotations

import json

import pytest

from tests.script_modules import load_script


@pytest.fixture(scope="module")
def lib():
    from navzoo.agents.amp.train import locomotion_reference

    return locomotion_reference().select(names=["amp_walk", "cmu_16_11"])


def test_a_clip_against_itself_errs_more_the_further_it_is_shifted(lib):
    floor = load_script("amp_rotation_phase_floor")
    zero = floor.shifted_errors(lib, 0.0)
    assert zero["n_clips"] == 2 and all(abs(zero[k]) < 1e-6 for k in floor.KEYS)
    rows = [floor.shifted_errors(lib, s) for s in (0.05, 0.1, 0.2)]
    rot = [r["mean_rot_error_rad"] for r in rows]
    assert 0.0 < rot[0] < rot[1] < rot[2] < 1.0


def test_the_phase_floor_cli_writes_its_rows(tmp_path, capsys):
    floor = load_script("amp_rotation_phase_floor")
    out = tmp_path / "floor.json"
    assert floor.main(["--shifts", "0.1", "--json", str(out)]) == 0
    rows = json.loads(out.read_text())
    assert len(rows) == 1 and rows[0]["n_clips"] == 78 and rows[0]["mean_rot_error_rad"] > 0


def test_the_motor_gain_probe_measures_noise_as_jitter(lib):
    probe = load_script("amp_motor_gain_probe")
    from navzoo.agents.amp.stage0 import sample_starts

    clips, t = sample_starts(lib, 4, seed=0, margin=1.0)
    clean = probe.probe(lib, clips, t, gain=1.0, sigma=0.0, lead=1, horizon=0.5)
    noisy = probe.probe(lib, clips, t, gain=1.0, sigma=0.1, lead=1, horizon=0.5)
    assert clean["n_starts"] == 4 and 0.0 <= clean["up_1s"] <= 1.0
    assert clean["rot_err_local_1s"] < noisy["rot_err_local_1s"]
    assert clean["jitter_ratio"] < noisy["jitter_ratio"]


def test_stance_offset_probe_offsets_the_chosen_actions_and_leaves_the_rest(lib):
    import numpy as np

    probe = load_script("amp_stance_offset_probe")

    class Fixed:
        obs_dim = 7

        def __call__(self, obs):
            return np.full((len(obs), 28), 0.95)

    offset = np.zeros(28)
    offset[probe.GROUPS["knees"]] = -0.5
    wrapped = probe.OffsetPolicy(Fixed(), offset)
    a = wrapped(np.zeros((3, 7)))
    assert wrapped.obs_dim == 7  # attributes pass through to the policy
    assert np.allclose(a[:, probe.GROUPS["knees"]], 0.45) and np.allclose(np.delete(a, probe.GROUPS["knees"], 1), 0.95)
    assert len(wrapped.actions) == 1 and wrapped.actions[0].max() <= 1.0
    mean = probe.reference_mean_action(lib)
    assert mean.shape == (28,) and np.isfinite(mean).all() and np.abs(mean).max() <= 1.0
    with pytest.raises(SystemExit, match="unknown group"):
        probe.main(["policies/amp_pedestrian", "--joints", "hips,tail"])
