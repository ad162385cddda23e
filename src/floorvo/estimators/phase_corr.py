"""``phase-corr``: dense odometry by windowed phase correlation (ours, not from a paper).

Per frame:

0. The whole camera model (issue 14): a camera with lens distortion or non-square pixels
   (``fx != fy``) has the region that is correlated resampled once per frame, through a
   map precomputed at start (``cv2.initUndistortRectifyMap`` / ``cv2.remap``), into an
   ideal pinhole with square pixels ``f = max(fx, fy)`` and the same principal point,
   where the floor's motion is a rigid image motion again; the principal point centres
   the crop (moved inside the frame where the principal point is nearer an edge than half
   the crop; motions stay about the principal point). An ideal square-pixel camera is used
   as it is (no resampling).
1. Divide out the LED falloff (flat-field frame, or a blur estimate without one), and replace
   the pixels brighter than twice their 3 x 3 median by it (``impulse_ratio``,
   :func:`floorvo.imaging.impulses_replaced`): a sensor's hot pixels stay put in the frame
   and, whitened by the phase correlation, held it at no motion (BENCHMARKS.md, "phase-corr
   and a sensor's hot and dead pixels").
2. Resample the current frame into the previous frame's coordinates through the
   predicted rigid motion (constant velocity: the last measured motion; its rotation turned
   on by the last change of the turn rate where the last three steps' rates changed alike,
   ``predict_turn_rate``), so the residual to measure is small and the window does not bias it.
3. Split a central crop into ``grid x grid`` blocks; in each, phase correlation
   ``ifft(B A* / |B A*|)`` gives the integer shift, and a weighted least-squares fit of
   the cross-power spectrum's phase slope over the low frequencies gives the sub-pixel
   part (for b(x) = a(x - d): B A* = |A|^2 exp(-2 pi i k.d / N)).
4. A rigid 2D fit (rotation + translation, least squares) of the block centres and
   their shifts updates the motion (this measures yaw); repeat 2-4 ``iterations`` times
   (a warp that rotates repeats until its estimate stops moving, else the step is lost),
   fewer when the next round's whole-pixel warp would be this one's: exactly, or for a
   rotating warp's first round within ``converged_px`` at the blocks (a steady turn started
   from the last step).
   When the blocks fail from the prediction and from no motion, a first guess is taken
   from the whole region (a step larger than half the crop) or from the crops' log-polar
   magnitude spectra (a sharp turn: Reddy & Chatterji's rotation by phase correlation).
   When the blocks fail from each of these, the step is measured once more with finer
   blocks (``robust_grid``, 3 x 3 over the same crop), leaving out up to
   ``robust_outlier_blocks`` that disagree with the rigid fit of the rest (more than two left
   out that agree on another motion are two motions: the measurement fails).
5. Pixels to floor millimetres with the camera model at the camera height (eq. (1) of
   paper 000 generalised), then to the camera motion ``T_prev_cur``.

Self-checks (issue 14: a step reported ok must be within 0.05 mm + 2 % of the step and 0.3
degrees of the truth, else it is lost with the reason): the weakest block's correlation
peak, the blocks' largest disagreement with the rigid fit, the yaw's standard error, the
convergence of the rounds, and two checks of the translation against that bound
(``max_step_error_*``): its standard error from the blocks' disagreement
(``precision_sigmas`` of them, as the AKAZE estimators check their fit), and its
reproducibility: measured again through the whole-pixel warp on its other side it must not
move by more than the bound (``check_warp_spread``; image content that does not move with the
floor pulls the blocks' shifts toward the warp, which the blocks' agreement does not show).
"""

from __future__ import annotations

import math
import time
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy import fft as sfft

from floorvo.camera import CameraModel
from floorvo.config import param, with_defaults
from floorvo.errors import ConfigError
from floorvo.estimators.base import (
    HEIGHT_DRIFT_STEPS,
    HEIGHT_SIGNAL_MISREAD,
    PICTURE_HEIGHT_READ_SHARE,
    RESTART_NOTE,
    Frame,
    StepBoundConfig,
    StepResult,
    frame_attitude_rad,
    frame_height_mm,
    frame_is_blank,
    frame_problem,
    height_signal_drift_problem,
    readout_change_problem,
    stage_timing_ms,
    state_error,
)
from floorvo.geometry import (
    R_nadir_cam,
    axis_scales_design,
    axis_scales_fit,
    f_sigmas,
    floor_rigid_to_T,
    motion_over_time,
    per_interval_px,
    pixel_rigid_to_floor,
    rigid_fit,
    rigid_fit_2d_information,
    rigid_fit_precision,
    rolling_shutter_undone,
    similarity_fit_2d,
)
from floorvo.imaging import flatfield_gain, illumination_corrected, impulses_replaced

__all__ = [
    "PhaseCorr",
    "PhaseCorrConfig",
    "PhaseCorrFast",
    "PhaseCorrFastConfig",
    "block_shift",
    "block_shifts",
    "block_shifts_near",
]


@dataclass(frozen=True)
class PhaseCorrConfig(StepBoundConfig):
    """``crop_px``: side of the central square crop that is correlated (a power of two is
    fastest; capped at 90 % of the shorter image side); ``margin_px``: extra border of the
    current frame normalised around the crop (the largest expected motion per frame);
    ``grid``: blocks per side; ``iterations``: warp-and-measure rounds; ``min_peak``: lowest
    phase-correlation peak (0..1) accepted; ``max_residual_px``: largest block disagreement
    with the rigid fit; ``low_freq_fraction``: frequencies used for the sub-pixel phase fit;
    ``exact_yaw_max_deg``: up to this yaw per frame the last round is measured without an
    interpolating warp (exact), above it through a rotating warp; ``max_yaw_sigma_deg``: when
    the blocks' shifts disagree beyond ``block_precision_px`` RMS (their residual from a
    similarity fit: the scale absorbs a height change), the standard error of the yaw they
    leave (:func:`floorvo.geometry.rigid_fit_precision`) must be at most this: four blocks
    disagreeing by 0.7-0.9 px RMS passed ``max_residual_px`` with a yaw 0.3-0.4 degrees off
    (BENCHMARKS.md, "Wrong steps reported ok"). Below ``block_precision_px`` the blocks agree
    as well as their shifts are measured, and small frames (blocks close together) keep
    their steps; where blocks agreeing that well could still leave the yaw's standard error
    above ``max_yaw_sigma_deg`` (:attr:`PhaseCorr.yaw_floor_deg`: a small crop), the precision
    check holds the yaw to issue 14's bound. ``precision_sigmas``: the translation's standard error at the principal
    point left by the blocks' disagreement (the same similarity fit), this many of them, must
    lie within issue 14's bound (``max_step_error_mm`` + ``max_step_error_fraction`` of the
    step): at half size binned 2 x 2 a block pixel is 0.49 mm, ten times the bound's 0.05 mm,
    and the checks in pixels let blocks 0.2-0.35 px RMS apart report steps 0.12-0.14 mm off
    (BENCHMARKS.md, "phase-corr-fast's wrong steps at half size"). ``check_warp_spread``: each step
    that passes is measured once more through the whole-pixel warp on its other side; the two
    warps must bracket it, and the two estimates agree within the same bound
    (:meth:`PhaseCorr._warp_spread`)."""

    crop_px: int = param(384, unit="px", min=32, max=4096, doc="side of the central square crop that is correlated")
    margin_px: int = param(
        128, unit="px", min=0, max=1024, doc="border normalised around the crop (largest motion per frame)"
    )
    grid: int = param(2, min=2, max=8, doc="blocks per side")
    iterations: int = param(2, min=1, max=10, doc="warp-and-measure rounds")
    min_peak: float = param(0.02, min=0.0, max=1.0, doc="lowest phase-correlation peak accepted")
    max_residual_px: float = param(1.5, unit="px", gt=0.0, doc="largest block disagreement with the rigid fit")
    low_freq_fraction: float = param(
        0.3, gt=0.0, max=0.5, doc="fraction of the frequencies used for the sub-pixel phase fit"
    )
    exact_yaw_max_deg: float = param(
        1.0, unit="deg", min=0.0, max=45.0, doc="up to this yaw per frame the last round has no interpolating warp"
    )
    max_yaw_sigma_deg: float = param(
        0.2,
        unit="deg",
        gt=0.0,
        doc="largest standard error of the yaw, from the block shifts' residual (a similarity fit): larger is lost",
    )
    block_precision_px: float = param(
        0.5,
        unit="px",
        min=0.0,
        doc="blocks agreeing within this RMS (a similarity fit) are within their own precision: yaw not checked",
    )
    downscale: int = param(
        1,
        min=1,
        max=4,
        doc="correlate the frames binned this many times smaller (area average; crop_px, margin_px and the "
        "pixel tolerances stay in the frame's pixels): about downscale^2 less work, less precise per step",
    )
    use_flatfield: bool = param(True, doc="divide by the sequence's flat-field frame when it has one")
    impulse_ratio: float = param(
        2.0,
        min=0.0,
        doc="a corrected pixel brighter than this times its 3 x 3 median is replaced by the median (hot pixels, "
        "fixed in the frame, otherwise hold the correlation at no motion); 0: none",
    )
    predict: bool = param(True, doc="start each frame from the last motion")
    predict_turn_rate: bool = param(
        True,
        doc="predict: turn the last motion's rotation on by the change of the rotation per frame between the "
        "last two steps, where the last three steps' rotations changed alike (a turn whose rate changes "
        "steadily: the S-curves)",
    )
    use_height_signal: bool = param(
        True, doc="convert pixels to mm at the frame's measured camera height when it has one (else the rig's)"
    )
    undo_rolling_shutter: bool = param(
        True,
        doc="in a sequence taken by a rolling shutter (sequence.json's sensor.readout_ms), the step is moved to "
        "what global shutters at the two frame times see, at its own image velocity "
        "(floorvo.geometry.rolling_shutter_undone): a step along the rows reads long by its rows times the row "
        "time over the frame interval",
    )
    check_readout_motion: bool = param(
        True,
        doc="undo_rolling_shutter: the blocks of the rows read first and of those read last are fitted apart; "
        "where their motions differ beyond the max_step_error_* bound, less precision_sigmas of the step's "
        "standard errors, the motion changed during the readout (a turn that starts or ends within a frame), "
        "which undoing it at one velocity cannot follow: lost",
    )
    use_attitude_signal: bool = param(
        True,
        doc="in a sequence with attitude.csv (an IMU's roll and pitch), each frame is levelled with its attitude "
        "before it is measured and the run's poses are the tilted camera's (floorvo.runner.run_frames)",
    )
    height_from_depth: bool = param(
        False, doc="in a sequence with depth (and no height.csv), measure the camera height from each depth image"
    )
    converged_px: float = param(
        0.1,
        unit="px",
        gt=0.0,
        doc="a rotating warp whose last round moves the estimate more than this (plus the blocks' disagreement) is "
        "lost; its first round is the last when the next round's warp would move no block centre by more than this",
    )
    max_residual_bound_fraction: float = param(
        0.5,
        min=0.0,
        max=1.0,
        doc="blocks may disagree by up to this fraction of issue 14's bound for the step (max_step_error_*, in px) "
        "where that is more than max_residual_px: a 30 mm step's bound is 0.65 mm (5.3 px at full size)",
    )
    weigh_blocks_by_texture: bool = param(
        False,
        doc="fit the motion to the blocks' shifts weighted by each block's texture (its shift's information "
        "along x and y: a grain along x measures little along x) where the blocks share a direction "
        "(texture_weight_min_coherence) and the warp does not rotate (fast runs along a grain); false: every "
        "coordinate alike",
    )
    texture_weight_min_coherence: float = param(
        0.8,
        min=0.0,
        max=1.0,
        doc="weigh the blocks by their texture only where the sum of their information's shapes has at least this "
        "coherence ((l1 - l2) / (l1 + l2) of its eigenvalues: a grain all of them see; wood 0.84-0.98, "
        "concrete, vinyl, asphalt 0.2-0.4, a tile's grout in several directions under 0.1)",
    )
    robust_grid: int = param(
        3,
        min=0,
        max=8,
        doc="a step whose blocks fail (a weak peak, blocks that disagree, an imprecise yaw) from every first "
        "guess is measured once more with this many blocks per side over the same crop, robust_outlier_blocks "
        "of which may disagree and are left out; 0 (or not more than grid): not",
    )
    robust_outlier_blocks: int = param(
        2,
        min=0,
        max=16,
        doc="robust_grid: the most blocks left out, one at a time, the one furthest from the rigid fit of the "
        "others, while the blocks disagree by more than the gross check allows",
    )
    robust_min_block_px: int = param(
        64,
        unit="px",
        min=16,
        doc="robust_grid only where its blocks are at least this many px of the correlated grid: on half-size "
        "frames binned 2 x 2 (36 px blocks) three steps of the wood arc that it measured were 0.14-0.23 mm off",
    )
    restart_after_lost: int = param(
        2, min=1, doc="lost frames in a row after which tracking restarts from the current frame"
    )
    check_warp_spread: bool = param(
        True,
        doc="measure each step again through the whole-pixel warp on its other side; warps that do not bracket "
        "it, or two estimates further apart than issue 14's bound (max_step_error_*): lost",
    )
    fit_image_scale: bool = param(
        True,
        doc="a frame without a measured height: follow the camera height from the blocks' image scale, "
        "h_cur = h_prev / scale, from the rig's, where it shows a change (image_scale_min_sigmas); false: the "
        "rig's height throughout, and a step whose blocks' scale shows a height change beyond the max_step_error_* "
        "bound is lost (precision_sigmas = 0: reported)",
    )
    image_scale_axis: str = param(
        "y",
        choices=("x", "y", "both"),
        doc="the image axis whose scale gives the height (fit_image_scale): y runs along the rig's LED bars, "
        "where the grazing light moves the picture evenly; both: the similarity fit's scale",
    )
    image_scale_min_sigmas: float = param(
        3.0,
        min=0.0,
        doc="fit_image_scale: the height changes only where the image scale differs from 1 by more than this many "
        "of its standard errors, at this many normal standard errors' confidence for the blocks' few degrees of "
        "freedom (Student's t: 9.2 for four blocks); elsewhere it is kept (no change measured); 0: wherever it differs",
    )
    image_scale_window: int = param(
        8,
        min=0,
        max=1000,
        unit="frames",
        doc="fit_image_scale: the height also follows the scale of every frame while the scales of the last this "
        "many measured frames, together, differ from 1 by more than their standard errors allow (an F test at "
        "image_scale_min_sigmas' confidence): a bouncing rig, whose height changes by less than one frame's scale "
        "shows; 0 or 1: each frame on its own",
    )


