"""``homography-6dof``: 6-DoF motion of a mono camera from the floor plane's homography (issue 14 item 4).

A downward camera sees a flat floor, so two frames are related by the floor plane's
homography, ``x_cur ~ H x_prev`` in normalised image coordinates with
``H ~ R + t n^T / d`` (``p_cur = R p_prev + t``; ``n . p = d`` the floor in the previous
camera; Hartley & Zisserman, Multiple View Geometry, 2nd ed., Result 13.1). A planar
estimator reads only its affine part (a rotation and a shift); its perspective terms carry
the change of tilt (a change of 0.004 rad changes the image scale by about 0.5 px from one
edge of a 648-px frame to the other) and its scale the change of height. Given the floor
plane of the previous frame the decomposition is unique
(:func:`floorvo.geometry.plane_homography_motion`), and it gives the current frame's plane,
so the plane is carried from frame to frame, starting level at the rig's height (or the
frame's measured height, ``Frame.height_mm``).

Per frame: akaze-guided's keypoints, matching (paper 000's guided matching with its
brute-force fallback), section II-C filter and self-checks (:mod:`floorvo.estimators.akaze`),
with the image motion a homography instead of a rigid motion (prediction, filter, fit
residual and the check for a second motion all use it); then the homography of the matched pairs in normalised coordinates (the camera model's
distortion undone): RANSAC at ``homography_threshold_px`` and a least-squares refit on its
inliers, and its decomposition with the carried plane. Self-checks added (issue 14, lost
with the reason): too few homography inliers, their RMS reprojection error over
``max_homography_rms_px``, a plane tilted more than ``max_tilt_rad`` from the optical axis,
a height change over ``max_height_step_mm`` in one frame, interleaved blocks of the
pairs giving steps that disagree beyond the bound a step reported ok may have
(:meth:`HomographySixDof._blocks_problem`), and, on a rig whose own grazing lights ride
with the camera, a tilt change larger than the bound allows (:meth:`HomographySixDof._light_problem`).

**What it cannot see: a tilt under the rig's own grazing light.** The LEDs ride with the
camera 3 mm over the floor and light it along the camera's x axis (across the bars), so
the shading moves along that axis relative to the floor: on a level run the picture of a
bumpy floor moves faster than the floor by an amount that varies across the frame (the
relief's shadows, DESIGN.md), and a tilt raises one bar and lowers the other (0.7 mm for
0.01 rad at 70 mm from the centre), which moves the shading by up to 0.6 px on the
full-size tilt scene (under 0.1 px across the light). The homography's perspective terms
along that axis are of the same size (0.5 px across the frame for 0.004 rad), so the fit
reads the shading's motion as tilt: 1-2.2 mrad where there was none on the full-size
asphalt and concrete runs (`material_*`, level and straight), 1-2.7 mrad of error for
9.4 mrad of tilt change on `motion_tilt_depth_stereo_concrete`, a bias every block of the
pairs shares. The pairs' error against the true motion is all in their along-light
components, and the across-light components alone measure the tilt about the bars' axis
only to 2.8 mrad, too imprecise to check against. So under the rig's own lights the tilt
is not measured: a step whose tilt read would move the camera's footprint (camera height x
tilt) by more than issue 14's bound is lost ("tilt not observable": the light can make up
that much), and any other step keeps the plane's tilt (the decomposition's ``tilt=False``:
yaw, shift and height change from the homography, its perspective terms left out). On the
tilt scene every step is lost; on the level asphalt and concrete runs and the bounce scenes
the steps keep a level plane, as they should (BENCHMARKS.md). Without the rig's lights (a
synthetic warp, ``rig_lights = no``) the tilt is measured, to 1 mrad on an exact view.

**The demo scene** (324x247, about 280 pairs of 0.55 px RMS): the tilt is not observable
at that size. Measuring it (``rig_lights = no``) every step is lost ("imprecise homography":
the blocks' standard errors are 0.25-1.9 mm at 2.5 of them), and rightly: with that check off
too (``precision_sigmas = 0``) 17 of its 20 level steps are wrong by issue 14's bound
(0.14-0.56 mm; a tilt of 1-4 mrad read from the keypoints' noise, also given the true floor
plane). With the rig's lights (the default on a render) the tilt is not measured: 7 steps
ok, none wrong (0.01-0.08 mm off), 13 lost because the tilt read from the noise would move
the footprint beyond the bound. Use it at full size (BENCHMARKS.md, "6-DoF with depth and
stereo").

Mono tilt is a relative measurement: the tilt and height errors of the steps add up over a
run (a random walk), unlike orb-icp's and stereo-sift's, which fit the plane in every
frame. BENCHMARKS.md, "6-DoF with depth and stereo", gives its precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import MAX_SEED, param
from floorvo.estimators.akaze import AkazeConfig, _AkazeBase, _Fit, _State
from floorvo.estimators.base import HEIGHT_SIGNAL_MISREAD, Frame
from floorvo.geometry import block_homographies, plane_homography_motion

__all__ = ["HomographySixDof", "HomographySixDofConfig", "HEIGHT_SIGNAL_DISAGREES"]

#: How a step lost to a height reading that contradicts the carried floor plane is said
#: (:meth:`HomographySixDof._height_signal_problem`).
HEIGHT_SIGNAL_DISAGREES = "height signal disagrees with the floor plane"


@dataclass(frozen=True)
class HomographySixDofConfig(AkazeConfig):
    """akaze-guided's settings, and those of the homography: ``homography_threshold_px``
    (RANSAC), ``min_homography_inliers``, ``max_homography_rms_px``, ``max_tilt_rad`` and
    ``max_height_step_mm`` (the self-checks), ``seed`` (OpenCV's RNG before RANSAC),
    ``rig_lights`` (whether a tilt must keep within the bound, under the rig's own lights)."""

    homography_threshold_px: float = param(1.0, unit="px", gt=0.0, doc="RANSAC threshold of the floor homography")
    min_homography_inliers: int = param(12, min=8, doc="fewer pairs behind the homography: the frame is lost")
    max_homography_rms_px: float = param(
        0.8, unit="px", gt=0.0, doc="larger RMS reprojection error of the homography's inliers: lost"
    )
    max_tilt_rad: float = param(0.2, unit="rad", gt=0.0, doc="a floor plane tilted more than this: lost")
    max_height_step_mm: float = param(5.0, unit="mm", gt=0.0, doc="a larger height change in one frame: lost")
    seed: int = param(0, min=0, max=MAX_SEED, doc="seeds OpenCV's RNG before each RANSAC")
    rig_lights: str = param(
        "auto",
        choices=("auto", "yes", "no"),
        doc="whether grazing lights ride with the camera (auto: when the sequence records the rig's LEDs)",
    )
    use_attitude_signal: bool = param(
        False, doc="not used: homography-6dof carries its own floor plane, tilt included (its poses are 6-DoF)"
    )


class HomographySixDof(_AkazeBase):
    name = "homography-6dof"
    description = "mono 6-DoF: akaze-guided's matching, the floor homography decomposed with the carried floor plane"
    Config = HomographySixDofConfig
    guided = True
    fits_own_scale = True
    measures_footprint = False  # its poses are 6-DoF: an attitude signal must not turn them again
    levels_with_attitude = False  # it measures the tilt itself
    height_change_from_signal = False  # the homography's (the readings only hold the plane to them)
    config: HomographySixDofConfig

    def __init__(
        self,
        config: HomographySixDofConfig,
        camera: CameraModel,
        *,
        height_mm: float,
        flatfield: np.ndarray | None = None,
        led_positions_cam_mm: np.ndarray | None = None,
        height_noise_mm: float | None = None,
        **rig,
    ):
        super().__init__(config, camera, height_mm=height_mm, flatfield=flatfield, **rig)
        #: The standard deviation of each height reading, as the sequence states it (``rig.height_noise_mm``).
        self.height_noise_mm = float(height_noise_mm or 0.0)
        #: Grazing lights ride with the camera: from the sequence's LEDs (``rig_lights = auto``) or as told.
        self.lights_ride = (
            led_positions_cam_mm is not None if config.rig_lights == "auto" else config.rig_lights == "yes"
        )

    def _rigid_px(self, src: np.ndarray, dst: np.ndarray, scale: float | None = 1.0) -> np.ndarray:
        """The image motion model of this estimator: the least-squares homography (3, 3) of
        the pairs ``src -> dst`` (N, 2) px, prev-centred px -> cur-centred px (the rigid model
        of akaze-guided leaves a tilt's perspective terms as residual, 1.3 px RMS for 0.009 rad
        at 648x494, and the matches they move as a "second motion"). The homography fits the
        image scale itself; ``scale`` (the height signal's) is used only by the rigid fallback."""
        if len(src) < 4:
            return super()._rigid_px(src, dst, scale)
        H, _ = cv2.findHomography((src - self.centre).astype(np.float64), (dst - self.centre).astype(np.float64), 0)
        return super()._rigid_px(src, dst, scale) if H is None else H / H[2, 2]

    def _predict(self, M: np.ndarray, pts_px: np.ndarray) -> np.ndarray:
        """(N, 2) previous-frame px -> current-frame px through the image motion ``M`` (a homography here)."""
        p = (pts_px - self.centre) @ M[:2, :2].T + M[:2, 2]
        w = (pts_px - self.centre) @ M[2, :2] + M[2, 2]
        return p / w[:, None] + self.centre

    def _precision_problem(self, M: np.ndarray, s: np.ndarray, d: np.ndarray) -> str:
        """akaze-guided's precision check, on the residuals of the homography ``M`` (not of
        its affine part, which leaves a tilt's perspective terms as residual): the pairs are
        given to it as a pure shift by ``M``'s translation plus those residuals."""
        M_shift = np.eye(3)
        M_shift[:2, 2] = M[:2, 2]
        return super()._precision_problem(M_shift, s, s + M[:2, 2] + (d - self._predict(M, s)))

    def _blocks_problem(
        self, x_prev: np.ndarray, x_cur: np.ndarray, n_prev: np.ndarray, d_prev_mm: float, T_prev_cur: np.ndarray
    ) -> tuple[str, float]:
        """Why the step ``T_prev_cur`` (4, 4) mm of the inlier pairs ``x_prev -> x_cur`` (K, 2),
        normalised coordinates, is too imprecise to report ('' if it is not): the agreement of
        independent blocks (issue 14 item 2).

        The pairs are dealt into ``m`` interleaved blocks (4, or 2 when there are fewer than 16
        pairs), each block's least-squares homography decomposed with the same plane. Each block
        has ``m`` times the variance of the whole, so the whole step's standard error is the
        blocks' spread over ``sqrt(m)``: ``s_t = sqrt(sum_i |t_i - mean t|^2 / (m - 1)) / sqrt(m)``
        in translation (mm), and likewise from the angle between each block's rotation and the
        whole step's (yaw and tilt). ``precision_sigmas`` of them must lie within the bound a step
        reported ok may have (``max_step_error_mm`` + ``max_step_error_fraction`` of the step,
        ``max_step_error_deg``; issue 14's bound). Why: a tilt change reads from the homography's
        perspective terms, a few tenths of a pixel across the frame; where the pairs are imprecise
        (a half-size frame, few keypoints) the fit turns their noise into a tilt, and 0.01 rad of
        tilt at 100 mm is a 1 mm shift, while the residual and the other checks pass (on the
        half-size motion suite this estimator reported most steps ok and wrong before this check).
        """
        cfg = self.config
        if cfg.precision_sigmas <= 0.0 or len(x_prev) < 8:
            return "", 0.0
        blocks = block_homographies(x_prev, x_cur)
        if blocks is None:
            return "no floor homography on a block of the pairs (the agreement check)", 0.0
        m = len(blocks)
        t_mm, angle_rad = [], []
        for H_block in blocks:
            T_block = plane_homography_motion(H_block, n_prev, d_prev_mm, tilt=not self.lights_ride)[0]
            t_mm.append(T_block[:3, 3])
            cos_angle = (float(np.trace(T_prev_cur[:3, :3].T @ T_block[:3, :3])) - 1.0) / 2.0
            angle_rad.append(float(np.arccos(np.clip(cos_angle, -1.0, 1.0))))
        t = np.asarray(t_mm)
        k = cfg.precision_sigmas
        err_mm = k * float(np.sqrt(np.sum((t - t.mean(axis=0)) ** 2) / (m - 1) / m))
        err_deg = k * float(np.degrees(np.sqrt(np.sum(np.square(angle_rad)) / (m - 1) / m)))
        height_sd_mm = float(np.sqrt(np.sum((t[:, 2] - t[:, 2].mean()) ** 2) / (m - 1) / m))
        bound_mm = cfg.bound_mm(float(np.linalg.norm(T_prev_cur[:3, 3])))
        if err_mm > bound_mm or err_deg > cfg.max_step_error_deg:
            return (
                f"imprecise homography: {m} blocks of its pairs disagree, {k:g} standard errors are "
                f"{err_mm:.3f} mm and {err_deg:.2f} deg (bound {bound_mm:.3f} mm, {cfg.max_step_error_deg:g} deg)"
            ), height_sd_mm
        return "", height_sd_mm

    def _light_problem(self, T_prev_cur: np.ndarray, height_mm: float) -> str:
        """Why the tilt of the step ``T_prev_cur`` (4, 4) mm, taken at ``height_mm`` over the floor,
        cannot be reported under the rig's own lights ('' when it can, or when no grazing light
        rides with the camera).

        The step's tilt change is the angle between the two frames' optical axes. Under grazing
        LEDs that ride with the camera the homography reads tilt from the shading's motion along
        the light (module docstring: 1-2.7 mrad, also where there was none), and a tilt error at
        the camera height is a shift of the step. So the tilt must be one whose shift, if it were
        all the light's bias, keeps the step within the bound a step reported ok may have:
        ``height_mm * tilt <= max_step_error_mm + max_step_error_fraction * |t|`` (issue 14's
        bound; 1.3 mrad for a 4 mm step at 100 mm)."""
        cfg = self.config
        if not self.lights_ride:
            return ""
        tilt = float(np.arccos(np.clip(T_prev_cur[2, 2], -1.0, 1.0)))
        bound_mm = cfg.bound_mm(float(np.linalg.norm(T_prev_cur[:3, 3])))
        if height_mm * tilt > bound_mm:
            return (
                f"tilt not observable: the step tilts the camera {1e3 * tilt:.1f} mrad, {height_mm * tilt:.3f} mm at "
                f"the floor (bound {bound_mm:.3f} mm), and the rig's grazing lights move the shading as much"
            )
        return ""

    def _start_reference(self, state: _State, frame: Frame) -> None:
        """The first frame (or a restart) is level at the rig's or the measured height; a
        restart keeps the last plane's normal."""
        h_read = self._frame_height(frame)
        n = np.array([0.0, 0.0, 1.0]) if state.plane is None else state.plane[0]
        state.plane = (n, h_read or self.height_mm)
        # as uncertain as one reading (nothing known of the rig's height: none, as without a stated noise)
        state.plane_var_mm2 = self.height_noise_mm**2 if h_read is not None else 0.0

    def _motion(self, state: _State, fit: _Fit, frame: Frame) -> tuple[np.ndarray | None, str]:
        cfg = self.config
        assert state.plane is not None  # set on the first frame
        src, dst = fit.pairs_gs
        x_prev = self.pinhole.unproject(src, 1.0)[:, :2]  # the pairs are the pinhole's (_levelled)
        x_cur = self.pinhole.unproject(dst, 1.0)[:, :2]
        f = float(np.sqrt(self.camera.fx_px * self.camera.fy_px))
        if len(x_prev) < cfg.min_homography_inliers:
            return None, f"too few pairs for the floor homography ({len(x_prev)} < {cfg.min_homography_inliers})"
        cv2.setRNGSeed(cfg.seed)
        H, mask = cv2.findHomography(
            x_prev, x_cur, cv2.RANSAC, cfg.homography_threshold_px / f, maxIters=2000, confidence=0.999
        )
        if H is None or mask is None:
            return None, "RANSAC found no floor homography"
        inl = mask.ravel().astype(bool)
        if inl.sum() < cfg.min_homography_inliers:
            return None, f"too few pairs behind the floor homography ({int(inl.sum())} < {cfg.min_homography_inliers})"
        H, _ = cv2.findHomography(x_prev[inl], x_cur[inl], 0)  # least squares on the inliers (LM-refined)
        if H is None:
            return None, "no least-squares floor homography"
        p = np.column_stack([x_prev[inl], np.ones(int(inl.sum()))]) @ H.T
        rms_px = f * float(np.sqrt(np.mean(np.sum((p[:, :2] / p[:, 2:3] - x_cur[inl]) ** 2, axis=1))))
        if rms_px > cfg.max_homography_rms_px:
            return None, f"floor homography residual {rms_px:.2f} px RMS > {cfg.max_homography_rms_px:g}"
        n_prev, d_prev = state.plane
        T, n_cur, d_cur = plane_homography_motion(H, n_prev, d_prev)
        problem = self._light_problem(T, d_prev)
        if self.lights_ride and not problem:
            # The tilt read is within what the light can make up: the step keeps the plane's tilt.
            T, n_cur, d_cur = plane_homography_motion(H, n_prev, d_prev, tilt=False)
        blocks_problem, height_sd_mm = self._blocks_problem(x_prev[inl], x_cur[inl], n_prev, d_prev, T)
        problem = problem or blocks_problem
        if problem:
            return None, problem
        tilt = float(np.arccos(min(1.0, abs(n_cur[2]))))
        if tilt > cfg.max_tilt_rad:
            return None, f"floor plane tilted {tilt:.2f} rad from the optical axis > {cfg.max_tilt_rad:g}"
        if abs(d_cur - d_prev) > cfg.max_height_step_mm:
            return None, f"height change {d_cur - d_prev:+.2f} mm in one frame > {cfg.max_height_step_mm:g}"
        h_read = self._frame_height(frame)
        problem = self._height_signal_problem(T, d_cur, h_read, state.plane_var_mm2)
        if problem:
            return None, problem
        problem = self._plane_height_problem(T, d_prev, state.plane_var_mm2)
        if self.height_noise_mm > 0.0 and state.plane_var_mm2 > 0.0:
            # The readings of a stated noise refine the plane's height, a Kalman filter of d:
            # started from one reading the plane is as uncertain as one (1 mm: steps up to 2.5 %
            # long); carried to the next frame by the homography, with the variance of the step's
            # own height change (its blocks', :meth:`_blocks_problem`), and updated with each
            # reading. A step the plane is still too uncertain for is lost, and its reading, taken
            # back to the reference by the homography's ratio of the heights, refines the
            # reference's plane, from which the next frame is measured (at 1.5 mm of noise every
            # step was lost, the plane never refined).
            if problem and h_read is not None:
                ratio = d_prev / d_cur
                gain = state.plane_var_mm2 / (state.plane_var_mm2 + (self.height_noise_mm * ratio) ** 2)
                state.plane = (n_prev, d_prev + gain * (h_read * ratio - d_prev))
                state.plane_var_mm2 *= 1.0 - gain
            if problem:
                return None, problem
            var_mm2 = state.plane_var_mm2 + height_sd_mm**2
            if h_read is not None:
                gain = var_mm2 / (var_mm2 + self.height_noise_mm**2)
                d_cur += gain * (h_read - d_cur)
                var_mm2 *= 1.0 - gain
            state.plane_var_mm2 = var_mm2
        elif problem:
            return None, problem
        state.plane = (n_cur, d_cur)
        return T, ""

    def _plane_height_problem(self, T_prev_cur: np.ndarray, d_prev_mm: float, var_mm2: float) -> str:
        """Why the step ``T_prev_cur`` (4, 4) mm, scaled by the plane's height ``d_prev_mm`` of the
        variance ``var_mm2`` (the readings', :meth:`_motion`), is too uncertain to report ('' if it
        is not): the step's length is uncertain by ``|t| sqrt(var) / d``, and ``precision_sigmas``
        of that must stay within issue 14's bound for the step."""
        if var_mm2 <= 0.0 or self.config.precision_sigmas <= 0.0:
            return ""
        t_mm = float(np.linalg.norm(T_prev_cur[:3, 3]))
        err_mm = self.config.precision_sigmas * t_mm * float(np.sqrt(var_mm2)) / d_prev_mm
        bound_mm = self.config.bound_mm(t_mm)
        if err_mm > bound_mm:
            return (
                f"floor plane's height too uncertain for the step: {np.sqrt(var_mm2):.3f} mm from the height "
                f"readings, {self.config.precision_sigmas:g} x that x the step over the height = {err_mm:.3f} mm "
                f"> bound {bound_mm:.3f} mm"
            )
        return ""

    def _motion_problem_restarts(self, problem: str) -> bool:
        """A height reading that contradicts the carried plane restarts tracking at a reading
        (:meth:`_height_signal_problem`): measured from the older reference the plane stays wrong."""
        return problem.startswith(HEIGHT_SIGNAL_DISAGREES)

    def _height_signal_problem(
        self, T_prev_cur: np.ndarray, d_cur_mm: float, h_meas_mm: float | None, plane_var_mm2: float = 0.0
    ) -> str:
        """Why the step ``T_prev_cur`` (4, 4) mm, which puts the camera ``d_cur_mm`` over the
        carried floor plane, contradicts the frame's measured height ``h_meas_mm`` (mm; None:
        none) ('' if it does not). The homography gives only the ratio of the heights (``t / d``,
        Result 13.1), so the carried plane's height scales every step: a plane started from a
        wrong reading (300 mm at 100 mm) made every step 3x long, reported ok. A reading further
        from the carried height than the plane may stray (:data:`HEIGHT_SIGNAL_MISREAD` of the
        height, and ``precision_sigmas`` x the standard deviation of the reading less the plane's
        height, from the readings' stated noise and the plane's ``plane_var_mm2``) plus issue
        14's bound for the step loses the step; after ``restart_after_lost``
        such frames tracking restarts at the reading (:meth:`_start_reference`), so a plane started
        wrong is lost, not chained, and a single wrong reading costs its own frame."""
        if h_meas_mm is None:
            return ""
        # and the reading's own noise, where the sequence states it (a 0.3-1 mm sensor lost 3-14 of
        # 40 steps on single readings, and restarted the plane at them)
        misread_mm = HEIGHT_SIGNAL_MISREAD * h_meas_mm + self.config.precision_sigmas * float(
            np.sqrt(self.height_noise_mm**2 + plane_var_mm2)
        )
        off_mm = abs(h_meas_mm - d_cur_mm) - misread_mm
        bound_mm = self.config.bound_mm(float(np.linalg.norm(T_prev_cur[:3, 3])))
        if off_mm > bound_mm:
            return (
                f"{HEIGHT_SIGNAL_DISAGREES}: it reads {h_meas_mm:.3f} mm, the carried plane "
                f"is {d_cur_mm:.3f} mm below the camera, beyond what the plane may stray ({misread_mm:.3f} mm) "
                f"{off_mm:.3f} mm > bound {bound_mm:.3f} mm"
            )
        return ""
