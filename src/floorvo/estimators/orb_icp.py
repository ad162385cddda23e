"""``orb-icp`` (paper 001: Li et al., ORB visual odometry for an AGV on RGB-D frames).

Per frame (section numbers and equations of paper 001):

1. Illumination correction (flat field, or a blur estimate), contrast-normalised to 8 bit.
2. ORB keypoints (section 3: FAST corners oriented by the intensity centroid, eqs. (1)-(3);
   steered BRIEF descriptors, eqs. (4)-(5)), **homogenised** over the image (section 6.2):
   FAST runs with a low threshold and the strongest ``per_cell`` corners of each cell of a
   ``grid_cols x grid_rows`` grid are kept, so the keypoints do not crowd into the most
   contrasted patches. This grid replaces the paper's own homogenisation, which it
   describes only as "the method of image contrast adaptive threshold" (the grey image
   "processed by adaptive threshold to reduce the density of feature points", section
   6.2, with no rule or parameter given); both serve the same end, neither is the other.
3. Hamming matching through FLANN-LSH with the ratio test ``gamma = d / L < ratio``
   (section 3: nearest distance d, second nearest L).
4. **PROSAC** (section 4, eqs. (6)-(7)): matches sorted by quality (ascending gamma) and
   passed to OpenCV's ``USAC_PROSAC`` homography estimator; its inliers are kept.
   Added here (not in paper 001): each inlier's position in the current frame is refined
   to sub-pixel by Lucas-Kanade from its match (``refine_win_px``); without it the whole-
   pixel FAST positions quantise the motion.
5. 3D points from the depth image (back-projection through the camera model).
6. **ICP solved by SVD** (section 5, eqs. (8)-(22), with the reflection check done as
   :func:`floorvo.geometry.umeyama` says, not the paper's ``-R``), iterated
   with residual rejection: ``p_prev = R p_cur + t`` is directly ``T_prev_cur``
   (``update = "icp"``, the paper's step: a full 6-DoF fit of the matched 3D points).
   The default ``update = "plane"`` (added here, issue 14) measures the same 6-DoF step
   more robustly: the floor plane of each frame is fitted to its whole depth image
   (:func:`floorvo.geometry.depth_floor_plane`, a grid of ``plane_step_px`` pixels, thousands of
   points, so height and tilt are precise), each matched pixel's ray is met with its
   frame's plane, and the yaw and in-plane shift are the rigid fit of those floor points in
   the levelled frames; the height change and the roll/pitch change come from the two
   planes (:func:`floorvo.geometry.floor_plane_step`). The ICP on the matched points
   alone lets the depth noise of a few hundred points tilt the fit, and a tilt error
   times the 100 mm depth becomes a shift.

Each frame is matched against the previous (last good) frame. Paper 001 matches "with the
feature points of the current key frame" (section 2) and obtains the pose "by combining the
key frames" (section 7), but gives no rule for choosing a key frame; this estimator keeps no
key frames (frame-to-frame, every good frame becomes the reference).

The estimator needs depth (``requires = {"depth"}``); a run refuses a sequence without it.
A lost frame is never the reference: the next frame is matched against the last good one, and
after ``restart_after_lost`` lost frames in a row tracking restarts from the current frame, said
in its reason (``RESTART_NOTE``), as the other estimators do. (Every frame with depth keypoints
became the reference, lost or not, and the next step was chained as if measured from the last
good frame: a frame of another floor made the one after it 2 mm off, reported ok.)
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import MAX_SEED, param, with_defaults
from floorvo.estimators.base import (
    RESTART_NOTE,
    Frame,
    StepBoundConfig,
    StepResult,
    frame_is_blank,
    frame_problem,
    plane_step_precision_problem,
    stage_timing_ms,
    state_error,
)
from floorvo.geometry import (
    consensus_problem,
    depth_floor_plane_precision,
    floor_plane_step,
    make_T,
    rigid_fit_robust,
    rolling_shutter_undone,
)
from floorvo.imaging import flatfield_gain, illumination_corrected, to_uint8_contrast
from floorvo.matching import knn_from_dmatches, ratio_test

__all__ = ["OrbIcp", "OrbIcpConfig", "OrbIcpFast", "OrbIcpFastConfig", "homogenise_keypoints"]


@dataclass(frozen=True)
class OrbIcpConfig(StepBoundConfig):
    """``fast_threshold``: FAST threshold on the normalised 8-bit frame (low, the grid picks
    the strongest); ``grid_cols x grid_rows`` cells keeping ``per_cell`` corners each
    (homogenisation); ``ratio``: FLANN-LSH ratio-test threshold gamma; ``prosac_threshold_px``:
    PROSAC reprojection threshold; ``icp_iterations``: SVD re-solves with residual rejection;
    ``update``: ``plane`` (6-DoF from each frame's floor plane and the in-plane fit of the
    matches) or ``icp`` (paper 001's ICP-SVD of the matched 3D points); ``plane_step_px``:
    the grid of depth pixels the plane is fitted to; ``refine_win_px``: window of the sub-pixel refinement of each inlier's position in the
    current frame (Lucas-Kanade from the match; 0 = off: FAST corners lie on whole pixels,
    which quantises a pure translation to whole pixels, 1.3 % of a 32.4 px step); ``seed``:
    OpenCV's RNG is seeded with it before each FLANN-LSH match (the LSH tables draw their bits
    from it), so a frame pair gives the same matches whatever ran before."""

    fast_threshold: int = param(8, min=1, max=100, doc="FAST threshold on the normalised 8-bit frame")
    grid_cols: int = param(8, min=1, max=64, doc="grid columns of the keypoint homogenisation")
    grid_rows: int = param(6, min=1, max=64, doc="grid rows of the keypoint homogenisation")
    per_cell: int = param(25, min=1, doc="strongest corners kept per grid cell")
    n_levels: int = param(4, min=1, max=12, doc="ORB pyramid levels")
    ratio: float = param(0.8, gt=0.0, max=1.0, doc="FLANN-LSH ratio-test threshold gamma")
    prosac_threshold_px: float = param(2.0, unit="px", gt=0.0, doc="PROSAC reprojection threshold")
    icp_iterations: int = param(3, min=0, max=20, doc="SVD re-solves with residual rejection")
    min_matches: int = param(8, min=4, doc="fewer matches: the frame is lost")
    min_inlier_fraction: float = param(
        0.2, min=0.0, max=1.0, doc="smaller fraction of the matches in PROSAC's consensus: the frame is lost"
    )
    max_rival_fraction: float = param(
        0.1,
        gt=0.0,
        doc="a second homography of the other matches backed by more than this fraction of the inliers: lost",
    )
    max_residual_mm: float = param(1.0, unit="mm", gt=0.0, doc="larger RMS residual of the ICP fit: the frame is lost")
    refine_win_px: int = param(
        15, unit="px", min=0, max=63, doc="window of the sub-pixel (Lucas-Kanade) refinement; 0 = off"
    )
    use_flatfield: bool = param(True, doc="divide by the sequence's flat-field frame when it has one")
    seed: int = param(0, min=0, max=MAX_SEED, doc="seeds OpenCV's RNG before each FLANN-LSH match")
    restart_after_lost: int = param(
        2, min=1, doc="lost frames in a row after which tracking restarts from the current frame"
    )
    update: str = param(
        "plane",
        choices=("plane", "icp"),
        doc="plane: floor plane of each depth image + in-plane fit of the matches (6-DoF); icp: paper 001's ICP-SVD",
    )
    plane_step_px: int = param(
        4, unit="px", min=1, max=64, doc="grid spacing of the depth pixels the floor plane is fitted to"
    )
    undo_rolling_shutter: bool = param(
        True,
        doc="in a sequence taken by a rolling shutter (sequence.json's sensor.readout_ms), the matched keypoints "
        "are moved to where global shutters at the two frame times see them (floorvo.geometry."
        "rolling_shutter_undone; their 3-D points with them, at their depth); the depth images and their floor "
        "planes are taken as they are",
    )


def homogenise_keypoints(kps: list, shape: tuple[int, int], cols: int, rows: int, per_cell: int) -> list:
    """The ``per_cell`` strongest keypoints (by response) of each grid cell: the homogenisation
    step of paper 001 (section 6.2), done by a grid where the paper uses a contrast-adaptive
    threshold (see the module docstring)."""
    if not kps:
        return []
    h, w = shape
    pts = np.array([k.pt for k in kps])
    resp = np.array([k.response for k in kps])
    cell = np.minimum((pts[:, 1] * rows / h).astype(int), rows - 1) * cols + np.minimum(
        (pts[:, 0] * cols / w).astype(int), cols - 1
    )
    order = np.lexsort((-resp, cell))  # by cell, strongest first
    keep, last, count = [], -1, 0
    for i in order:
        if cell[i] != last:
            last, count = cell[i], 0
        if count < per_cell:
            keep.append(kps[i])
            count += 1
    return keep


@dataclass
class _State:
    kps: np.ndarray | None = None  # (N, 2) px
    desc: np.ndarray | None = None  # (N, 32) uint8
    xyz: np.ndarray | None = None  # (N, 3) mm, camera frame; NaN where no depth
    img8: np.ndarray | None = None  # normalised previous frame
    # floor plane (n, d_mm) of the previous frame, camera frame, and its standard errors (height mm, tilt rad)
    plane: tuple[np.ndarray, float, tuple[float, float]] | None = None
    n_lost: int = 0  # frames lost in a row since the reference
    t_ref_s: float = 0.0  # the reference frame's time (s)


class OrbIcp:
    """ORB + FLANN-LSH ratio test + PROSAC + ICP-SVD on depth (paper 001)."""

    name = "orb-icp"
    description = (
        "paper 001: homogenised ORB, FLANN-LSH ratio test, PROSAC, depth; 6-DoF from each depth image's "
        "floor plane (update=icp: ICP by SVD)"
    )
    Config = OrbIcpConfig
    requires = frozenset({"depth"})

    def __init__(
        self,
        config: OrbIcpConfig,
        camera: CameraModel,
        *,
        height_mm: float,
        flatfield: np.ndarray | None = None,
        row_time_s: float = 0.0,
        **rig,
    ):
        self.config = config
        self.camera = camera
        self.height_mm = float(height_mm)
        # A rolling shutter's time between neighbouring rows (s; 0: a global shutter).
        self.row_time_s = float(row_time_s) if config.undo_rolling_shutter else 0.0
        self.flatfield = flatfield if config.use_flatfield else None
        self.flat_gain = None if self.flatfield is None else flatfield_gain(self.flatfield)  # once, not per frame
        n_max = config.grid_cols * config.grid_rows * config.per_cell
        self.orb = cv2.ORB.create(
            nfeatures=4 * n_max,
            nlevels=config.n_levels,
            fastThreshold=config.fast_threshold,
            edgeThreshold=19,
            patchSize=19,
        )
        # FLANN with locality-sensitive hashing for binary descriptors (FLANN_INDEX_LSH = 6).
        self.flann = cv2.FlannBasedMatcher(
            dict(algorithm=6, table_number=6, key_size=12, multi_probe_level=1), dict(checks=50)
        )

    def floor_plane(self, depth_mm: np.ndarray) -> tuple[np.ndarray, float, tuple[float, float]] | None:
        """The floor plane ``(n, d_mm)`` (camera frame) of a depth image, from the pixels of a
        ``plane_step_px`` grid, and its standard errors ``(height mm, tilt rad)``
        (:func:`floorvo.geometry.depth_floor_plane_precision`); None with fewer than 100 of
        them carrying depth."""
        return depth_floor_plane_precision(depth_mm, self.camera, self.config.plane_step_px)

    def start(self) -> _State:
        return _State()

    def _features(
        self, image: np.ndarray, depth_mm: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        cfg = self.config
        img8 = to_uint8_contrast(illumination_corrected(image, gain=self.flat_gain))
        kps = self.orb.detect(img8, None)
        kps = homogenise_keypoints(list(kps), img8.shape, cfg.grid_cols, cfg.grid_rows, cfg.per_cell)
        kps, desc = self.orb.compute(img8, kps)
        if desc is None or not kps:
            return np.zeros((0, 2)), np.zeros((0, 32), np.uint8), np.zeros((0, 3)), img8
        uv = np.array([k.pt for k in kps], dtype=np.float64)
        xyz = self._depth_xyz(depth_mm, uv)
        return uv, desc, xyz, img8

    def _depth_xyz(self, depth_mm: np.ndarray, uv: np.ndarray) -> np.ndarray:
        """(N, 3) camera points of pixels ``uv`` from the depth image (bilinear; NaN without depth)."""
        depth = np.asarray(depth_mm, dtype=np.float32)
        mx = uv[:, 0].astype(np.float32).reshape(-1, 1)
        my = uv[:, 1].astype(np.float32).reshape(-1, 1)
        z = cv2.remap(depth, mx, my, cv2.INTER_LINEAR).ravel()
        zn = cv2.remap(depth, mx, my, cv2.INTER_NEAREST).ravel()
        return self.camera.unproject(uv, np.where((z > 0) & (zn > 0), z, np.nan))

    def _match(self, d_prev: np.ndarray, d_cur: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(i_prev, i_cur, gamma) of the matches passing the ratio test, one per current
        keypoint (the lowest gamma), best (lowest gamma) first."""
        if len(d_prev) < 2 or len(d_cur) < 2:
            return np.zeros(0, int), np.zeros(0, int), np.zeros(0)
        cv2.setRNGSeed(self.config.seed)  # the LSH index built on d_cur draws its hash bits from OpenCV's RNG
        # LSH may return fewer than 2 neighbours for a row: that row has no ratio and no match.
        dist, idx = knn_from_dmatches(self.flann.knnMatch(d_prev, d_cur, k=2), len(d_prev), 2)
        # Section 3: gamma = d / L under the threshold.
        m = ratio_test(dist, idx, self.config.ratio, unique="best")
        gamma = np.asarray(m.ratio)
        order = np.argsort(gamma, kind="stable")  # PROSAC takes the matches by quality
        return m.i0[order], m.i1[order], gamma[order]

    def step(self, state: _State, frame: Frame) -> StepResult:
        if not isinstance(state, _State):
            raise state_error(self.name, state)
        t0 = time.perf_counter()
        img = np.asarray(frame.image)
        if frame.depth_mm is None:
            return StepResult("lost", reason="frame has no depth image", timing_ms=stage_timing_ms(t0, t0, t0, t0))
        bad = frame_problem(img, self.camera) or frame_problem(frame.depth_mm, self.camera, "depth image", finite=False)
        if bad:
            return StepResult("lost", reason=bad, timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter()))
        depth_mm = np.asarray(frame.depth_mm)
        if depth_mm.dtype.kind == "f" and not np.isfinite(depth_mm).all():  # NaN, inf: no measurement, as 0
            depth_mm = np.where(np.isfinite(depth_mm), depth_mm, 0.0).astype(depth_mm.dtype)
        if frame_is_blank(img):
            return StepResult(
                "lost", reason="empty frame (no texture)", timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter())
            )
        uv, desc, xyz, img8 = self._features(frame.image, depth_mm)
        plane = self.floor_plane(depth_mm) if self.config.update == "plane" else None
        t1 = time.perf_counter()
        n_depth = int(np.isfinite(xyz).all(axis=1).sum())
        usable = n_depth >= self.config.min_matches and (plane is not None or self.config.update != "plane")
        current = (uv, desc, xyz, img8, plane)
        if state.kps is None:
            state.kps, state.desc, state.xyz, state.img8, state.plane = current
            state.t_ref_s = float(frame.timestamp_s)
            return StepResult(
                "init",
                reason="first frame",
                n_keypoints=len(uv),
                timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()),
            )
        res = self._measured(state, current, depth_mm, n_depth, t0, t1, float(frame.timestamp_s) - state.t_ref_s)
        # The next frame is matched against the last good one; after restart_after_lost lost
        # frames in a row, against the current one, said (RESTART_NOTE: the motion over the gap is
        # unknown). Every frame with depth keypoints became the reference, lost or not, and the
        # next step was chained onto the last good frame's pose as if measured from it.
        if res.status == "ok":
            state.kps, state.desc, state.xyz, state.img8, state.plane = current
            state.n_lost, state.t_ref_s = 0, float(frame.timestamp_s)
            return res
        state.n_lost += 1
        if state.n_lost >= self.config.restart_after_lost and usable:
            state.kps, state.desc, state.xyz, state.img8, state.plane = current
            state.n_lost, state.t_ref_s = 0, float(frame.timestamp_s)
            res = dataclasses.replace(res, reason=f"{res.reason}; {RESTART_NOTE}")
        return res

    def _measured(
        self,
        state: _State,
        current: tuple,
        depth_mm: np.ndarray,
        n_depth: int,
        t0: float,
        t1: float,
        interval_s: float = 0.0,
    ) -> StepResult:
        """The step from the reference frame of ``state`` to the ``current`` one (its keypoints (N, 2)
        px, descriptors, 3-D points (N, 3) mm, normalised image and floor plane), ``interval_s``
        after it, ok or lost."""
        uv, desc, xyz, img8, plane = current
        prev = (state.kps, state.desc, state.xyz, state.img8)
        plane_prev = state.plane
        if len(uv) < self.config.min_matches:
            return StepResult(
                "lost",
                reason=f"too few keypoints ({len(uv)})",
                n_keypoints=len(uv),
                timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()),
            )
        if n_depth < self.config.min_matches:
            return StepResult(
                "lost",
                reason=f"too few keypoints with depth ({n_depth})",
                n_keypoints=len(uv),
                timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()),
            )
        kp0, d0, xyz0, img0 = prev
        assert kp0 is not None and d0 is not None and xyz0 is not None and img0 is not None  # set by frame 0
        qi, ti, gam = self._match(d0, desc)
        t2 = time.perf_counter()
        n_matches = len(qi)

        def lost(why: str, n_in: int = 0) -> StepResult:
            return StepResult(
                "lost",
                reason=why,
                n_keypoints=len(uv),
                n_matches=n_matches,
                n_inliers=n_in,
                timing_ms=stage_timing_ms(t0, t1, t2, time.perf_counter()),
            )

        def ok(T_prev_cur: np.ndarray, uv_prev_kept: np.ndarray, uv_cur_kept: np.ndarray) -> StepResult:
            """The step ``T_prev_cur`` (4, 4) mm from the kept matches (K, 2) px of both frames."""
            return StepResult(
                "ok",
                T_prev_cur,
                n_keypoints=len(uv),
                n_matches=n_matches,
                n_inliers=len(uv_prev_kept),
                timing_ms=stage_timing_ms(t0, t1, t2, time.perf_counter()),
                matches_px=np.hstack([uv_prev_kept, uv_cur_kept]),
            )

        if n_matches < self.config.min_matches:
            return lost(f"too few matches ({n_matches})")
        # PROSAC: matches sorted by quality (ascending gamma), homography model (eq. (6)).
        src = kp0[qi].astype(np.float32)
        dst = uv[ti].astype(np.float32)
        H, mask = cv2.findHomography(
            src, dst, cv2.USAC_PROSAC, self.config.prosac_threshold_px, maxIters=2000, confidence=0.999
        )
        if H is None or mask is None:
            return lost("PROSAC found no consistent homography")
        inl = mask.ravel().astype(bool)
        # Self-checks (issue 14): the consensus is a large enough share of the matches, and no
        # second motion is nearly as well supported by the matches PROSAC left out.
        why = consensus_problem(
            src,
            dst,
            inl,
            self.config.prosac_threshold_px,
            min_fraction=self.config.min_inlier_fraction,
            min_count=self.config.min_matches,
            max_rival_fraction=self.config.max_rival_fraction,
            seed=self.config.seed,
        )
        if why:
            return lost(why, int(inl.sum()))
        uv_prev, uv_cur = kp0[qi[inl]], uv[ti[inl]]
        P_prev, P_cur = xyz0[qi[inl]], xyz[ti[inl]]
        w = self.config.refine_win_px
        if w > 0 and len(uv_prev):
            p1, st, _ = cv2.calcOpticalFlowPyrLK(
                img0,
                img8,
                uv_prev.astype(np.float32).reshape(-1, 1, 2),
                uv_cur.astype(np.float32).reshape(-1, 1, 2).copy(),
                winSize=(w, w),
                maxLevel=0,
                flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
                criteria=(cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001),
            )
            p1 = p1.reshape(-1, 2).astype(np.float64)
            good = (st.ravel() == 1) & (np.linalg.norm(p1 - uv_cur, axis=1) < 1.5)
            uv_prev, uv_cur, P_prev = uv_prev[good], p1[good], P_prev[good]
            P_cur = self._depth_xyz(depth_mm, uv_cur)
            if len(uv_prev) < self.config.min_matches:  # one pair left was a ValueError of the fit
                return lost(f"too few matches after the sub-pixel refinement ({len(uv_prev)})", len(uv_prev))
        # A rolling shutter's readout undone: the keypoints where global shutters at the two frame
        # times see them, their 3-D points moved with them at their own depth (the reports keep the
        # frames' own pixels).
        uv_prev_gs, uv_cur_gs = rolling_shutter_undone(
            uv_prev,
            uv_cur,
            interval_s=interval_s,
            row_time_s=self.row_time_s,
            mid_row_px=(self.camera.height_px - 1) / 2.0,
        )
        if self.row_time_s:
            P_prev = (
                P_prev + self.camera.unproject(uv_prev_gs, P_prev[:, 2]) - self.camera.unproject(uv_prev, P_prev[:, 2])
            )
            P_cur = P_cur + self.camera.unproject(uv_cur_gs, P_cur[:, 2]) - self.camera.unproject(uv_cur, P_cur[:, 2])
        if self.config.update == "plane":
            if plane is None or plane_prev is None:
                return lost("too few depth pixels to fit the floor plane")
            # 6-DoF from the two floor planes and the in-plane rigid fit of the matched rays.
            T, keep, rms_mm = floor_plane_step(
                uv_prev_gs, uv_cur_gs, self.camera, plane_prev[:2], plane[:2], iterations=self.config.icp_iterations
            )
            if keep.sum() < self.config.min_matches:
                return lost(f"too few matches behind the in-plane fit ({int(keep.sum())})", int(keep.sum()))
            if rms_mm > self.config.max_residual_mm:
                return lost(
                    f"in-plane fit residual {rms_mm:.2f} mm RMS > {self.config.max_residual_mm:g}", int(keep.sum())
                )
            why = self._precision_problem(T, uv_prev_gs[keep], uv_cur_gs[keep], plane_prev, plane)
            if why:
                return lost(why, int(keep.sum()))
            return ok(T, uv_prev[keep], uv_cur[keep])
        has_depth = np.isfinite(P_prev).all(axis=1) & np.isfinite(P_cur).all(axis=1)
        P_prev, P_cur = P_prev[has_depth], P_cur[has_depth]
        if len(P_prev) < self.config.min_matches:
            return lost(f"too few inliers with depth ({len(P_prev)})", len(P_prev))
        # ICP by SVD (eqs. (8)-(22)) with residual rejection: p_prev = R p_cur + t (eq. (9)), so (R, t) is T_prev_cur.
        R, t, keep = rigid_fit_robust(P_cur, P_prev, iterations=self.config.icp_iterations)
        if keep.sum() < self.config.min_matches:
            return lost(f"too few points behind the ICP fit ({int(keep.sum())})", int(keep.sum()))
        rms_mm = float(np.sqrt(np.mean(np.sum((P_cur[keep] @ R.T + t - P_prev[keep]) ** 2, axis=1))))
        if rms_mm > self.config.max_residual_mm:
            return lost(f"ICP residual {rms_mm:.2f} mm RMS > {self.config.max_residual_mm:g}", int(keep.sum()))
        return ok(make_T(R, t), uv_prev[has_depth][keep], uv_cur[has_depth][keep])

    def _precision_problem(
        self,
        T: np.ndarray,
        uv_prev: np.ndarray,
        uv_cur: np.ndarray,
        plane_prev: tuple[np.ndarray, float, tuple[float, float]],
        plane_cur: tuple[np.ndarray, float, tuple[float, float]],
    ) -> str:
        """Why the 6-DoF step ``T`` (``update = plane``) from the pairs it kept ``uv_prev ->
        uv_cur`` (K, 2) px and the two frames' floor planes is too imprecise to report ('' if it
        is not): its standard errors (:func:`floorvo.geometry.floor_plane_step_precision`: the
        in-plane fit's and the planes' height and tilt), ``precision_sigmas`` of them, must lie
        within issue 14's bound (``max_step_error_*``), as stereo-sift's. Without it a step of
        few pairs (a turn of 90 degrees between two 160 x 120 frames) was reported ok 0.06-0.14
        mm off against a 0.05 mm bound."""
        return plane_step_precision_problem(
            self.config, T, uv_prev, uv_cur, self.camera, plane_prev[:2], plane_cur[:2], plane_prev[2], plane_cur[2]
        )


#: The real-time preset (issue 14 item 5): one ORB level instead of the pyramid (at a fixed
#: camera height the floor keeps its scale), and 15 corners per grid cell instead of 25 (720
#: instead of 1200 keypoints: detection, description and matching scale with them; a step
#: is measured by the 200-450 that PROSAC keeps). Frames/s and drift against the default:
#: BENCHMARKS.md, "Real time on one core".
OrbIcpFastConfig = with_defaults(OrbIcpConfig, "OrbIcpFastConfig", n_levels=1, per_cell=15)


class OrbIcpFast(OrbIcp):
    name = "orb-icp-fast"
    description = "orb-icp's real-time preset: ORB on one pyramid level, 15 corners per grid cell"
    Config = OrbIcpFastConfig
