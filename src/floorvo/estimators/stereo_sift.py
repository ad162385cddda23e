"""``stereo-sift`` (paper 002: Mohamed et al., stereo SIFT localisation, Algorithm 1).

Algorithm 1 of paper 002, per new stereo frame i+1 (frame i's features are kept in the
state, so each frame's SIFT runs once):

1. SIFT features ``D_L``, ``D_R`` of the left and right frames (eqs. (4)-(6): DoG scale
   space), on illumination-corrected, contrast-normalised frames.
2. Left-right matching ``M_2`` of each frame as it arrives (ratio test plus the epipolar
   constraint of the calibrated rig); only the left keypoints with a right match are kept,
   triangulated (step 5), with their descriptors.
3. Temporal matching ``M_1`` (Lowe's ratio test) of frame i's kept left descriptors with
   frame i+1's; fewer than ``min_matches``: lost. Algorithm 1 runs the two in the other
   order, ``M_1`` of all of ``D_Li`` and ``D_Li+1`` first ("If M_1 > 0") and ``M_2`` after;
   here ``M_1`` sees only the left keypoints that ``M_2`` kept, so its ratio test compares a
   match with the second-nearest of those, not of every left keypoint of frame i+1. A pair
   is used when L_i -> L_i+1, L_i -> R_i and L_i+1 -> R_i+1 all matched; R_i and R_i+1 are
   not matched to each other.
4. RANSAC on the temporal matches (a homography: the floor is a plane) keeps the trusted
   points.
5. Triangulation of ``P_3dL1`` and ``P_3dL2`` in the left camera (projection matrices
   from the camera models, eqs. (1)-(3), and ``T_cam0_cam1``), of the keypoints taken into
   each camera's ideal pinhole first (a lens's distortion undone,
   :meth:`floorvo.camera.CameraModel.undistorted_px`), as for the epipolar check and the
   homographies of steps 3 and 4.
6. Position update: the paper's ``DP_L = P_3dL1 - P_3dL2`` (mean difference, a pure
   translation; ``update = "mean"``), or the improvement made here: a rigid SVD fit of the
   two 3D point sets. The full 3D fit (``update = "rigid"``) is ill-conditioned on a floor:
   the points span +/-20 mm across but only the depth noise along z, so a small tilt error
   times the 100 mm depth becomes a translation error (0.8 mm/frame on a rendered stereo
   sequence). ``update = "planar"`` fits the rotation about the optical axis and
   the x-y translation by SVD (the rigid fit of the x-y coordinates) and the height change
   as the mean z difference: it cannot see a tilt. ``update = "plane"`` (issue 14) measures
   the full 6-DoF step robustly: the floor plane of each frame is fitted to all of its
   triangulated points (:func:`floorvo.geometry.fit_plane`: hundreds of points, so height
   and tilt are precise), the matched left pixels' rays are met with their frame's plane
   and the yaw and in-plane shift are the rigid fit of those floor points in the levelled
   frames; the height and roll/pitch change come from the two planes
   (:func:`floorvo.geometry.floor_plane_step`). ``plane`` is the default (see
   BENCHMARKS.md, "6-DoF with depth and stereo").

Self-checks (issue 14: a step reported ok must be within 0.05 mm + 2 % of the true step and
0.3 degrees): the temporal matches' consensus and the two-motions check after RANSAC; with
``update = mean`` a step that turns, which a translation cannot hold (:meth:`StereoSift._turn_problem`),
is lost; and with ``update = plane`` the step's precision (``precision_sigmas``): its standard errors from the
residuals of the in-plane fit and of the two floor planes. A floor plane's tilt error turns the
step and shifts it by the height times that error (0.3 mrad: 0.03 mm at 100 mm), which the
pairs cannot see; on small frames (324x247) the planes alone leave a step about 0.06 mm
uncertain, and such steps are lost rather than reported (BENCHMARKS.md, "stereo-sift: the
step's precision"). A lost step after the current frame became the reference says so
(``RESTART_NOTE``).

The real-time preset ``stereo-sift-fast`` (issue 14 item 5) departs from step 3: SIFT runs on
the left frame only, and the left keypoints are found in the right frame by Lucas-Kanade from
their positions through the previous frame's floor plane (``right_features = "flow"``; SIFT
again when fewer than ``min_matches`` are found). The temporal matching, RANSAC, the self-checks
and the update are the same.

Requires a stereo sequence (``requires = {"stereo"}``).
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import MAX_SEED, param, with_defaults
from floorvo.errors import ConfigError
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
    fit_plane,
    floor_plane_step,
    invert_T,
    plane_fit_precision,
    rigid_fit_robust,
    rolling_shutter_undone,
)
from floorvo.imaging import flatfield_gain, illumination_corrected, local_contrast_uint8, to_uint8_contrast
from floorvo.matching import match_ratio

__all__ = ["StereoSift", "StereoSiftConfig", "StereoSiftFast", "StereoSiftFastConfig"]

#: Where OpenCV's SIFT puts a keypoint, less where its point is, in each axis (px of the image
#: SIFT sees): its first octave doubles the image, and without ``enable_precise_upscale`` the
#: doubled image's pixel j is mapped back to j / 2 while its centre lies at j / 2 - 0.25. Measured:
#: the keypoints of a frame turned 180 degrees lie 2 x 0.2500 px off the turned keypoints of the
#: frame (2948 pairs; with ``enable_precise_upscale`` 0.0000, but other keypoints: the suite's
#: stereo runs lost more steps). Uncorrected, a turn of 180 degrees in place read 0.18 mm of
#: translation at 320x240 (twice that on the frame halved, -fast, where the right frame's
#: keypoints, followed by Lucas-Kanade, have no such offset and the disparity took half a pixel).
SIFT_UPSCALE_OFFSET_PX = 0.25


@dataclass(frozen=True)
class StereoSiftConfig(StepBoundConfig):
    """``n_features``: SIFT keypoint budget per image; ``contrast_threshold``: SIFT's DoG
    threshold; ``ratio``: Lowe ratio test; ``epipolar_px``: largest distance of a right
    keypoint from its epipolar line; ``ransac_threshold_px``: RANSAC homography threshold;
    ``update``: ``plane`` (6-DoF: each frame's floor plane from all its triangulated points and
    the in-plane fit of the matched rays), ``planar`` (SVD fit of the 3D sets restricted to a
    rotation about the optical axis, plus the mean height change), ``rigid`` (full 3D SVD
    fit) or ``mean`` (paper 002's DP_L). ``precision_sigmas``, ``max_step_error_*``: with
    ``update = plane``, a step whose standard errors, this many of them, exceed issue 14's bound
    is lost (:meth:`StereoSift._precision_problem`)."""

    n_features: int = param(1000, min=10, doc="SIFT keypoint budget per image")
    contrast_threshold: float = param(0.02, gt=0.0, doc="SIFT's DoG contrast threshold")
    n_octave_layers: int = param(3, min=1, max=8, doc="SIFT's DoG layers per octave (OpenCV's default 3)")
    detect_scale: float = param(
        1.0,
        gt=0.0,
        max=1.0,
        doc="SIFT runs on the frame resized by this factor (0.5: its doubled first octave is the frame's own size)",
    )
    ratio: float = param(0.8, gt=0.0, max=1.0, doc="Lowe ratio test")
    epipolar_px: float = param(
        1.5, unit="px", gt=0.0, doc="largest distance of a right keypoint from its epipolar line"
    )
    ransac_threshold_px: float = param(2.0, unit="px", gt=0.0, doc="RANSAC homography threshold")
    min_matches: int = param(8, min=4, doc="fewer matches: the frame is lost")
    min_inlier_fraction: float = param(
        0.2, min=0.0, max=1.0, doc="smaller fraction of the temporal matches in RANSAC's consensus: the frame is lost"
    )
    max_rival_fraction: float = param(
        0.1,
        gt=0.0,
        doc="a second homography of the other matches backed by more than this fraction of the inliers: lost",
    )
    seed: int = param(0, min=0, max=MAX_SEED, doc="seeds OpenCV's RNG before each RANSAC")
    update: str = param(
        "plane",
        choices=("planar", "rigid", "mean", "plane"),
        doc="plane: 6-DoF from each frame's floor plane; planar: rotation about the optical axis; "
        "rigid: full 3D; mean: paper 002's DP_L",
    )
    use_flatfield: bool = param(True, doc="divide by the sequence's flat-field frame when it has one")
    undo_rolling_shutter: bool = param(
        True,
        doc="in a sequence taken by rolling shutters read out together (sequence.json's sensor.readout_ms), the "
        "left keypoints of the temporal matches are moved to where global shutters at the two frame times see "
        "them (floorvo.geometry.rolling_shutter_undone; their 3-D points with them, at their depth); the stereo "
        "points' floor planes are taken as they are",
    )
    refine_win_px: int = param(
        21,
        unit="px",
        min=0,
        max=63,
        doc="update = plane: window of the Lucas-Kanade refinement of the stereo grid the plane is fitted to; 0 = off",
    )
    contrast_blur_downscale: int = param(
        1,
        min=1,
        max=8,
        doc="update = plane: the local-contrast images' blurs computed on copies this many times smaller (1: exact)",
    )
    right_features: str = param(
        "sift",
        choices=("sift", "flow"),
        doc="sift: SIFT on the right frame, ratio-matched (paper 002's M_2); flow: the left keypoints followed "
        "into the right frame by Lucas-Kanade through the previous frame's floor plane (SIFT when too few)",
    )
    flow_max_correction_px: float = param(
        4.0, unit="px", gt=0.0, doc="right_features = flow: a point moved further from its prediction is dropped"
    )
    plane_step_px: int = param(
        12, unit="px", min=2, max=128, doc="update = plane: spacing of the left-image grid the plane is fitted to"
    )
    max_tilt_rad: float = param(
        0.2, unit="rad", gt=0.0, doc="update = plane: a floor plane tilted more than this from the optical axis: lost"
    )


@dataclass
class _Side:
    uv: np.ndarray  # (N, 2) left keypoints with a right match
    desc: np.ndarray  # (N, 128) float32 their descriptors
    xyz: np.ndarray  # (N, 3) mm in the left camera, triangulated
    uv_pinhole: np.ndarray  # (N, 2) the keypoints in the left camera's ideal pinhole (uv without distortion)
    plane: tuple[np.ndarray, float] | None = None  # floor plane (n, d_mm) of all the xyz, left camera
    plane_sigma: tuple[float, float] = (float("inf"), float("inf"))  # its standard errors (height mm, tilt rad)
    t_s: float = 0.0  # the frame's time (s)


@dataclass
class _State:
    prev: _Side | None = None


class StereoSift:
    """SIFT left/right at i and i+1, LR + temporal matching, RANSAC, triangulation, 3D update (paper 002)."""

    name = "stereo-sift"
    description = (
        "paper 002 Algorithm 1: stereo SIFT, LR + temporal matching, RANSAC, triangulation, 6-DoF floor-plane update"
    )
    Config = StereoSiftConfig
    requires = frozenset({"stereo"})

    def __init__(
        self,
        config: StereoSiftConfig,
        camera: CameraModel,
        *,
        height_mm: float,
        flatfield: np.ndarray | None = None,
        camera_right: CameraModel | None = None,
        T_cam0_cam1: np.ndarray | None = None,
        flatfield_right: np.ndarray | None = None,
        row_time_s: float = 0.0,
        **rig,
    ):
        if camera_right is None or T_cam0_cam1 is None:
            raise ConfigError("stereo-sift: needs camera_right and T_cam0_cam1 (a stereo rig); the sequence is mono")
        self.config = config
        self.camera = camera
        # A rolling shutter's time between neighbouring rows (s; 0: a global shutter).
        self.row_time_s = float(row_time_s) if config.undo_rolling_shutter else 0.0
        self.camera_right = camera_right
        self.height_mm = float(height_mm)
        self.flatfield = flatfield if config.use_flatfield else None
        self.flatfield_right = flatfield_right if config.use_flatfield else None
        # The flat fields' gains, once per run rather than per frame.
        self.flat_gain = None if self.flatfield is None else flatfield_gain(self.flatfield)
        self.flat_gain_right = None if self.flatfield_right is None else flatfield_gain(self.flatfield_right)
        self.T_cam0_cam1 = np.asarray(T_cam0_cam1, dtype=float)
        self.T10 = T10 = invert_T(self.T_cam0_cam1)  # left camera -> right camera
        # Eqs. (1)-(3) of paper 002: P = K [R | t] for each camera, the left camera as reference.
        self.P_left = camera.K @ np.hstack([np.eye(3), np.zeros((3, 1))])
        self.P_right = camera_right.K @ T10[:3, :]
        # Fundamental matrix for the epipolar check: x_R^T F x_L = 0.
        R, t = T10[:3, :3], T10[:3, 3]
        tx = np.array([[0, -t[2], t[1]], [t[2], 0, -t[0]], [-t[1], t[0], 0]])
        self.F = np.linalg.inv(camera_right.K).T @ tx @ R @ np.linalg.inv(camera.K)
        self.sift = cv2.SIFT.create(
            nfeatures=config.n_features,
            nOctaveLayers=config.n_octave_layers,
            contrastThreshold=config.contrast_threshold,
        )

    def start(self) -> _State:
        return _State()

    def _detect(self, img8: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(N, 2) keypoints in full-frame px (x, y; pixel centres at integers) and (N, 128) descriptors.

        With ``detect_scale`` s < 1 SIFT sees the frame resized by s (area averaging); a
        keypoint u' of the small image is u = (u' + 0.5) / s - 0.5 in the frame. OpenCV's
        keypoints lie :data:`SIFT_UPSCALE_OFFSET_PX` off their points: taken out first.
        """
        s = self.config.detect_scale
        if s != 1.0:
            img8 = cv2.resize(img8, None, fx=s, fy=s, interpolation=cv2.INTER_AREA)
        kps, desc = self.sift.detectAndCompute(img8, None)
        if desc is None or not kps:
            return np.zeros((0, 2)), np.zeros((0, 128), np.float32)
        uv = np.array([k.pt for k in kps], dtype=np.float64) - SIFT_UPSCALE_OFFSET_PX
        return (uv + 0.5) / s - 0.5 if s != 1.0 else uv, desc

    def _ratio_match(self, da: np.ndarray, db: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lowe's ratio test (L2); several rows of ``da`` may take one row of ``db``."""
        m = match_ratio(da, db, self.config.ratio, unique="none")
        return m.i0, m.i1

    def _stereo(
        self, image: np.ndarray, image_right: np.ndarray, plane_guess: tuple[np.ndarray, float] | None = None
    ) -> _Side:
        """Left keypoints matched in the right frame (M_2), triangulated in the left camera.

        ``right_features = "flow"``: the left keypoints are followed into the right frame by
        Lucas-Kanade from their positions through ``plane_guess`` (the previous frame's floor
        plane ``(n, d_mm)`` in the left camera; the rig's nominal one when None), instead of
        SIFT on the right frame and the ratio test; with fewer than ``min_matches`` followed,
        the frame is matched by SIFT.
        """
        cfg = self.config
        imgL = to_uint8_contrast(illumination_corrected(image, gain=self.flat_gain))
        imgR = to_uint8_contrast(illumination_corrected(image_right, gain=self.flat_gain_right))
        uvL, dL = self._detect(imgL)
        contrast = None
        qi, uvR_q = np.zeros(0, np.int64), np.zeros((0, 2))
        if cfg.right_features == "flow":
            contrast = self._local_contrast(imgL, imgR)
            qi, uvR_q = self._flow_right(contrast, uvL, plane_guess or (np.array([0.0, 0.0, 1.0]), self.height_mm))
        if len(qi) < cfg.min_matches:
            uvR, dR = self._detect(imgR)
            qi, ti = self._ratio_match(dL, dR)
            uvR_q = uvR[ti]
        if len(qi) == 0:
            return _Side(np.zeros((0, 2)), np.zeros((0, 128), np.float32), np.zeros((0, 3)), np.zeros((0, 2)))
        # The epipolar check, the triangulation (eqs. (1)-(3): P = K [R | t]) and the homographies
        # below hold for a pinhole: a distorted lens's keypoints are taken into its ideal pinhole
        # first (they were triangulated as they were, and every step of a lens with k1 = -0.05
        # was lost as imprecise, update = rigid's 11 of 11 reported ok and 31 % long).
        pinL = self.camera.undistorted_px(uvL[qi])
        pinR = self.camera_right.undistorted_px(uvR_q)
        xl = np.hstack([pinL, np.ones((len(qi), 1))])
        xr = np.hstack([pinR, np.ones((len(qi), 1))])
        line = xl @ self.F.T  # epipolar lines in the right image
        dist = np.abs(np.sum(line * xr, axis=1)) / np.maximum(np.hypot(line[:, 0], line[:, 1]), 1e-12)
        ok = dist < cfg.epipolar_px
        qi, uvR_q, pinL, pinR = qi[ok], uvR_q[ok], pinL[ok], pinR[ok]
        if len(qi) == 0:
            return _Side(np.zeros((0, 2)), np.zeros((0, 128), np.float32), np.zeros((0, 3)), np.zeros((0, 2)))
        X = cv2.triangulatePoints(self.P_left, self.P_right, pinL.T.astype(np.float64), pinR.T.astype(np.float64))
        xyz = (X[:3] / X[3]).T
        front = xyz[:, 2] > 0
        side = _Side(uvL[qi][front], dL[qi][front], xyz[front], pinL[front])
        if cfg.update == "plane" and int(front.sum()) >= cfg.min_matches:
            fitted = self._floor_plane(imgL, imgR, pinL[front], pinR[front], contrast)
            if fitted is not None:
                side.plane, side.plane_sigma = fitted
        return side

    def _local_contrast(self, imgL: np.ndarray, imgR: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The left and right frames' local-contrast images (:func:`floorvo.imaging.local_contrast_uint8`)."""
        f = self.config.contrast_blur_downscale
        return local_contrast_uint8(imgL, blur_downscale=f), local_contrast_uint8(imgR, blur_downscale=f)

    def _flow_right(
        self, contrast: tuple[np.ndarray, np.ndarray], uvL: np.ndarray, plane: tuple[np.ndarray, float]
    ) -> tuple[np.ndarray, np.ndarray]:
        """The left keypoints ``uvL`` (N, 2) px found in the right frame: ``(indices (K,), right px (K, 2))``.

        Each is carried through the homography the floor plane ``n . p = d`` (left camera, mm)
        induces between the two cameras, ``H = K_R (R + t n^T / d) K_L^-1`` with ``p_R = R p_L + t``
        (Hartley & Zisserman, Result 13.1), then aligned by Lucas-Kanade (window ``refine_win_px``,
        two pyramid levels) on the local-contrast images; a point moved more than
        ``flow_max_correction_px`` from its prediction, or lost by Lucas-Kanade, is dropped.
        """
        cfg = self.config
        n, d = plane
        Hn = self.T10[:3, :3] + np.outer(self.T10[:3, 3], np.asarray(n, dtype=float)) / float(d)
        H = self.camera_right.K @ Hn @ np.linalg.inv(self.camera.K)
        lcL, lcR = contrast
        w = max(cfg.refine_win_px, 9)
        h_px, w_px = lcR.shape
        if len(uvL) == 0:
            return np.zeros(0, np.int64), np.zeros((0, 2))
        # H maps the ideal pinholes' pixels (CameraModel.undistorted_px): a distorted lens's
        # keypoints go through it from the left pinhole and back into the right frame.
        pin = self.camera.undistorted_px(uvL).reshape(-1, 1, 2).astype(np.float64)
        pred = self.camera_right.distorted_px(cv2.perspectiveTransform(pin, H).reshape(-1, 2))
        inside = (pred[:, 0] >= w) & (pred[:, 0] < w_px - w) & (pred[:, 1] >= w) & (pred[:, 1] < h_px - w)
        # SIFT gives a point of several dominant gradient orientations once per orientation: keep
        # one (the ratio-matched right SIFT of the paper's M_2 keeps at most one of them, too).
        _, first = np.unique(uvL, axis=0, return_index=True)
        inside[np.setdiff1d(np.arange(len(uvL)), first)] = False
        idx = np.nonzero(inside)[0]
        if len(idx) == 0:
            return idx, np.zeros((0, 2))
        p1, st, _ = cv2.calcOpticalFlowPyrLK(
            lcL,
            lcR,
            uvL[idx].reshape(-1, 1, 2).astype(np.float32),
            pred[idx].reshape(-1, 1, 2).astype(np.float32),
            winSize=(w, w),
            maxLevel=1,
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
            criteria=(cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001),
        )
        p1 = p1.reshape(-1, 2).astype(np.float64)
        good = (st.ravel() == 1) & (np.linalg.norm(p1 - pred[idx], axis=1) <= cfg.flow_max_correction_px)
        return idx[good], p1[good]

    def _floor_plane(
        self,
        imgL: np.ndarray,
        imgR: np.ndarray,
        uvL: np.ndarray,
        uvR: np.ndarray,
        contrast: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[tuple[np.ndarray, float], tuple[float, float]] | None:
        """The floor plane ``(n, d_mm)`` in the left camera, from a dense grid of stereo points,
        and its standard errors ``(height mm, tilt rad)`` (:func:`floorvo.geometry.plane_fit_precision`).

        The SIFT left/right matches (N, 2) px, in the two cameras' ideal pinholes
        (:meth:`CameraModel.undistorted_px`), give the floor's left -> right homography
        (RANSAC); a grid of left pixels every ``plane_step_px`` is carried through it (from the
        left pinhole and back into the right frame: a homography holds between pinholes) and each
        right position refined to sub-pixel by Lucas-Kanade (``refine_win_px``) on the
        local-contrast images (:func:`floorvo.imaging.local_contrast_uint8`: the two cameras'
        illumination differs smoothly, which would bias the alignment): about a thousand points whose disparity is good to a few hundredths of a pixel, where SIFT's
        positions are a tenth or two off (a few tenths of a millimetre of depth each at a 20 mm
        baseline). They are triangulated and the plane fitted to them
        (:func:`floorvo.geometry.fit_plane`). None when the homography or fewer than
        ``min_matches`` points remain. ``contrast``: the two local-contrast images when already made.
        """
        cfg = self.config
        if len(uvL) < cfg.min_matches:
            return None
        cv2.setRNGSeed(cfg.seed)
        H, _ = cv2.findHomography(uvL.astype(np.float32), uvR.astype(np.float32), cv2.RANSAC, cfg.ransac_threshold_px)
        if H is None:
            return None
        g, w = cfg.plane_step_px, cfg.refine_win_px
        h_px, w_px = imgL.shape
        v, u = np.mgrid[w : h_px - w : g, w : w_px - w : g]
        gl = np.column_stack([u.ravel(), v.ravel()]).astype(np.float32)
        pin = self.camera.undistorted_px(gl).reshape(-1, 1, 2)
        gr = self.camera_right.distorted_px(cv2.perspectiveTransform(pin, H).reshape(-1, 2))
        inside = (gr[:, 0] >= w) & (gr[:, 0] < w_px - w) & (gr[:, 1] >= w) & (gr[:, 1] < h_px - w)
        gl, gr = gl[inside], gr[inside]
        if w > 0 and len(gl):
            lcL, lcR = contrast or self._local_contrast(imgL, imgR)
            p1, st, _ = cv2.calcOpticalFlowPyrLK(
                lcL,
                lcR,
                gl.reshape(-1, 1, 2),
                gr.reshape(-1, 1, 2).copy(),
                winSize=(w, w),
                maxLevel=0,
                flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
                criteria=(cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_COUNT, 30, 0.001),
            )
            p1 = p1.reshape(-1, 2)
            good = (st.ravel() == 1) & (np.linalg.norm(p1 - gr, axis=1) < 1.5)
            gl, gr = gl[good], p1[good]
        if len(gl) < cfg.min_matches:
            return None
        gl, gr = self.camera.undistorted_px(gl), self.camera_right.undistorted_px(gr)
        X = cv2.triangulatePoints(self.P_left, self.P_right, gl.T.astype(np.float64), gr.T.astype(np.float64))
        xyz = (X[:3] / X[3]).T
        xyz = xyz[xyz[:, 2] > 0]
        if len(xyz) < 4:
            return None
        n, d, keep = fit_plane(xyz)
        if w > 0:
            # Neighbouring grid points' Lucas-Kanade windows overlap when the window is wider
            # than the spacing: (w / g)^2 of them share each pixel, so one independent error.
            return (n, d), plane_fit_precision(xyz[keep], n, d, overlap=(w / g) ** 2)
        # Unrefined, the grid lies exactly on the plane of the homography: the plane is as
        # precise as the SIFT stereo points it came from, whose scatter about it measures that.
        X = cv2.triangulatePoints(self.P_left, self.P_right, uvL.T.astype(np.float64), uvR.T.astype(np.float64))
        return (n, d), plane_fit_precision((X[:3] / X[3]).T, n, d)

    def step(self, state: _State, frame: Frame) -> StepResult:
        if not isinstance(state, _State):
            raise state_error(self.name, state)
        t0 = time.perf_counter()
        if frame.image_right is None:
            return StepResult("lost", reason="frame has no right image", timing_ms=stage_timing_ms(t0, t0, t0, t0))
        bad = frame_problem(frame.image, self.camera) or frame_problem(
            frame.image_right, self.camera_right, "right frame"
        )
        if bad:
            return StepResult("lost", reason=bad, timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter()))
        for im in (frame.image, frame.image_right):
            if frame_is_blank(im):
                return StepResult(
                    "lost",
                    reason="empty frame (no texture)",
                    timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter()),
                )
        cur = dataclasses.replace(
            self._stereo(frame.image, frame.image_right, state.prev.plane if state.prev is not None else None),
            t_s=float(frame.timestamp_s),
        )
        t1 = time.perf_counter()
        prev = state.prev
        if prev is None:
            state.prev = cur
            return StepResult(
                "init",
                reason="first frame",
                n_keypoints=len(cur.uv),
                timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()),
            )
        n_kp = len(cur.uv)
        if n_kp < self.config.min_matches:
            return StepResult(
                "lost",
                reason=f"too few stereo keypoints ({n_kp})",
                n_keypoints=n_kp,
                timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()),
            )
        # From here on the current frame is the next step's reference, lost or not: a lost step
        # restarts the track on it (the motion over the gap is unknown; scoring measures the
        # next step from this frame, RESTART_NOTE).
        state.prev = cur
        qi, ti = self._ratio_match(prev.desc, cur.desc)  # M_1 (restricted to stereo-matched points)
        t2 = time.perf_counter()
        n_m = len(qi)

        def lost(why: str, n_in: int = 0) -> StepResult:
            return StepResult(
                "lost",
                reason=f"{why}; {RESTART_NOTE}",
                n_keypoints=n_kp,
                n_matches=n_m,
                n_inliers=n_in,
                timing_ms=stage_timing_ms(t0, t1, t2, time.perf_counter()),
            )

        if n_m < self.config.min_matches:
            return lost(f"too few temporal matches ({n_m})")
        cv2.setRNGSeed(self.config.seed)
        # The floor's motion is a homography between the ideal pinhole's frames (uv_pinhole).
        src, dst = prev.uv_pinhole[qi].astype(np.float32), cur.uv_pinhole[ti].astype(np.float32)
        H, mask = cv2.findHomography(src, dst, cv2.RANSAC, self.config.ransac_threshold_px)
        if H is None or mask is None:
            return lost("RANSAC found no consistent homography")
        inl = mask.ravel().astype(bool)
        # Self-checks (issue 14): the consensus is a large enough share of the matches, and no
        # second motion is nearly as well supported by the matches RANSAC left out.
        why = consensus_problem(
            src,
            dst,
            inl,
            self.config.ransac_threshold_px,
            min_fraction=self.config.min_inlier_fraction,
            min_count=self.config.min_matches,
            max_rival_fraction=self.config.max_rival_fraction,
            seed=self.config.seed,
            what="temporal matches",
        )
        if why:
            return lost(why, int(inl.sum()))
        P1, P2 = prev.xyz[qi[inl]], cur.xyz[ti[inl]]
        if len(P1) < self.config.min_matches:
            return lost(f"too few RANSAC inliers ({len(P1)})", len(P1))
        # A rolling shutter's readout undone: the left keypoints where global shutters at the two frame
        # times see them, their 3-D points moved with them at their own depth (the reports keep the
        # frames' own pixels).
        uv1, uv2 = prev.uv[qi[inl]], cur.uv[ti[inl]]
        uv1_gs, uv2_gs = rolling_shutter_undone(
            uv1,
            uv2,
            interval_s=cur.t_s - prev.t_s,
            row_time_s=self.row_time_s,
            mid_row_px=(self.camera.height_px - 1) / 2.0,
        )
        if self.row_time_s:
            P1 = P1 + self.camera.unproject(uv1_gs, P1[:, 2]) - self.camera.unproject(uv1, P1[:, 2])
            P2 = P2 + self.camera.unproject(uv2_gs, P2[:, 2]) - self.camera.unproject(uv2, P2[:, 2])
        T = np.eye(4)
        if self.config.update == "mean":
            # Algorithm 1: DP_L = P_3dL1 - P_3dL2 (the camera moved opposite to the points).
            T[:3, 3] = np.mean(P1 - P2, axis=0)
            n_in = len(P1)
            why = self._turn_problem(P1, P2, T[:3, 3])
            if why:
                return lost(why, n_in)
        elif self.config.update == "plane":
            if prev.plane is None or cur.plane is None:
                return lost("too few stereo points to fit the floor plane")
            tilt = float(np.arccos(min(1.0, abs(cur.plane[0][2]))))
            if tilt > self.config.max_tilt_rad:
                return lost(f"floor plane tilted {tilt:.2f} rad from the optical axis > {self.config.max_tilt_rad:g}")
            # 6-DoF from the two floor planes and the in-plane rigid fit of the matched left rays.
            T, keep, _ = floor_plane_step(uv1_gs, uv2_gs, self.camera, prev.plane, cur.plane)
            n_in = int(keep.sum())
            why = self._precision_problem(T, prev, cur, uv1_gs[keep], uv2_gs[keep])
            if why:
                return lost(why, n_in)
        elif self.config.update == "rigid":
            # Improvement: rigid SVD fit, P_3dL1 = R P_3dL2 + t, i.e. T_prev_cur.
            R, t, keep = rigid_fit_robust(P2, P1)
            T[:3, :3], T[:3, 3] = R, t
            n_in = int(keep.sum())
        else:
            # Planar rigid SVD fit: yaw and x-y translation from the x-y coordinates, height from z.
            R2, t_xy, keep = rigid_fit_robust(P2[:, :2], P1[:, :2], iterations=2)
            T[:2, :2], T[:2, 3] = R2, t_xy
            T[2, 3] = float(np.mean(P1[keep, 2] - P2[keep, 2]))
            n_in = int(keep.sum())
        t3 = time.perf_counter()
        return StepResult(
            "ok",
            T,
            n_keypoints=n_kp,
            n_matches=n_m,
            n_inliers=n_in,
            timing_ms=stage_timing_ms(t0, t1, t2, t3),
            matches_px=np.hstack([prev.uv[qi[inl]], cur.uv[ti[inl]]]),
        )

    def _turn_problem(self, P1: np.ndarray, P2: np.ndarray, t_mean: np.ndarray) -> str:
        """Why the translation-only step ``t_mean`` (``update = mean``, Algorithm 1's DP_L) is wrong
        ('' if it is not): with ``P1 = R P2 + t`` (the point sets (K, 3), mm, of the previous and the
        current frame), DP_L = t + (R - I) mean(P2), so a turn R moves it by its rotation of the
        points' centroid, and leaves R itself unmeasured. The rotation about the optical axis and
        the x-y translation are fitted (the ``planar`` update's SVD fit); where that yaw or the
        translation's difference from DP_L exceed issue 14's bound, the step is lost: paper 002's
        update reported such steps ok (a principal point off the centre, 2.3 degrees a frame:
        every step wrong, 16 % drift)."""
        cfg = self.config
        R2, t_xy, _ = rigid_fit_robust(P2[:, :2], P1[:, :2], iterations=2)
        yaw_deg = float(np.degrees(np.arctan2(R2[1, 0], R2[0, 0])))
        off_mm = float(np.linalg.norm(t_mean[:2] - t_xy))
        bound_mm = cfg.bound_mm(float(np.linalg.norm(t_mean)))
        if abs(yaw_deg) > cfg.max_step_error_deg or off_mm > bound_mm:
            return (
                f"the points turned {abs(yaw_deg):.2f} deg about the optical axis, which update = mean (a translation) "
                "cannot measure: "
                f"its step is {off_mm:.3f} mm off the planar fit's (bound {bound_mm:.3f} mm, {cfg.max_step_error_deg:g} deg)"
            )
        return ""

    def _precision_problem(
        self, T: np.ndarray, prev: _Side, cur: _Side, uv_prev: np.ndarray, uv_cur: np.ndarray
    ) -> str:
        """Why the 6-DoF step ``T`` (``update = plane``) is too imprecise to report ('' if it is not).

        Its standard errors come from three fits' residuals: the in-plane rigid fit of the
        pairs ``uv_prev -> uv_cur`` (K, 2) px it kept, in the levelled floor coordinates
        (:func:`floorvo.geometry.rigid_fit_precision`: the camera's own displacement and the
        yaw), and each frame's floor plane (:func:`floorvo.geometry.plane_fit_precision`: its
        height, which is the step's height change, and its tilt, which turns the step and
        shifts every floor point, so the in-plane displacement, by the height times the tilt
        error). ``precision_sigmas`` of them must lie within the error a step reported ok may
        have (``max_step_error_mm`` + ``max_step_error_fraction`` of the step,
        ``max_step_error_deg``: issue 14's bound), as akaze's precision check. A few
        imprecise pairs (a frame with few keypoints, SIFT on small frames) otherwise pass every
        other check with the step a tenth of a millimetre or a few tenths of a degree off.
        """
        if prev.plane is None or cur.plane is None:
            return (
                ""
                if self.config.precision_sigmas <= 0.0
                else f"too few pairs to measure the step's precision ({len(uv_prev)})"
            )
        return plane_step_precision_problem(
            self.config, T, uv_prev, uv_cur, self.camera, prev.plane, cur.plane, prev.plane_sigma, cur.plane_sigma
        )


#: The real-time preset (issue 14 item 5): SIFT doubles the frame before its first octave,
#: which at a fixed camera height buys nothing but time (most of SIFT's cost is that doubled
#: octave). Run on the frame halved, its first octave is the frame's own size. Meant for the
#: full-size 648x494 camera (on a frame already halved it sees too little). SIFT runs on the
#: left frame only: the right frame's keypoints are the left ones followed by Lucas-Kanade
#: through the previous frame's floor plane (``right_features = "flow"``), and the
#: local-contrast images are blurred at half size. Frames/s and drift against the default:
#: BENCHMARKS.md, "Real time on one core".
StereoSiftFastConfig = with_defaults(
    StereoSiftConfig, "StereoSiftFastConfig", detect_scale=0.5, contrast_blur_downscale=2, right_features="flow"
)


class StereoSiftFast(StereoSift):
    name = "stereo-sift-fast"
    description = (
        "stereo-sift's real-time preset: SIFT on the left frame halved (its first octave at full size), "
        "right keypoints by Lucas-Kanade through the floor plane"
    )
    Config = StereoSiftFastConfig
