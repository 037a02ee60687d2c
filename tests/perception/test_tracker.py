"""PersonTracker and CLEAR-MOT on cases with known answers (synthetic walkers, hand-made sequences)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from navzoo.perception.tracker import (
    GATE_CHI2_99,
    PersonTracker,
    Track,
    clear_mot,
    radial_covariance,
    to_world,
)

DT = 0.1


def walk(tracker: PersonTracker, start: tuple[float, float], vel: tuple[float, float], n: int,
         k0: int = 0) -> list[Track]:
    """Feed ``n`` exact detections of a walker at constant velocity; returns the last confirmed tracks."""
    out: list[Track] = []
    for k in range(k0, k0 + n):
        out = tracker.update(np.array([start]) + np.array([vel]) * k * DT)
    return out


# ---------------------------------------------------------------------- filtering


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_constant_velocity_walker_is_smoothed(seed: int) -> None:
    rng = np.random.default_rng(seed)
    sigma, v = 0.1, np.array([1.0, 0.5])
    tracker = PersonTracker(dt=DT, process_noise=0.05, measurement_std=sigma)   # a steady walker
    vel_err, vels, pos_err, det_err = [], [], [], []
    for k in range(60):
        truth = np.array([0.0, 1.0]) + v * k * DT
        z = truth + rng.normal(0.0, sigma, 2)
        tracks = tracker.update(z[None])
        if k >= tracker.n_init - 1:
            assert [t.id for t in tracks] == [1]
        if k >= 15:
            t = tracks[0]
            vels.append(t.velocity)
            vel_err.append(np.linalg.norm(t.velocity - v))
            pos_err.append(np.linalg.norm(t.position - truth))
            det_err.append(np.linalg.norm(z - truth))
    assert np.linalg.norm(np.mean(vels, axis=0) - v) < 0.05       # unbiased
    assert np.median(vel_err) < 0.12                                # within ~0.1 m/s frame by frame
    assert np.mean(pos_err) < 0.8 * np.mean(det_err)               # better than the raw detections


def test_default_tracker_estimates_velocity_on_average() -> None:
    rng = np.random.default_rng(7)
    v = np.array([-0.8, 1.1])
    tracker = PersonTracker()
    vels = []
    for k in range(50):
        tracks = tracker.update((np.array([2.0, -1.0]) + v * k * DT + rng.normal(0.0, 0.1, 2))[None])
        if k >= 10:
            vels.append(tracks[0].velocity)
    assert np.linalg.norm(np.mean(vels, axis=0) - v) < 0.1


def test_kalman_update_matches_hand_computation_and_weights_by_covariance() -> None:
    """One predict + update by hand (F, continuous white-noise Q, gain P (P + R)^-1) for two R's."""
    q = 0.5

    def shifted(cov: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        tracker = PersonTracker(dt=DT, process_noise=q)
        (before,) = walk(tracker, (0.0, 0.0), (1.0, 0.0), 5)
        F = np.eye(4)
        F[0, 2] = F[1, 3] = DT
        Q = q * np.kron(np.array([[DT**3 / 3, DT**2 / 2], [DT**2 / 2, DT]]), np.eye(2))   # order x, y, vx, vy
        x_prior = F @ np.r_[before.position, before.velocity]
        P_prior = F @ before.covariance @ F.T + Q
        z = x_prior[:2] + np.array([0.0, 0.2])            # 0.2 m off the prediction, sideways
        K = P_prior[:, :2] @ np.linalg.inv(P_prior[:2, :2] + cov)
        expected = x_prior + K @ (z - x_prior[:2])
        (after,) = tracker.update(z[None], cov[None])
        np.testing.assert_allclose(np.r_[after.position, after.velocity], expected, atol=1e-12)
        return after.position - x_prior[:2], z - x_prior[:2]

    small, y = shifted(np.eye(2) * 0.01)
    huge, _ = shifted(np.eye(2) * 25.0)
    assert 0.5 * y[1] < small[1] < y[1]                  # a precise detection pulls most of the way
    assert 0.0 < huge[1] < 0.05 * small[1]               # a vague one (5 m std) barely moves the estimate


def test_far_detection_with_large_uncertainty_moves_estimate_less() -> None:
    cov_near, cov_far = radial_covariance(np.array([[2.0, 0.0], [12.0, 0.0]]), [0.1, 1.5], [0.05, 0.3])
    moves = []
    for cov in (cov_near, cov_far):
        tracker = PersonTracker(dt=DT)
        walk(tracker, (5.0, 0.0), (0.0, 0.0), 5)
        (t,) = tracker.update(np.array([[5.4, 0.0]]), cov[None])   # 0.4 m off along the ray
        moves.append(t.position[0] - 5.0)
    assert 0.0 < moves[1] < 0.5 * moves[0]


# ---------------------------------------------------------------------- association and management


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_crossing_walkers_keep_their_ids(seed: int) -> None:
    rng = np.random.default_rng(seed)
    tracker = PersonTracker(dt=DT)
    gt_frames, hyp_frames = [], []
    for k in range(60):                                      # X pattern, paths cross at (0, 0) at k = 30
        a = np.array([-3.0, -3.0]) + np.array([1.0, 1.0]) * k * DT
        b = np.array([-3.0, 3.0]) + np.array([1.0, -1.0]) * k * DT
        det = np.stack([a, b]) + rng.normal(0.0, 0.15, (2, 2))
        if rng.random() < 0.5:
            det = det[::-1]                                  # detection order carries no identity
        tracks = tracker.update(det)
        if k >= tracker.n_init - 1:                         # confirmed from the n_init-th frame on
            assert sorted(t.id for t in tracks) == [1, 2]
        gt_frames.append({"a": a, "b": b})
        hyp_frames.append({t.id: t.position for t in tracks})
    res = clear_mot(gt_frames, hyp_frames, threshold=0.5)
    assert res.idsw == 0
    assert res.fp == 0
    assert res.fn == 2 * (tracker.n_init - 1)              # only the frames before confirmation
    # the track that started on a is still on a after the crossing
    first = {t_id: np.linalg.norm(p - gt_frames[2]["a"]) for t_id, p in hyp_frames[2].items()}
    on_a = min(first, key=first.get)
    assert np.linalg.norm(hyp_frames[-1][on_a] - gt_frames[-1]["a"]) < 0.5


def test_gate_rejects_far_detection_which_births_a_tentative_track() -> None:
    tracker = PersonTracker(dt=DT)
    walk(tracker, (0.0, 0.0), (1.0, 0.0), 5)
    z = np.array([[0.5, 0.0], [0.5, 10.0]])
    tracks = tracker.update(z)
    assert [t.id for t in tracks] == [1]                       # tentative track not returned
    assert abs(tracks[0].position[0] - 0.5) < 0.1 and abs(tracks[0].position[1]) < 1e-9   # not pulled north
    tentative = [t for t in tracker.all_tracks if not t.confirmed]
    assert [t.id for t in tentative] == [2]
    np.testing.assert_allclose(tentative[0].position, [0.5, 10.0])
    # alone, the far detection is still not associated: the person is missed, another track is born
    tracks = tracker.update(np.array([[0.6, 10.0]]))
    assert tracks[0].id == 1 and tracks[0].misses == 1
    assert abs(tracks[0].position[1]) < 1e-9
    assert [(t.id, t.confirmed, t.hits) for t in tracker.all_tracks] == [(1, True, 6), (2, False, 2)]


def test_gate_squared_mahalanobis_boundary() -> None:
    assert GATE_CHI2_99 == pytest.approx(9.2103, abs=1e-4)
    for offset, joined in [(0.99, True), (1.01, False)]:
        tracker = PersonTracker(dt=DT, measurement_std=0.3, n_init=1)
        (t,) = tracker.update(np.zeros((1, 2)))
        s = t.covariance[0, 0] + t.covariance[2, 2] * DT**2 + 0.5 * DT**3 / 3 + 0.3**2   # predicted S_xx
        d = offset * math.sqrt(GATE_CHI2_99 * s)
        tracks = tracker.update(np.array([[d, 0.0]]))
        assert (tracks[0].id == 1 and tracks[0].misses == 0) is joined


def test_confirmed_tracks_pick_before_tentative_ones() -> None:
    tracker = PersonTracker(dt=DT)
    walk(tracker, (0.0, 0.0), (0.0, 0.0), 10)
    tracker.update(np.array([[0.0, 0.0], [0.4, 0.0]]))          # clutter at 0.4 m births tentative 2
    assert [t.id for t in tracker.all_tracks] == [1, 2]
    # the next detection is nearer tentative 2 (also in Mahalanobis distance, its covariance being wider),
    # but the established track is served first
    (t,) = tracker.update(np.array([[0.25, 0.0]]))
    assert (t.id, t.misses) == (1, 0)
    assert [t.id for t in tracker.all_tracks] == [1]


def test_tentative_track_dies_at_first_miss_and_confirms_after_n_init_hits() -> None:
    tracker = PersonTracker(dt=DT, n_init=3)
    assert tracker.update(np.array([[1.0, 1.0]])) == []
    assert tracker.update(np.array([[1.0, 1.0]])) == []
    assert [t.id for t in tracker.update(np.array([[1.0, 1.0]]))] == [1]   # third hit confirms
    tracker.update(np.array([[1.0, 1.0], [5.0, 5.0]]))                      # tentative 2 born
    assert [t.id for t in tracker.all_tracks] == [1, 2]
    tracker.update(np.array([[1.0, 1.0]]))                                  # 2 misses once: gone
    assert [t.id for t in tracker.all_tracks] == [1]


def test_track_dies_after_max_age_misses_and_ids_are_never_reused() -> None:
    tracker = PersonTracker(dt=DT, max_age=4)
    walk(tracker, (0.0, 0.0), (0.0, 0.0), 5)
    for miss in range(1, 4):                                   # coasts through max_age - 1 misses
        tracks = tracker.update(np.zeros((0, 2)))
        assert [(t.id, t.misses) for t in tracks] == [(1, miss)]
    assert tracker.update(np.zeros((0, 2))) == []              # deleted at the max_age-th miss
    assert tracker.all_tracks == []
    walk(tracker, (0.0, 0.0), (0.0, 0.0), 3)                   # same place, new person: new id
    assert [t.id for t in tracker.tracks] == [2]
    tracker.reset()
    walk(tracker, (0.0, 0.0), (0.0, 0.0), 3)
    assert [t.id for t in tracker.tracks] == [3]
    tracker.reset(restart_ids=True)
    walk(tracker, (0.0, 0.0), (0.0, 0.0), 3)
    assert [t.id for t in tracker.tracks] == [1]


def test_missed_frames_coast_on_prediction() -> None:
    tracker = PersonTracker(dt=DT)
    v = np.array([1.2, -0.4])
    walk(tracker, (0.0, 0.0), tuple(v), 15)
    spread = []
    for k, miss in [(15, 1), (16, 2)]:
        (t,) = tracker.update(np.empty((0, 2)))
        assert (t.id, t.misses, t.confirmed) == (1, miss, True)
        np.testing.assert_allclose(t.position, v * k * DT, atol=0.05)   # predicted forward
        spread.append(np.trace(t.position_covariance))
    assert spread[1] > spread[0]                               # uncertainty grows while coasting
    (t,) = tracker.update((v * 17 * DT)[None])
    assert (t.id, t.misses, t.hits, t.age) == (1, 0, 16, 18)
    assert np.trace(t.position_covariance) < spread[1]         # and shrinks with the detection


def test_orientation_is_smoothed_on_the_circle_and_extras_are_carried() -> None:
    a = 0.5
    tracker = PersonTracker(dt=DT, n_init=1, orientation_smoothing=a)
    z = np.array([[0.0, 0.0]])

    def sincos(theta: float) -> np.ndarray:
        return np.array([[math.sin(theta), math.cos(theta)]])

    (t,) = tracker.update(z, extras={"orientation": sincos(math.pi - 0.1), "confidence": np.array([0.9])})
    assert t.orientation == pytest.approx(math.pi - 0.1)
    assert t.confidence == pytest.approx(0.9)
    (t,) = tracker.update(z, extras={"orientation": sincos(-math.pi + 0.1), "confidence": np.array([0.4]),
                                     "label": np.array(["adult"])})
    assert abs(abs(t.orientation) - math.pi) < 1e-9        # mean of +-(pi - 0.1) is pi, not 0
    assert t.confidence == pytest.approx(0.4) and t.extras["label"] == "adult"
    (t,) = tracker.update(z, extras={"orientation": np.array([np.nan])})   # unobserved: kept
    assert abs(abs(t.orientation) - math.pi) < 1e-9
    (t,) = tracker.update(z, extras={"orientation": np.array([math.pi / 2])})   # radians accepted too
    u = (1 - a) * np.array([-1.0, 0.0]) + a * np.array([0.0, 1.0])
    assert t.orientation == pytest.approx(math.atan2(u[1], u[0]))
    assert PersonTracker(n_init=1).update(z)[0].orientation is None


def test_same_inputs_give_same_tracks_and_snapshots_are_frozen() -> None:
    rng = np.random.default_rng(3)
    frames = [rng.uniform(-5, 5, (rng.integers(0, 5), 2)) for _ in range(30)]
    runs = []
    for _ in range(2):
        tracker = PersonTracker(dt=DT, n_init=2)
        runs.append([[(t.id, *t.position, *t.velocity) for t in tracker.update(f)] for f in frames])
    assert runs[0] == runs[1]
    (t,) = walk(PersonTracker(), (0.0, 0.0), (1.0, 0.0), 3)
    with pytest.raises(ValueError):
        t.position[0] = 1.0


# ---------------------------------------------------------------------- validation


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"detections": np.array([[0.0, np.nan]])}, "NaN"),
        ({"detections": np.zeros((2, 3))}, r"shape \(N, 2\)"),
        ({"detections": np.zeros(2)}, r"shape \(N, 2\)"),
        ({"detections": np.zeros((2, 2)), "covariances": np.tile(np.eye(2), (3, 1, 1))}, r"shape \(2, 2, 2\)"),
        ({"detections": np.zeros((1, 2)), "covariances": np.array([[[1.0, 0.5], [0.0, 1.0]]])}, "symmetric"),
        ({"detections": np.zeros((1, 2)), "covariances": np.array([[[1.0, 2.0], [2.0, 1.0]]])},
         "positive definite"),
        ({"detections": np.zeros((1, 2)), "covariances": np.zeros((1, 2, 2))}, "positive definite"),
        ({"detections": np.zeros((1, 2)), "covariances": np.full((1, 2, 2), np.inf)}, "NaN or inf"),
        ({"detections": np.zeros((1, 2)), "dt": 0.0}, "dt must be"),
        ({"detections": np.zeros((1, 2)), "dt": -0.1}, "dt must be"),
        ({"detections": np.zeros((2, 2)), "extras": {"confidence": np.ones(3)}}, "confidence"),
        ({"detections": np.zeros((2, 2)), "extras": {"orientation": np.ones((2, 3))}}, "orientation"),
    ],
)
def test_update_rejects_bad_inputs_and_leaves_tracker_unchanged(kwargs: dict, match: str) -> None:
    tracker = PersonTracker(dt=DT)
    walk(tracker, (0.0, 0.0), (1.0, 0.0), 4)
    before = [(t.id, t.age, *t.position) for t in tracker.all_tracks]
    with pytest.raises(ValueError, match=match):
        tracker.update(**kwargs)
    assert [(t.id, t.age, *t.position) for t in tracker.all_tracks] == before


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [({"dt": 0.0}, "dt"), ({"dt": float("nan")}, "dt"), ({"measurement_std": -1.0}, "measurement_std"),
     ({"gate": 0.0}, "gate"), ({"n_init": 0}, "n_init"), ({"max_age": 0}, "max_age"),
     ({"orientation_smoothing": 0.0}, "orientation_smoothing"), ({"process_noise": -0.1}, "process_noise")],
)
def test_constructor_rejects_bad_parameters(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        PersonTracker(**kwargs)


# ---------------------------------------------------------------------- sensor-frame helpers


def test_radial_covariance_and_to_world() -> None:
    cov = radial_covariance(np.array([[3.0, 0.0], [0.0, 2.0], [1.0, 1.0]]), 2.0, 1.0)
    np.testing.assert_allclose(cov[0], np.diag([4.0, 1.0]), atol=1e-12)    # along x
    np.testing.assert_allclose(cov[1], np.diag([1.0, 4.0]), atol=1e-12)    # along y
    np.testing.assert_allclose(cov[2], [[2.5, 1.5], [1.5, 2.5]], atol=1e-12)  # 45 degrees
    p, c = to_world(np.array([[1.0, 0.0]]), np.diag([4.0, 1.0])[None], (1.0, 2.0, math.pi / 2))
    np.testing.assert_allclose(p, [[1.0, 3.0]], atol=1e-12)
    np.testing.assert_allclose(c[0], np.diag([1.0, 4.0]), atol=1e-12)
    with pytest.raises(ValueError, match="> 0"):
        radial_covariance(np.zeros((1, 2)), 0.0, 1.0)


# ---------------------------------------------------------------------- CLEAR-MOT


def test_clear_mot_perfect_tracking() -> None:
    gt = [{"a": (0.0, float(k)), "b": (3.0, -float(k))} for k in range(5)]
    hyp = [{10: p["a"], 20: p["b"]} for p in gt]
    res = clear_mot(gt, hyp)
    assert (res.mota, res.motp, res.fn, res.fp, res.idsw, res.matches, res.num_gt) == (1.0, 0.0, 0, 0, 0, 10, 10)
    assert res.as_dict()["idsw"] == 0


def test_clear_mot_counts_id_swap() -> None:
    gt = [{"a": (0.0, 0.0), "b": (5.0, 0.0)} for _ in range(6)]
    hyp = [{1: (0.1, 0.0), 2: (5.1, 0.0)} for _ in range(3)] + [{2: (0.1, 0.0), 1: (5.1, 0.0)} for _ in range(3)]
    res = clear_mot(gt, hyp)
    assert res.idsw == 2                       # both objects change hypothesis once, at frame 3
    assert (res.fn, res.fp, res.matches) == (0, 0, 12)
    assert res.mota == pytest.approx(1.0 - 2 / 12)
    assert res.motp == pytest.approx(0.1)


def test_clear_mot_misses_false_positives_and_threshold() -> None:
    gt = [{"a": (0.0, 0.0)} for _ in range(4)]
    hyp: list[dict] = [{1: (0.0, 0.0)}, {}, {}, {1: (0.0, 0.0)}]
    res = clear_mot(gt, hyp)
    assert (res.fn, res.fp, res.idsw, res.matches) == (2, 0, 0, 2)
    assert res.mota == pytest.approx(0.5)
    # back after a gap under another id: a switch against the last known correspondence
    res = clear_mot(gt, [{1: (0.0, 0.0)}, {}, {}, {7: (0.0, 0.0)}])
    assert (res.fn, res.idsw) == (2, 1)
    # an extra hypothesis far from everything is a false positive in each frame
    res = clear_mot(gt, [{1: (0.0, 0.0), 9: (4.0, 4.0)} for _ in range(4)])
    assert (res.fn, res.fp, res.idsw) == (0, 4, 0)
    assert res.mota == pytest.approx(0.0)
    # a hypothesis beyond the threshold is both a miss and a false positive
    res = clear_mot([{"a": (0.0, 0.0)}], [{1: (0.6, 0.0)}], threshold=0.5)
    assert (res.fn, res.fp, res.matches) == (1, 1, 0) and math.isnan(res.motp)
    assert res.mota == pytest.approx(-1.0)


def test_clear_mot_motp_hand_computed() -> None:
    gt = [{"a": (0.0, 0.0)}, {"a": (1.0, 0.0)}, {"a": (2.0, 0.0), "b": (9.0, 9.0)}]
    hyp = [{1: (0.3, 0.4)}, {1: (1.0, 0.1)}, {1: (2.0, -0.3)}]         # distances 0.5, 0.1, 0.3
    res = clear_mot(gt, hyp, threshold=1.0)
    assert res.motp == pytest.approx(0.3)
    assert (res.matches, res.fn, res.num_gt) == (3, 1, 4)
    assert res.mota == pytest.approx(0.75)


def test_clear_mot_keeps_valid_correspondence_over_a_closer_newcomer() -> None:
    gt = [{"a": (0.0, 0.0)}, {"a": (0.0, 0.0)}]
    hyp = [{1: (0.4, 0.0)}, {1: (0.4, 0.0), 2: (0.0, 0.0)}]
    res = clear_mot(gt, hyp)
    assert (res.idsw, res.fp, res.matches) == (0, 1, 2)
    assert res.motp == pytest.approx(0.4)


def test_clear_mot_rejects_bad_input() -> None:
    with pytest.raises(ValueError, match="differ in length"):
        clear_mot([{}], [])
    with pytest.raises(ValueError, match="threshold"):
        clear_mot([{}], [{}], threshold=0.0)
    with pytest.raises(ValueError, match="finite"):
        clear_mot([{"a": (0.0, np.nan)}], [{}])
    assert math.isnan(clear_mot([{}], [{}]).mota)