#: The most blocks left out (``robust_outlier_blocks``) that may agree on one other motion: two
#: (something fixed to the rig over two of the 3 x 3 blocks); three that agree are a second motion
#: (:meth:`PhaseCorr._second_motion`).
SECOND_MOTION_MIN_BLOCKS = 2

#: Rounds a rotating warp may take beyond ``iterations`` while its estimate still moves.
MAX_EXTRA_ROUNDS = 3


@dataclass
class _Measured:
    """One measurement of a step: ``M`` (3x3, prev-centred px -> cur-centred px), the lowest
    block peak, the largest block residual from the rigid fit (px), the blocks' RMS residual
    from a similarity fit (px) and the standard error of the yaw it leaves (deg), how far
    the last round of a rotating warp moved the estimate at a block centre (px; 0 when the
    warp did not rotate), the step's length at the principal point (mm, at the rig's
    height) and the standard error of its translation there from the blocks' residual (mm;
    the similarity fit's, :func:`floorvo.geometry.rigid_fit_precision`). ``warp`` (3x3, the last round's whole-pixel
    warp, grid px), ``offset`` (the previous frame's crop offset) and ``prev_blocks``,
    ``centres`` (the blocks it was measured with, those it kept): what :meth:`PhaseCorr._warp_spread`
    measures the step again with; ``layout`` and ``keep``: which blocks those are. ``scale``, ``scale_sigma``: the image scale of the current
    frame relative to the previous one and its standard error (:meth:`PhaseCorr._image_scale`;
    1 and 0 without ``fit_image_scale``)."""

    M: np.ndarray
    min_peak: float
    resid_px: float
    block_rms_px: float
    yaw_sigma_deg: float
    unconverged_px: float
    step_mm: float
    shift_sigma_mm: float
    warp: np.ndarray
    offset: tuple[int, int]
    prev_blocks: np.ndarray
    centres: np.ndarray
    layout: _Layout  # the blocks it was measured with
    scale: float = 1.0
    scale_sigma: float = 0.0
    keep: np.ndarray | None = None  # the indices of the layout's blocks it kept (None: all)
    # the blocks left out that agree on one other shift (px from the kept blocks' fit), when they
    # are more than SECOND_MOTION_MIN_BLOCKS: (their number, the shift's length)
    second_motion: tuple[int, float] | None = None
    # :meth:`PhaseCorr._warp_spread`'s result, once measured: (mm, deg, bracketed, M through the other warp)
    spread: tuple[float, float, bool, np.ndarray] | None = None
    # :meth:`PhaseCorr._gross_problem`'s verdict, once made (a step asks it of a measurement up to five times)
    gross: str | None = None
    # the blocks' similarity fit's image scale and its relative standard error, whatever fit_image_scale
    # (:meth:`PhaseCorr._height_signal_problem` holds a measured height to it)
    similarity_scale: float = 1.0
    similarity_sigma: float = 0.0
    # the kept blocks' centres moved by their own last-round shifts, in the current frame (B, 2, cur-centred
    # grid px; the pairs centres -> moved the step was fitted to)
    moved: np.ndarray | None = None


class _BlockFit:
    """One round's blocks: their ``centres`` (B, 2) grid px moved to ``moved`` (B, 2), and the
    similarity fit ``Rs``, ``ts``, ``sc`` of them; their RMS residual from it (grid px) and its
    standard errors (:func:`floorvo.geometry.rigid_fit_precision`), each computed once, when
    first asked for (:meth:`PhaseCorr._settled_px` and the round's result ask for the same)."""

    def __init__(self, centres: np.ndarray, moved: np.ndarray, Rs: np.ndarray, ts: np.ndarray, sc: float):
        self.centres, self.moved, self.Rs, self.ts, self.sc = centres, moved, Rs, ts, sc
        self._rms: float | None = None
        self._precision: tuple[float, float] | None = None

    @property
    def rms(self) -> float:
        if self._rms is None:
            r = self.moved - self.sc * self.centres @ self.Rs.T - self.ts
            self._rms = float(np.sqrt(np.mean(np.sum(r**2, axis=1))))
        return self._rms

    @property
    def precision(self) -> tuple[float, float]:
        """``(sigma_origin px, sigma_angle rad)`` of the similarity fit."""
        if self._precision is None:
            self._precision = rigid_fit_precision(self.centres, self.moved, self.Rs, self.ts, scale=self.sc)
        return self._precision


class _Layout:
    """The blocks a crop is cut into: ``grid`` x ``grid`` blocks of ``block`` px (grid px) over its
    central ``grid * block`` px square, whose top-left corner is ``inset`` px into the crop, and
    what follows from the layout alone: the blocks' spectral constants (``sp``), their
    ``centres`` (B, 2) prev-centred grid px, row by row, the image-scale fit's least squares
    at them (``scale_design``), the yaw's standard error blocks agreeing at
    ``block_precision_px`` leave (``yaw_floor_deg``, frame px) and whether it bounds the yaw
    (``bounds_yaw``), and the image-scale tests' limits (``image_scale_window_limits``).
    ``max_outliers`` blocks may be left out of a measurement (:meth:`PhaseCorr._agreeing`)."""

    def __init__(
        self,
        config: PhaseCorrConfig,
        grid: int,
        block: int,
        crop_origin_centred: np.ndarray,
        inset: int,
        max_outliers: int = 0,
    ):
        self.grid, self.block, self.inset, self.max_outliers = grid, block, inset, max_outliers
        self.sp = _Spectral(block, config.low_freq_fraction)
        c = (np.arange(grid) + 0.5) * block + inset
        cx, cy = np.meshgrid(c + crop_origin_centred[0], c + crop_origin_centred[1])
        self.centres = np.stack([cx.ravel(), cy.ravel()], axis=1)  # prev-centred px
        # fit_image_scale's least squares at the block centres, made once (the crop moved back
        # for a large step, or blocks left out, make their own)
        self.scale_design = axis_scales_design(self.centres)
        # The yaw's standard error that blocks agreeing at their own precision (block_precision_px
        # RMS) leave, from the layout alone: sigma / sqrt(sum |c_i - c_mean|^2), in the frame's
        # pixels. Blocks agreeing that well skip the gross yaw check; where this exceeds
        # max_yaw_sigma_deg their agreement does not bound the yaw, and the precision check holds
        # the yaw itself to issue 14's bound (_precision_problem). 0.11 deg for the default 384 px
        # crop, 0.18-0.19 deg for half-size frames; 16 px blocks: 1.3 deg, and their steps were
        # reported ok degrees off.
        k = config.downscale
        spread_px = k * np.sqrt(np.sum((self.centres - self.centres.mean(axis=0)) ** 2))
        self.yaw_floor_deg = float(np.degrees(config.block_precision_px / spread_px))
        self.bounds_yaw = self.yaw_floor_deg <= config.max_yaw_sigma_deg
        # The image-scale tests (fit_image_scale, :meth:`PhaseCorr._height_changed`): the blocks'
        # 2 B coordinates (the fewest a measurement keeps) less the fit's parameters (a
        # similarity's 4, or axis_scales_fit's 5) leave the scale's standard error its degrees
        # of freedom, fixed by the layout. Over n frames sum (s_i - 1)^2 / sum sigma_i^2 is F(n, n
        # dof)-distributed where the height does not change: its limit for each n at the
        # two-sided tail of image_scale_min_sigmas normal standard errors (n = 1: one frame's,
        # Student's t squared: 9.2^2 for four blocks).
        dof = 2 * (grid**2 - max_outliers) - (4 if config.image_scale_axis == "both" else 5)
        self.image_scale_window_limits = [
            f_sigmas(config.image_scale_min_sigmas, n, n * dof) for n in range(1, max(config.image_scale_window, 1) + 1)
        ]
        #: The one-frame limit in standard errors (9.2 for four blocks): what one frame's scale may misread.
        self.one_frame_sigmas = float(np.sqrt(self.image_scale_window_limits[0]))

    def blocks(self, crop: np.ndarray, low_only: bool = False) -> np.ndarray:
        """The spectra (grid * grid, n, n // 2 + 1) of the blocks of ``crop`` (the estimator's whole
        crop, grid px), row by row, in one transform (``low_only``: their low frequencies
        alone, :meth:`_Spectral.spectrum`)."""
        bs, g, o = self.block, self.grid, self.inset
        sq = np.asarray(crop, dtype=np.float32)[o : o + g * bs, o : o + g * bs]
        return self.sp.spectrum(sq.reshape(g, bs, g, bs).swapaxes(1, 2).reshape(g * g, bs, bs), low_only)


def _hann2(h: int, w: int) -> np.ndarray:
    return np.outer(np.hanning(h), np.hanning(w)).astype(np.float32)


