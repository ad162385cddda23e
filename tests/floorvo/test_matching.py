"""floorvo.matching: nearest neighbours, the ratio test and its uniqueness rules, guided matching.

Hand-made one-byte binary descriptors, whose Hamming distances are counted by hand:

    desc0: q0 = 00000000, q1 = 11110000, q2 = 10101010, q3 = 00001111
    desc1: t0 = 00000001, t1 = 11110001, t2 = 01010101, t3 = 11111111

          t0  t1  t2  t3
    q0     1   5   4   8
    q1     5   1   4   4
    q2     5   5   8   4
    q3     3   7   4   4
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from floorvo.matching import (
    Matches,
    hamming_distances,
    knn,
    knn_from_dmatches,
    match_guided,
    match_nn,
    match_ratio,
    pack_descriptors,
    ratio_test,
)

D0 = np.array([[0b00000000], [0b11110000], [0b10101010], [0b00001111]], dtype=np.uint8)
D1 = np.array([[0b00000001], [0b11110001], [0b01010101], [0b11111111]], dtype=np.uint8)
HAND = np.array([[1, 5, 4, 8], [5, 1, 4, 4], [5, 5, 8, 4], [3, 7, 4, 4]])


def test_hamming_distances_by_hand():
    got = hamming_distances(pack_descriptors(D0)[:, None, :], pack_descriptors(D1)[None, :, :])
    np.testing.assert_array_equal(got, HAND)
    # 61-byte AKAZE descriptors pack into 8 words, zero padded: the distance is unchanged.
    rng = np.random.default_rng(0)
    a, b = rng.integers(0, 256, (5, 61), dtype=np.uint8), rng.integers(0, 256, (5, 61), dtype=np.uint8)
    assert pack_descriptors(a).shape == (5, 8)
    np.testing.assert_array_equal(
        hamming_distances(pack_descriptors(a), pack_descriptors(b)), np.unpackbits(a ^ b, axis=1).sum(axis=1)
    )


def test_knn_nearest_first_and_missing_neighbours():
    dist, idx = knn(D0, D1, 2)
    np.testing.assert_array_equal(dist[:, 0], HAND.min(axis=1))
    np.testing.assert_array_equal(dist[:, 1], np.sort(HAND, axis=1)[:, 1])
    assert idx[0].tolist() == [0, 2] and idx[1, 0] == 1 and idx[2, 0] == 3 and idx[3, 0] == 0
    dist, idx = knn(D0, D1[:1], 2)  # one row in desc1: no second neighbour
    assert np.isinf(dist[:, 1]).all() and (idx[:, 1] == -1).all()


def test_knn_arrays_from_opencv_matches_short_rows_included():
    """OpenCV knnMatch results (as a FLANN index returns them) become knn()'s arrays."""
    full = cv2.BFMatcher(cv2.NORM_HAMMING).knnMatch(D0, D1, k=2)
    dist, idx = knn_from_dmatches(full, len(D0), 2)
    np.testing.assert_array_equal(dist, knn(D0, D1, 2)[0])
    np.testing.assert_array_equal(dist[:, 0], HAND.min(axis=1))
    assert idx[0].tolist() == [0, 2] and idx[3, 0] == 0
    # A row with one neighbour and a row with none (an approximate index may return fewer).
    short = [full[0], full[1][:1], [], full[3]]
    dist, idx = knn_from_dmatches(short, 4, 2)
    assert idx[1].tolist() == [1, -1] and np.isinf(dist[1, 1]) and idx[2].tolist() == [-1, -1]
    assert idx[0].tolist() == [0, 2] and idx[3, 0] == 0
    assert ratio_test(dist, idx, 0.8).idx.tolist() == [[0, 0], [3, 0]]  # rows 1 and 2 have no ratio


def test_match_nn_with_and_without_cross_check():
    m = match_nn(D0, D1)
    assert m.idx.tolist() == [[0, 0], [1, 1], [2, 3], [3, 0]]
    np.testing.assert_array_equal(m.distance, [1, 1, 4, 3])
    # Mutual only: t0's nearest is q0 (not q3); t3's nearest is q1 (4 bits, tied with q2 and q3: lowest index).
    assert match_nn(D0, D1, cross_check=True).idx.tolist() == [[0, 0], [1, 1]]
    assert len(match_nn(D0, D1[:0])) == 0


def test_ratio_test_on_hand_made_descriptors():
    # ratio 0.5: q0 (1 < 0.5 * 4) and q1 (1 < 0.5 * 4) pass; q2 (4 vs 5) and q3 (3 vs 4) fail.
    m = match_ratio(D0, D1, 0.5)
    assert m.idx.tolist() == [[0, 0], [1, 1]]
    np.testing.assert_allclose(m.ratio, [0.25, 0.25])
    # ratio 0.8: q3 passes too (3 < 3.2) and takes t0 as q0 does; q2 fails on the strict rule (4 < 4.0).
    m = match_ratio(D0, D1, 0.8)
    assert m.idx.tolist() == [[0, 0], [1, 1], [3, 0]]
    np.testing.assert_allclose(m.ratio, [0.25, 0.25, 0.75])
    np.testing.assert_array_equal(m.distance, [1, 1, 3])
    # One match per row of desc1: q0 comes first and has the lower ratio.
    assert match_ratio(D0, D1, 0.8, unique="first").idx.tolist() == [[0, 0], [1, 1]]
    assert match_ratio(D0, D1, 0.8, unique="best").idx.tolist() == [[0, 0], [1, 1]]
    # No second neighbour, no ratio: nothing matches.
    assert len(match_ratio(D0, D1[:1], 1.0)) == 0


