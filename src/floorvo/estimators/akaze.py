"""``akaze-guided`` (paper 000) and ``akaze-bruteforce`` (the conventional method it is compared with).

Paper 000 (Nakashima et al., IEEE Access 2019), faithfully, then extended to yaw:

* AKAZE keypoints and binary (MLDB) descriptors on the illumination-corrected frame
  (with default thresholds AKAZE finds almost nothing on a raw grazing-light frame).
* **Motion-predicted matching** (section II-B, Fig. 6). Each previous keypoint's position
  in the new frame is predicted from the previous frame's motion, eq. (2):
  x' = x - R(theta) v, here in the general form p' = M_last(p) with M_last the last
  measured rigid image motion about the principal point (eq. (2) with rotation; eq. (3)
  when theta = 0). The new frame's keypoints within ``search_radius_px`` of the
  prediction are visited nearest first and the first whose Hamming distance is under
  ``hamming_threshold`` is the match; otherwise the next nearest is tried (up to
  ``max_candidates``). The radius is the change of the per-frame motion the prediction
  must absorb: paper 000's acceleration models change it by up to 2 mm in one frame
  (16 px), and the threshold is low enough (120 of 486 bits) that a nearer keypoint of
  another floor point is refused and the search goes on to the true one (with 12 px and
  200 bits the steepest sigmoid step was measured as the prediction, BENCHMARKS.md).
* **Outlier removal**, section II-C: the movement of every matched pair is computed, and
  pairs outside mean +/- one standard deviation (per axis, x and y) are dropped; the
  filter is applied twice. The movement is measured relative to the prediction, which is
  the paper's filter when the prediction is a translation and stays valid under yaw.
* **Pixels to millimetres**, eq. (1): 2 d tan(theta) / w per pixel, generalised to the
  full camera model (each pixel back-projected onto the floor at the camera height).
* **SE(2) extension**: the motion is the least-squares rigid fit (rotation + translation)
  in floor millimetres, instead of the mean x/y movement, of the filtered pairs and then
  (``refine_passes``) of every match within ``inlier_tol_px`` of that fit. The filter
  keeps a band of one standard deviation and drops most true matches with the false
  ones; under yaw the band is a strip of the image, which conditions the rotation poorly
  (0.1-0.2 degrees per frame of error on a rendered S-curve, 0.01 with the refit).
* **Sub-pixel pairs** (ours, off by default: ``refine_window_px``): the fit's pairs' current
  positions refined by Lucas-Kanade about the previous keypoints, and the motion fitted again
  (:meth:`_AkazeBase._refined`); BENCHMARKS.md, "AKAZE's pairs refined to a sub-pixel by
  Lucas-Kanade", has what it gains and where it loses.

Never silently wrong (issue 14): each step checks itself and is reported ``lost`` with
the reason when it fails a check: too few matches, too few pairs behind the fit, the
pairs' RMS distance from the fit, too small a fraction of all matches agreeing with it
(random matches on a featureless floor agree with no motion). A guided step whose
prediction is doubtful (a check failed, or the fit corrects the prediction by most of
the search radius, so that true matches may lie beyond it) is matched again by brute
force, and its ``reason`` (``timing.csv``'s reason column) says so; so is a guided step
whose fit moves beyond issue 14's bound when its keypoints are matched again around it
(the prediction pulled the matches: a repetitive floor). Where brute force then finds no
motion (a repetitive floor), the step is matched guided again from the last motion turned
by a few degrees more or less (``turn_sweep_deg``: a turn that starts between two frames)
and taken where the turns that fit agree. A rigid step at an assumed camera
height (the paper's: no height signal) is lost where the floor homography of its pairs reads
a height change beyond issue 14's bound (``check_height_change``: a bounce; a rigid fit
reports none, and was wrong by it). A frame of another
size or channel count than the camera's is refused. After a lost frame the next one is
matched against the last good frame by brute force (there is no motion to predict from),
as the first pair is; a brute-force fit that the section II-C filter leaves failing a check
(on a repetitive floor most brute-force matches are wrong) is fitted again from the pairs a
RANSAC similarity finds in agreement (``ransac_retry``, ours) and taken if it passes every
check; after ``restart_after_lost`` lost frames in a row tracking restarts from the current
frame (the motion over the gap is unknown; the lost frames show it).
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import param, with_defaults
from floorvo.errors import ConfigFieldError
from floorvo.estimators.base import (
    HEIGHT_DRIFT_STEPS,
    PICTURE_HEIGHT_READ_SHARE,
    RESTART_NOTE,
    Frame,
    StepBoundConfig,
    StepResult,
    frame_attitude_rad,
    frame_height_mm,
    frame_problem,
    height_signal_drift_problem,
    readout_change_problem,
    stage_timing_ms,
    state_error,
)
from floorvo.geometry import (
    R_nadir_cam,
    block_homographies,
    consensus_problem,
    floor_rigid_to_T,
    motion_over_time,
    pixels_to_floor_mm,
    plane_homography_motion,
    rigid_fit,
    rigid_fit_precision,
    rolling_shutter_undone,
    rot_z,
    t_sigmas,
    tilt_change_rad,
    umeyama,
    yaw_of_R,
)
from floorvo.imaging import flatfield_gain, illumination_corrected, to_uint8_contrast
from floorvo.matching import match_guided, match_nn, pack_descriptors

__all__ = [
    "AkazeGuided",
    "AkazeBruteforce",
    "AkazeGuidedFast",
    "AkazeBruteforceFast",
    "AkazeGuidedSubpixel",
    "AkazeConfig",
    "AkazeFastConfig",
    "AkazeSubpixelConfig",
    "mean_std_filter",
]


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
class AkazeConfig(StepBoundConfig):
    """AKAZE detector threshold, keypoint budget, guided-matching, filter and self-check settings.

    Guided matching (section II-B): around each eq. (2) prediction the new frame's
    keypoints within ``search_radius_px`` (the largest change of the per-frame image
    motion from one frame to the next that the prediction absorbs) are visited nearest
    first, up to ``max_candidates``, and the first whose Hamming distance is under
    ``hamming_threshold`` bits (of the MLDB descriptor's 486) is the match. Paper 000's
    sigmoid models change the per-frame motion by up to 2 mm (2 -> 4 mm/frame on the 1-mm
    strip, 16 px at 100 mm with 0.1233 mm/px), so the radius covers 24 px (3 mm). The threshold separates the
    descriptor of the same floor point in the next frame from that of a neighbour: on the
    rendered vinyl strip (4 frame pairs, 1-4 mm apart) a true match differs by a median 62
    bits and 77 % of them by under 120, a keypoint 4-30 px away from the true position by
    under 120 bits in 0.02 % of cases (1 % under 160, 13 % under 200).

    Self-checks of each step (a step failing one is reported ``lost`` with the reason):
    at least ``min_matches`` matches and ``min_inliers`` pairs left by the section II-C
    filter; the RMS distance of those pairs from the fitted rigid motion at most
    ``max_rms_px``; at least ``min_consensus`` of all matches within ``inlier_tol_px`` of
    it; with ``check_height_change``, a rigid fit at an assumed camera height whose pairs'
    floor homography shows no height change beyond issue 14's bound (plus
    ``height_change_tilt_share`` of the shift its tilt change beyond
    ``height_change_light_tilt_rad`` makes). A guided step whose prediction is doubtful (it fails a check, its correction of
    the prediction reaches ``doubt_radius_fraction`` of the search radius, or, with
    ``check_rematch``, matching again around its own fit moves the step beyond issue 14's
    bound) is matched again by brute force, and the step's ``reason`` says so.
    """

    akaze_threshold: float = param(0.0005, gt=0.0, doc="AKAZE detector response threshold")
    n_octaves: int = param(4, min=1, max=8, doc="AKAZE scale-space octaves (OpenCV's default 4)")
    n_octave_layers: int = param(4, min=1, max=8, doc="AKAZE sublevels per octave (OpenCV's default 4)")
    upright: bool = param(False, doc="MLDB descriptors without orientation (MLDB_UPRIGHT): for small yaw per frame")
    max_keypoints: int = param(1500, min=10, doc="strongest keypoints kept per frame")
    describe_kept_only: bool = param(
        False,
        doc="detect, keep the max_keypoints strongest, then describe those only (the same descriptors; "
        "pays for a second scale space, so it only helps with a small one and many more keypoints than kept)",
    )
    adapt_threshold: bool = param(
        False,
        doc="detect at adapt_threshold_margin x the response of the previous frame's max_keypoints-th strongest "
        "keypoint (never below akaze_threshold): one detectAndCompute finds the same strongest keypoints with "
        "one scale space instead of describe_kept_only's two; a frame yielding fewer is detected again; after a "
        "frame with fewer than max_keypoints, one detectAndCompute at akaze_threshold",
    )
    adapt_threshold_margin: float = param(
        0.8, gt=0.0, max=1.0, doc="adapt_threshold: the previous frame's max_keypoints-th response times this"
    )
    hamming_threshold: int = param(120, min=1, max=512, doc="largest descriptor distance of a match, in bits (of 486)")
    search_radius_px: float = param(
        24.0, unit="px", gt=0.0, doc="guided search radius around each predicted position (24 px: 3 mm on the rig)"
    )
    max_candidates: int = param(32, min=1, max=256, doc="nearest candidates tried per keypoint in the guided search")
    filter_passes: int = param(2, min=0, max=10, doc="passes of the mean +/- one std movement filter (section II-C)")
    refine_passes: int = param(2, min=0, max=10, doc="re-fits on the matches within inlier_tol_px of the fit")
    refine_window_px: int = param(
        0,
        min=0,
        max=63,
        doc="the fit's pairs' current-frame positions refined to a sub-pixel by Lucas-Kanade in windows of this "
        "size (3 or more) around the previous keypoints, on the previous picture turned by the fit, and the "
        "motion fitted again (ours); 0: the keypoints' own positions (paper 000)",
    )
    refine_max_pairs: int = param(
        300, min=3, doc="refine_window_px: at most this many of the fit's pairs refined, spread over them"
    )
    min_matches: int = param(6, min=2, doc="fewer matches: the frame is lost")
    min_inliers: int = param(8, min=2, doc="fewer pairs behind the fit: the frame is lost")
    max_rms_px: float = param(1.25, unit="px", gt=0.0, doc="larger RMS distance of the pairs from the fit: lost")
    inlier_tol_px: float = param(2.0, unit="px", gt=0.0, doc="a match this close to the fitted motion agrees with it")
    min_consensus: float = param(
        0.2, min=0.0, max=1.0, doc="smaller fraction of the matches agreeing with the fit: the frame is lost"
    )
    max_rival_fraction: float = param(
        0.1,
        gt=0.0,
        doc="a second homography of the disagreeing matches backed by more than this fraction of the agreeing: lost",
    )
    ransac_retry: bool = param(
        True,
        doc="a brute-force fit (no prediction: the first frame, after a lost one, a doubtful prediction) that the "
        "section II-C filter leaves failing a check: fitted again from the pairs a RANSAC similarity finds in "
        "agreement, with the same refinement and checks (ours; a repetitive floor, where most matches are wrong)",
    )
    restart_after_lost: int = param(
        2, min=1, doc="lost frames in a row after which tracking restarts from the current frame"
    )
    doubt_radius_fraction: float = param(
        0.75, gt=0.0, max=1.0, doc="a guided fit correcting the prediction by this much of the radius: brute force"
    )
    turn_sweep_deg: float = param(
        15.0,
        unit="deg",
        min=0.0,
        max=45.0,
        doc="a doubtful guided prediction whose brute-force fit finds no motion: matched guided again from the "
        "last motion turned by +/- turn_sweep_step_deg up to this much more or less, taken if the turns' fits "
        "that pass every check with twice the evidence agree (ours; a turn that starts between two frames on a "
        "repetitive floor); 0: off",
    )
    turn_sweep_step_deg: float = param(
        2.5, unit="deg", gt=0.0, max=45.0, doc="turn_sweep_deg: the step between the turns tried"
    )
    check_rematch: bool = param(
        True,
        doc="match a guided step again around its own fit: a step that moves beyond the max_step_error_* bound "
        "was pulled by the prediction (a repetitive floor): brute force",
    )
    use_flatfield: bool = param(True, doc="divide by the sequence's flat-field frame when it has one")
    use_height_signal: bool = param(
        True, doc="convert pixels to mm at the frame's measured camera height when it has one (else the rig's)"
    )
    undo_rolling_shutter: bool = param(
        True,
        doc="in a sequence taken by a rolling shutter (sequence.json's sensor.readout_ms), each pair of the step "
        "is moved to where global shutters at the two frame times see it, at the pair's own image velocity "
        "(floorvo.geometry.rolling_shutter_undone): a step along the rows reads long by its rows times the "
        "row time over the frame interval",
    )
    check_readout_motion: bool = param(
        True,
        doc="undo_rolling_shutter: the pairs of the rows read first and of those read last (the reference frame's "
        "upper and lower halves) are fitted apart; where their motions differ beyond the max_step_error_* bound, "
        "less precision_sigmas of their standard errors, the motion changed during the readout (a turn that "
        "starts or ends within a frame), which undoing it at one velocity cannot follow: lost",
    )
    use_attitude_signal: bool = param(
        True,
        doc="in a sequence with attitude.csv (an IMU's roll and pitch), each frame's keypoints are levelled with its "
        "attitude before they are matched and the run's poses are the tilted camera's (floorvo.runner.run_frames)",
    )
    height_from_depth: bool = param(
        False, doc="in a sequence with depth (and no height.csv), measure the camera height from each depth image"
    )
    fit_image_scale: bool = param(
        False,
        doc="a frame without a measured height: fit the image scale too (a similarity) and follow the camera "
        "height from it, h_cur = h_prev / scale, from the rig's (paper 000: a rigid fit at the rig's height)",
    )
    check_height_change: bool = param(
        True,
        doc="a rigid step at an assumed camera height (no measured height, fit_image_scale off) is lost where "
        "the floor homography of its pairs reads a height change beyond the max_step_error_* bound plus "
        "height_change_tilt_share x the camera height x the step's tilt change",
    )
    height_change_tilt_share: float = param(
        1.0,
        min=0.0,
        doc="check_height_change: the share of the shift a tilt change makes at the floor (camera height x tilt) "
        "that the rig's grazing shading may show as a false height change",
    )
    height_change_read_share: float = param(
        PICTURE_HEIGHT_READ_SHARE,
        gt=0.0,
        max=1.0,
        doc="check_height_change: the share of a true height change that a step's floor homography reads under "
        "the rig's moving shading (0.85-0.97, median per scene, on the full-size motion suite's bounces and "
        "vibrations); the check takes a read as this share of the change",
    )
    height_change_light_tilt_rad: float = param(
        0.002,
        unit="rad",
        min=0.0,
        doc="check_height_change: the tilt change a step's floor homography reads from the rig's moving shading "
        "where there is none; only a tilt beyond it widens the check's bound",
    )
    image_scale_min_sigmas: float = param(
        3.0,
        min=0.0,
        doc="fit_image_scale: the height changes only where the fitted image scale differs from 1 by more than this "
        "many of its standard errors, at this many normal standard errors' confidence for the pairs' degrees of "
        "freedom (Student's t); elsewhere the rigid fit, the height kept; 0: wherever it differs",
    )

    def validate(self) -> None:
        if 0 < self.refine_window_px < 3:  # Lucas-Kanade needs a window of 3 px or more (OpenCV asserts)
            raise ConfigFieldError("refine_window_px", f" = {self.refine_window_px}: must be 0 (off) or >= 3")


@dataclass
class _State:
    kps: np.ndarray | None = None  # (N, 2) px
    desc: np.ndarray | None = None  # (N, B) uint8
    packed: np.ndarray | None = None  # (N, W) uint64, the same descriptors packed
    M_last: np.ndarray | None = None  # 3x3 prev-centred px -> cur-centred px, None = no prediction
    m_last_span_s: float = 0.0  # the time (s) the step M_last spans (0: none known)
    t_ref_s: float = 0.0  # the reference frame's time (s)
    n_lost: int = 0  # frames lost in a row since the reference
    height_mm: float | None = None  # camera height of the reference frame, measured or fitted (None: the rig's)
    height_read: bool = False  # height_mm is the reference frame's own reading (a height signal's)
    plane: tuple[np.ndarray, float] | None = None  # floor plane (n, d_mm) of the reference (homography-6dof)
    plane_var_mm2: float = 0.0  # variance of the plane's d_mm, from the height readings it rests on (homography-6dof)
    threshold: float | None = None  # adapt_threshold: the detector threshold of the next frame (None: the config's)
    attitude: tuple[float, float] | None = None  # the reference's attitude its keypoints were levelled with
    img8: np.ndarray | None = None  # (H, W) uint8 picture of the reference (refine_window_px)
    # the last steps' disagreement of the height signal with the picture (height_signal_drift_problem)
    height_drift: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=HEIGHT_DRIFT_STEPS))


@dataclass(frozen=True)
class _Fit:
    """A rigid image motion fitted to matches, and what its self-checks found.

    ``M``: 3x3 prev-centred px -> cur-centred px; ``src``, ``dst``: (K, 2) px, the pairs
    the section II-C filter kept; ``problem``: '' when every check passed, else why not;
    ``scale_fitted``: ``M``'s image scale was fitted (``fit_image_scale``), not known; ``src_gs``,
    ``dst_gs``: the pairs with a rolling shutter's readout undone (:attr:`pairs_gs`);
    ``no_motion``: the problem is that the filter's pairs hold no motion (too few of them, too
    few matches agreeing with their fit), not a later check on one (its residual, precision).
    """

    M: np.ndarray | None
    src: np.ndarray
    dst: np.ndarray
    n_matches: int
    rms_px: float = float("nan")
    consensus: float = 0.0
    problem: str = ""
    scale_fitted: bool = False
    no_motion: bool = False  # the filter's pairs hold no motion (too few of them, too few matches agree)
    # the pairs as global shutters at the two frame times see them (a rolling shutter's readout
    # undone: _AkazeBase._shutter_undone); None: src and dst are (a global shutter)
    src_gs: np.ndarray | None = None
    dst_gs: np.ndarray | None = None
    # with the scale fitted: the image scale of the undone pairs the height follows (_AkazeBase._shutter_undone)
    scale_gs: float | None = None

    @property
    def pairs_gs(self) -> tuple[np.ndarray, np.ndarray]:
        """The pairs (K, 2) px as global shutters see them: what the step, the height the image
        scale follows and the height checks are measured on."""
        return (self.src, self.dst) if self.src_gs is None or self.dst_gs is None else (self.src_gs, self.dst_gs)


def _image_scale(M: np.ndarray) -> float:
    """The image scale of a similarity ``M`` (3x3 px, ``M[:2, :2]`` = scale R): sqrt |det|."""
    return float(np.sqrt(abs(np.linalg.det(M[:2, :2]))))


class _AkazeBase:
    Config = AkazeConfig
    requires: frozenset[str] = frozenset()
    #: The standard deviation (mm) of a height reading, where the estimator is told it
    #: (homography-6dof: ``rig.height_noise_mm``); 0: not known.
    height_noise_mm: float = 0.0
    #: A planar mono estimator: it measures the motion of the camera's floor footprint
    #: (:func:`floorvo.geometry.footprint_T`), which an attitude signal makes 6-DoF
    #: (``use_attitude_signal``, :func:`floorvo.runner.uses_attitude_signal`).
    measures_footprint: bool = True
    #: With a frame's attitude (``use_attitude_signal``) its keypoints are levelled first
    #: (:meth:`_levelled`): the steps are then the camera's own, of a virtual camera looking
    #: straight down from the camera's centre, and the runner tilts that pose with the frame's
    #: attitude (:func:`floorvo.runner.run_frames`) instead of turning a footprint back.
    levels_with_attitude: bool = True
    #: With a frame's measured height (``use_height_signal``) the step's height change is the
    #: readings' difference, so the runner holds it to the signal's stated noise
    #: (:func:`floorvo.runner.takes_height_change_from_signal`).
    height_change_from_signal: bool = True
    guided: bool = False
    #: The image motion model fits the scale itself (a homography): ``fit_image_scale`` is not used.
    fits_own_scale: bool = False

    def __init__(
        self,
        config: AkazeConfig,
        camera: CameraModel,
        *,
        height_mm: float,
        flatfield: np.ndarray | None = None,
        row_time_s: float = 0.0,
        **rig,
    ):
        self.config = config
        self.camera = camera
        # A rolling shutter's time between neighbouring rows (s; 0: a global shutter), undone in
        # each step's pairs (:meth:`_shutter_undone`).
        self.row_time_s = float(row_time_s) if config.undo_rolling_shutter else 0.0
        # The camera's ideal pinhole (the same K, no distortion): the keypoints are matched and
        # fitted in its pixels (:meth:`_levelled`), where the floor's motion is the rigid (or
        # similarity) image motion the fit and its checks assume. In a distorted lens's own
        # pixels it is not: at k1 = -0.25 the similarity read the distortion as a change of
        # height (the real-time presets' steps 5.7 % short, 2 reported ok and wrong), at k1 = -0.4
        # the pairs the rigid fit left out agreed on "two motions" and every step was lost.
        self.pinhole = (
            CameraModel(camera.width_px, camera.height_px, camera.fx_px, camera.fy_px, camera.cx_px, camera.cy_px)
            if camera.has_distortion
            else camera
        )
        self.height_mm = float(height_mm)
        self.flatfield = flatfield if config.use_flatfield else None
        self.flat_gain = None if self.flatfield is None else flatfield_gain(self.flatfield)  # once, not per frame
        self.detector = cv2.AKAZE.create(
            descriptor_type=cv2.AKAZE_DESCRIPTOR_MLDB_UPRIGHT if config.upright else cv2.AKAZE_DESCRIPTOR_MLDB,
            threshold=config.akaze_threshold,
            nOctaves=config.n_octaves,
            nOctaveLayers=config.n_octave_layers,
        )
        self.centre = np.array([camera.cx_px, camera.cy_px])

    def start(self) -> _State:
        return _State()

    def _levelled(self, kps: np.ndarray, attitude: tuple[float, float] | None) -> np.ndarray:
        """Keypoints (N, 2) px of the frame in the pixels of the camera's ideal pinhole
        (:attr:`pinhole`: a distorted lens's undone, :meth:`CameraModel.undistorted_px`), where
        the fit works, and levelled when the frame has an ``attitude`` (roll, pitch): a camera at
        that attitude (``attitude.csv``'s convention, :func:`floorvo.geometry.attitude_of_T`)
        has its keypoints moved to where a camera at the same centre and yaw looking straight
        down sees them: each pixel's ray (distortion undone, :meth:`CameraModel.unproject`)
        turned by :func:`floorvo.geometry.R_nadir_cam` and projected into the ideal pinhole, a
        homography ``K R K^-1`` of it. A turn about the camera's centre moves every pixel as
        the floor does not, so what is left between two levelled frames is the floor's motion as
        a level camera sees it (a rigid motion and the scale of the height change): a tilt change
        of a few mrad a frame, which the pixel fit read in part as a height change (the
        real-time presets' image scale on the tilted asphalt: 32 of 40 steps wrong), and its
        turn about the optical axis, no longer enter the fit."""
        if len(kps) == 0:
            return kps
        if attitude is None:
            return self.camera.undistorted_px(kps)
        rays = self.camera.unproject(kps, 1.0) @ R_nadir_cam(*attitude).T
        return self.pinhole.project(rays)

    def _unlevelled(self, pts: np.ndarray, attitude: tuple[float, float] | None) -> np.ndarray:
        """Points (N, 2) px of :meth:`_levelled` back in the pixels of the frame taken at
        ``attitude`` (the inverse turn, None: not levelled), the lens's distortion applied."""
        if len(pts) == 0:
            return pts
        if attitude is None:
            return self.camera.distorted_px(pts)
        rays = self.pinhole.unproject(pts, 1.0) @ R_nadir_cam(*attitude)  # R^T v, row-wise
        return self.camera.project(rays)

    def _detect(self, image: np.ndarray, state: _State | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ``max_keypoints`` strongest keypoints (N, 2) px, their descriptors (N, B) uint8 and
        the (H, W) uint8 picture they were found in (the frame, illumination corrected).

        With ``adapt_threshold`` and a ``state`` that holds a threshold from the previous frame,
        AKAZE detects and describes at that threshold in one pass: every keypoint whose response
        is above it is found, so when at least ``max_keypoints`` are, the strongest of them are
        the strongest the config's threshold would give, with the same descriptors (the scale
        space and the descriptors do not depend on the threshold). A frame yielding fewer is
        detected again at the config's threshold. The next frame's threshold is
        ``adapt_threshold_margin`` times the response of this frame's ``max_keypoints``-th keypoint;
        after a frame with fewer (a floor with few keypoints: wood), the next is detected and
        described whole at the config's threshold in one pass.
        """
        cfg = self.config
        img8 = to_uint8_contrast(illumination_corrected(image, gain=self.flat_gain))
        adapt = cfg.adapt_threshold and state is not None
        kps: Sequence[cv2.KeyPoint] | None = None
        desc: np.ndarray | None = None
        kept_only = cfg.describe_kept_only
        if adapt and state is not None and state.threshold is not None and state.threshold > cfg.akaze_threshold:
            self.detector.setThreshold(state.threshold)
            try:
                kps, desc = self.detector.detectAndCompute(img8, None)
            finally:
                self.detector.setThreshold(cfg.akaze_threshold)
            if len(kps) < cfg.max_keypoints:
                kps, desc = None, None  # fewer than are kept: detect again at the config's threshold
        elif adapt:
            # No threshold to adapt (the first frame, or fewer than max_keypoints in the last one):
            # a floor giving fewer keypoints than are kept is described whole in one pass.
            kept_only = False
        found: Sequence[cv2.KeyPoint] | None = kps  # every keypoint found (the next threshold is taken from them)
        if kps is None and kept_only:
            # The descriptors of the keypoints that are dropped are never used: describe the
            # kept ones only (OpenCV builds the scale space again for compute(): worth it
            # with one octave of one sublevel and thousands of keypoints, 7 ms of 36 on vinyl).
            found = self.detector.detect(img8, None)
            kept = found
            if len(found) > cfg.max_keypoints:
                order = np.argsort([-k.response for k in found])[: cfg.max_keypoints]
                kept = [found[i] for i in order]
            kps, desc = self.detector.compute(img8, kept) if len(kept) else ((), None)
        elif kps is None:
            kps, desc = self.detector.detectAndCompute(img8, None)
            found = kps
        if adapt and state is not None:
            state.threshold = self._next_threshold(found or ())
        if desc is None or len(kps) == 0:
            return np.zeros((0, 2)), np.zeros((0, 61), dtype=np.uint8), img8
        if len(kps) > cfg.max_keypoints:
            order = np.argsort([-k.response for k in kps])[: cfg.max_keypoints]
            kps = [kps[i] for i in order]
            desc = desc[order]
        return np.array([k.pt for k in kps], dtype=np.float64), desc, img8

    def _next_threshold(self, kps: Sequence[cv2.KeyPoint]) -> float | None:
        """``adapt_threshold``: the next frame's detector threshold from this frame's keypoints
        (None, the config's, when there are fewer than ``max_keypoints``)."""
        n = self.config.max_keypoints
        if len(kps) < n:
            return None
        responses = np.fromiter((k.response for k in kps), dtype=np.float64, count=len(kps))
        return float(self.config.adapt_threshold_margin * np.partition(responses, len(responses) - n)[-n])

    def _bruteforce(self, state: _State, kps: np.ndarray, desc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Mutual nearest Hamming neighbours (cross-checked brute force)."""
        prev_kps, prev_desc = state.kps, state.desc
        assert prev_kps is not None and prev_desc is not None  # kept since the first frame
        m = match_nn(prev_desc, desc, cross_check=True)
        return prev_kps[m.i0], kps[m.i1]

    def _bruteforce_fit(
        self, state: _State, kps: np.ndarray, desc: np.ndarray, scale: float | None
    ) -> tuple[_Fit, str]:
        """The fit of brute-force matches (:meth:`_bruteforce`, :meth:`_fit` without a prediction) and a note.

        Without a prediction the section II-C filter keeps the band about the mean movement
        of all matches; on a repetitive floor most of them are wrong (a tile's corners match
        the next tile's), the band holds no motion, and the step was lost: the ceramic floor's
        first two frames at two of three floor seeds, whose runs then restarted 8 mm on, 5 %
        of their path (BENCHMARKS.md, "A brute-force fit retried with RANSAC"). With
        ``ransac_retry`` such a fit is made again from the pairs a RANSAC similarity finds
        in agreement; it is taken only if it passes every check. Only a fit whose filter found no
        motion (too few pairs, too few matches agreeing) is tried again: one whose motion failed a
        later check (its residual, imprecise, a rival motion) stays lost (retried, an imprecise
        half-size ceramic step came back 0.58 degrees wrong)."""
        src, dst = self._bruteforce(state, kps, desc)
        fit = self._fit(src, dst, np.eye(3), scale)
        if not fit.no_motion or not self.config.ransac_retry:
            # Found a motion that failed a later check (imprecise, a rival motion): that verdict stands.
            return fit, ""
        again = self._fit(src, dst, np.eye(3), scale, ransac=True)
        if again.problem or len(again.src) < 2 * self.config.min_inliers:
            # Agreement found among mostly wrong matches is weaker evidence: twice the pairs a fit needs.
            return fit, ""
        return again, f"fitted on the RANSAC pairs ({fit.problem} with the filter's)"

    def _predict(self, M: np.ndarray, pts_px: np.ndarray) -> np.ndarray:
        """Eq. (2) in its general rigid form: (N, 2) previous-frame px -> predicted current-frame px."""
        return (pts_px - self.centre) @ M[:2, :2].T + M[:2, 2] + self.centre

    def _guided(
        self, state: _State, kps: np.ndarray, packed: np.ndarray, M_pred: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Eq. (2) prediction, then nearest-first candidates accepted under the Hamming threshold (Fig. 6).

        ``kps`` (M, 2) px and ``packed`` (M, W) descriptors of the new frame; ``M_pred``: the
        3x3 image motion (prev-centred px -> cur-centred px) the previous keypoints are
        predicted with, None: the last step's (``state.M_last``, eq. (2)). Returns the
        matched (K, 2) previous and current positions.
        """
        cfg = self.config
        prev_kps, prev_packed = state.kps, state.packed
        M = state.M_last if M_pred is None else M_pred
        assert prev_kps is not None and prev_packed is not None and M is not None  # a guided step has them
        m = match_guided(
            self._predict(M, prev_kps),
            kps,
            prev_packed,
            packed,
            radius_px=cfg.search_radius_px,
            max_candidates=cfg.max_candidates,
            max_distance=cfg.hamming_threshold,
        )
        return prev_kps[m.i0], kps[m.i1]

    def _fit(
        self, src: np.ndarray, dst: np.ndarray, pred_M: np.ndarray, scale: float | None = 1.0, ransac: bool = False
    ) -> _Fit:
        """Section II-C filter and the SE(2) fit of the matches ``src -> dst`` (px), then the self-checks.

        ``scale``: the known image scale ratio of the current frame to the previous one
        (:meth:`_scale_ratio`, from the frames' measured heights); the fit is the rigid
        motion of the previous points scaled by it about the principal point. None: the
        scale is fitted too (``fit_image_scale``, a frame without a measured height).
        ``ransac``: the pairs a RANSAC similarity finds within ``inlier_tol_px`` instead of
        the filter's (:meth:`_bruteforce_fit`); none found: the filter's.
        """
        cfg = self.config
        n = len(src)
        if n < cfg.min_matches:
            return _Fit(None, src, dst, n, problem=f"too few matches ({n} < {cfg.min_matches})")
        # Section II-C: twice mean +/- std on the movement (relative to the prediction).
        keep = mean_std_filter(dst - self._predict(pred_M, src), cfg.filter_passes)
        if ransac:
            _, agree = cv2.estimateAffinePartial2D(
                src, dst, method=cv2.RANSAC, ransacReprojThreshold=cfg.inlier_tol_px, maxIters=2000, confidence=0.999
            )
            if agree is not None and int(agree.sum()) >= cfg.min_inliers:
                keep = agree.ravel().astype(bool)
        s, d = src[keep], dst[keep]
        if len(s) < cfg.min_inliers:
            return _Fit(
                None,
                s,
                d,
                n,
                problem=f"too few pairs left by the filter ({len(s)} < {cfg.min_inliers})",
                no_motion=True,
            )
        M = self._rigid_px(s, d, scale)
        # Refinement: the fit again on every match within inlier_tol_px of it. The filter
        # keeps a band of +/- one standard deviation and drops most true matches with
        # them; under yaw that band is a strip of the image, which conditions the
        # rotation poorly. The matches that agree with the filtered fit are all used.
        inl = np.linalg.norm(self._predict(M, src) - dst, axis=1) <= cfg.inlier_tol_px
        for _ in range(cfg.refine_passes):
            if inl.sum() < 3:
                break
            M = self._rigid_px(src[inl], dst[inl], scale)
            inl = np.linalg.norm(self._predict(M, src) - dst, axis=1) <= cfg.inlier_tol_px
        if cfg.refine_passes:
            s, d = src[inl], dst[inl]
            if len(s) < cfg.min_inliers:
                return _Fit(
                    M,
                    s,
                    d,
                    n,
                    consensus=float(inl.mean()),
                    problem=f"too few matches agree with the fit ({len(s)} < {cfg.min_inliers})",
                    no_motion=True,
                )
        if scale is None and not self._scale_changed(M, s, d):
            # No change of height measured: the rigid fit, the height kept.
            return self._fit(src, dst, pred_M, 1.0, ransac)
        rms = float(np.sqrt(np.mean(np.sum((self._predict(M, s) - d) ** 2, axis=1))))
        consensus = float(inl.mean())
        problem = ""
        no_motion = rms <= cfg.max_rms_px and consensus < cfg.min_consensus
        if rms > cfg.max_rms_px:
            problem = f"fit residual {rms:.2f} px RMS > {cfg.max_rms_px:g}"
        elif consensus < cfg.min_consensus:
            problem = (
                f"only {100 * consensus:.0f} % of {n} matches agree with the fit "
                f"(within {cfg.inlier_tol_px:g} px; needs {100 * cfg.min_consensus:.0f} %)"
            )
        else:
            # Two motions in one frame (a static glare or dirt, an object moving on the floor):
            # the matches that disagree with the fit must not agree on another motion.
            # (The consensus share was checked above, against the fit itself: min_fraction 0 here.)
            problem = consensus_problem(
                src,
                dst,
                inl,
                cfg.inlier_tol_px,
                min_fraction=0.0,
                min_count=cfg.min_inliers,
                max_rival_fraction=cfg.max_rival_fraction,
            ) or (self._similarity_precision_problem(M, s, d) if scale is None else self._precision_problem(M, s, d))
        return _Fit(M, s, d, n, rms, consensus, problem, scale_fitted=scale is None, no_motion=no_motion)

    def _precision_problem(self, M: np.ndarray, s: np.ndarray, d: np.ndarray) -> str:
        """Why the fit ``M`` of the pairs ``s -> d`` (K, 2) px is too imprecise to report ('' if it is not).

        The step's standard errors from the fit's residuals (:func:`floorvo.geometry.rigid_fit_precision`:
        the camera's own displacement, at the principal point, and the yaw), ``precision_sigmas`` of
        them, must lie within the error a step reported ok may have (``max_step_error_mm`` +
        ``max_step_error_fraction`` of the step, ``max_step_error_deg``; issue 14's bound). A few
        imprecise pairs (a floor turning under one grazing LED, a blurred fast step, tiles) fit
        with residuals of a pixel and can leave the step 0.15-0.5 mm or 0.3-0.7 degrees off while
        every other check passes (BENCHMARKS.md, "Wrong steps reported ok").
        """
        cfg = self.config
        if cfg.precision_sigmas <= 0.0 or len(s) < 3:
            return ""
        sig_px, sig_rad = rigid_fit_precision(s - self.centre, d - self.centre, M[:2, :2], M[:2, 2])
        return self._bound_problem(M, sig_px, sig_rad)

    def _scale_changed(self, M: np.ndarray, s: np.ndarray, d: np.ndarray) -> bool:
        """The image scale of the similarity ``M`` (``M[:2, :2]`` = scale R) fitted to the pairs
        ``s -> d`` (K, 2) px tells a change of the camera height: it differs from 1 by more than
        ``image_scale_min_sigmas`` of its standard errors (the scale's relative error is the
        rotation's, :func:`floorvo.geometry.rigid_fit_precision`). Within them no change is
        measured: following such a scale made the height a random walk on level runs
        (BENCHMARKS.md, "A fitted image scale"; phase-corr's blocks likewise: "phase-corr: the
        camera height only where the image scale shows it")."""
        if len(s) < 4:
            return True
        k, _, sig_rad = self._similarity_precision(M, s, d)
        limit = t_sigmas(self.config.image_scale_min_sigmas, 2 * len(s) - 4)  # the similarity's 4 parameters
        return not abs(k - 1.0) <= limit * k * sig_rad

    def _similarity_precision(self, M: np.ndarray, s: np.ndarray, d: np.ndarray) -> tuple[float, float, float]:
        """The image scale of the similarity ``M`` (``M[:2, :2]`` = scale R) fitted to the pairs
        ``s -> d`` (K, 2) px, and the fit's standard errors from its residuals
        (:func:`floorvo.geometry.rigid_fit_precision`): its displacement at the principal point
        (px) and its rotation (rad), which is also the scale's relative error."""
        k = _image_scale(M)
        sig_px, sig_rad = rigid_fit_precision(s - self.centre, d - self.centre, M[:2, :2] / k, M[:2, 2], scale=k)
        return k, sig_px, sig_rad

    def _similarity_precision_problem(self, M: np.ndarray, s: np.ndarray, d: np.ndarray) -> str:
        """:meth:`_precision_problem` of a fit whose image scale was fitted too (``M[:2, :2]`` =
        scale R). The scale is a fourth parameter of the fit: its relative error (the rotation's
        standard error, :func:`floorvo.geometry.rigid_fit_precision`) carries over the lever arm
        to the principal point, and it is the relative error of the height change the step
        reports (``h sigma_scale`` along the optical axis), which adds to the displacement's."""
        if self.config.precision_sigmas <= 0.0 or len(s) < 4:
            return ""
        _, sig_px, sig_rad = self._similarity_precision(M, s, d)
        sig_height_px = self.height_mm * sig_rad / self.camera.gsd_mm_per_px(self.height_mm)
        return self._bound_problem(M, float(np.hypot(sig_px, sig_height_px)), sig_rad)

    def _bound_problem(self, M: np.ndarray, sig_px: float, sig_rad: float) -> str:
        """Why a step with the standard errors ``sig_px`` (its displacement, px) and ``sig_rad``
        (its yaw) is too imprecise for issue 14's bound ('' if it is not)."""
        cfg = self.config
        mm_per_px = self.camera.gsd_mm_per_px(self.height_mm)
        bound_mm = cfg.bound_mm(float(np.linalg.norm(M[:2, 2])) * mm_per_px)
        k = cfg.precision_sigmas
        if k * sig_px * mm_per_px > bound_mm or k * np.degrees(sig_rad) > cfg.max_step_error_deg:
            return (
                f"imprecise fit: {k:g} standard errors are {k * sig_px * mm_per_px:.3f} mm and "
                f"{k * np.degrees(sig_rad):.2f} deg (bound {bound_mm:.3f} mm, {cfg.max_step_error_deg:g} deg)"
            )
        return ""

    def _rigid_px(self, src: np.ndarray, dst: np.ndarray, scale: float | None = 1.0) -> np.ndarray:
        """3x3 least-squares motion (prev-centred px -> cur-centred px) of the pairs ``src -> dst`` (N, 2) px:
        ``p_cur = scale R p_prev + t`` with the rotation ``R`` and ``t`` fitted and the image scale
        ratio ``scale`` known (1: the rigid fit; :meth:`_scale_ratio`), or fitted too when
        ``scale`` is None (the least-squares similarity, Umeyama's closed form).
        ``M[:2, :2]`` is ``scale R``."""
        M = np.eye(3)
        if scale is None:
            R, t, k = umeyama(src - self.centre, dst - self.centre, with_scale=True)
            M[:2, :2], M[:2, 2] = k * R, t
            return M
        R, t = rigid_fit(scale * (src - self.centre), dst - self.centre)
        M[:2, :2], M[:2, 2] = scale * R, t
        return M

    def _height_after(self, state: _State, fit: _Fit, frame: Frame) -> float | None:
        """The camera height (mm) of ``frame`` as the next step's reference: the measured one
        when it has one; with the image scale fitted (``fit_image_scale``), the reference's
        divided by the fitted image scale (the picture scales by ``h_prev / h_cur`` about the
        principal point: eq. (1) of paper 000 read backwards); else the reference's, kept (None:
        the rig's; a frame without a reading in a run with a height signal had been converted at
        the rig's height, a jump of the readings' difference from it)."""
        h = self._frame_height(frame)
        if h is None and fit.M is not None and fit.scale_fitted:
            h_prev = state.height_mm or self.height_mm
            h = h_prev / self._picture_scale(fit)
        elif h is None:
            h = state.height_mm  # the scale showed no change (:meth:`_scale_changed`), or none fitted: kept
        return h

    def _height_read_now(self, state: _State, frame: Frame) -> bool:
        """Whether the step to ``frame`` takes its height change from two readings: the frame's
        and its reference's (a height signal's; the first frame or a restart without one has none)."""
        return state.height_read and self._frame_height(frame) is not None

    def _height_from(self, state: _State, fit: _Fit, frame: Frame) -> float:
        """The reference's height (mm) the step to ``frame`` is converted and its height change
        taken from: the reference's (:attr:`_State.height_mm`, the rig's where None); where the
        frame has a reading and its reference had none (the first frame, a restart), the reading
        put back by the picture's change (the fitted image scale; none with a rigid fit): the
        rig's height less a reading had been reported as the height change (0.77 mm off, ok)."""
        h_read = self._frame_height(frame)
        if h_read is None or state.height_read:
            return state.height_mm or self.height_mm
        k = self._picture_scale(fit) if fit.M is not None and fit.scale_fitted else 1.0
        return h_read * k

    def _scale_ratio(self, state: _State, frame: Frame) -> float | None:
        """The image scale of ``frame`` relative to the reference's, from their camera heights (1 without a height signal;
        None when it is to be fitted: ``fit_image_scale`` and no measured height).

        A downward camera over a flat floor sees a floor point at ``f r / h`` px from the
        principal point (eq. (1) of paper 000 read backwards), so between heights ``h_prev``
        and ``h_cur`` the picture scales by ``h_prev / h_cur`` about the principal point: 0.8 %
        per frame on a 2 mm bounce at 2 Hz, 2.6 px at the corners of a 648x494 frame, which a
        rigid pixel fit leaves as residual (BENCHMARKS.md, "akaze-guided and akaze-bruteforce on
        a bounce with a height signal"). The heights are those :meth:`_motion` converts the pixels with (the rig's
        where a frame has no measured height)."""
        h_measured = self._frame_height(frame)
        read_now = self._height_read_now(state, frame)
        if not read_now and self.config.fit_image_scale and not self.fits_own_scale:
            return None
        if h_measured is None or not read_now:
            return 1.0  # a height kept, or one read at the frame only: no change known (:meth:`_height_from`)
        return (state.height_mm or self.height_mm) / h_measured

    def _frame_height(self, frame: Frame) -> float | None:
        """The frame's measured camera height (mm) when it has one and ``use_height_signal``, else None."""
        return frame_height_mm(frame, self.config.use_height_signal)

    def _start_reference(self, state: _State, frame: Frame) -> None:
        """Hook: a frame becomes the reference without a measured step (the first, a restart)."""

    def _prediction(self, state: _State, t_s: float) -> np.ndarray:
        """Eq. (2)'s prediction (3x3, centred px) of the frame at time ``t_s`` (s): the last step's
        image motion ``M_last``, at constant velocity over the time the frame is after the
        reference (:func:`floorvo.geometry.per_interval_px`). Frames at a steady rate (paper
        000's, a render's) take ``M_last`` as it is; after frames the camera dropped, the step
        predicted one interval long had been doubted and matched by brute force. A homography
        (homography-6dof's image motion) is taken as it is."""
        M = state.M_last
        assert M is not None
        return M if self.fits_own_scale else motion_over_time(M, state.m_last_span_s, t_s - state.t_ref_s)

    def _motion_problem_restarts(self, problem: str) -> bool:
        """Whether a frame lost by its motion's ``problem`` (:meth:`_motion`; not by the pairs'
        fit) counts toward a restart after ``restart_after_lost`` lost frames: no by default, the
        next frame is measured from the older reference, which bridges the gap (homography-6dof
        on the full-size concrete bounce: 0.43 % end drift so, 4.75 % restarting)."""
        return False

    def _motion(self, state: _State, fit: _Fit, frame: Frame) -> tuple[np.ndarray | None, str]:
        """The step ``T_prev_cur`` (4, 4) mm of the fit's pairs (px), or None and why not.

        Eq. (1) via the camera model, then the SE(2) least-squares rigid fit in floor mm.
        Each frame's pixels go to the floor at its own height: the frame's measured height
        (``Frame.height_mm``: a range sensor, or the depth image's floor plane) when it has
        one, else the rig's; the step then carries the height change along the optical axis.
        """
        h_prev = self._height_from(state, fit, frame)
        h_cur = self._height_after(state, fit, frame) or self.height_mm
        src, dst = fit.pairs_gs
        q_prev = pixels_to_floor_mm(src, self.pinhole, h_prev)  # the pairs are the pinhole's (_levelled)
        q_cur = pixels_to_floor_mm(dst, self.pinhole, h_cur)
        R2, t2_mm = rigid_fit(q_prev, q_cur)
        T = floor_rigid_to_T(R2, t2_mm)
        T[2, 3] = h_prev - h_cur  # the camera rose by h_cur - h_prev: its z axis points down
        return T, ""

    def _shutter_undone(self, state: _State, fit: _Fit, frame: Frame) -> _Fit:
        """The fit with its pairs as global shutters at the reference's and the frame's times see
        them (:attr:`_Fit.pairs_gs`; :func:`floorvo.geometry.rolling_shutter_undone`); the fit as
        it is under a global shutter. The rows are the ideal pinhole's, which the pairs are in
        (:meth:`_levelled`): a distorted lens's or a levelled frame's rows differ from the
        sensor's by a few px, a share of a per cent of a step's correction. The fit itself, its
        checks and the prediction the next frame is matched with stay in the frames' own pixels,
        where the readout's shear is the same from frame to frame; the step, the height the
        image scale follows and the height checks take the undone pairs (on the wood arc with a
        15 ms readout the frames' own pixels read the turning picture's distortion as the camera
        rising 0.05 mm a frame: akaze-guided-fast 1.55 % end drift). Where the frame before was
        measured, its turn gives the turn rate's change (an S-curve's)."""
        if self.row_time_s == 0.0 or fit.M is None:
            return fit
        turn_before = None
        if state.M_last is not None and state.m_last_span_s > 0.0:  # the frame before measured: the turn rate's change
            turn_before = (float(np.arctan2(state.M_last[1, 0], state.M_last[0, 0])), state.m_last_span_s)
        src, dst = rolling_shutter_undone(
            fit.src,
            fit.dst,
            interval_s=float(frame.timestamp_s) - state.t_ref_s,
            row_time_s=self.row_time_s,
            mid_row_px=(self.camera.height_px - 1) / 2.0,
            turn_before=turn_before,
            centre_px=(float(self.centre[0]), float(self.centre[1])),
        )
        scale_gs = None
        if fit.scale_fitted:  # the height follows the undone pairs' scale, 1 where it shows no change
            similarity = _AkazeBase._rigid_px(self, src, dst, scale=None)
            scale_gs = _image_scale(similarity) if self._scale_changed(similarity, src, dst) else 1.0
        return replace(fit, src_gs=src, dst_gs=dst, scale_gs=scale_gs)

    def _readout_problem(self, fit: _Fit) -> str:
        """Why the step's motion is not one over the readout ('' where it is, or the frames have a
        global shutter): :func:`floorvo.geometry.rolling_shutter_undone` moves the pairs at one
        velocity (a constant planar twist), and a turn that starts or ends between a frame's first
        and last rows breaks that. The undone pairs whose reference keypoint lies in the rows read
        first (above the median row) and in those read last are fitted apart, with the fit's image
        scale (fitted again where the fit fitted it); the two motions' yaws and displacements at
        the principal point may differ by issue 14's bound (``max_step_error_*``) plus
        ``precision_sigmas`` of their standard errors (:func:`floorvo.geometry.rigid_fit_precision`).
        On the vinyl corner with a 15 ms readout, the steps where the 90-degree turn starts and ends
        were reported 0.5-0.9 degrees off, ok (both halves' turns: their difference)."""
        cfg = self.config
        if not cfg.check_readout_motion or fit.src_gs is None or fit.dst_gs is None or fit.M is None:
            return ""
        src, dst = fit.pairs_gs
        upper = fit.src[:, 1] < np.median(fit.src[:, 1])
        if min(int(upper.sum()), int((~upper).sum())) < max(cfg.min_inliers, 4):
            return ""
        similarity = fit.scale_fitted or self.fits_own_scale
        scale = None if similarity else _image_scale(fit.M)
        halves = []
        for rows in (upper, ~upper):
            s, d = src[rows], dst[rows]
            M = _AkazeBase._rigid_px(self, s, d, scale)
            if similarity:
                _, sig_px, sig_rad = self._similarity_precision(M, s, d)
            else:
                k = _image_scale(M)
                sig_px, sig_rad = rigid_fit_precision(
                    s - self.centre, d - self.centre, M[:2, :2] / k, M[:2, 2], scale=k
                )
            halves.append((M, sig_px, sig_rad))
        (M1, sp1, sr1), (M2, sp2, sr2) = halves
        mm_per_px = self.camera.gsd_mm_per_px(self.height_mm)
        return readout_change_problem(
            "the pairs",
            float(np.linalg.norm(M1[:2, 2] - M2[:2, 2])) * mm_per_px,
            abs(float(np.degrees(np.arctan2(M1[1, 0], M1[0, 0]) - np.arctan2(M2[1, 0], M2[0, 0])))),
            float(np.hypot(sp1, sp2)) * mm_per_px,
            float(np.degrees(np.hypot(sr1, sr2))),
            cfg,
            cfg.bound_mm(float(np.linalg.norm(fit.M[:2, 2])) * mm_per_px),
        )

    @staticmethod
    def _picture_scale(fit: _Fit) -> float:
        """The image scale (current over reference) the camera height follows from a fit whose
        scale was fitted (``fit_image_scale``): ``M``'s, or under a rolling shutter that of the
        least-squares similarity of the undone pairs, 1 where it shows no change of height
        (:meth:`_scale_changed`, the test the fit itself made in the frames' pixels), computed
        once by :meth:`_shutter_undone` (``_Fit.scale_gs``)."""
        assert fit.M is not None
        return _image_scale(fit.M) if fit.scale_gs is None else fit.scale_gs

    def _height_change_problem(
        self, state: _State, fit: _Fit, frame: Frame, attitude: tuple[float, float] | None
    ) -> str:
        """Why a rigid step at an assumed camera height cannot be reported ('' if it can, or if
        the check does not apply): the camera's height changed by more than the step may be off.

        Paper 000's fit is rigid at the rig's height (eq. (1) with a fixed ``d``), and a planar
        step reports no height change; on a bounce the camera rises and falls by up to 0.8 mm
        a frame, and a step whose pairs the rigid fit still holds (a residual under
        ``max_rms_px``) was reported ok and wrong by that change (11-15 of each full-size bounce's
        40 steps, BENCHMARKS.md). The check fits the least-squares floor homography of the
        fit's pairs (``fit.src -> fit.dst``, px; normalised by the camera model) and decomposes
        it with the level floor at the reference's height (:func:`floorvo.geometry.plane_homography_motion`:
        its height change and its tilt change). The step is lost where the height change it
        reads differs from the one the fit assumed (none without a height signal), less
        ``precision_sigmas`` of its standard errors and divided by ``height_change_read_share``,
        by more than the bound a step reported ok may have (``max_step_error_mm`` +
        ``max_step_error_fraction`` of the step) plus ``height_change_tilt_share`` x the camera height x the tilt change
        beyond ``height_change_light_tilt_rad``. Why the tilt: under grazing LEDs that ride with
        the camera a tilt moves the shading as a height change does (the full-size tilted runs'
        homographies read false height changes of up to 0.26 x that shift on asphalt, 0.4 x on
        95 % of the wood run's steps), and the shift (camera height x tilt change) is what a
        planar estimator is allowed on a tilted step (issue 14; homography-6dof's
        ``_light_problem`` takes the same bound). Why beyond 2 mrad: the moving shading also
        makes the homography read a tilt of up to 2-2.5 mrad on level steps (0.4-1.3 mrad
        median on the level scenes of the motion suite), which would let a bounce's 0.2 mm
        steps through. Why the read share: the LEDs rise and fall with the camera, and the
        shading their lower or higher light casts moves against the image's change of scale, so
        the homography reads 85-97 % of a true height change (median per scene, the motion
        suite's bounces and vibrations, full size); a 0.171 mm rise read as 0.145 mm passed a
        0.130 mm bound (BENCHMARKS.md, "A height change read as a share"). The tilt change is
        the homography's, or the attitude signal's where the frames were levelled with it (their
        pairs then show none). What it cannot see: the height itself. A rigid fit at 100 mm over
        a camera at 98.2 mm makes every step 1.8 % long (BENCHMARKS.md)."""
        cfg = self.config
        if not cfg.check_height_change or cfg.fit_image_scale or self.fits_own_scale or fit.M is None:
            return ""
        if self._height_read_now(state, frame) or len(fit.src) < 8:
            return ""  # the height change is measured (the fit used it), or too few pairs for a homography
        src, dst = fit.pairs_gs
        x_prev = self.pinhole.unproject(src, 1.0)[:, :2]
        x_cur = self.pinhole.unproject(dst, 1.0)[:, :2]
        spread = np.linalg.svd(x_prev - x_prev.mean(axis=0), compute_uv=False)
        if spread[1] < 1e-3 * spread[0]:
            return ""  # pairs on a line fix no homography: no evidence either way, the step as the fit has it
        H, _ = cv2.findHomography(x_prev, x_cur, 0)
        if H is None:
            return ""
        h_prev = state.height_mm or self.height_mm
        level = np.array([0.0, 0.0, 1.0])
        T, _, h_cur = plane_homography_motion(H, level, h_prev)
        # The height change's standard error from interleaved blocks of the pairs (as
        # homography-6dof's agreement check): a floor whose pairs condition the homography
        # poorly (tiles: clustered corners) reads a height change that is its noise, and a step
        # is lost only where the change stands beyond it.
        blocks = block_homographies(x_prev, x_cur)
        if blocks is None:
            return ""
        h_blocks = [plane_homography_motion(H_block, level, h_prev)[2] for H_block in blocks]
        sig_mm = float(np.std(h_blocks, ddof=1)) / np.sqrt(len(blocks))
        tilt = float(np.arccos(np.clip(T[2, 2], -1.0, 1.0)))
        if attitude is not None and state.attitude is not None:
            tilt = max(tilt, tilt_change_rad(state.attitude, attitude))
        assumed = (self._height_after(state, fit, frame) or self.height_mm) - self._height_from(state, fit, frame)
        off_mm = abs((h_cur - h_prev) - assumed)
        mm_per_px = self.camera.gsd_mm_per_px(self.height_mm)
        bound_mm = cfg.bound_mm(float(np.linalg.norm(fit.M[:2, 2])) * mm_per_px)
        # A tilt's shading may be read as a height change: allowed a planar run, whose steps are held
        # to the footprint's. Not a run levelled with an attitude signal: its poses claim the camera's
        # 6-DoF step, which a height change the rigid fit does not report makes wrong whatever the
        # light does (a bouncing, tilting run with an IMU had 36 of 43 steps ok and wrong).
        share = 0.0 if attitude is not None else cfg.height_change_tilt_share
        allowance_mm = share * h_prev * max(0.0, tilt - cfg.height_change_light_tilt_rad)
        # The least change the read stands for: less its standard errors, over the share of a change the
        # homography reads (the shading of LEDs that rise and fall with the camera hides a part of it).
        least_mm = (off_mm - cfg.precision_sigmas * sig_mm) / cfg.height_change_read_share
        if least_mm > bound_mm + allowance_mm:
            return (
                f"height change not measured: the pairs' floor homography reads {h_cur - h_prev:+.3f} mm of "
                f"camera height (standard error {sig_mm:.3f}, tilt {1e3 * tilt:.1f} mrad), the rigid fit assumes "
                f"{assumed:+.3f} mm: {off_mm:.3f} mm less {cfg.precision_sigmas:g} standard errors, over the "
                f"{cfg.height_change_read_share:g} of a change the homography reads: {least_mm:.3f} mm > bound "
                f"{bound_mm:.3f} + {allowance_mm:.3f} mm (fit_image_scale or a height signal measures it)"
            )
        return ""

    def _height_drift_problem(self, state: _State, fit: _Fit, frame: Frame) -> str:
        """Why the step's height change, the difference of the reference's reading and the
        frame's, is not to be reported ('' where it may be): the height signal drifts from the
        picture over the last steps (:func:`floorvo.estimators.base.height_signal_drift_problem`).
        The fit holds the pairs to the image scale the readings give (:meth:`_scale_ratio`), so the
        picture's scale is the least-squares similarity of the same pairs (:meth:`_rigid_px`,
        Umeyama's closed form), its standard error the rotation's (:meth:`_similarity_precision`); the
        picture's rise is ``h_prev / k - h_prev``. Only a step whose height change the readings
        give joins the record."""
        if fit.M is None or len(fit.src) < 4 or not self._height_read_now(state, frame):
            return ""
        h_prev = state.height_mm or self.height_mm
        h_read = self._frame_height(frame)
        assert h_read is not None
        # the similarity of the pairs: _AkazeBase's, also for homography-6dof, whose _rigid_px fits a homography
        src, dst = fit.pairs_gs
        similarity = _AkazeBase._rigid_px(self, src, dst, scale=None)
        k, _, sig_rad = self._similarity_precision(similarity, src, dst)
        mm_per_px = self.camera.gsd_mm_per_px(self.height_mm)
        return height_signal_drift_problem(
            state.height_drift,
            h_read - h_prev,
            h_prev / k - h_prev,
            h_prev * sig_rad / k,
            self.config.bound_mm(float(np.linalg.norm(fit.M[:2, 2])) * mm_per_px),
            h_prev,
            sigmas=self.config.precision_sigmas,
            read_share=self.config.height_change_read_share,
            reading_sigma_mm=self.height_noise_mm,
        )

    def _refined(self, state: _State, fit: _Fit, img8: np.ndarray, attitude: tuple[float, float] | None) -> _Fit:
        """The fit with its pairs' current-frame positions refined to a sub-pixel (``refine_window_px``, ours).

        AKAZE finds a keypoint to about half a pixel (0.55-0.7 px median against the true motion
        on the rendered ceramic floor), and its position follows the shading as much as the
        floor. Pyramidal Lucas-Kanade (one level; ``cv2.calcOpticalFlowPyrLK``) aligns the
        ``refine_window_px`` window about each previous keypoint with the current picture,
        starting at its matched keypoint, so each pair names one floor point in both pictures
        (the previous keypoint's window) to a tenth of a pixel where the floor has texture.
        Lucas-Kanade fits a translation of the window only, so the previous picture is first
        warped by the least-squares similarity of the pairs (bilinear, ``cv2.warpAffine``): the
        window is then compared with the current picture turned and scaled as the step turns
        and scales it, not as it was (a 6-degree turn moves a 21 px window's corners by 1.5 px
        against its centre: on a synthetic 8-degree turn, Lucas-Kanade on the unturned picture
        left the pairs 0.24 px off and read the turn 0.025 degrees short, on the turned one
        0.01 px and 0.001 degrees; BENCHMARKS.md, "Sub-pixel pairs on the previous picture
        turned by the step"). At
        most ``refine_max_pairs`` pairs, evenly spread over the fit's, are refined; a pair
        whose window does not converge or moves by more than ``inlier_tol_px`` is left out, and
        the motion is fitted again on the rest with the fit's own model (the known image scale,
        or the fitted similarity). Fewer than ``min_inliers`` left, or a homography
        (``fits_own_scale``): the fit as it was. The pairs (in the ideal pinhole's pixels, levelled
        with an attitude signal: :meth:`_levelled`) are refined in the frames' own pixels and
        taken back into the pinhole. The fit's checks were made on
        its pairs before this; the height-change check (:meth:`_height_change_problem`) and
        the step (:meth:`_motion`) use the refined pairs.
        """
        cfg = self.config
        if fit.M is None or self.fits_own_scale or state.img8 is None or len(fit.src) < cfg.min_inliers:
            return fit
        pick = np.unique(np.linspace(0, len(fit.src) - 1, min(len(fit.src), cfg.refine_max_pairs)).astype(int))
        src, dst = fit.src[pick], fit.dst[pick]
        p0 = self._unlevelled(src, state.attitude).astype(np.float32).reshape(-1, 1, 2)
        guess = self._unlevelled(dst, attitude).astype(np.float32).reshape(-1, 1, 2)
        # The previous picture turned and scaled by the pairs' similarity (frames' own pixels):
        # warped(S(p)) = prev(p), so the window about S(p0) shows the floor about p0.
        p0_px, guess_px = p0.reshape(-1, 2).astype(np.float64), guess.reshape(-1, 2).astype(np.float64)
        R, t, k = umeyama(p0_px, guess_px, with_scale=True)
        S = np.hstack([k * R, t[:, None]])
        prev_turned = cv2.warpAffine(state.img8, S, (img8.shape[1], img8.shape[0]), flags=cv2.INTER_LINEAR)
        p0_turned = (p0_px @ S[:, :2].T + S[:, 2]).astype(np.float32).reshape(-1, 1, 2)
        w = int(cfg.refine_window_px)
        p1, ok, _ = cv2.calcOpticalFlowPyrLK(
            prev_turned,
            img8,
            p0_turned,
            guess.copy(),
            winSize=(w, w),
            maxLevel=0,
            criteria=(cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01),
            flags=cv2.OPTFLOW_USE_INITIAL_FLOW,
        )
        p1 = p1.reshape(-1, 2).astype(np.float64)
        keep = (ok.ravel() == 1) & (np.linalg.norm(p1 - guess.reshape(-1, 2), axis=1) <= cfg.inlier_tol_px)
        if keep.sum() < cfg.min_inliers:
            return fit
        src = src[keep]
        dst = self._levelled(p1[keep], attitude)
        scale = None if fit.scale_fitted else _image_scale(fit.M)
        return replace(fit, M=self._rigid_px(src, dst, scale), src=src, dst=dst)

    def _turned_fit(
        self, state: _State, kps: np.ndarray, packed: np.ndarray, scale: float | None
    ) -> tuple[_Fit | None, str]:
        """A guided fit from the last motion turned by more or less (``turn_sweep_deg``, ours), and a note.

        A robot that starts a turn between two frames (the suite's ceramic corner: 0 then 7.6
        degrees a frame) moves the frame's edges 50 px from the eq. (2) prediction, beyond the
        search radius, and on a repetitive floor brute force finds no motion (a tile's
        corners match the next tile's): the step was lost and the track broken there (the
        ceramic corner at floor seeds 1-4, BENCHMARKS.md, "A turn that starts between two
        frames"). Matched guided from the last motion ``M_last`` turned about the principal
        point by +/- ``turn_sweep_step_deg``, 2 x that, ... up to ``turn_sweep_deg``, the
        keypoints are found where the turn put them. A turn's fit counts only if it passes
        every check of :meth:`_fit` with twice the evidence a fit needs (``2 min_inliers``
        pairs, ``2 min_consensus`` of the matches agreeing: several turns were tried, and on
        tile a turn 1.6 degrees off the true one fitted 29 pairs, 21 % of the matches, and was
        its own fixed point, where the true turn fitted 69, 51 %), is not doubtful against its
        own prediction (:meth:`_prediction_doubt`) and is its own fixed point
        (:meth:`_rematch_problem`). None of them: ``(None, '')``, the step stays lost. Several:
        they must agree within issue 14's bound (``max_step_error_*``, at the principal point
        and in yaw) with the one of most pairs, which is taken; else a lost fit says that the
        turns disagree (a repetitive floor that fits more than one turn). ``kps``, ``packed``,
        ``scale``: as for :meth:`_rematch_problem`."""
        cfg = self.config
        if cfg.turn_sweep_deg <= 0 or state.M_last is None or self.fits_own_scale:
            return None, ""
        n = int(np.floor(cfg.turn_sweep_deg / cfg.turn_sweep_step_deg + 1e-9))
        passing: list[tuple[float, _Fit]] = []
        for k in range(1, n + 1):
            for sign in (1.0, -1.0):
                turn_deg = sign * k * cfg.turn_sweep_step_deg
                M = rot_z(np.radians(turn_deg)) @ state.M_last  # about the principal point (centred px)
                fit = self._fit(*self._guided(state, kps, packed, M), M, scale)
                if fit.problem or fit.M is None:
                    continue
                # Several turns tried: twice the evidence a fit needs (pairs and agreeing share).
                if len(fit.src) < 2 * cfg.min_inliers or fit.consensus < 2 * cfg.min_consensus:
                    continue
                if self._prediction_doubt(fit, M) or self._rematch_problem(state, kps, packed, fit, scale):
                    continue
                passing.append((turn_deg, fit))
        if not passing:
            return None, ""
        best_deg, best = max(passing, key=lambda p: len(p[1].src))
        assert best.M is not None
        for turn_deg, fit in passing:
            assert fit.M is not None
            apart_mm, apart_deg, bound_mm = self._steps_apart(fit.M, best.M)
            if apart_mm > bound_mm or apart_deg > cfg.max_step_error_deg:
                problem = (
                    f"the last motion turned by {best_deg:+g} and {turn_deg:+g} deg predicts steps "
                    f"{apart_mm:.3f} mm and {apart_deg:.2f} deg apart (bound {bound_mm:.3f} mm, "
                    f"{cfg.max_step_error_deg:g} deg): the turns disagree"
                )
                return replace(best, problem=problem), ""
        return best, (
            f"matched guided from the last motion turned by {best_deg:+g} deg ({len(passing)} of {2 * n} turns "
            "fit, and agree)"
        )

    def _prediction_doubt(self, fit: _Fit, pred_M: np.ndarray) -> str:
        """Why the eq. (2) prediction behind a guided fit is doubtful ('' if it is not)."""
        if fit.problem or fit.M is None:
            return fit.problem or "no fit"
        # The largest correction of the prediction over the frame's keypoints: near the
        # search radius, true matches may lie beyond it and the nearer wrong ones were taken.
        corr = float(np.max(np.linalg.norm(self._predict(fit.M, fit.src) - self._predict(pred_M, fit.src), axis=1)))
        limit = self.config.doubt_radius_fraction * self.config.search_radius_px
        if corr > limit:
            return f"the motion differs from the prediction by {corr:.1f} px (search radius {self.config.search_radius_px:.1f})"
        return ""

    def _steps_apart(self, M: np.ndarray, M_ref: np.ndarray) -> tuple[float, float, float]:
        """How far the image motion ``M`` is from ``M_ref`` (both 3x3 prev-centred px -> cur-centred
        px): the principal point's image (mm at the rig's height), the yaw (deg; of ``scale R``, the
        angle alone), and issue 14's bound (``max_step_error_*``) for ``M_ref``'s step (mm)."""
        mm_per_px = self.camera.gsd_mm_per_px(self.height_mm)
        apart_mm = float(np.linalg.norm(M[:2, 2] - M_ref[:2, 2])) * mm_per_px
        apart_deg = abs(float(np.degrees(yaw_of_R(M[:2, :2] @ M_ref[:2, :2].T))))
        return apart_mm, apart_deg, self.config.bound_mm(float(np.linalg.norm(M_ref[:2, 2])) * mm_per_px)

    def _rematch_problem(
        self, state: _State, kps: np.ndarray, packed: np.ndarray, fit: _Fit, scale: float | None
    ) -> str:
        """Why a guided fit is not its own fixed point ('' if it is): the prediction pulled it.

        On a repetitive floor (tiles: rows of like corners and grout lines) the nearest-first
        search takes, around each prediction, a like keypoint near it, so a wrong prediction
        (a turn whose rate changes) pulls the matches, and the fit lands between the
        prediction and the truth while passing every check: the full-size ceramic corner's
        6-degree turn, predicted at 7.6 degrees, was measured at 6.5 from 13 pairs, its
        standard error saying 0.09 degrees (BENCHMARKS.md, "Wrong steps reported ok: a guided
        step pulled by its prediction"). The check matches the previous keypoints again,
        predicted with the fit ``fit.M`` instead, and fits again (:meth:`_guided`,
        :meth:`_fit`): a fit that does not depend on its prediction comes back (right steps
        moved by at most 0.03 degrees there); one that moves beyond issue 14's bound
        (``max_step_error_mm`` + ``max_step_error_fraction`` of the step at the principal
        point, ``max_step_error_deg`` in yaw) says that the matches follow the prediction.
        ``kps`` (M, 2) px, ``packed`` (M, W): the new frame's keypoints and descriptors;
        ``scale``: as for :meth:`_fit`. A second fit that fails its own checks is no evidence
        either way ('' : the filter, centred on the fit, may leave too few pairs). Only for a
        rigid or similarity image motion (not a homography, ``fits_own_scale``).
        """
        cfg = self.config
        if not cfg.check_rematch or self.fits_own_scale or fit.M is None:
            return ""
        again = self._fit(*self._guided(state, kps, packed, fit.M), fit.M, scale)
        if again.problem or again.M is None:
            return ""
        moved_mm, moved_deg, bound_mm = self._steps_apart(again.M, fit.M)
        if moved_mm > bound_mm or moved_deg > cfg.max_step_error_deg:
            return (
                f"matched again around its fit, the step moves by {moved_mm:.3f} mm and {moved_deg:.2f} deg "
                f"(bound {bound_mm:.3f} mm, {cfg.max_step_error_deg:g} deg): the prediction pulled the matches"
            )
        return ""

    def step(self, state: _State, frame: Frame) -> StepResult:
        if not isinstance(state, _State):
            raise state_error(self.name, state)
        t0 = time.perf_counter()
        bad = frame_problem(frame.image, self.camera)
        if bad:
            return StepResult("lost", reason=bad, timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter()))
        attitude = frame_attitude_rad(frame, self.levels_with_attitude and self.config.use_attitude_signal)
        if isinstance(attitude, str):
            return StepResult("lost", reason=attitude, timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter()))
        kps, desc, img8 = self._detect(frame.image, state)
        kps = self._levelled(kps, attitude)
        packed = pack_descriptors(desc)
        t1 = time.perf_counter()
        if state.kps is None:
            if len(kps) < self.config.min_matches:
                return StepResult(
                    "lost",
                    reason=f"too few keypoints ({len(kps)}) to start from",
                    n_keypoints=len(kps),
                    timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()),
                )
            state.kps, state.desc, state.packed, state.attitude, state.img8 = kps, desc, packed, attitude, img8
            state.height_mm = self._frame_height(frame)
            state.height_read = state.height_mm is not None
            state.t_ref_s = float(frame.timestamp_s)
            self._start_reference(state, frame)
            return StepResult(
                "init",
                reason="first frame",
                n_keypoints=len(kps),
                timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()),
            )
        note = ""
        if len(kps) < self.config.min_matches:
            fit = _Fit(None, kps, kps, 0, problem=f"too few keypoints ({len(kps)})")
        elif self.guided and state.M_last is not None:
            scale = self._scale_ratio(state, frame)
            M_pred = self._prediction(state, float(frame.timestamp_s))
            fit = self._fit(*self._guided(state, kps, packed, M_pred), M_pred, scale)
            doubt = self._prediction_doubt(fit, M_pred) or self._rematch_problem(state, kps, packed, fit, scale)
            if doubt:
                # The prediction is doubtful: match again without it (brute force, as at the start).
                fit, how = self._bruteforce_fit(state, kps, desc, scale)
                note = f"guided prediction doubtful ({doubt}): matched by brute force" + (f"; {how}" if how else "")
                if fit.no_motion:
                    # Brute force found no motion (a repetitive floor): the last motion turned.
                    turned, how = self._turned_fit(state, kps, packed, scale)
                    if turned is not None:
                        note = f"{note}; {fit.problem}" + (f"; {how}" if how else "")
                        fit = turned
        else:
            fit, note = self._bruteforce_fit(state, kps, desc, self._scale_ratio(state, frame))
        if not fit.problem and self.config.refine_window_px:
            fit = self._refined(state, fit, img8, attitude)
        if not fit.problem:
            fit = self._shutter_undone(state, fit, frame)
            problem = self._readout_problem(fit) or self._height_change_problem(state, fit, frame, attitude)
            drift = self._height_drift_problem(state, fit, frame)
            fit = replace(fit, problem=problem or drift)
        t2 = time.perf_counter()
        T, problem = (None, fit.problem) if fit.problem else self._motion(state, fit, frame)
        if T is None:
            # Lost (the pairs' fit failed, or the motion of the pairs did): the next frame is
            # matched against the last good one, without a prediction; after restart_after_lost
            # such frames the current one becomes the reference (the motion over the gap is
            # unknown, and the gap shows in the run).
            state.M_last = None
            state.n_lost += 1
            why = f"{note}; {problem}" if note else problem
            restarts = bool(fit.problem) or self._motion_problem_restarts(problem)
            if restarts and state.n_lost >= self.config.restart_after_lost and len(kps) >= self.config.min_matches:
                state.kps, state.desc, state.packed, state.n_lost = kps, desc, packed, 0
                state.attitude, state.img8 = attitude, img8
                state.height_mm = self._frame_height(frame)
                state.height_read = state.height_mm is not None
                state.t_ref_s = float(frame.timestamp_s)
                self._start_reference(state, frame)
                why += f"; {RESTART_NOTE}"
            return StepResult(
                "lost",
                reason=why,
                n_keypoints=len(kps),
                n_matches=fit.n_matches,
                n_inliers=len(fit.src),
                timing_ms=stage_timing_ms(t0, t1, t2, time.perf_counter()),
            )
        # The pairs in each frame's own pixels (levelled keypoints moved back), for reports.
        matches_px = np.hstack([self._unlevelled(fit.src, state.attitude), self._unlevelled(fit.dst, attitude)])
        state.kps, state.desc, state.packed, state.M_last, state.n_lost = kps, desc, packed, fit.M, 0
        state.m_last_span_s = float(frame.timestamp_s) - state.t_ref_s
        state.t_ref_s = float(frame.timestamp_s)
        state.attitude, state.img8 = attitude, img8
        state.height_mm = self._height_after(state, fit, frame)
        state.height_read = self._frame_height(frame) is not None
        t3 = time.perf_counter()
        return StepResult(
            "ok",
            T,
            reason=note,
            n_keypoints=len(kps),
            n_matches=fit.n_matches,
            n_inliers=len(fit.src),
            timing_ms=stage_timing_ms(t0, t1, t2, t3),
            matches_px=matches_px,
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


#: The real-time presets (issue 14 item 5). At a fixed camera height the floor's picture keeps
#: its scale, so one octave of one sublevel replaces AKAZE's 4 x 4 nonlinear scale space; the
#: yaw between two frames is a few degrees, so the descriptors are upright (no orientation:
#: half the descriptor time); a threshold of 0.001 and the 600 strongest keypoints bound the
#: descriptor and matching time. The matching, the section II-C filter, the fit and the
#: self-checks are the paper's. Frames/s and drift against the defaults: BENCHMARKS.md,
#: "Real time on one core". Unlike the paper's rigid fit at the rig's height, the presets follow
#: the camera height from the image scale where it shows a change (``fit_image_scale``): at the
#: rig's height 13-14 steps of each full-size bounce were reported ok and wrong against the
#: camera's step (BENCHMARKS.md, "A fitted image scale": the real-time presets). They leave
#: ``ransac_retry`` off: their weaker matches (upright descriptors, 600 keypoints) let the
#: tracks it rescued on the ceramic corner and the 30 mm/frame wood run report 1-2 steps wrong
#: at the bound (BENCHMARKS.md, "A brute-force fit retried with RANSAC").
AkazeFastConfig = with_defaults(
    AkazeConfig,
    "AkazeFastConfig",
    n_octaves=1,
    n_octave_layers=1,
    upright=True,
    akaze_threshold=0.001,
    max_keypoints=600,
    describe_kept_only=True,
    adapt_threshold=True,
    fit_image_scale=True,
    ransac_retry=False,
)


class AkazeGuidedFast(AkazeGuided):
    name = "akaze-guided-fast"
    description = "akaze-guided's real-time preset: one AKAZE octave of one sublevel, upright, 600 keypoints"
    Config = AkazeFastConfig


class AkazeBruteforceFast(AkazeBruteforce):
    name = "akaze-bruteforce-fast"
    description = "akaze-bruteforce's real-time preset: one AKAZE octave of one sublevel, upright, 600 keypoints"
    Config = AkazeFastConfig


#: Sub-pixel pairs (ours): akaze-guided with its fit's pairs refined by Lucas-Kanade
#: (``refine_window_px`` 21, :meth:`_AkazeBase._refined`). AKAZE's keypoints are found to about
#: half a pixel; on a floor that gives few of them (tile: 30-130 pairs a step) that noise is the
#: drift, and the refined pairs take it to about a tenth. Its scale is the refined pairs', which
#: follow the grazing shading with the step's length: calibrated on a 4 mm/frame straight run
#: the blurred 10-20 mm/frame runs read 0.2-0.3 % long, so calibrate it at the rig's speed
#: (BENCHMARKS.md, "Sub-pixel pairs on the previous picture turned by the step").
AkazeSubpixelConfig = with_defaults(AkazeConfig, "AkazeSubpixelConfig", refine_window_px=21)


class AkazeGuidedSubpixel(AkazeGuided):
    name = "akaze-guided-subpixel"
    description = (
        "akaze-guided with its pairs refined to a sub-pixel by Lucas-Kanade (refine_window_px = 21; ours): "
        "floors with few keypoints (tile); calibrate it at the rig's speed"
    )
    Config = AkazeSubpixelConfig
