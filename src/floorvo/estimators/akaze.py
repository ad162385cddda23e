"""``akaze-guided`` (paper 000) and ``akaze-bruteforce`` (the conventional method it is compared with).

Paper 000 (Nakashima et al., IEEE Access 2019), faithfully, then extended to yaw:

* AKAZE keypoints and binary (MLDB) descriptors on the illumination-corrected frame
  (with default thresholds AKAZE finds almost nothing on a raw grazing-light frame).
* **Motion-predicted matching.** Each previous keypoint's position in the new frame is
  predicted from the previous frame's motion, eq. (2): x' = x - R(theta) v, here in the
  general form p' = M_last(p) with M_last the last measured rigid image motion about the
  principal point (eq. (2) with rotation; eq. (3) when theta = 0). The new frame's
  keypoints are visited in order of distance from the prediction and the first whose
  Hamming distance is under ``hamming_threshold`` is the match; otherwise the next
  nearest is tried (up to ``max_candidates`` within ``search_radius_px``).
* **Outlier removal**, section II-C: the movement of every matched pair is computed, and
  pairs outside mean +/- one standard deviation (per axis, x and y) are dropped; the
  filter is applied twice. The movement is measured relative to the prediction, which is
  the paper's filter when the prediction is a translation and stays valid under yaw.
* **Pixels to millimetres**, eq. (1): 2 d tan(theta) / w per pixel, generalised to the
  full camera model (each pixel back-projected onto the floor at the camera height).
* **SE(2) extension**: the motion is the least-squares rigid fit (rotation + translation)
  of the surviving pairs in floor millimetres, instead of the mean x/y movement.

The first pair, and the pair after a lost frame, have no motion to predict from; they
are matched by brute force (as ``akaze-bruteforce`` does) to bootstrap.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import Config, param
from floorvo.estimators.base import Frame, StepResult
from floorvo.geometry import floor_rigid_to_T, pixels_to_floor_mm, rigid_fit
from floorvo.imaging import illumination_corrected, to_uint8_contrast
from floorvo.matching import match_guided, match_nn, pack_descriptors

__all__ = ["AkazeGuided", "AkazeBruteforce", "AkazeConfig", "mean_std_filter"]


def mean_std_filter(movement: np.ndarray, passes: int = 2) -> np.ndarray:
    """Boolean mask of rows of ``movement`` (N, 2) kept by the paper-000 filter.

    Each pass keeps pairs with a - s <= m <= a + s on both axes (a: mean, s: standard
    deviation of the pairs kept so far); section II-C of paper 000 applies it twice.
    """
    keep = np.ones(len(movement), dtype=bool)
    for _ in range(passes):
        if keep.sum() < 3:
            break
        m = movement[keep]
        a, s = m.mean(axis=0), m.std(axis=0)
        inside = np.all(np.abs(movement - a) <= s + 1e-9, axis=1)
        keep = keep & inside
    return keep


@dataclass(frozen=True)
class AkazeConfig(Config):
    """AKAZE detector threshold, keypoint budget, guided-matching and filter settings.

    ``search_radius_px`` and ``max_candidates`` bound the guided search around each
    prediction; ``hamming_threshold`` is in bits (the MLDB descriptor has 486). Grazing
    light changes a bump's shading as the LEDs move with the rig, so true matches differ
    by more bits than under diffuse light; the nearest-first order keeps geometry first.
    """

    akaze_threshold: float = param(0.0005, gt=0.0, doc="AKAZE detector response threshold")
    max_keypoints: int = param(1500, min=10, doc="strongest keypoints kept per frame")
    hamming_threshold: int = param(200, min=1, max=512, doc="largest descriptor distance of a match, in bits (of 486)")
    search_radius_px: float = param(12.0, unit="px", gt=0.0, doc="guided search radius around each predicted position")
    max_candidates: int = param(8, min=1, max=64, doc="nearest candidates tried per keypoint in the guided search")
    filter_passes: int = param(2, min=0, max=10, doc="passes of the mean +/- one std movement filter (section II-C)")
    min_matches: int = param(6, min=2, doc="fewer matches: the frame is lost")
    use_flatfield: bool = param(True, doc="divide by the sequence's flat-field frame when it has one")


@dataclass
class _State:
    kps: np.ndarray | None = None  # (N, 2) px
    desc: np.ndarray | None = None  # (N, B) uint8
    packed: np.ndarray | None = None  # (N, W) uint64, the same descriptors packed
    M_last: np.ndarray | None = None  # 3x3 prev-centred px -> cur-centred px, None = no prediction


class _AkazeBase:
    Config = AkazeConfig
    requires = frozenset()

    def __init__(
        self, config: AkazeConfig, camera: CameraModel, *, height_mm: float, flatfield: np.ndarray | None = None, **rig
    ):
        self.config = config
        self.camera = camera
        self.height_mm = float(height_mm)
        self.flatfield = flatfield if config.use_flatfield else None
        self.detector = cv2.AKAZE_create(threshold=config.akaze_threshold)
        self.centre = np.array([camera.cx_px, camera.cy_px])

    def start(self) -> _State:
        return _State()

    def _detect(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        img8 = to_uint8_contrast(illumination_corrected(image, self.flatfield))
        kps, desc = self.detector.detectAndCompute(img8, None)
        if desc is None or len(kps) == 0:
            return np.zeros((0, 2)), np.zeros((0, 61), dtype=np.uint8)
        if len(kps) > self.config.max_keypoints:
            order = np.argsort([-k.response for k in kps])[: self.config.max_keypoints]
            kps = [kps[i] for i in order]
            desc = desc[order]
        return np.array([k.pt for k in kps], dtype=np.float64), desc

    def _bruteforce(self, state: _State, kps: np.ndarray, desc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mutual nearest Hamming neighbours (cross-checked brute force)."""
        m = match_nn(state.desc, desc, cross_check=True)
        return state.kps[m.i0], kps[m.i1]

    def _guided(self, state: _State, kps: np.ndarray, desc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Eq. (2) prediction, then nearest-first candidates accepted under the Hamming threshold."""
        cfg = self.config
        M = state.M_last
        p = state.kps - self.centre
        pred = p @ M[:2, :2].T + M[:2, 2] + self.centre  # eq. (2), general rigid form
        m = match_guided(
            pred,
            kps,
            state.packed,
            pack_descriptors(desc),
            radius_px=cfg.search_radius_px,
            max_candidates=cfg.max_candidates,
            max_distance=cfg.hamming_threshold,
        )
        return state.kps[m.i0], kps[m.i1]

    def step(self, state: _State, frame: Frame) -> StepResult:
        t0 = time.perf_counter()
        kps, desc = self._detect(frame.image)
        t1 = time.perf_counter()
        if state.kps is None:
            state.kps, state.desc, state.packed = kps, desc, pack_descriptors(desc)
            return StepResult(
                "init", reason="first frame", n_keypoints=len(kps), timing_ms=_timing(t0, t1, t1, time.perf_counter())
            )
        if len(kps) < self.config.min_matches or len(state.kps) < self.config.min_matches:
            if len(kps) < self.config.min_matches:
                # This frame cannot be tracked: the next one is matched against the last frame
                # kept (estimator contract), with no motion to predict from across the gap.
                why = f"too few keypoints ({len(kps)})"
                state.M_last = None
            else:
                # The frame kept has too few keypoints (an untextured first frame): this one replaces it.
                why = f"too few keypoints in the previous frame ({len(state.kps)})"
                state.kps, state.desc, state.packed, state.M_last = kps, desc, pack_descriptors(desc), None
            return StepResult(
                "lost", reason=why, n_keypoints=len(kps), timing_ms=_timing(t0, t1, t1, time.perf_counter())
            )
        if self.guided and state.M_last is not None:
            src, dst = self._guided(state, kps, desc)
            pred_M = state.M_last
        else:
            src, dst = self._bruteforce(state, kps, desc)
            pred_M = np.eye(3)
        t2 = time.perf_counter()
        n_matches = len(src)
        if n_matches < self.config.min_matches:
            state.kps, state.desc, state.packed, state.M_last = kps, desc, pack_descriptors(desc), None
            return StepResult(
                "lost",
                reason=f"too few matches ({n_matches})",
                n_keypoints=len(kps),
                n_matches=n_matches,
                timing_ms=_timing(t0, t1, t2, time.perf_counter()),
            )
        # Section II-C: twice mean +/- std on the movement (relative to the prediction).
        p = src - self.centre
        predicted = p @ pred_M[:2, :2].T + pred_M[:2, 2] + self.centre
        keep = mean_std_filter(dst - predicted, self.config.filter_passes)
        src, dst = src[keep], dst[keep]
        if len(src) < max(2, self.config.min_matches // 2):
            state.kps, state.desc, state.packed, state.M_last = kps, desc, pack_descriptors(desc), None
            return StepResult(
                "lost",
                reason=f"too few inliers ({len(src)})",
                n_keypoints=len(kps),
                n_matches=n_matches,
                timing_ms=_timing(t0, t1, t2, time.perf_counter()),
            )
        # Eq. (1) via the camera model, then the SE(2) least-squares rigid fit.
        q_prev = pixels_to_floor_mm(src, self.camera, self.height_mm)
        q_cur = pixels_to_floor_mm(dst, self.camera, self.height_mm)
        R2, t2_mm = rigid_fit(q_prev, q_cur)
        T = floor_rigid_to_T(R2, t2_mm)
        Rpx, tpx = rigid_fit(src - self.centre, dst - self.centre)
        M = np.eye(3)
        M[:2, :2], M[:2, 2] = Rpx, tpx
        state.kps, state.desc, state.packed, state.M_last = kps, desc, pack_descriptors(desc), M
        t3 = time.perf_counter()
        return StepResult(
            "ok",
            T,
            n_keypoints=len(kps),
            n_matches=n_matches,
            n_inliers=int(keep.sum()),
            timing_ms=_timing(t0, t1, t2, t3),
            matches_px=np.hstack([src, dst]),
        )


class AkazeGuided(_AkazeBase):
    name = "akaze-guided"
    description = (
        "paper 000: AKAZE, motion-predicted nearest-first Hamming matching, twice mean+/-std filter, SE(2) fit"
    )
    guided = True


class AkazeBruteforce(_AkazeBase):
    name = "akaze-bruteforce"
    description = "paper 000's baseline: AKAZE with brute-force Hamming matching (cross-checked), same filter and fit"
    guided = False


def _timing(t0: float, t1: float, t2: float, t3: float) -> dict:
    return {"detect": (t1 - t0) * 1e3, "match": (t2 - t1) * 1e3, "estimate": (t3 - t2) * 1e3, "total": (t3 - t0) * 1e3}