def test_uniqueness_rules_differ_where_the_later_row_is_better():
    dist = np.array([[2.0, 4.0], [1.0, 4.0], [1.0, 1.0], [3.0, np.inf], [0.0, 0.0]])
    idx = np.array([[5, 1], [5, 2], [0, 3], [7, -1], [9, 8]])
    # Rows 0 and 1 both take j = 5 (ratios 0.5 and 0.25); row 2 fails (1 < 0.6 is false);
    # row 3 has no second neighbour; row 4 has d_second = 0 (no ratio can pass).
    assert ratio_test(dist, idx, 0.6).idx.tolist() == [[0, 5], [1, 5]]
    assert ratio_test(dist, idx, 0.6, unique="first").idx.tolist() == [[0, 5]]
    best = ratio_test(dist, idx, 0.6, unique="best")
    assert best.idx.tolist() == [[1, 5]]
    np.testing.assert_allclose(best.ratio, [0.25])
    np.testing.assert_allclose(best.distance, [1.0])
    # Equal ratios: the lowest row wins.
    tie = ratio_test(np.array([[1.0, 4.0], [1.0, 4.0]]), np.array([[3, 0], [3, 1]]), 0.8, unique="best")
    assert tie.idx.tolist() == [[0, 3]]


def test_ratio_test_refuses_bad_arguments_by_name():
    dist, idx = knn(D0, D1, 2)
    with pytest.raises(ValueError, match="unique"):
        ratio_test(dist, idx, 0.8, unique="mutual")
    with pytest.raises(ValueError, match=r"ratio = 1.5"):
        ratio_test(dist, idx, 1.5)
    with pytest.raises(ValueError, match=r"\(N, 2\)"):
        ratio_test(dist[:, :1], idx[:, :1], 0.8)
    with pytest.raises(ValueError, match="two kinds"):
        match_nn(D0, D1.astype(np.float32))


@pytest.mark.parametrize("unique", ["none", "first", "best"])
def test_ratio_matches_of_float_descriptors_against_a_brute_force_truth(unique):
    """SIFT-like float rows: the matches are exactly those of a numpy L2 distance matrix."""
    rng = np.random.default_rng(5)
    d1 = rng.normal(size=(60, 16)).astype(np.float32)
    d0 = np.vstack([d1[rng.permutation(60)[:30]] + rng.normal(0, 0.05, (30, 16)), rng.normal(size=(20, 16))])
    d0 = d0.astype(np.float32)
    D = np.linalg.norm(d0[:, None, :].astype(np.float64) - d1[None, :, :], axis=2)
    order = np.argsort(D, axis=1)
    near, second = D[np.arange(50), order[:, 0]], D[np.arange(50), order[:, 1]]
    rows = np.nonzero(near < 0.8 * second)[0]
    m = match_ratio(d0, d1, 0.8, unique=unique)
    assert 25 <= len(m) <= 50
    if unique == "none":
        assert m.i0.tolist() == rows.tolist()
    assert set(map(tuple, m.idx.tolist())) <= {(i, order[i, 0]) for i in rows}
    np.testing.assert_allclose(m.distance, D[m.i0, m.i1], rtol=1e-5)
    if unique != "none":
        assert len(np.unique(m.i1)) == len(m)
    assert isinstance(m, Matches) and np.all(np.diff(m.i0) > 0)


def test_guided_matching_visits_candidates_nearest_first():
    xy1 = np.array([[10.0, 10.0], [12.0, 10.0], [30.0, 30.0]])
    pred = np.array([[10.5, 10.0], [29.0, 30.0], [100.0, 100.0]])
    d0 = np.zeros((3, 8), np.uint8)
    d1 = np.zeros((3, 8), np.uint8)
    d1[0, 0] = 0b00000111  # 3 bits from every row of d0
    d1[1, 0] = 0b00000001  # 1 bit
    p0, p1 = pack_descriptors(d0), pack_descriptors(d1)
    m = match_guided(pred, xy1, p0, p1, radius_px=5.0, max_candidates=4, max_distance=2)
    # Row 0: t0 is nearer (0.5 px) but 3 bits away; t1 (1.5 px, 1 bit) is the match. Row 1: t2.
    # Row 2: nothing within 5 px.
    assert m.idx.tolist() == [[0, 1], [1, 2]]
    np.testing.assert_array_equal(m.distance, [1, 0])
    # Only the nearest candidate may be tried: row 0 finds none.
    m1 = match_guided(pred, xy1, p0, p1, radius_px=5.0, max_candidates=1, max_distance=2)
    assert m1.idx.tolist() == [[1, 2]]
    # With a looser threshold the nearest candidate passes.
    assert match_guided(pred, xy1, p0, p1, radius_px=5.0, max_candidates=4, max_distance=4).idx[0].tolist() == [0, 0]