class _Spectral:
    """Per-block-size constants: window, frequency grids, low-frequency mask."""

    def __init__(self, n: int, low_frac: float):
        self.n = n
        self.win = _hann2(n, n)
        ky = np.fft.fftfreq(n)[:, None] * np.ones((1, n // 2 + 1))
        kx = np.fft.rfftfreq(n)[None, :] * np.ones((n, 1))
        self.kx, self.ky = kx, ky
        low = (np.abs(kx) <= low_frac) & (np.abs(ky) <= low_frac)
        low[0, 0] = False
        self.low = low
        # The low frequencies as whole rows (|ky| <= low_frac) of the first columns (kx <= low_frac):
        # taken by rows, not by a mask; the DC term, in it, has weight 0.
        self.low_rows = np.nonzero(np.abs(ky[:, 0]) <= low_frac)[0]
        self.low_cols = int(np.count_nonzero(np.abs(kx[0]) <= low_frac))
        kx_l, ky_l = kx[self.low_rows, : self.low_cols], ky[self.low_rows, : self.low_cols]
        self.low_not_dc = ((kx_l != 0) | (ky_l != 0)).astype(np.float32)
        self.kx_low, self.ky_low = kx_l.ravel(), ky_l.ravel()
        self.low_shape = (len(self.low_rows), self.low_cols)
        self.A_low = np.stack([-2 * np.pi * self.kx_low, -2 * np.pi * self.ky_low], axis=1)  # phi = A d
        self.A_low_T = np.ascontiguousarray(self.A_low.T)  # (2, L): d0 @ A_low_T is the phase of shifts d0
        self.AA_low = (self.A_low[:, :, None] * self.A_low[:, None, :]).reshape(-1, 4)  # (L, 4): A_l^T A_l

    def spectrum(self, block: np.ndarray, low_only: bool = False) -> np.ndarray:
        """rfft2 of the windowed, mean-free block (..., n, n), in single precision (complex64): scipy's FFT
        keeps float32 (numpy's computes in double), 2x faster forward and 6x inverse on a
        192 px block; the phase-slope fit needs no more (its sub-pixel part is fitted in double).
        A stack of blocks (B, n, n) is transformed in one call. ``low_only``: its low frequencies
        only (``low_rows`` of the first ``low_cols`` columns, what :func:`block_shifts_near`
        fits), the same numbers: the rows' rfft, then the columns' FFT of those columns alone
        (four 96 px blocks: 48 us instead of 58)."""
        b = np.asarray(block, dtype=np.float32)
        b = b - b.mean(axis=(-2, -1), keepdims=True)
        b *= self.win
        if low_only:
            return sfft.fft(sfft.rfft(b, axis=-1)[..., : self.low_cols], axis=-2)[..., self.low_rows, :]
        return sfft.rfft2(b, axes=(-2, -1))


def block_shift(Fa: np.ndarray, Fb: np.ndarray, sp: _Spectral) -> tuple[np.ndarray, float]:
    """Content displacement ``d = (dx, dy)`` px of block b relative to a, and the peak height.

    ``Fa``, ``Fb``: rfft2 spectra of the windowed blocks (size sp.n). :func:`block_shifts` for a stack.
    """
    d, peak, _ = block_shifts(Fa[None], Fb[None], sp)
    return d[0], float(peak[0])


def block_shifts(Fa: np.ndarray, Fb: np.ndarray, sp: _Spectral) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`block_shift` of a stack of B block pairs in one pass: ``(d (B, 2) px, peaks (B,),
    information (B, 2, 2))``, the last the sub-pixel fit's normal matrices (:func:`_phase_slope`).

    ``Fa``, ``Fb``: (B, n, n // 2 + 1) rfft2 spectra of the windowed blocks (size sp.n). Phase
    correlation ``ifft(Fb Fa* / |Fb Fa*|)`` gives each block's integer shift at its peak; a
    weighted least-squares fit of the cross-power spectrum's phase slope over the low
    frequencies, after the integer shift is removed, gives the sub-pixel part (for
    b(x) = a(x - d): Fb Fa* = |Fa|^2 exp(-2 pi i k.d / n)).
    """
    R = Fb * np.conj(Fa)  # the cross-power spectrum, normalised in place below
    mag = np.abs(R)
    # Normalised by multiplying with the magnitude's reciprocal: a third of a complex division's time.
    inv_mag = np.maximum(mag, np.float32(1e-12))
    R *= np.reciprocal(inv_mag, out=inv_mag)
    n = sp.n
    corr = sfft.irfft2(R, s=(n, n), axes=(-2, -1)).reshape(len(R), -1)
    flat_peak = np.argmax(corr, axis=1)
    peaks = corr[np.arange(len(R)), flat_peak].astype(np.float64)
    iy, ix = np.divmod(flat_peak, n)
    d0 = np.stack([ix, iy], axis=1)
    d0[d0 > n // 2] -= n  # beyond half the block: a negative shift
    d0 = d0.astype(np.float64)
    low = (slice(None), sp.low_rows, slice(0, sp.low_cols))
    frac, info = _phase_slope(R[low], mag[low], d0, sp)
    return d0 + frac, peaks, info


def block_shifts_near(Fa: np.ndarray, Fb: np.ndarray, sp: _Spectral, d0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`block_shifts` of block pairs whose integer shifts ``d0`` (B, 2) px are known: no
    correlation and no peak search, the phase-slope fit alone over the low frequencies (the
    cross-power spectrum formed there only). ``Fa``, ``Fb``: whole spectra, or their low
    frequencies alone (``sp.spectrum(..., low_only=True)``: a spectrum of that shape is taken
    as them). ``(d (B, 2) px, information (B, 2, 2))``."""
    low = (slice(None), sp.low_rows, slice(0, sp.low_cols))
    cross = (Fb if Fb.shape[-2:] == sp.low_shape else Fb[low]) * np.conj(
        Fa if Fa.shape[-2:] == sp.low_shape else Fa[low]
    )
    d0 = np.asarray(d0, dtype=np.float64).reshape(-1, 2)
    frac, info = _phase_slope(cross, np.abs(cross), d0, sp)
    return d0 + frac, info


def _phase_slope(
    cross_low: np.ndarray, mag_low: np.ndarray, d0: np.ndarray, sp: _Spectral
) -> tuple[np.ndarray, np.ndarray]:
    """The sub-pixel shifts (B, 2) px left after the integer shifts ``d0`` (B, 2): a weighted
    least-squares fit of the phase slope ``phi = -2 pi (kx dx + ky dy)`` of the cross-power
    spectrum ``cross_low`` (B, rows, cols: the low frequencies of :class:`_Spectral`, or a
    positive multiple of them), weighted by its magnitude ``mag_low``; and each fit's normal
    matrix (B, 2, 2), ``sum_l w_l A_l^T A_l``: the shift's information up to the phase noise's
    variance, whose shape is the block's texture (a grain along x gives little along x)."""
    B = len(cross_low)
    phi = np.angle(cross_low).reshape(B, -1).astype(np.float64)
    if d0.any():  # the phase of R exp(2 pi i k.d0), wrapped into [-pi, pi] (by rounding: np.mod is 7x slower)
        phi -= d0 @ sp.A_low_T  # one product: 6 us less than the two axes' (four blocks)
        phi -= 2 * np.pi * np.round(phi * (0.5 / np.pi))
    w = (mag_low * sp.low_not_dc).reshape(B, -1).astype(np.float64)
    lhs = w @ sp.AA_low  # (B, 4): sum_l w_l A_l^T A_l, per block
    rhs = (w * phi) @ sp.A_low  # (B, 2): sum_l w_l phi_l A_l
    # Each block's 2 x 2 normal equations (+ 1e-12 on the diagonal) by Cramer's rule in plain
    # Python: the fit of four blocks 10 us from the weights, where building the stacked 2 x 2
    # matrices for np.linalg.solve and solving them took 14.
    out = []
    for (a, b, c, d), (r0, r1) in zip(lhs.tolist(), rhs.tolist(), strict=True):
        a, d = a + 1e-12, d + 1e-12
        det = a * d - b * c
        out.append(((d * r0 - b * r1) / det, (a * r1 - c * r0) / det))
    return np.array(out), lhs.reshape(B, 2, 2)


@dataclass
class _State:
    prev: np.ndarray | None = None  # corrected previous frame, float32
    prev_blocks: np.ndarray | None = None  # spectra (g * g, n, n // 2 + 1) of the previous frame's blocks
    prev_crop: np.ndarray | None = None  # the previous frame's crop (its spectrum is made when needed)
    M_pred: np.ndarray = field(default_factory=lambda: np.eye(3))  # prev-centred px -> cur-centred px
    # the time (s) from the reference frame that M_pred spans (0: none known; then it is used as it is)
    pred_span_s: float = 0.0
    t_ref_s: float = 0.0  # the reference frame's time (s)
    # the rotation (rad) per frame of the last ok steps in a row, oldest first (predict_turn_rate)
    yaws_per_frame: deque[float] = field(default_factory=lambda: deque(maxlen=3))
    # the last step's turn (rad) and the time it spanned (s), None after a lost frame: a rolling
    # shutter's readout is undone with the turn rate changing from it (PhaseCorr._shutter_undone)
    turn_before: tuple[float, float] | None = None
    n_lost: int = 0  # frames lost in a row since the reference
    height_mm: float | None = None  # camera height of the reference frame: measured or followed (None: the rig's)
    height_read: bool = False  # height_mm is the reference frame's own reading (a height signal's)
    # (scale - 1)^2 and the scale's variance of the last image_scale_window measured frames (fit_image_scale)
    scale_window: deque[tuple[float, float]] = field(default_factory=deque)
    # the last steps' disagreement of the height signal with the picture (height_signal_drift_problem)
    height_drift: deque[tuple[float, float]] = field(default_factory=lambda: deque(maxlen=HEIGHT_DRIFT_STEPS))


class PhaseCorr:
    """Windowed phase correlation with sub-pixel phase-slope fit and block-wise yaw."""

    name = "phase-corr"
    description = "dense: flat-field corrected, windowed phase correlation, sub-pixel phase fit, block-wise yaw (ours)"
    Config = PhaseCorrConfig
    requires: frozenset[str] = frozenset()
    #: A planar mono estimator: it measures the motion of the camera's floor footprint
    #: (:func:`floorvo.geometry.footprint_T`), which an attitude signal makes 6-DoF
    #: (``use_attitude_signal``, :func:`floorvo.runner.uses_attitude_signal`).
    measures_footprint: bool = True
    #: With a frame's attitude (``use_attitude_signal``) its normalised region is levelled
    #: first (:meth:`_levelled`): the steps are then those of a camera at the camera's centre
    #: looking straight down, and the runner tilts that pose with the frame's attitude
    #: (:func:`floorvo.runner.run_frames`) instead of turning a footprint back.
    levels_with_attitude: bool = True
    #: With a frame's measured height (``use_height_signal``) the step's height change is the
    #: readings' difference, so the runner holds it to the signal's stated noise
    #: (:func:`floorvo.runner.takes_height_change_from_signal`).
    height_change_from_signal: bool = True

    def __init__(
        self,
        config: PhaseCorrConfig,
        camera: CameraModel,
        *,
        height_mm: float,
        flatfield: np.ndarray | None = None,
        row_time_s: float = 0.0,
        **rig,
    ):
        self.config = config
        self.camera = camera
        # The ideal pinhole the frames are measured in (step 0 of the module doc): square
        # pixels, no distortion, the camera's principal point.
        self.pinhole = camera.square_pinhole()
        # The pixel grid the frames are correlated on: the pinhole's, or its pixels binned
        # ``downscale`` x ``downscale`` (area average); crop, margin and blocks are in its pixels.
        if 0.0 < config.impulse_ratio <= 1.0:
            raise ConfigError(
                f"phase-corr.impulse_ratio = {config.impulse_ratio:g}: must be 0 (none) or > 1 (a pixel brighter "
                "than that times its 3 x 3 median is replaced)"
            )
        k = config.downscale
        self.grid_cam = self.pinhole if k == 1 else _binned(self.pinhole, k)
        gc = self.grid_cam
        self.height_mm = float(height_mm)
        self.flatfield = flatfield if config.use_flatfield else None
        side = min(gc.width_px, gc.height_px)
        g = config.grid
        crop = min(config.crop_px // k, int(0.9 * side))
        bs = crop // g
        bs -= bs % 2
        if bs < 16:
            raise ConfigError(
                f"phase-corr: crop_px = {config.crop_px} on a {camera.width_px}x{camera.height_px} image "
                f"(downscale {k}: a crop of {crop} px) makes {g}x{g} blocks of {bs} px: they must be at least "
                "16 px (a larger crop_px or image, a smaller grid or downscale)"
            )
        self.block = bs
        self.crop = bs * g
        # The crop centred on the principal point, moved inside the frame where the principal
        # point lies nearer an edge than half the crop (a real calibration's: (200, 140) on a
        # 648x494 frame, (159.5, 100) on a 320x240 one, whose 216 px crop fits centred only within
        # 12 px of the middle): a crop past the edge ended the run in a ValueError from a block
        # reshape. Every use below takes the crop's offset from the principal point
        # (crop_from_centre, the layout's block centres), so the motion stays about that point.
        self.x0 = int(np.clip(round(gc.cx_px - self.crop / 2 + 0.5), 0, gc.width_px - self.crop))
        self.y0 = int(np.clip(round(gc.cy_px - self.crop / 2 + 0.5), 0, gc.height_px - self.crop))
        # The region of each frame that is normalised: the crop plus a margin for the motion.
        m = config.margin_px // k
        self.rx0, self.ry0 = max(0, self.x0 - m), max(0, self.y0 - m)
        self.rx1 = min(gc.width_px, self.x0 + self.crop + m)
        self.ry1 = min(gc.height_px, self.y0 + self.crop + m)
        # Rectifying map of the normalised region, in the frame's pixels (None: the camera is an
        # ideal square pinhole).
        self.rect_map: tuple[np.ndarray, np.ndarray] | None = None
        fy0, fy1, fx0, fx1 = k * self.ry0, k * self.ry1, k * self.rx0, k * self.rx1
        maps = camera.rectify_maps(self.pinhole)
        if maps is not None:
            mx, my = maps
            self.rect_map = (mx[fy0:fy1, fx0:fx1], my[fy0:fy1, fx0:fx1])
        # The flat-field gain of the region, in the grid's pixels (None: no flat field).
        self.region_gain: np.ndarray | None = None
        if self.flatfield is not None:
            flat = np.asarray(self.flatfield, dtype=np.float32)
            if flat.shape != (camera.height_px, camera.width_px):
                raise ValueError(
                    f"flatfield shape {flat.shape} differs from the camera's {camera.height_px}x{camera.width_px}"
                )
            self.region_gain = self._region(flatfield_gain(flat)).astype(np.float32)
        self.sp_crop = _Spectral(self.crop, config.low_freq_fraction)
        origin = np.array([self.x0 - gc.cx_px, self.y0 - gc.cy_px], dtype=float)
        self.layout = _Layout(config, g, bs, origin, 0)
        # The finer blocks a failed step is measured with once more (robust_grid), over the same crop.
        self.robust_layout: _Layout | None = None
        rg = config.robust_grid
        if rg and rg**2 - config.robust_outlier_blocks < 4:
            raise ConfigError(
                f"phase-corr.robust_outlier_blocks = {config.robust_outlier_blocks}: leaves fewer than 4 of "
                f"robust_grid {rg}'s {rg**2} blocks (a rigid fit of the rest must be checked by their agreement)"
            )
        if rg > g:
            rbs = self.crop // rg
            rbs -= rbs % 2
            if rbs >= config.robust_min_block_px:
                inset = (self.crop - rg * rbs) // 2
                self.robust_layout = _Layout(config, rg, rbs, origin, inset, config.robust_outlier_blocks)
        # Levelling (:meth:`_levelled`): region px -> rays of the grid's pinhole, and rays -> region px.
        to_region = np.array([[1.0, 0.0, -self.rx0], [0.0, 1.0, -self.ry0], [0.0, 0.0, 1.0]]) @ gc.K
        self.level_frame = (to_region, np.linalg.inv(to_region))
        # The crop's top-left corner from the principal point, and the principal point in the
        # region (grid px): what a warp into the crop adds around the centred motion.
        self.crop_from_centre = np.array([self.x0 - gc.cx_px, self.y0 - gc.cy_px])
        self.centre_in_region = np.array([gc.cx_px - self.rx0, gc.cy_px - self.ry0])
        self.crop_corners_centred = (
            np.array([[0, 0], [1, 0], [0, 1], [1, 1]], dtype=float) * self.crop + self.crop_from_centre
        )
        # A rolling shutter (:meth:`_shutter_undone`): the time between neighbouring rows of the
        # grid (s; 0: a global shutter), and the centre row, exposed at the frame time, in the
        # grid's centred px (a binned row k spans the frame's rows k r .. k r + k - 1).
        self.row_time_grid_s = float(row_time_s) * k if config.undo_rolling_shutter else 0.0
        self.mid_row_centred = ((camera.height_px - 1) / 2.0 + 0.5) / k - 0.5 - gc.cy_px

    @property
    def yaw_floor_deg(self) -> float:
        """The yaw's standard error (deg) the default blocks leave when they agree at their own
        precision (:class:`_Layout`)."""
        return self.layout.yaw_floor_deg

    @property
    def layout_bounds_yaw(self) -> bool:
        """Whether the default blocks' agreement bounds the yaw (:class:`_Layout`)."""
        return self.layout.bounds_yaw

    def start(self) -> _State:
        return _State()

    # ------------------------------------------------------------------ helpers
    def _rectified(self, img: np.ndarray) -> np.ndarray:
        """The region around the crop of a full frame, resampled into the ideal pinhole (float32)."""
        assert self.rect_map is not None
        return cv2.remap(
            np.asarray(img, dtype=np.float32),
            *self.rect_map,
            interpolation=cv2.INTER_CUBIC,
            borderMode=cv2.BORDER_REFLECT,
        )

    def _region(self, img: np.ndarray) -> np.ndarray:
        """The region around the crop of a full frame (or of a per-pixel map such as the flat-field
        gain) in the grid's pixels: resampled into the ideal pinhole when the camera is not one,
        then binned ``downscale`` x ``downscale`` (float32; the frame's own pixels, sliced, otherwise)."""
        k = self.config.downscale
        if self.rect_map is not None:
            reg = self._rectified(img)
        else:
            reg = img[k * self.ry0 : k * self.ry1, k * self.rx0 : k * self.rx1]
        if k == 1:
            return reg
        return cv2.resize(
            np.asarray(reg, dtype=np.float32),
            (self.rx1 - self.rx0, self.ry1 - self.ry0),
            interpolation=cv2.INTER_AREA,
        )

    def _normalised(self, img: np.ndarray) -> np.ndarray:
        """Flat-field corrected (or blur-normalised) region around the crop, float32, grid coordinates offset by
        (rx0, ry0), in the ideal pinhole's (binned) pixels."""
        reg = self._region(img)
        if self.region_gain is not None:
            out = reg.astype(np.float32, copy=False) * self.region_gain
            mean = float(out.mean())
            if mean > 0:
                out /= mean  # in place: the same division without another region-sized array
        else:
            out = illumination_corrected(reg, None)
        if self.config.impulse_ratio > 0.0:
            out = impulses_replaced(out, self.config.impulse_ratio)
        return out

    def _levelled(self, region: np.ndarray, roll_rad: float, pitch_rad: float) -> np.ndarray:
        """The normalised region (grid px, offset by ``(rx0, ry0)``) of a frame taken at attitude
        ``roll_rad``, ``pitch_rad`` (``attitude.csv``, :func:`floorvo.geometry.attitude_of_T`) as a
        camera at the same centre and yaw looking straight down sees it: resampled through the
        homography ``K R K^-1`` of the grid's pinhole (:func:`floorvo.geometry.R_nadir_cam`; the
        region is already in the ideal pinhole, so the homography is exact), the border
        reflected (a tilt of 0.03 rad moves the picture by 24 px of 648 at full size, within the
        region's margin around the crop). Bilinear on the frame's own pixels (``downscale = 1``:
        1 ms a frame for the 640 x 494 px region at full size, bicubic 2.7 ms; on the tilted
        renders the same drift within 0.03 points, on the synthetic tilted run the end within
        1 um of the bicubic one), bicubic on a binned grid (0.13 ms; bilinear took the binned
        wood tilt from 0.136 to 0.233 % calibrated: BENCHMARKS.md, "A measured attitude"). A turn
        about the camera's centre moves every pixel as the floor does not, so what is left between two levelled frames is the floor's motion as
        a level camera sees it. The flat field was applied before: it belongs to the sensor's
        pixels."""
        to_region, from_region = self.level_frame
        H = to_region @ R_nadir_cam(roll_rad, pitch_rad) @ from_region
        return cv2.warpPerspective(
            region,
            H,
            (region.shape[1], region.shape[0]),
            flags=cv2.INTER_LINEAR if self.config.downscale == 1 else cv2.INTER_CUBIC,
            borderMode=cv2.BORDER_REFLECT,
        )

    def _blocks(self, img: np.ndarray, low_only: bool = False) -> np.ndarray:
        """The spectra (g * g, n, n // 2 + 1) of the crop ``img``'s default blocks (:meth:`_Layout.blocks`)."""
        return self.layout.blocks(img, low_only)

    def _warp_into_prev(self, cur: np.ndarray, M: np.ndarray, offset: tuple[int, int] = (0, 0)) -> np.ndarray:
        """cur sampled at M(p) for p on the previous frame's crop grid (moved by ``offset`` px).

        ``M`` (3x3) maps prev-centred px to cur-centred px; a crop pixel p (from the crop's corner)
        is sampled at the region's pixel ``A p = R (p + o - c) + t + c - r0`` (o: the crop's corner,
        c: the principal point, r0: the region's corner; R, t: M's rotation and translation)."""
        R = M[:2, :2]
        A = np.empty((2, 3))
        A[:, :2] = R
        A[:, 2] = R @ (self.crop_from_centre + offset) + M[:2, 2] + self.centre_in_region
        if R[0, 0] == 1.0 and R[1, 1] == 1.0 and R[0, 1] == 0.0 and R[1, 0] == 0.0 and np.all(A[:, 2] % 1.0 == 0.0):
            # A whole-pixel translation: a slice, exact and free.
            x, y = int(A[0, 2]), int(A[1, 2])
            if 0 <= x and 0 <= y and x + self.crop <= cur.shape[1] and y + self.crop <= cur.shape[0]:
                return cur[y : y + self.crop, x : x + self.crop]
        return cv2.warpAffine(
            cur, A, (self.crop, self.crop), flags=cv2.INTER_CUBIC | cv2.WARP_INVERSE_MAP, borderMode=cv2.BORDER_REFLECT
        )

    # ------------------------------------------------------------------ step
    def step(self, state: _State, frame: Frame) -> StepResult:
        if not isinstance(state, _State):
            raise state_error(self.name, state)
        t0 = time.perf_counter()
        bad = frame_problem(frame.image, self.camera)
        if bad:
            return StepResult("lost", reason=bad, timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter()))
        img = np.asarray(frame.image)
        if frame_is_blank(img):
            return StepResult(
                "lost",
                reason="empty frame (no texture)",
                timing_ms={"detect": 0.0, "match": 0.0, "estimate": 0.0, "total": 0.0},
            )
        attitude = frame_attitude_rad(frame, self.levels_with_attitude and self.config.use_attitude_signal)
        if isinstance(attitude, str):
            return StepResult("lost", reason=attitude, timing_ms=stage_timing_ms(t0, t0, t0, time.perf_counter()))
        cur = self._normalised(img)
        if attitude is not None:
            cur = self._levelled(cur, *attitude)
        t1 = time.perf_counter()
        if state.prev is None:
            state.prev = cur
            crop = cur[
                self.y0 - self.ry0 : self.y0 - self.ry0 + self.crop, self.x0 - self.rx0 : self.x0 - self.rx0 + self.crop
            ]
            state.prev_blocks = self._blocks(crop)
            state.prev_crop = crop
            state.height_mm = self._frame_height(frame)
            state.height_read = state.height_mm is not None
            state.t_ref_s = float(frame.timestamp_s)
            return StepResult("init", reason="first frame", timing_ms=stage_timing_ms(t0, t1, t1, time.perf_counter()))
        M0 = self._prediction(state, float(frame.timestamp_s)) if self.config.predict else np.eye(3)
        m = self._measure(state, cur, M0)
        tried = [m]
        if self._failed(m) and not np.array_equal(M0, np.eye(3)):
            m = self._measure(state, cur, np.eye(3))  # the prediction misled: start afresh
            tried.append(m)
        if self._failed(m):
            # A step too large for the crop (its correlation wraps beyond half the crop): a
            # first guess from the whole normalised region, then the blocks where both frames see them.
            M_big = self._coarse(state, cur)
            if M_big is not None:
                m = self._measure(state, cur, M_big)
                tried.append(m)
        if self._failed(m):
            # A turn sharper than the blocks follow from the prediction (the first frame of a
            # 90-degree corner on a 30 mm radius turns 7.6 degrees): a first guess of the
            # rotation from the crops' magnitude spectra, then the blocks measure the step.
            M_rot = self._coarse_rotation(state, cur)
            if M_rot is not None:
                m = self._measure(state, cur, M_rot)
                tried.append(m)
        if self._failed(m) and self.robust_layout is not None:
            # The blocks failed from every first guess: once more with finer blocks
            # (robust_grid) from the guess whose blocks agreed best, leaving out those that
            # disagree (robust_outlier_blocks). Over a texture that varies little along the
            # motion (the wood's grain along x at 30 mm/frame) one or two of the four blocks
            # find another peak, or a wide one.
            m_robust = self._measure(state, cur, min(tried, key=lambda t: t.resid_px).M, self.robust_layout)
            if not self._failed(m_robust):
                m = m_robust
        gross = self._gross_problem(m)
        if self.config.check_warp_spread and not gross:
            # Measured again through the whole-pixel warp beyond it, the blocks still see the step
            # further on (:meth:`_warp_spread`): it had not converged. The rounds go on from there
            # once, and the step is checked as any other. Along a grain the blocks' shifts are
            # pulled toward their warp: on the 30 mm/frame wood run a step read -244.59 px through
            # the warp at -244 and -245.15 through the one at -245.
            _, _, bracketed, M_beyond = self._warp_spread(cur, m)
            if not bracketed:
                m_on = self._measure(state, cur, M_beyond, m.layout)
                gross_on = self._gross_problem(m_on)
                if not gross_on:
                    m, gross = m_on, gross_on
        M = m.M
        t2_ = time.perf_counter()
        # the blocks measured, and those the step kept (robust_grid may leave some out)
        n_blocks, n_kept = len(m.layout.centres), len(m.centres)
        crop = cur[
            self.y0 - self.ry0 : self.y0 - self.ry0 + self.crop, self.x0 - self.rx0 : self.x0 - self.rx0 + self.crop
        ]
        # The camera height of the current frame: measured (a height signal), followed from the
        # image scale (fit_image_scale: the picture scales by h_prev / h_cur about the principal
        # point, eq. (1) of paper 000 read backwards), or the rig's.
        h_prev = state.height_mm or self.height_mm
        h_signal = self._frame_height(frame)
        h_meas = h_signal
        height_sigma_mm = 0.0
        # The height change is the picture's where the readings do not give it: a frame without
        # a reading, or one whose reference had none (the first frame, a restart on a frame
        # without one: the rig's height less a reading was reported as the height change, 0.77
        # mm off, ok).
        h_from = h_prev  # the reference's height the step's height change is taken from
        if h_signal is None or not state.height_read:
            h_pic = h_prev
            if self.config.fit_image_scale and self._height_changed(state, m, measured=not gross):
                h_pic = h_prev / m.scale
                height_sigma_mm = h_prev * m.scale_sigma / m.scale**2
            if h_signal is None:
                # followed by the picture (fit_image_scale), else kept: a frame without a reading
                # was converted at the rig's height, a jump of the reading's difference from it
                h_meas = h_pic
            else:
                h_from = h_signal * h_prev / h_pic  # the picture's change, at the reading's height
        drift = "" if gross else self._height_drift_problem(state, m, h_prev, h_signal)
        problem = (
            gross
            or self._height_signal_problem(m, h_prev, h_signal)
            or drift
            or self._height_change_problem(state, m, h_prev, h_signal)
            or self._precision_problem(m, height_sigma_mm)
            or self._readout_problem(m, float(frame.timestamp_s) - state.t_ref_s)
            or self._spread_problem(cur, m)
        )
        if problem:
            # Lost: the next frame is measured against the last good one; after
            # restart_after_lost such frames the current one becomes the reference (the motion
            # over the gap is unknown, and the gap shows in the run). A step lost only for its
            # precision was measured nonetheless (the blocks agree, the rounds converged): the
            # next frame is predicted from it, one frame on (a spin lost every later frame from
            # no prediction); after a gross failure, from no motion.
            per_frame = per_interval_px(M, state.n_lost + 1)
            dt_s = self._interval_s(state, frame)
            state.n_lost += 1
            state.turn_before = None
            why = problem
            state.M_pred = np.eye(3) if gross else M @ per_frame
            state.pred_span_s = float(frame.timestamp_s) - state.t_ref_s + dt_s if dt_s else 0.0
            if state.n_lost >= self.config.restart_after_lost:
                state.prev, state.prev_blocks, state.prev_crop, state.n_lost = cur, self._blocks(crop), crop, 0
                state.height_mm = self._frame_height(frame)
                state.height_read = state.height_mm is not None
                state.M_pred = np.eye(3) if gross else per_frame
                state.t_ref_s, state.pred_span_s = float(frame.timestamp_s), dt_s
                why += f"; {RESTART_NOTE}"
            return StepResult(
                "lost", reason=why, n_matches=n_blocks, timing_ms=stage_timing_ms(t0, t1, t2_, time.perf_counter())
            )
        new_blocks = self._blocks(crop)
        # M maps prev-centred px to cur-centred px: the floor's motion in the image. A floor
        # point at the previous image centre is at t px in the current image, i.e. at
        # t h_cur / f mm: the current frame's height converts the shift (the measured height
        # when the frame has one, or the one its image scale gives, else the rig's); the step
        # carries the height change.
        h_cur = h_meas or self.height_mm
        M_floor = self._shutter_undone(M, m.centres, float(frame.timestamp_s) - state.t_ref_s, state.turn_before)
        state.turn_before = (float(np.arctan2(M[1, 0], M[0, 0])), float(frame.timestamp_s) - state.t_ref_s)
        R2, t2_mm = pixel_rigid_to_floor(M_floor[:2, :2], M_floor[:2, 2], self.grid_cam, h_cur, centred=True)
        T = floor_rigid_to_T(R2, t2_mm)  # eq. (1) of paper 000 via the camera model
        T[2, 3] = h_from - h_cur  # the camera rose by h_cur - h_from: its z axis points down
        # The next frame is predicted from the motion per frame: a step measured across lost
        # frames spans n_lost + 1 of them (as a prediction, twice the step left phase-corr-fast's
        # rounds 1.5 px short of it).
        state.M_pred = per_interval_px(M, state.n_lost + 1)
        state.pred_span_s = self._interval_s(state, frame)
        state.t_ref_s = float(frame.timestamp_s)
        if state.n_lost:
            state.yaws_per_frame.clear()  # the turn's rate over the gap is not known
        state.yaws_per_frame.append(float(np.arctan2(state.M_pred[1, 0], state.M_pred[0, 0])))
        if self.config.predict_turn_rate:
            state.M_pred[:2, :2] = _rotation(_predicted_yaw(state.yaws_per_frame))[:2, :2]
        state.n_lost, state.height_mm, state.height_read = 0, h_meas, h_signal is not None
        state.prev, state.prev_blocks, state.prev_crop = cur, new_blocks, crop
        t3 = time.perf_counter()
        return StepResult("ok", T, n_matches=n_blocks, n_inliers=n_kept, timing_ms=stage_timing_ms(t0, t1, t2_, t3))

    def _frame_height(self, frame: Frame) -> float | None:
        """The frame's measured camera height (mm) when it has one and ``use_height_signal``, else None."""
        return frame_height_mm(frame, self.config.use_height_signal)

    def _readout_problem(self, m: _Measured, interval_s: float) -> str:
        """Why the step ``m`` is not one motion over the readout ('' where it is, or the frames
        have a global shutter): :meth:`_shutter_undone` moves the blocks at one velocity (a
        constant planar twist), and a turn that starts or ends between a frame's first and last
        rows breaks that. The blocks' pairs (``m.centres -> m.moved``, the readout undone) above
        and below their median row are fitted apart: a rigid fit of each half (two blocks of the
        default grid) at the blocks' image scale, without which a bounce's halves moved apart.
        The two motions' yaws and displacements at the principal point may differ by issue 14's
        bound (``max_step_error_*``) plus ``precision_sigmas`` of the step's own standard errors. (The halves' fits of two blocks each leave one degree of freedom apiece,
        too few for a standard error of their own; the step's, from all the blocks, grows with
        their disagreement, so that a twice larger allowance let the change through.) On the
        vinyl corner with a 15 ms readout, the frame where the 90-degree turn starts had been
        reported 0.33 degrees off, ok: its halves turn 0.65 degrees apart, at a standard error of
        0.12; on steady turns they are 0.01-0.04 degrees apart."""
        cfg = self.config
        if not cfg.check_readout_motion or self.row_time_grid_s == 0.0 or m.moved is None:
            return ""
        src, dst = rolling_shutter_undone(
            m.centres,
            m.moved,
            interval_s=interval_s,
            row_time_s=self.row_time_grid_s,
            mid_row_px=self.mid_row_centred,
        )
        upper = m.centres[:, 1] < np.median(m.centres[:, 1])
        if min(int(upper.sum()), int((~upper).sum())) < 2:
            return ""
        scale = m.similarity_scale  # the blocks' image scale (a height change), whatever fit_image_scale
        (R1, t1), (R2, t2) = (rigid_fit(scale * src[rows], dst[rows]) for rows in (upper, ~upper))
        mm_per_px = self.grid_cam.gsd_mm_per_px(self.height_mm)
        return readout_change_problem(
            "the blocks",
            float(np.linalg.norm(t1 - t2)) * mm_per_px,
            abs(float(np.degrees(np.arctan2(R1[1, 0], R1[0, 0]) - np.arctan2(R2[1, 0], R2[0, 0])))),
            m.shift_sigma_mm,
            m.yaw_sigma_deg,
            cfg,
            cfg.bound_mm(m.step_mm),
        )

    def _shutter_undone(
        self, M: np.ndarray, points: np.ndarray, interval_s: float, turn_before: tuple[float, float] | None = None
    ) -> np.ndarray:
        """The step ``M`` (3x3, prev-centred grid px -> cur-centred grid px; ``M[:2, :2]`` = scale R)
        measured over ``interval_s`` by a rolling shutter, as global shutters at the two frame
        times see it (``M`` itself under a global shutter): the blocks' centres ``points`` (B, 2,
        prev-centred grid px), where the step was measured, carried by ``M`` and moved as
        :func:`floorvo.geometry.rolling_shutter_undone` moves a pair, and the rigid motion at
        ``M``'s image scale fitted to them. (The crop's corners, where ``M`` only extrapolates the
        readout's non-rigid distortion, left a turn's steps 0.2 % off on a synthetic arc: the
        centres 0.004 %.) ``turn_before``: the last step's turn and the time it spanned, where the
        frame before was measured (the turn rate changing from it: an S-curve's). The
        measurement, its checks and the next frame's prediction stay in the frames' own pixels,
        where the readout's shear is the same from frame to frame; only the step reported is the
        global shutter's."""
        if self.row_time_grid_s == 0.0:
            return M
        src, dst = rolling_shutter_undone(
            points,
            points @ M[:2, :2].T + M[:2, 2],
            interval_s=interval_s,
            row_time_s=self.row_time_grid_s,
            mid_row_px=self.mid_row_centred,
            turn_before=turn_before,
        )
        scale = float(np.sqrt(abs(np.linalg.det(M[:2, :2]))))
        R, t = rigid_fit(scale * src, dst)
        out = np.eye(3)
        out[:2, :2], out[:2, 2] = scale * R, t
        return out

    @staticmethod
    def _interval_s(state: _State, frame: Frame) -> float:
        """The mean frame interval (s) over the step from the reference frame to ``frame``, which
        spans ``state.n_lost + 1`` frames; 0.0 where the times give none (not increasing)."""
        dt_s = (float(frame.timestamp_s) - state.t_ref_s) / (state.n_lost + 1)
        return dt_s if dt_s > 0.0 and math.isfinite(dt_s) else 0.0

    @staticmethod
    def _prediction(state: _State, t_s: float) -> np.ndarray:
        """The motion (3x3, centred px) from the reference frame predicted for the frame at time
        ``t_s`` (s): ``M_pred``, made for ``pred_span_s`` after the reference, at constant velocity
        over the time the frame is really after it (:func:`_per_frame`). A frame after a gap in the
        times (frames the camera dropped) is predicted as far as the robot went in that time: at
        240 mm/s, 3 and 5 intervals lost the track with the prediction of one interval (the blocks
        disagreed by 10-17 px). Frames at a steady rate (a render's, i / fps) take it as it is."""
        return motion_over_time(state.M_pred, state.pred_span_s, t_s - state.t_ref_s).copy()

    def _height_changed(self, state: _State, m: _Measured, *, measured: bool = True) -> bool:
        """The image scale ``m.scale`` (``fit_image_scale``) tells a change of the camera height.

        On its own: it differs from 1 by more than ``image_scale_min_sigmas`` of its standard
        errors, at that many standard errors' confidence for the few blocks they are estimated
        from (:func:`floorvo.geometry.t_sigmas`: 9.2 of them for four blocks along one axis, whose
        fit leaves 3 degrees of freedom). A scale within them is no measured change, and the
        height is kept: on a level run the four blocks' scale, fitted each frame, read changes
        that were not there (each then held for the rest of the run), and their standard
        error, added to the step's, lost steps whose translation was precise (BENCHMARKS.md,
        "phase-corr: the camera height only where the image scale shows it").

        Or with the frames before it: the scales of the last ``image_scale_window`` measured
        frames (this one included; ``measured``: the step passed the gross checks, else it
        joins no window) scatter about 1 by more than their standard errors allow,
        ``sum (s_i - 1)^2 / sum sigma_i^2`` beyond :func:`floorvo.geometry.f_sigmas` at the same
        confidence (4.26 for eight frames of four blocks, where one frame needs 85): the rig is
        bouncing, and each frame's scale is the height change, some of them too small to show
        on their own (the half-size bounces: the gate above followed 21-22 of 40 frames in
        phase-corr-fast, 34-36 in phase-corr; full size 34-38; the scales of level runs scatter
        by 0.15-2.0 of their standard errors, of bounces by 9-45).
        """
        dev2, var = (m.scale - 1.0) ** 2, m.scale_sigma**2
        limits = m.layout.image_scale_window_limits
        if not measured:
            return not dev2 <= limits[0] * var
        window = state.scale_window
        window.append((dev2, var))
        while len(window) > len(limits):
            window.popleft()
        if not dev2 <= limits[0] * var:
            return True
        n = len(window)
        if n < 2:
            return False
        sum_dev2, sum_var = (float(np.sum(a)) for a in zip(*window))
        return not sum_dev2 <= limits[n - 1] * sum_var

    def _height_signal_problem(self, m: _Measured, h_prev: float, h_meas: float | None) -> str:
        """Why the frame's measured height ``h_meas`` (mm; None: none) cannot convert the step
        ``m`` ('' if it can): the picture contradicts it. The picture scales by ``h_prev /
        h_cur`` about the principal point, so the blocks' similarity scale ``s`` (standard error
        ``sigma``, relative) gives the height ``h_prev / s``. The reading is contradicted where it
        lies further from that than the blocks can misread it plus issue 14's bound for the step
        (which carries the height change, and is converted at that height). What the blocks can
        misread: the one-frame limit of the image-scale test (:meth:`_height_changed`: 9.2
        standard errors for four blocks), and at least :data:`HEIGHT_SIGNAL_MISREAD` of the
        height, since the blocks' scale errs beyond its standard errors on some floors (on the
        polished and ceramic vibrations by up to 0.6 % at 17 of them). A reading of 300 mm in a
        level run at 100 mm, or one creeping 5 mm a frame, was taken as it was and the steps
        reported ok that far off (akaze's fits, holding the pairs to the scale the heights give,
        lost them)."""
        if h_meas is None or self.config.precision_sigmas <= 0.0:
            return ""
        rise = self._picture_rise(m, h_prev)
        if rise is None:
            return ""
        s, sig_h_mm = m.similarity_scale, rise[1]
        h_img = h_prev / s
        misread_mm = max(m.layout.one_frame_sigmas * sig_h_mm, HEIGHT_SIGNAL_MISREAD * h_prev)
        off_mm = abs(h_meas - h_img) - misread_mm
        bound_mm = self.config.bound_mm(m.step_mm)
        if off_mm > bound_mm:
            return (
                f"height signal disagrees with the picture: it reads {h_meas:.3f} mm, the blocks' image scale "
                f"{s:.5f} gives {h_img:.3f} +/- {sig_h_mm:.3f} mm, beyond what the blocks may misread "
                f"({misread_mm:.3f} mm) {off_mm:.3f} mm > bound {bound_mm:.3f} mm"
            )
        return ""

    @staticmethod
    def _picture_rise(m: _Measured, h_prev: float) -> tuple[float, float] | None:
        """The camera's rise over the step ``m`` (mm) that the blocks' similarity scale ``s``
        gives, and its standard error (mm; from the scale's relative one, ``sigma``): the
        picture scales by ``h_prev / h_cur`` about the principal point, so ``h_cur = h_prev / s``
        and the rise is ``h_prev / s - h_prev``, its standard error ``h_prev sigma / s^2``. None
        where the fit gave no scale."""
        s, sig = m.similarity_scale, m.similarity_sigma
        if not (s > 0.0 and np.isfinite(sig)):
            return None
        return h_prev / s - h_prev, h_prev * sig / s**2

    def _height_change_problem(self, state: _State, m: _Measured, h_prev: float, h_signal: float | None) -> str:
        """Why a step at a kept camera height cannot be reported ('' if it can, or if the check
        does not apply): with ``fit_image_scale = false`` and no height change measured (two
        readings), the step keeps the reference's height ``h_prev`` (mm), and the camera's height
        changed by more than the step may be off. The blocks' similarity scale ``s`` reads the
        rise ``h_prev / s - h_prev`` (its standard error ``h_prev sigma / s^2``); the step is lost
        where that rise, less the one-frame limit of the image-scale test's standard errors
        (:meth:`_height_changed`: 9.2 for four blocks) and divided by the share of a change the
        picture reads under the rig's lights (:data:`floorvo.estimators.base.PICTURE_HEIGHT_READ_SHARE`),
        exceeds issue 14's bound. As the paper's rigid AKAZE checks its steps
        (``check_height_change``); on the motion suite's full-size 2 mm bounces phase-corr so had
        reported 35-37 of 40 steps ok and wrong, each up to 0.8 mm off along the optical axis, and
        with a range sensor's dropouts the frames without a reading likewise (BENCHMARKS.md,
        "phase-corr at the rig height")."""
        if self.config.fit_image_scale or self.config.precision_sigmas <= 0.0:
            return ""
        if h_signal is not None and state.height_read:
            return ""  # the readings give the change
        rise = self._picture_rise(m, h_prev)
        if rise is None:
            return ""
        s = m.similarity_scale
        rise_mm, sig_mm = rise
        k = m.layout.one_frame_sigmas
        least_mm = (abs(rise_mm) - k * sig_mm) / PICTURE_HEIGHT_READ_SHARE
        bound_mm = self.config.bound_mm(m.step_mm)
        if least_mm > bound_mm:
            return (
                f"height change not measured: the blocks' image scale {s:.5f} reads {rise_mm:+.3f} mm of camera "
                f"height (standard error {sig_mm:.3f}), the step keeps the height: {abs(rise_mm):.3f} mm less "
                f"{k:.1f} standard errors, over the {PICTURE_HEIGHT_READ_SHARE:g} of a change the picture reads: "
                f"{least_mm:.3f} mm > bound {bound_mm:.3f} mm (fit_image_scale or a height signal measures it)"
            )
        return ""

    def _height_drift_problem(self, state: _State, m: _Measured, h_prev: float, h_signal: float | None) -> str:
        """Why the step ``m``'s height change, two readings' difference (the reference's
        ``h_prev`` and the frame's ``h_signal``, mm), is not to be reported ('' where it may be): the
        height signal drifts from the blocks' image scale over the last steps
        (:func:`floorvo.estimators.base.height_signal_drift_problem`; the picture's rise is
        ``h_prev / s - h_prev``, its standard error from the scale's, as in
        :meth:`_height_signal_problem`). Only a step whose height change the readings give joins
        the record."""
        rise = self._picture_rise(m, h_prev)
        if h_signal is None or not state.height_read or rise is None:
            return ""
        return height_signal_drift_problem(
            state.height_drift,
            h_signal - h_prev,
            *rise,
            self.config.bound_mm(m.step_mm),
            h_prev,
            sigmas=self.config.precision_sigmas,
        )

    def _failed(self, m: _Measured) -> bool:
        """The measurement failed (:meth:`_gross_problem`): worth measuring again from another start.
        A step that is only imprecise is not measured again from a worse start."""
        return bool(self._gross_problem(m))

    def _gross_problem(self, m: _Measured) -> str:
        """Why a measurement failed ('' when it did not): a weak peak, blocks that disagree, an
        imprecise yaw, a rotating warp that did not converge (:meth:`_gross_check`, made once
        per measurement and kept in ``m.gross``)."""
        if m.gross is None:
            m.gross = self._gross_check(m)
        return m.gross

    def _gross_check(self, m: _Measured) -> str:
        """:meth:`_gross_problem`'s verdict on ``m``, made."""
        cfg = self.config
        if m.second_motion is not None:
            n, off_px = m.second_motion
            return f"two motions: the {n} blocks left out agree on another, {off_px:.1f} px from the rest"
        if m.min_peak < cfg.min_peak:
            return f"weak correlation peak {m.min_peak:.3f}"
        if m.resid_px > self._max_residual_px(m.step_mm):
            return f"blocks disagree by {m.resid_px:.2f} px"
        if m.block_rms_px > cfg.block_precision_px and m.yaw_sigma_deg > cfg.max_yaw_sigma_deg:
            return (
                f"imprecise yaw: blocks disagree by {m.block_rms_px:.2f} px RMS, "
                f"standard error {m.yaw_sigma_deg:.2f} deg > {cfg.max_yaw_sigma_deg:g}"
            )
        if m.unconverged_px > cfg.converged_px + m.resid_px:
            return (
                f"rotating warp not converged: the last round moved the blocks {m.unconverged_px:.2f} px "
                f"> {cfg.converged_px:g} + their disagreement {m.resid_px:.2f}"
            )
        return ""

    def _max_residual_px(self, step_mm: float) -> float:
        """The largest disagreement (frame px) of the blocks with their rigid fit for a step of
        ``step_mm``: ``max_residual_px``, or ``max_residual_bound_fraction`` of issue 14's bound
        for the step (``max_step_error_*``) in px where that is more. The check is for blocks
        whose correlation found another peak (10-30 px off); blocks within a fraction of the
        bound of each other do not show a wrong step, and the precision checks hold the step to
        the bound. At 30 mm/frame over the wood floor, whose grain runs along the motion, the
        blocks that agreed disagreed by 1.3-2.2 px and the steps were 0.03-0.12 mm off."""
        cfg = self.config
        mm_per_frame_px = self.grid_cam.gsd_mm_per_px(self.height_mm) / cfg.downscale
        return max(cfg.max_residual_px, cfg.max_residual_bound_fraction * cfg.bound_mm(step_mm) / mm_per_frame_px)

    def _agreeing(self, centres: np.ndarray, shifts: np.ndarray, max_outliers: int) -> np.ndarray | None:
        """The indices of the blocks kept (None: all): up to ``max_outliers`` blocks left out,
        one at a time, the one furthest from the rigid fit of those left, while the largest
        disagreement is beyond ``max_residual_px`` (frame px; the gross check's measure,
        :func:`_rigid_residuals`; ``centres``, ``shifts``: (B, 2) grid px).

        The tolerance is ``max_residual_px`` itself, not the gross check's wider one for a long
        step (:meth:`_max_residual_px`): on the full-size 30 mm/frame wood run the blocks kept
        up to that (8-9 of 9 instead of 7) read the steps 0.04-0.08 mm longer."""
        if max_outliers <= 0:
            return None
        keep = np.arange(len(centres))
        k = self.config.downscale
        for _ in range(max_outliers):
            _, _, r = _rigid_residuals(centres[keep], shifts[keep])
            if r.max() * k <= self.config.max_residual_px:
                break
            keep = np.delete(keep, int(np.argmax(r)))
        return None if len(keep) == len(centres) else keep

    def _second_motion(
        self, centres: np.ndarray, shifts: np.ndarray, keep: np.ndarray, R: np.ndarray, t: np.ndarray, step_mm: float
    ) -> tuple[int, float] | None:
        """Whether the blocks :meth:`_agreeing` left out agree on one other motion: more than
        :data:`SECOND_MOTION_MIN_BLOCKS` of them, each within ``max_residual_px`` of their mean
        residual from the kept blocks' rigid fit ``R`` (2, 2), ``t`` (2,) (:func:`_rigid_residuals`),
        that mean further from it along x or y than the gross check's tolerance for a step of
        ``step_mm`` (:meth:`_max_residual_px`; frame px; ``centres``, ``shifts``: (B, 2) grid px of
        all the layout's blocks; ``keep``: the indices kept). Then a third of the view or more moves otherwise than the
        rest, and which is the floor is not known: ``(their number, that motion's distance from the
        kept fit, px)``, else None. Two blocks may agree so (something fixed to the rig in a corner
        of the view) and are left out as before; blocks left out for a wrong peak each (a tile's
        bare glaze) do not agree."""
        dropped = np.setdiff1d(np.arange(len(centres)), keep)
        if len(dropped) <= SECOND_MOTION_MIN_BLOCKS:
            return None
        k = self.config.downscale
        resid = (centres[dropped] @ R.T + t - centres[dropped] - shifts[dropped]) * k
        mean = resid.mean(axis=0)
        if float(np.abs(resid - mean).max()) > self.config.max_residual_px:
            return None
        if not float(np.abs(mean).max()) > self._max_residual_px(step_mm):
            return None
        return len(dropped), float(np.hypot(*mean))

    def _block_motion(
        self,
        centres: np.ndarray,
        shifts: np.ndarray,
        information: np.ndarray,
        rotating: bool,
        equal: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """The rigid motion ``(R (2, 2), t (2,))`` that takes the block ``centres`` (B, 2) grid px to
        ``centres + shifts``: every coordinate alike (the fit of :func:`_rigid_residuals`;
        ``equal``: that fit when already made), or, with ``weigh_blocks_by_texture`` where the
        blocks see a grain and the warp does not rotate, each block's residual weighted by the
        shape of its shift's ``information`` (B, 2, 2, :func:`_phase_slope`), scaled to the same
        trace for every block (:func:`floorvo.geometry.rigid_fit_2d_information`).

        On the wood floor whose grain runs along the motion, at 30 mm/frame, the blocks'
        information along x is 1-3 % of that along y, and their x shifts disagreed by up to 3.4 px
        where their y shifts agreed within 0.1: fitted alike, the x shifts of the rows set the yaw
        (0.096 degrees standard deviation a step); weighted, it comes from the y shifts (0.005).
        Why the shape only: the information's size follows the block's contrast, but what limits
        a block here is how the shading changed between the frames, which the contrast does not
        tell; its shape tells which way the block sees the motion.

        Weighted only where both of these hold (else alike):
        - the sum of the blocks' shapes has a coherence (``(l1 - l2) / (l1 + l2)``, its
          eigenvalues) of at least ``texture_weight_min_coherence``: the blocks see one
          direction, a grain. On the ceramic tile their strong directions differ (the grout's
          lines and corners), and weighted so a 15-degree two-frame step of the corner came out
          0.39 degrees off where the checks passed it;
        - the warp does not rotate (``rotating``): on a wood S-curve the weighted fit read the
          turns 1.3 % short (phase-corr-fast), against 0.2 % alike.

        Off by default: on wood runs at 4 mm/frame with the grain at 60 or 120 degrees to the
        motion, or bouncing, the weighted yaw was less noisy but biased (0.003-0.007 degrees a
        step, its sign the grain's side: the shading's pattern across the frame, which an oblique
        weighting turns into yaw), and their drift grew by 0.02-0.09 points; at 20-30 mm/frame
        along the grain it fell by up to 0.38 (BENCHMARKS.md, "phase-corr on a grained floor: the
        blocks weighted by what they see")."""
        R, t = equal if equal is not None else similarity_fit_2d(centres, centres + shifts, with_scale=False)[:2]
        cfg = self.config
        if not cfg.weigh_blocks_by_texture or rotating:
            return R, t
        tr = information[:, 0, 0] + information[:, 1, 1]
        shape = information * (2.0 / np.maximum(tr, 1e-300))[:, None, None]
        sxx, syy, sxy = (float(v) for v in (shape[:, 0, 0].sum(), shape[:, 1, 1].sum(), shape[:, 0, 1].sum()))
        if not float(np.hypot(sxx - syy, 2.0 * sxy)) >= cfg.texture_weight_min_coherence * (sxx + syy):
            return R, t
        try:
            return rigid_fit_2d_information(centres, centres + shifts, shape)
        except ValueError:  # blocks without texture (no information): their shifts alike
            return R, t

    def _imprecise(self, sigma_mm: float, step_mm: float) -> bool:
        """``precision_sigmas`` standard errors ``sigma_mm`` of a step of ``step_mm`` exceed issue
        14's bound for it (``max_step_error_*``); never with ``precision_sigmas = 0``."""
        cfg = self.config
        return cfg.precision_sigmas > 0.0 and not cfg.precision_sigmas * sigma_mm <= cfg.bound_mm(step_mm)

    def _precision_problem(self, m: _Measured, height_sigma_mm: float = 0.0) -> str:
        """Why a measured step is too imprecise to report ('' when it is not): its translation's
        standard error from the blocks' disagreement, with that of the height change the image
        scale gives (``height_sigma_mm``, ``fit_image_scale``: ``h_prev sigma_scale / scale^2``),
        ``precision_sigmas`` of them, beyond issue 14's bound (``max_step_error_*``); and, where
        the blocks lie too close together for their own precision to bound the yaw
        (:attr:`yaw_floor_deg` > ``max_yaw_sigma_deg``: a small ``crop_px``), the yaw's standard
        error (the same similarity fit), ``precision_sigmas`` of them, beyond the bound's
        ``max_step_error_deg``. With ``crop_px = 33`` (16 px blocks) on the vinyl run, 12 of 17
        steps reported ok were 0.36-2.0 degrees off at standard errors of 0.11-0.79 degrees."""
        cfg = self.config
        if cfg.precision_sigmas <= 0.0:
            return ""
        sigma_mm = float(np.hypot(m.shift_sigma_mm, height_sigma_mm))
        if self._imprecise(sigma_mm, m.step_mm):
            what = "its translation" if not height_sigma_mm else "its translation and height change"
            return (
                f"imprecise step: {cfg.precision_sigmas:g} standard errors of {what} are "
                f"{cfg.precision_sigmas * sigma_mm:.3f} mm (bound {cfg.bound_mm(m.step_mm):.3f} mm)"
            )
        if not m.layout.bounds_yaw and not cfg.precision_sigmas * m.yaw_sigma_deg <= cfg.max_step_error_deg:
            return (
                f"imprecise step: {cfg.precision_sigmas:g} standard errors of its yaw are "
                f"{cfg.precision_sigmas * m.yaw_sigma_deg:.2f} deg (bound {cfg.max_step_error_deg:g} deg)"
            )
        return ""

    def _measure(self, state: _State, cur: np.ndarray, M: np.ndarray, layout: _Layout | None = None) -> _Measured:
        """Refine the image motion ``M`` (3x3, prev-centred px -> cur-centred px of the grid) from a start value.

        ``iterations`` warp-and-measure rounds, fewer when the whole-pixel warp repeats (a
        rotating warp's first round: when the next one's would move no block centre by more
        than ``converged_px`` and the blocks agree, :meth:`_settled_px`); a
        rotating warp (yaw above ``exact_yaw_max_deg``) takes up to ``MAX_EXTRA_ROUNDS`` more
        while the estimate still moves at a block centre by more than ``converged_px`` plus the
        blocks' own disagreement (their largest residual: what a round can resolve): a
        7.6-degree turn measured from a straight prediction moved 1.2 px in its second round,
        and two rounds reported it ok and 0.15 mm off.
        The residuals and the last round's move are returned in the frame's pixels, whatever the grid.
        ``layout``: the blocks (default: ``grid``'s); a layout that may leave blocks out
        (``robust_grid``) keeps those that agree (:meth:`_agreeing`) in each round.
        """
        assert state.prev_crop is not None and state.prev_blocks is not None  # set by the first frame
        cfg = self.config
        mm_per_grid_px = self.grid_cam.gsd_mm_per_px(self.height_mm)
        M = M.copy()
        if not M[:2, 2].any():
            # No prediction of the translation (none at all, or a rotation guess): a
            # whole-crop translation first, for large motions.
            w = self._warp_into_prev(cur, M)
            d, _ = block_shift(self.sp_crop.spectrum(state.prev_crop), self.sp_crop.spectrum(w), self.sp_crop)
            M = M @ _translation(d)
        # A step that carries the crop out of the current frame's region: the previous frame's
        # crop moves back by half the step (within its region), so both frames see the blocks.
        off = self._crop_offset(M)
        lay = layout or self.layout
        centres = lay.centres
        if off != (0, 0):
            assert state.prev is not None
            ox, oy = self.x0 - self.rx0 + off[0], self.y0 - self.ry0 + off[1]
            prev_blocks = lay.blocks(state.prev[oy : oy + self.crop, ox : ox + self.crop])
            centres = lay.centres + np.array(off, dtype=float)
        else:
            prev_blocks = state.prev_blocks if lay is self.layout else lay.blocks(state.prev_crop)
        all_centres, all_prev_blocks, keep = centres, prev_blocks, None
        min_peak, resid = 0.0, np.inf
        exact_yaw = np.radians(cfg.exact_yaw_max_deg)
        moved_px, M_last = np.inf, None  # how far the last round moved the estimate at the blocks
        for rnd in range(1, cfg.iterations + MAX_EXTRA_ROUNDS + 1):
            # Warp by whole pixels only: OpenCV quantises interpolated sample positions to
            # 1/32 px, which biased the measured shift by ~0.03 px per frame; the phase-slope
            # fit measures the whole fractional part instead (exact for a translation).
            M[:2, 2] = np.round(M[:2, 2])
            rotating = abs(np.arctan2(M[1, 0], M[0, 0])) > exact_yaw
            if not rotating:
                # The same quantisation in a rotating warp biases yaw (+17 % at 0.2 deg/frame):
                # small rotations are left to the block shifts, which measure them themselves.
                M[:2, :2] = np.eye(2)
            W = M.copy()  # the whole-pixel warp of this round
            w = self._warp_into_prev(cur, M, off)
            shifts, peaks, info = block_shifts(all_prev_blocks, lay.blocks(w), lay.sp)
            keep = self._agreeing(all_centres, shifts, lay.max_outliers)
            all_shifts = shifts
            if keep is not None:
                centres, shifts, peaks, info, prev_blocks = (
                    all_centres[keep],
                    shifts[keep],
                    peaks[keep],
                    info[keep],
                    all_prev_blocks[keep],
                )
            else:
                centres, prev_blocks = all_centres, all_prev_blocks
            # E maps block centres c to c + d (warped(p) = prev(E^-1 p)); M_true = M E.
            # The rigid fit (the blocks' disagreement) and the similarity fit (for the
            # precision below): the least-squares rotation does not depend on the scale
            # (Umeyama), the same in both. The motion itself from the blocks weighted by their
            # texture (:meth:`_block_motion`).
            moved = centres + shifts
            Rs, ts, sc = similarity_fit_2d(centres, moved)
            R2, t2, block_resid = _rigid_residuals(centres, shifts)
            second = (
                None
                if keep is None
                else self._second_motion(
                    all_centres, all_shifts, keep, R2, t2, float(np.linalg.norm(M[:2, 2])) * mm_per_grid_px
                )
            )
            R2, t2 = self._block_motion(centres, shifts, info, rotating, (R2, t2))
            fit = _BlockFit(centres, moved, Rs, ts, sc)
            E = np.eye(3)
            E[:2, :2], E[:2, 2] = R2, t2
            resid = float(block_resid.max())
            min_peak = float(peaks.min())
            M_new = M @ E
            # Converged when the next whole-pixel warp would be the same one.
            same_warp = (
                not rotating
                and np.array_equal(np.round(M_new[:2, 2]), M[:2, 2])
                and abs(np.arctan2(M_new[1, 0], M_new[0, 0])) <= exact_yaw
            )
            if M_last is not None:
                moved_px = float(
                    np.abs((centres @ (M_new[:2, :2] - M_last[:2, :2]).T) + M_new[:2, 2] - M_last[:2, 2]).max()
                )
            elif rotating:
                # The first round of a rotating warp (a steady turn, started from the last step's
                # motion): when the next round's warp would move no block centre by more than
                # converged_px it would measure the same, and is left out (:meth:`_settled_px`);
                # that move is reported as the last round's.
                settled_px = self._settled_px(W, M_new, fit, exact_yaw)
                if settled_px is not None:
                    M, M_last, moved_px = M_new, M_new.copy(), settled_px / cfg.downscale
                    break
            M, M_last = M_new, M_new.copy()
            if same_warp:
                moved_px = 0.0
                break
            if rnd >= cfg.iterations and (not rotating or moved_px <= cfg.converged_px + resid):
                break
        # The yaw's and the translation's precision from the last round's blocks; a similarity
        # fit, so that the scale change of a height bounce is not counted as disagreement.
        rms = fit.rms
        sig_px, sig_rad = fit.precision
        if not rotating:
            # A whole-pixel warp's last round measures the step itself (no rounds to converge);
            # one that leaves a residual is pulled toward the warp, which the warp on its other side
            # shows (:meth:`_warp_spread`).
            moved_px = 0.0
        # The residuals in the frame's pixels, whatever the grid (the config's tolerances are in them).
        k = cfg.downscale
        mm_per_px = self.grid_cam.gsd_mm_per_px(self.height_mm)
        return _Measured(
            M,
            min_peak,
            resid * k,
            rms * k,
            float(np.degrees(sig_rad)),
            moved_px * k,
            float(np.linalg.norm(M[:2, 2])) * mm_per_px,
            sig_px * mm_per_px,
            W,
            off,
            prev_blocks,
            centres,
            lay,
            *self._image_scale(centres, shifts, float(sc), float(sig_rad), lay),
            keep=keep,
            second_motion=second,
            similarity_scale=float(sc),
            similarity_sigma=float(sig_rad),
            moved=(centres + shifts) @ W[:2, :2].T + W[:2, 2],
        )

    def _settled_px(self, W: np.ndarray, M_new: np.ndarray, fit: _BlockFit, exact_yaw_rad: float) -> float | None:
        """After the first round of a rotating warp ``W`` (3x3, whole-pixel translation) measured
        ``M_new`` (3x3, prev-centred px -> cur-centred px of the grid) from the blocks ``fit``
        (their centres, where they moved, and the similarity fit of that): how far (frame px)
        the next round's warp would move a block centre from this round's, when that round can
        be left out, else None.

        It can when the next warp has the same whole-pixel translation and a rotation that moves
        no block centre by more than ``converged_px`` (the tolerance a round's move is held to),
        and the blocks agree: within ``block_precision_px`` RMS (their similarity fit), and
        closely enough that the translation passes the precision check
        (:meth:`_precision_problem`, its standard error without a height change's): the next
        round would see the step through the same warp, to within that, and measure the same. A
        residual rotation or a block disagreement beyond that takes the second round (the
        S-curves' turn rate changes 0.5-0.65 degrees a frame: their first round's estimate moved
        up to 0.17 frame px in the second; on the full-size polished spin two steps whose first
        round was imprecise were precise after the second). The step is then measured through
        the other whole-pixel warp as every step is (:meth:`_warp_spread`)."""
        cfg = self.config
        if round(M_new[0, 2]) != W[0, 2] or round(M_new[1, 2]) != W[1, 2]:  # np.round's halves to even too
            return None
        # The next round's warp: M_new with its translation rounded (the same), its rotation
        # dropped at or below exact_yaw_max_deg (a non-rotating warp: another warp).
        R_next = M_new[:2, :2] if abs(np.arctan2(M_new[1, 0], M_new[0, 0])) > exact_yaw_rad else np.eye(2)
        k = cfg.downscale
        change_px = float(np.abs(fit.centres @ (R_next - W[:2, :2]).T).max()) * k
        if change_px > cfg.converged_px:
            return None
        if fit.rms * k > cfg.block_precision_px:
            return None
        if cfg.precision_sigmas > 0.0:
            mm_per_px = self.grid_cam.gsd_mm_per_px(self.height_mm)
            sig_px, _ = fit.precision
            if self._imprecise(sig_px * mm_per_px, float(np.linalg.norm(M_new[:2, 2])) * mm_per_px):
                return None
        return change_px

    def _image_scale(
        self, centres: np.ndarray, shifts: np.ndarray, similarity_scale: float, similarity_sigma: float, layout: _Layout
    ) -> tuple[float, float]:
        """The current frame's image scale relative to the previous one's (``h_prev / h_cur``)
        and its standard error, from the block ``shifts`` (B, 2) px at their ``centres`` (B, 2)
        px (the warp is rigid, so the blocks see the whole scale): along ``image_scale_axis``
        (:func:`floorvo.geometry.axis_scales_fit`), or for ``both`` the similarity fit's that
        :meth:`_measure` made of the same shifts (``similarity_scale``, and ``similarity_sigma``:
        the rotation's standard error, :func:`floorvo.geometry.rigid_fit_precision`).
        ``(1, 0)`` without ``fit_image_scale``.

        Under the rig's grazing LEDs the picture moves unevenly across the bars (x): on the
        full-size vinyl run the x scale (and a similarity's) read a camera rising 0.01 mm a
        frame that did not; along the bars (y) it did not (BENCHMARKS.md, "phase-corr: the
        camera height from the image scale")."""
        cfg = self.config
        if not cfg.fit_image_scale:
            return 1.0, 0.0
        if cfg.image_scale_axis == "both":
            return similarity_scale, similarity_sigma
        scales, sigmas = axis_scales_fit(centres, shifts, layout.scale_design if centres is layout.centres else None)
        i = 0 if cfg.image_scale_axis == "x" else 1
        return float(scales[i]), float(sigmas[i])

    def _warp_spread(self, cur: np.ndarray, m: _Measured) -> tuple[float, float, bool, np.ndarray]:
        """The step ``m.M``, measured through the whole-pixel warp ``m.warp``, measured again
        through the whole-pixel warp on its other side (per axis, the nearest whole pixel
        beyond ``m.M`` seen from ``m.warp``; the neighbour of a warp that converged): the
        distance between the two estimates' translations at the principal point (mm, at the
        rig's height), between their yaws (deg), and whether the two warps bracket the step
        (each one's blocks see it toward the other), and the step measured through the other
        warp (3x3, as ``m.M``). Measured once per measurement (kept in ``m.spread``).

        The blocks' phase-slope fit measures what is left after the warp, and image content
        that does not move with the floor (under LEDs that ride with the camera: structure of
        the illumination, strongest in the lowest spatial frequencies) pulls each block's shift
        toward zero, i.e. the estimate toward the warp: on a half-size render of the tilted
        wood run binned 2 x 2 (54 px blocks) the blocks measured 0.55 px per pixel of residual,
        and a step half a pixel from its warp came out 0.2 mm off while the blocks agreed.
        Through two warps that bracket the step the two estimates lie either side of it, so
        their distance bounds the error of either; warps that do not bracket it (a step still
        1.5 px from its warp after the rounds: the prediction after a lost frame was twice the
        step) leave it unknown how far off it is. One more round through a warp per step that
        passed every other check."""
        if m.spread is not None:
            return m.spread
        d = m.M[:2, 2] - m.warp[:2, 2]
        W2 = m.warp.copy()
        W2[:2, 2] = np.where(d >= 0.0, np.floor(m.M[:2, 2]) + 1.0, np.ceil(m.M[:2, 2]) - 1.0)
        w = self._warp_into_prev(cur, W2, m.offset)
        # Through W2 each block sees the step where M puts it (M = W2 E: block centre c moves by
        # E c - c), so its whole pixels are known and the phase-slope fit measures the rest.
        E = np.linalg.solve(W2, m.M)
        d0 = np.round(m.centres @ E[:2, :2].T + E[:2, 2] - m.centres)
        lay = m.layout
        cur_blocks = lay.blocks(w, low_only=True)
        if m.keep is not None:
            cur_blocks = cur_blocks[m.keep]
        shifts, info = block_shifts_near(m.prev_blocks, cur_blocks, lay.sp, d0)
        R2, t2 = self._block_motion(m.centres, shifts, info, bool(W2[1, 0] != 0.0))
        E = np.eye(3)
        E[:2, :2], E[:2, 2] = R2, t2
        M2 = W2 @ E
        mm_per_px = self.grid_cam.gsd_mm_per_px(self.height_mm)
        spread_mm = float(np.linalg.norm(M2[:2, 2] - m.M[:2, 2])) * mm_per_px
        spread_deg = abs(float(np.degrees(np.arctan2(M2[1, 0], M2[0, 0]) - np.arctan2(m.M[1, 0], m.M[0, 0]))))
        bracketed = bool(np.all((M2[:2, 2] - W2[:2, 2]) * d <= 0.0))
        m.spread = (spread_mm, spread_deg, bracketed, M2)
        return m.spread

    def _spread_problem(self, cur: np.ndarray, m: _Measured) -> str:
        """Why the step ``m`` is not the same measured through the whole-pixel warp on its other
        side ('' if it is; :meth:`_warp_spread`), against issue 14's bound (``max_step_error_*``).
        The translation only: the height change ``fit_image_scale`` reads from the image scale
        is checked by its standard error (:meth:`_precision_problem`); through the other warp it
        moved by up to 0.18 mm on the full-size bounce where its error was under 0.09 mm."""
        cfg = self.config
        if not cfg.check_warp_spread:
            return ""
        spread_mm, spread_deg, bracketed, _ = self._warp_spread(cur, m)
        if not bracketed:
            return (
                "step not converged: measured again through the whole-pixel warp beyond it, the blocks "
                "still see it further on"
            )
        bound_mm = cfg.bound_mm(m.step_mm)
        if spread_mm > bound_mm or spread_deg > cfg.max_step_error_deg:
            return (
                f"step depends on the warp: through the whole-pixel warp on its other side it moves "
                f"{spread_mm:.3f} mm and {spread_deg:.2f} deg (bound {bound_mm:.3f} mm, {cfg.max_step_error_deg:g} deg)"
            )
        return ""

    def _crop_offset(self, M: np.ndarray) -> tuple[int, int]:
        """Where the previous frame's crop is measured (px from the centred one): (0, 0) when the
        motion ``M`` keeps the crop inside the current frame's region, else half the motion back,
        kept inside the previous frame's region."""
        moved = self.crop_corners_centred @ M[:2, :2].T + M[:2, 2] + self.centre_in_region  # region px
        lo, hi = moved.min(axis=0), moved.max(axis=0)
        if lo[0] >= 0 and lo[1] >= 0 and hi[0] <= self.rx1 - self.rx0 and hi[1] <= self.ry1 - self.ry0:
            return (0, 0)
        ox = int(np.clip(-round(float(M[0, 2]) / 2), self.rx0 - self.x0, self.rx1 - self.crop - self.x0))
        oy = int(np.clip(-round(float(M[1, 2]) / 2), self.ry0 - self.y0, self.ry1 - self.crop - self.y0))
        return (ox, oy)

    def _coarse(self, state: _State, cur: np.ndarray) -> np.ndarray | None:
        """A first guess of a large step: the translation of the whole normalised region (3x3, or None).

        The crop's own correlation wraps beyond half its side (192 px at full size; a 30 mm
        step is 243 px); the region (crop and margin, 640 px wide at full size) sees up to half
        of its width. ``cv2.phaseCorrelate`` is only a first guess (0.3-0.5 px off): the blocks
        measure the step."""
        assert state.prev is not None
        win = cv2.createHanningWindow((cur.shape[1], cur.shape[0]), cv2.CV_32F)
        (dx, dy), response = cv2.phaseCorrelate(state.prev.astype(np.float32), cur.astype(np.float32), win)
        if not np.isfinite(dx) or not np.isfinite(dy) or response <= 0.0:
            return None
        return _translation(np.array([dx, dy]))

    def _coarse_rotation(self, state: _State, cur: np.ndarray) -> np.ndarray | None:
        """A first guess of a sharp turn: the rotation (3x3, no translation) between the previous
        and the current crop, from the phase correlation of their log-polar magnitude spectra
        (:func:`_log_polar_magnitude`), or None. The spectrum is symmetric, so the angle is known
        modulo 180 degrees: the one within +-90 is taken (a floor robot turns less per frame).
        Only a first guess (about 0.1 degrees off): the blocks measure the step, and their
        checks decide whether it is kept."""
        assert state.prev_crop is not None
        n_angles = 720
        crop = cur[
            self.y0 - self.ry0 : self.y0 - self.ry0 + self.crop, self.x0 - self.rx0 : self.x0 - self.rx0 + self.crop
        ]
        a = _log_polar_magnitude(state.prev_crop, self.sp_crop, n_angles)
        b = _log_polar_magnitude(crop, self.sp_crop, n_angles)
        (_, d_rows), response = cv2.phaseCorrelate(a, b)
        if not np.isfinite(d_rows) or response <= 0.0:
            return None
        angle_deg = (d_rows * 360.0 / n_angles + 90.0) % 180.0 - 90.0
        return _rotation(np.radians(angle_deg))


def _log_polar_magnitude(crop: np.ndarray, sp: _Spectral, n_angles: int) -> np.ndarray:
    """The windowed crop's magnitude spectrum (its origin centred, high frequencies
    emphasised, log-compressed) resampled on ``n_angles`` angles over 360 degrees (rows) and
    the radii ``n/16 .. n/4`` of an ``n x n`` crop (columns): float32 (n_angles, n/8).

    The magnitude spectrum does not change with a translation and turns with the image, so a
    rotation of the image is a shift of this map along its rows (Reddy & Chatterji, 1996)."""
    n = sp.n
    b = np.asarray(crop, dtype=np.float32)
    F = np.abs(sfft.fftshift(sfft.fft2((b - b.mean()) * sp.win)))
    k = sfft.fftshift(sfft.fftfreq(n)).astype(np.float32)
    radius = np.hypot(k[:, None], k[None, :])
    mag = np.log1p(F * np.minimum(4.0 * radius, 1.0)).astype(np.float32)
    polar = cv2.warpPolar(mag, (n // 2, n_angles), (n / 2, n / 2), n / 2, cv2.WARP_POLAR_LINEAR)
    return np.ascontiguousarray(polar[:, n // 16 : n // 4])


def _rotation(angle_rad: float) -> np.ndarray:
    """3x3 rotation of centred pixel coordinates by ``angle_rad`` (x right, y down)."""
    c, s = np.cos(angle_rad), np.sin(angle_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _predicted_yaw(yaws_rad: Sequence[float]) -> float:
    """The next frame's rotation (rad) from the last steps' rotations per frame ``yaws_rad``
    (oldest first): the last one turned on by its change from the one before where the two
    changes before it agree (a turn whose rate changes steadily, as on an S-curve: 0.5-0.8
    degrees a frame, which a constant-rate prediction leaves to a second round), else the last
    one (constant rate: a steady turn, or a change of rate that did not go on, a turn's start or
    end). They agree when both are of one sign and differ by at most half the larger."""
    last = yaws_rad[-1]
    if len(yaws_rad) < 3:
        return last
    a1, a2 = yaws_rad[-2] - yaws_rad[-3], last - yaws_rad[-2]
    if a1 * a2 > 0 and abs(a2 - a1) <= 0.5 * max(abs(a1), abs(a2)):
        return last + a2
    return last


def _binned(camera: CameraModel, k: int) -> CameraModel:
    """The pinhole ``camera`` with its pixels binned ``k`` x ``k`` from the top-left corner (a
    partial row or column at the far edges dropped): f' = f / k, c' = (c + 0.5) / k - 0.5."""
    return CameraModel(
        camera.width_px // k,
        camera.height_px // k,
        camera.fx_px / k,
        camera.fy_px / k,
        (camera.cx_px + 0.5) / k - 0.5,
        (camera.cy_px + 0.5) / k - 0.5,
    )


def _rigid_residuals(centres: np.ndarray, shifts: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The rigid fit (rotation R (2, 2), translation t (2,)) that takes the block ``centres`` (B, 2)
    px to ``centres + shifts``, and each block's disagreement with it (B,): the larger of its two
    components' residuals, px. The one measure of blocks that disagree: the gross check
    (``max_residual_px``) holds the largest to a tolerance, and a finer layout leaves out the
    largest while it is beyond it (:meth:`PhaseCorr._agreeing`)."""
    R, t, _ = similarity_fit_2d(centres, centres + shifts, with_scale=False)
    return R, t, np.abs(centres @ R.T + t - centres - shifts).max(axis=1)


def _translation(d: np.ndarray) -> np.ndarray:
    T = np.eye(3)
    T[:2, 2] = d
    return T


#: The real-time preset (issue 14 item 5: phase-corr at least 10x faster than the fastest feature
#: estimator): the same method on the frames binned 2 x 2, a 192 px crop of four 96 px blocks
#: (the 384 px crop of the frame's own pixels), without the impulse check: the 2 x 2 binning already
#: averages a hot or dead pixel with three others (it tracked the renders with them); a rotating
#: warp converged within 0.2 frame px (``converged_px``), which is 0.1 px of the binned grid it
#: measures on, the default's tolerance in its own pixels (1.34 rounds a frame on the S-curves
#: instead of 1.48). Frames/s and drift against the default: BENCHMARKS.md, "Real time on one
#: core" and "phase-corr-fast: a binned pixel's tolerance".
PhaseCorrFastConfig = with_defaults(
    PhaseCorrConfig, "PhaseCorrFastConfig", downscale=2, impulse_ratio=0.0, converged_px=0.2
)


class PhaseCorrFast(PhaseCorr):
    name = "phase-corr-fast"
    description = "phase-corr's real-time preset: the same on the frames binned 2 x 2"
    Config = PhaseCorrFastConfig
