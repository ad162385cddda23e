"""Candidate keyframe retrieval: a bag of binary words over ORB descriptors.

The paper compares a live frame with every keyframe by content similarity; with thousands
of keyframes that is too slow, so a retrieval step first ranks the keyframes and only the
best few are verified. Words are binary centres found by k-majority clustering (k-means
under Hamming distance: assign each descriptor to the nearest centre, then set each bit of
a centre to the majority bit of its members). A frame is a tf-idf weighted, L2-normalised
histogram of its words; keyframes are ranked by the cosine score against an inverted
(sparse) index, so a query costs O(words per frame) plus a sparse product.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from scipy import sparse

from floorvo.errors import ConfigError

__all__ = ["BinaryVocabulary", "KeyframeIndex"]

_BF = cv2.BFMatcher(cv2.NORM_HAMMING)


@dataclass(frozen=True)
class BinaryVocabulary:
    """``words`` (V, 32) uint8 binary centres; ``idf`` (V,) float32 inverse document frequency."""

    words: np.ndarray
    idf: np.ndarray

    @classmethod
    def train(
        cls,
        descriptors: list[np.ndarray],
        n_words: int = 512,
        iterations: int = 4,
        max_samples: int = 40000,
        seed: int = 0,
    ) -> BinaryVocabulary:
        """k-majority clustering of the descriptors of the documents (one array per keyframe);
        the idf is computed over those documents."""
        rng = np.random.default_rng(seed)
        allx = np.concatenate([d for d in descriptors if len(d)]) if descriptors else np.zeros((0, 32), np.uint8)
        if len(allx) == 0:
            raise ValueError("BinaryVocabulary.train: no descriptors")
        if len(allx) > max_samples:
            allx = allx[rng.choice(len(allx), max_samples, replace=False)]
        k = int(min(n_words, max(1, len(allx) // 8)))
        centres = allx[rng.choice(len(allx), k, replace=False)].copy()
        bits = np.unpackbits(allx, axis=1)
        for _ in range(iterations):
            lab = _assign(allx, centres)
            counts = np.bincount(lab, minlength=k)
            sums = np.zeros((k, bits.shape[1]), np.int64)
            np.add.at(sums, lab, bits)
            new = np.packbits((2 * sums > counts[:, None]).astype(np.uint8), axis=1)
            empty = counts == 0
            if empty.any():
                new[empty] = allx[rng.choice(len(allx), int(empty.sum()), replace=False)]
            centres = new
        df = np.zeros(k, np.int64)
        for d in descriptors:
            if len(d):
                df[np.unique(_assign(d, centres))] += 1
        idf = np.log((len(descriptors) + 1) / (df + 1)).astype(np.float32) + 1e-3
        return cls(centres, idf)

    @property
    def size(self) -> int:
        return int(len(self.words))

    def vector(self, desc: np.ndarray) -> np.ndarray:
        """tf-idf vector (V,) float32, L2-normalised (zeros for no descriptors)."""
        v = np.zeros(self.size, np.float32)
        if len(desc) == 0:
            return v
        np.add.at(v, _assign(desc, self.words), 1.0)
        v *= self.idf / max(len(desc), 1)
        n = float(np.linalg.norm(v))
        return v / n if n > 0 else v


def _assign(desc: np.ndarray, centres: np.ndarray) -> np.ndarray:
    m = _BF.match(np.ascontiguousarray(desc), np.ascontiguousarray(centres))
    lab = np.empty(len(desc), np.int64)
    for x in m:
        lab[x.queryIdx] = x.trainIdx
    return lab


class KeyframeIndex:
    """Inverted index of keyframe word vectors; :meth:`query` returns the best keyframes."""

    def __init__(self, vocab: BinaryVocabulary, keyframe_desc: list[np.ndarray]):
        self.vocab = vocab
        rows = [sparse.csr_matrix(vocab.vector(d)) for d in keyframe_desc]
        self.matrix = sparse.vstack(rows).tocsr() if rows else sparse.csr_matrix((0, vocab.size), dtype=np.float32)

    def query(self, desc: np.ndarray, top_k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(keyframe ids (k,), scores (k,))``, best first (cosine of tf-idf vectors)."""
        q = self.vocab.vector(desc)
        scores = np.asarray(self.matrix @ q).ravel()
        k = min(top_k, len(scores))
        if k == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.float32)
        idx = np.argpartition(-scores, k - 1)[:k]
        idx = idx[np.argsort(-scores[idx])]
        return idx, scores[idx]


