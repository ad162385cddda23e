"""Run an estimator over a sequence folder and write RUN/trajectory.txt, timing.csv, result.json.

``trajectory.txt`` (TUM, metres, stamped with the sequence's frame times) starts at the
ground-truth pose of the first frame run (the nearest in time, within
:data:`~floorvo.sequence.GROUNDTRUTH_MAX_DIFF_S`; of the first frame the estimator starts on
where it loses the first ones) when there is one, at the identity
otherwise; frames where the track was lost are left out, so the gap shows in the file,
and the chain continues from the last good pose (the next frame is matched against the
last good one). The loop is :func:`floorvo.runner.run_sequence`, the files
:class:`floorvo.runfolder.RunFolder`.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import asdict, dataclass, replace

import cv2
import numpy as np

from floorvo.calibration import ScaleCalibration, calibration_use_problems
from floorvo.errors import ConfigError, FloorbenchError, shorten
from floorvo.estimators import estimator_source, get_estimator, make_config
from floorvo.geometry import MAX_POSITION_MM, T_from_se2, T_from_xyz_quat, position_problem
from floorvo.io import ensure_writable_dir
from floorvo.locking import locks_folder
from floorvo.runfolder import SEQUENCE_SHA256, remove_program_files, sequence_sha256
from floorvo.runner import RunResult, camera_height_mm, run_sequence
from floorvo.sequence import Sequence

__all__ = ["run_estimator", "RunResult", "build_estimator", "estimator_faults", "InitialPose"]

log = logging.getLogger(__name__)


@contextmanager
def estimator_faults(name: str, what: str) -> Iterator[None]:
    """Run ``what`` of estimator ``name``: an exception raised by the code of a plugin or a
    ``module:Class`` estimator (its ``__init__``, ``start`` or ``step``, or a step that breaks
    the protocol, :func:`floorvo.runner.run_frames`) becomes a one-line :class:`FloorbenchError`
    naming the estimator, where it came from and the exception (``-v`` logs its traceback), so
    ``floorvo run`` exits 1 in one line and the bench records a failed row and goes on, as for
    an external program that crashes; so does its ``sys.exit`` (a plugin's ``SystemExit`` ended
    ``floorvo run`` with the plugin's exit code and no word, and the whole bench with it) and an
    ``OSError`` raised through its own code (:func:`_raised_by`: a model file it cannot open).
    A built-in's exception is a bug of this project and keeps its traceback; user errors
    (:class:`FloorbenchError`) and the OS errors of reading the frames pass as they are."""
    try:
        yield
    except FloorbenchError:
        raise
    except (Exception, SystemExit) as exc:
        src = estimator_source(name)
        if src.kind == "built-in" or (isinstance(exc, OSError) and not _raised_by(get_estimator(name), exc)):
            raise
        log.debug("%s: %s raised", name, what, exc_info=True)
        raise FloorbenchError(
            f"estimator {name!r} ({src.kind} {src.detail}): {what} raised {type(exc).__name__}: {shorten(str(exc), 300)}"
        ) from exc


def _raised_by(cls: type, exc: BaseException) -> bool:
    """Whether ``exc`` went through code of the estimator class ``cls`` (a method of it or of a
    base class other than ``object``) on its way up: raised in it or in what it called."""
    codes = {
        getattr(v, "__code__", None)
        for klass in cls.__mro__[:-1]
        for v in vars(klass).values()
        for v in ((v.__func__,) if isinstance(v, (staticmethod, classmethod)) else (v,))
    }
    codes.discard(None)
    tb = exc.__traceback__
    while tb is not None:
        if tb.tb_frame.f_code in codes:
            return True
        tb = tb.tb_next
    return False


def require_opencv4(name: str) -> None:
    """Refuse, in one line, to build the built-in estimator ``name`` on OpenCV 5 or newer.

    OpenCV 5.0 moved AKAZE (with KAZE and BRISK) out of the main package into contrib's
    ``xfeatures2d``: on it the AKAZE estimators failed with ``AttributeError: module 'cv2' has
    no attribute 'AKAZE'`` (seen on a machine whose image had OpenCV 5.0.0). The project pins
    ``opencv-python-headless>=4.10,<5``; a plugin's estimator may bring its own needs."""
    if estimator_source(name).kind == "built-in" and int(str(cv2.__version__).split(".")[0]) >= 5:
        raise FloorbenchError(
            f"estimator {name!r} needs OpenCV 4 (opencv-python-headless>=4.10,<5), and this Python has OpenCV "
            f"{cv2.__version__}, which moved AKAZE to contrib: pip install 'opencv-python-headless>=4.10,<5'"
        )


def build_estimator(seq: Sequence, name: str, overrides: Mapping[str, str] | None = None):
    """Instantiate estimator ``name`` for ``seq``; refuses a sequence lacking what it requires, and a
    built-in estimator on OpenCV 5 (:func:`require_opencv4`)."""
    cls = get_estimator(name)
    require_opencv4(name)
    cfg = make_config(name, overrides)
    lacking = seq.lacks(getattr(cls, "requires", ()), name)
    if lacking:
        raise FloorbenchError(lacking)
    height = camera_height_mm(seq)
    rig: dict = {}
    if seq.has_stereo:
        rig = {
            "camera_right": seq.camera_model("cam1"),
            "T_cam0_cam1": seq.T_cam0_cam1,
            "flatfield_right": seq.flatfield("cam1"),
        }
    if seq.led_positions_cam_mm is not None:  # the rig's own lights (homography-6dof's tilt check)
        rig["led_positions_cam_mm"] = seq.led_positions_cam_mm
    if seq.row_time_s > 0.0:  # a rolling shutter: the estimators undo its readout (undo_rolling_shutter)
        rig["row_time_s"] = seq.row_time_s
    if seq.height_noise_mm is not None and seq.height_signal_mm is not None:  # homography-6dof's reading check
        rig["height_noise_mm"] = seq.height_noise_mm
    flat = seq.flatfield()
    with estimator_faults(name, "__init__"):
        est = cls(cfg, seq.camera, height_mm=height, flatfield=flat, **rig)
    # what an instance needs beyond its class's (map-fused: its odometry's, known once configured)
    lacking = seq.lacks(getattr(est, "requires", ()), name)
    if lacking:
        raise FloorbenchError(lacking)
    return est, cfg


@locks_folder("out_dir", "run folder")
def run_estimator(
    seq: Sequence | str | os.PathLike,
    name: str,
    out_dir: str | os.PathLike,
    overrides: Mapping[str, str] | None = None,
    frames: range | list[int] | None = None,
    on_frame: Callable[[int, int], None] | None = None,
    scale_calibration: ScaleCalibration | None = None,
    T_world_start: np.ndarray | None = None,
) -> RunResult:
    """Run estimator ``name`` over ``seq`` (or the listed ``frames`` of it) into ``out_dir``.

    ``scale_calibration`` (:mod:`floorvo.calibration`): divide each step's camera-frame
    x, y translation and its yaw by the rig's calibrated scales before chaining it. ``T_world_start``
    (4, 4) mm: where the run starts (default: the first frame's ground-truth pose, else the
    identity; ``--initial-pose``, :class:`InitialPose`). ``out_dir`` is locked while the run
    lasts (:func:`floorvo.locking.lock_folder`): a second writer of it is refused in one line.
    """
    if not isinstance(seq, Sequence):
        seq = Sequence.open(seq)
    est, cfg = build_estimator(seq, name, overrides)
    cal_problems = (
        [] if scale_calibration is None else calibration_use_problems(scale_calibration, seq.root, asdict(cfg))
    )
    for problem in cal_problems:
        log.warning("%s on %s: %s", name, seq.root, problem)
    out = ensure_writable_dir(out_dir)
    remove_program_files(out)  # a program's earlier run into this folder
    indices = list(range(seq.frame_count) if frames is None else frames)
    n = len(indices)
    with estimator_faults(name, "the run"):
        run = run_sequence(
            seq,
            est,
            frames=indices,
            scale_calibration=scale_calibration,
            T_world_start=T_world_start,
            on_step=None if on_frame is None else (lambda k, frame, res: on_frame(k + 1, n)),
            name=name,
        )
    run = replace(run, run_dir=str(out))
    header = f"floorvo {name}: T_world_cam, metres" if run.placed.any() else f"floorvo {name}: no frame tracked"
    result = {
        **run.summary(),
        "config": asdict(cfg),
        "scale_calibration": None if scale_calibration is None else scale_calibration.to_dict(),
        **({"scale_calibration_problems": cal_problems} if cal_problems else {}),
        "sequence": str(seq.root),
        SEQUENCE_SHA256: sequence_sha256(seq.meta),
        "source": estimator_source(name).to_dict(),
    }
    run.run_folder(header=header, result=result, reasons=True).write(out)
    counts = run.status_counts
    log.info("%s on %s: %d ok, %d lost, %.1f frames/s", name, seq.root, counts["ok"], counts["lost"], run.fps)
    return run


@dataclass(frozen=True)
class InitialPose:
    """Where a run on a sequence without ground truth starts (``--initial-pose``).

    Either a floor pose ``x_mm, y_mm, yaw_rad`` of the downward camera (placed at the
    sequence's camera height, :func:`floorvo.geometry.T_from_se2`), or a full pose read from
    a TUM line (``[timestamp] tx ty tz qx qy qz qw``, metres; the timestamp is ignored).
    """

    se2: tuple[float, float, float] | None = None
    T_full: np.ndarray | None = None

    @classmethod
    def parse(cls, text: str) -> InitialPose:
        """``"x_mm,y_mm,yaw_rad"`` or a TUM line (7 or 8 numbers separated by spaces)."""
        parts = text.replace(",", " ").split()
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = []
        if len(values) in (7, 8) and all(np.isfinite(values)):
            xyz_m, quat = np.array(values[-7:-4]), np.array(values[-4:])
            with np.errstate(over="ignore"):  # metres beyond 1.8e305 overflow in mm: refused below
                xyz_mm = xyz_m * 1000.0
            norm = float(np.linalg.norm(quat))
            if not position_problem(xyz_mm) and 0 < norm < np.inf:  # an inf pose ended in 'SVD did not converge'
                return cls(T_full=T_from_xyz_quat(xyz_mm, quat / norm))
        if len(values) == 3 and "," in text and all(np.isfinite(values)) and not position_problem(values[:2] + [0.0]):
            return cls(se2=(values[0], values[1], values[2]))
        raise ConfigError(
            f"--initial-pose {text!r}: expected x_mm,y_mm,yaw_rad (e.g. 0,0,0) or a TUM line "
            f"'[t] tx ty tz qx qy qz qw' (finite metres, at most {MAX_POSITION_MM / 1000.0:g} m from the origin along "
            "an axis, a non-zero quaternion)"
        )

    def T_world_cam(self, height_mm: float | None) -> np.ndarray:
        """The pose (4, 4) mm; a floor pose is placed ``height_mm`` above the floor (0 when unknown)."""
        if self.T_full is not None:
            return np.array(self.T_full, dtype=float)
        assert self.se2 is not None
        x, y, yaw = self.se2
        return T_from_se2(x, y, yaw, 0.0 if height_mm is None else float(height_mm))
