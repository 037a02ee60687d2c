"""scripts/amp_policy_drift.py: the KL between exported AMP policies on the states a reference walks into."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

import amp_policy_drift  # noqa: E402

from navzoo.agents.amp.checkpoint import load_policy  # noqa: E402
from navzoo.agents.amp.pedestrian_policy import default_policy_dir  # noqa: E402


def test_drift_is_the_fixed_std_kl_of_the_clipped_mean_actions():
    shipped = load_policy(default_policy_dir())
    states = amp_policy_drift.collect_states(shipped, [("two_doors", 2)], steps=3, seed=0)
    assert states.shape[0] == 6  # 3 steps x 2 people
    assert amp_policy_drift.drift(shipped, shipped, states) == {"kl": 0.0, "rms_action": 0.0}

    def shifted(obs):  # one action dimension moved by one exploration std, where the shipped action leaves room
        act = np.clip(shipped(obs), -1.0, 1.0)
        act[:, 0] = np.where(act[:, 0] < 0.5, act[:, 0] + amp_policy_drift.TRAIN_STD, act[:, 0] - amp_policy_drift.TRAIN_STD)
        return act

    d = amp_policy_drift.drift(shipped, shifted, states)
    assert d["kl"] == pytest.approx(0.5, rel=1e-4)
    assert d["rms_action"] == pytest.approx(amp_policy_drift.TRAIN_STD / math.sqrt(28), rel=1e-3)  # 28 actions


def test_bad_scenes_are_refused_by_name():
    r = subprocess.run([sys.executable, str(REPO / "scripts" / "amp_policy_drift.py"), "--policies",
                        str(default_policy_dir()), "--scenes", "lobby:0"], capture_output=True, text=True)
    assert r.returncode == 2 and "'lobby:0' is not SCENE:PEOPLE" in r.stderr