class VoteIndex:
    """Descriptor voting: approximate nearest neighbours (FLANN LSH, Hamming) of every query
    descriptor among all keyframe descriptors; each keyframe that holds one of the query
    descriptor's ``neighbours`` nearest descriptors within ``max_hamming_bits`` gets one
    vote from it. A stationary floor texture gives nearly the same word histogram
    everywhere, so this keeps the descriptors themselves (their exact appearance) rather
    than their words; LSH keeps the query sublinear in the number of keyframes.

    Why a radius and not Lowe's ratio test: neighbouring keyframes overlap, so a floor
    point's descriptor is in two or three keyframes at nearly the same distance from the
    query, and a ratio test against the second neighbour throws out exactly the matches of
    the best-covered floor (on the rendered paper003 kidnap run the right keyframe ranked
    9th to 20th for 6 of 96 frames, and three kidnaps were recovered a frame late; with
    the radius every frame is localised, BENCHMARKS.md). Wrong votes are harmless here:
    retrieval only ranks candidates, which the rigid fit and the content similarity then
    verify. 48 bits of 256 is ORB's usual "good match" distance (ORB-SLAM's ``TH_LOW`` 50).
    """

    #: LSH tables and hash key bits. ORB bits on a floor texture are far from uniform, so short
    #: keys give few, crowded buckets and the query degrades to a linear scan (12 tables of 20
    #: bits: 3.4 s per query at 5000 keyframes); 6 tables of 24 bits keep the buckets small
    #: and still let enough true matches collide to rank the overlapping keyframes first.
    LSH_TABLES = 6
    LSH_KEY_BITS = 24

    def __init__(self, keyframe_desc: list[np.ndarray], max_hamming_bits: int = 48, neighbours: int = 4, seed: int = 0):
        if not 0 < max_hamming_bits <= 256:
            raise ConfigError(f"VoteIndex max_hamming_bits = {max_hamming_bits}: must be in (0, 256]")
        if neighbours < 1:
            raise ConfigError(f"VoteIndex neighbours = {neighbours}: must be >= 1")
        self.max_hamming_bits = int(max_hamming_bits)
        self.neighbours = int(neighbours)
        self.owner = (
            np.concatenate([np.full(len(d), k, np.int64) for k, d in enumerate(keyframe_desc)])
            if keyframe_desc
            else np.zeros(0, np.int64)
        )
        self.n_keyframes = len(keyframe_desc)
        self.matcher = cv2.FlannBasedMatcher(
            dict(algorithm=6, table_number=self.LSH_TABLES, key_size=self.LSH_KEY_BITS, multi_probe_level=0),
            dict(checks=32),
        )
        allx = [np.ascontiguousarray(d) for d in keyframe_desc if len(d)]
        if allx:
            self.matcher.add([np.concatenate(allx)])
            # The LSH tables draw their hash bits from OpenCV's RNG: seed it, so that the same
            # map gives the same candidates in every index built from it (and in every process).
            cv2.setRNGSeed(int(seed))
            self.matcher.train()

    def query(self, desc: np.ndarray, top_k: int) -> tuple[np.ndarray, np.ndarray]:
        """``(keyframe ids (k,), votes (k,))``, most votes first (keyframes with no vote left out)."""
        if len(desc) == 0 or len(self.owner) == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.float32)
        votes = np.zeros(self.n_keyframes, np.float32)
        for m in self.matcher.knnMatch(np.ascontiguousarray(desc), k=self.neighbours):
            near = {int(self.owner[x.trainIdx]) for x in m if x.distance <= self.max_hamming_bits}
            for k in near:  # one vote per keyframe and query descriptor
                votes[k] += 1.0
        k = min(top_k, int((votes > 0).sum()))
        if k == 0:
            return np.zeros(0, np.int64), np.zeros(0, np.float32)
        idx = np.argpartition(-votes, k - 1)[:k]
        idx = idx[np.argsort(-votes[idx])]
        return idx, votes[idx]
