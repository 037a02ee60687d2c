"""navzoo eval pedestrians --seeds: the following protocol over several seeds (navzoo.benchmark.pedestrians)."""

import numpy as np
import pytest

from navzoo.benchmark import pedestrians


@pytest.mark.parametrize("bad, msg", [([], "at least one"), ([0, 0], "distinct"), ([0, 1.5], "integers"),
                                      ([True], "integers")])
def test_bad_seed_lists_are_refused_by_name(bad, msg):
    with pytest.raises(ValueError, match=msg):
        pedestrians.check_seeds(bad)


def test_the_cli_refuses_seed_with_seeds_and_a_malformed_list():
    with pytest.raises(SystemExit, match="not both"):
        pedestrians.main(["--seed", "1", "--seeds", "0,1"])
    with pytest.raises(SystemExit, match="--seeds '0,x'"):
        pedestrians.main(["--seeds", "0,x"])
    with pytest.raises(SystemExit, match="distinct"):
        pedestrians.main(["--seeds", "2,2"])


def test_several_seeds_pool_the_trips_and_keep_each_seeds_own_rates():
    kw = dict(scenes=("station",), seconds=20.0, people=[3])  # a few trips per seed, ~10 s each
    multi, poses = pedestrians.following(seeds=[0, 1], **kw)
    one = [pedestrians.following(seed=s, **kw) for s in (0, 1)]
    assert multi["seeds"] == [0, 1]
    for row, (single, _) in zip(multi["by_seed"], one, strict=True):
        for k in pedestrians._SEED_KEYS:  # each seed's rates are those of a single-seed run (deterministic)
            assert row[k] == pytest.approx(single[k]), k
    assert multi["trips"] == one[0][0]["trips"] + one[1][0]["trips"]
    assert [r["seed"] for r in multi["scenes"]] == [0, 1]
    assert multi["trips"] > 0 and all(r["trips"] > 0 for r in multi["by_seed"])
    ended = sum(r["success"] for r in multi["scenes"])
    assert multi["success_rate"] == pytest.approx(ended / multi["trips"])
    rates = [r["success_rate"] for r in multi["by_seed"]]
    assert multi["success_rate_seed_sd"] == pytest.approx(float(np.std(rates, ddof=1)))
    np.testing.assert_array_equal(poses, one[0][1])  # realism reads the first seed's poses only
    result = {"tracking": {k: 0.0 for k in pedestrians.PAPER["tracking"]} | {"n_clips": 1},
              "following": multi,
              "realism": {m: dict.fromkeys(("coverage_k50", "entropy_k50", "dist_k50", "coverage_k100",
                                            "entropy_k100", "dist_k100", "mmd", "n_generated"), 0.0)
                          for m in ("amp", "kinematic")} | {"reference_mmd_floor": 0.0}}
    text = pedestrians.markdown(result)
    assert "| seed | trips | success |" in text and "| station | 1 | 3 |" in text
