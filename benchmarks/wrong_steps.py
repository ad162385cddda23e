"""Every step an estimator reports ok that is wrong, dumped: the step, the pairs behind it, their errors.

    .venv/bin/python benchmarks/wrong_steps.py SEQ --estimator akaze-guided                  # the wrong ok steps
    .venv/bin/python benchmarks/wrong_steps.py SEQ --estimator akaze-guided --all --set precision_sigmas=0
    .venv/bin/python benchmarks/wrong_steps.py SEQ --estimator homography-6dof --truth 6dof     # a tilted run

Issue 14: a step reported ok must not be off by more than 0.05 mm + 2 % of the true step
or 0.3 degrees (:func:`floorvo.metrics.wrong_steps`). This runs the estimator frame by
frame over the sequence folder SEQ (OpenCV on one thread) and compares each ok step with
the true planar step of the camera's footprint (:func:`floorvo.geometry.footprint_T`: what a
planar mono estimator can see; the 6-DoF step on a run without tilt or bounce), or with
``--truth 6dof`` the camera's true 6-DoF step (the bound for an estimator that models tilt,
homography-6dof; and, whatever ``--truth`` says, for a planar estimator levelled with the
sequence's ``attitude.csv``, whose run's 6-DoF steps are taken as the score takes them), measured from the frame the estimator measured it from (the last tracked
one, or the frame it restarted on). For each wrong step (each step with ``--all``) one line
gives the true and measured step, the error, the estimator's counts and reason (with
``--truth 6dof`` also the true and measured tilt change, the angle between the two frames'
optical axes, and height change), and, for an estimator that reports the pairs behind its
fit (``StepResult.matches_px``): their number, the standard errors the fit's residual leaves
the step (:func:`floorvo.geometry.rigid_fit_precision`, in mm and degrees, and as a fraction
of the bound) and each pair's distance from where the true motion puts it (the floor plane
at the camera height carried by the true step, exact without tilt; with ``--truth 6dof`` the
true floor plane of the frame it was measured from) - the median, the 90th percentile, how
many are over 2 px, and the mean error along the image's x and y axes (x is across the
rig's LED bars: the direction the grazing light falls in, along which a change of the light
moves the shading). Which self-check should have caught the step reads
from these: wrong matches (pairs far from the truth), too few or imprecise pairs (large
standard errors), or a precise but biased fit.
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from floorvo.config import parse_set_args  # noqa: E402
from floorvo.estimators.base import RESTART_NOTE  # noqa: E402
from floorvo.geometry import (  # noqa: E402
    footprint_T,
    invert_T,
    pixels_to_floor_mm,
    rays_to_plane,
    rigid_fit,
    rigid_fit_precision,
    yaw_of_R,
)
from floorvo.metrics import WRONG_STEP_DEG, WRONG_STEP_FRACTION, WRONG_STEP_MM, step_errors, wrong_steps  # noqa: E402
from floorvo.run import build_estimator, run_estimator  # noqa: E402
from floorvo.runner import sequence_frames, uses_attitude_signal  # noqa: E402
from floorvo.scoring import ok_step_table  # noqa: E402
from floorvo.sequence import Sequence  # noqa: E402


def pair_report(
    matches_px: np.ndarray,
    est,
    T_true: np.ndarray,
    step_mm: float,
    plane: tuple[np.ndarray, float] | None = None,
) -> str:
    """The pairs ``matches_px`` (K, 4: u, v previous; u, v current) against the true step ``T_true`` (4, 4) mm.

    ``plane``: the true floor plane ``(n, d_mm)`` in the previous camera's frame (``n . p = d``);
    None: level at the estimator's camera height."""
    src, dst = matches_px[:, :2], matches_px[:, 2:]
    h = est.height_mm
    q_prev = pixels_to_floor_mm(src, est.camera, h)
    q_cur = pixels_to_floor_mm(dst, est.camera, h)
    R, t = rigid_fit(q_prev, q_cur)
    sig_mm, sig_rad = rigid_fit_precision(q_prev, q_cur, R, t)
    bound = WRONG_STEP_MM + WRONG_STEP_FRACTION * step_mm
    if plane is None:
        plane = (np.array([0.0, 0.0, 1.0]), h)
    P = rays_to_plane(src, est.camera, *plane)
    true_px = est.camera.project((invert_T(T_true) @ np.column_stack([P, np.ones(len(P))]).T).T[:, :3])
    d_px = dst - true_px
    err = np.linalg.norm(d_px, axis=1)
    return (
        f"{len(src)} pairs; standard errors {sig_mm:.3f} mm ({sig_mm / bound:.2f} of the bound), "
        f"{np.degrees(sig_rad):.3f} deg; pair error vs truth px: median {np.median(err):.2f}, "
        f"p90 {np.percentile(err, 90):.2f}, > 2 px {int(np.sum(err > 2))}, mean x {d_px[:, 0].mean():+.2f} "
        f"y {d_px[:, 1].mean():+.2f}"
    )


def attitude_run(seq: Sequence, args: argparse.Namespace) -> None:
    """The steps of a run whose poses the sequence's attitude signal makes 6-DoF (``attitude.csv``:
    the estimator levels its frames with it, :mod:`floorvo.runner`): its levelled steps are not
    the camera's, so the run is made as ``floorvo run`` makes it and its steps are taken as the
    score holds them, against the camera's 6-DoF step (:func:`floorvo.scoring.ok_step_table`;
    ``--truth`` does not apply). Compared with the raw levelled steps, nearly every step had
    been called wrong (27 of 27 where the score counts 4). No pair report: the pairs are levelled."""
    with tempfile.TemporaryDirectory() as tmp:
        run_estimator(seq, args.estimator, Path(tmp) / "run", parse_set_args(args.set))
        table = ok_step_table(Path(tmp) / "run", seq.root)
    for s in table:
        if not (s["wrong"] or args.all):
            continue
        T_true, T_est = s["true"], s["measured"]
        print(
            f"{'WRONG' if s['wrong'] else 'ok   '} frame {s['from_frame']} -> {s['to_frame']}: true "
            f"{float(np.linalg.norm(T_true[:3, 3])):.3f} mm, {np.degrees(yaw_of_R(T_true[:3, :3])):.2f} deg; measured "
            f"{float(np.linalg.norm(T_est[:3, 3])):.3f} mm, {np.degrees(yaw_of_R(T_est[:3, :3])):.2f} deg; error "
            f"{s['trans_mm']:.3f} mm, {s['rot_deg']:.3f} deg (bound "
            f"{WRONG_STEP_MM + WRONG_STEP_FRACTION * s['step_mm']:.3f} mm, {WRONG_STEP_DEG} deg) | the camera's 6-DoF "
            f"step (attitude.csv): tilt change true {tilt_mrad(T_true):.1f} mrad, measured {tilt_mrad(T_est):.1f}; "
            f"height change true {-T_true[2, 3]:+.3f} mm, measured {-T_est[2, 3]:+.3f}"
        )
    n_wrong = sum(s["wrong"] for s in table)
    print(
        f"{args.estimator} on {args.sequence}: {len(table)} ok steps scored, {n_wrong} of them wrong (attitude signal)"
    )


def tilt_mrad(T: np.ndarray) -> float:
    """The tilt change of a step ``T`` (4, 4): the angle between the two frames' optical axes, mrad."""
    return 1e3 * float(np.arccos(np.clip(T[2, 2], -1.0, 1.0)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sequence", type=Path)
    ap.add_argument("--estimator", required=True)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="an estimator config key")
    ap.add_argument("--all", action="store_true", help="every ok step, not only the wrong ones")
    ap.add_argument(
        "--truth",
        choices=("footprint", "6dof"),
        default="footprint",
        help="compare with the footprint's planar step (default) or the camera's 6-DoF step",
    )
    args = ap.parse_args()
    cv2.setNumThreads(1)
    seq = Sequence.open(args.sequence)
    est, _ = build_estimator(seq, args.estimator, parse_set_args(args.set))
    gt = seq.groundtruth()
    if gt is None:
        raise SystemExit(f"{args.sequence}: no groundtruth.txt to compare with")
    if seq.attitude_signal_rad is not None and uses_attitude_signal(est):
        attitude_run(seq, args)
        return
    T_gt = gt[1] if args.truth == "6dof" else footprint_T(gt[1], float(np.median(gt[1][:, 2, 3])))
    state = est.start()
    ref: int | None = None
    n_ok = n_wrong = n_lost = 0
    for frame in sequence_frames(seq, range(seq.frame_count), getattr(est, "requires", ())):
        res = est.step(state, frame)
        i = frame.index
        if res.status == "init":
            ref = i
            continue
        if res.status != "ok" or ref is None or res.T_prev_cur is None:
            n_lost += res.status == "lost"
            if RESTART_NOTE in res.reason:
                ref = i
            continue
        n_ok += 1
        T_true = invert_T(T_gt[ref]) @ T_gt[i]
        e = step_errors(np.stack([np.eye(4), T_true]), np.stack([np.eye(4), res.T_prev_cur]))
        wrong = bool(wrong_steps(e)[0])
        n_wrong += wrong
        if wrong or args.all:
            step = float(e["step_mm"][0])
            line = (
                f"{'WRONG' if wrong else 'ok   '} frame {ref} -> {i}: true {step:.3f} mm, "
                f"{np.degrees(yaw_of_R(T_true[:3, :3])):.2f} deg; measured "
                f"{float(np.linalg.norm(res.T_prev_cur[:3, 3])):.3f} mm, "
                f"{np.degrees(yaw_of_R(res.T_prev_cur[:3, :3])):.2f} deg; error {float(e['trans_mm'][0]):.3f} mm, "
                f"{float(e['rot_deg'][0]):.3f} deg (bound {WRONG_STEP_MM + WRONG_STEP_FRACTION * step:.3f} mm, "
                f"{WRONG_STEP_DEG} deg) | keypoints {res.n_keypoints}, matches {res.n_matches}, "
                f"inliers {res.n_inliers} | {res.reason or '-'}"
            )
            plane = None
            if args.truth == "6dof":  # the floor z = 0 in the previous camera: n = -R^T e_z, d = the height
                plane = (-T_gt[ref][2, :3], float(T_gt[ref][2, 3]))
                line += (
                    f" | tilt change true {tilt_mrad(T_true):.1f} mrad, measured {tilt_mrad(res.T_prev_cur):.1f}; "
                    f"height change true {-T_true[2, 3]:+.3f} mm, measured {-res.T_prev_cur[2, 3]:+.3f}"
                )
            if res.matches_px is not None and len(res.matches_px) >= 3:
                line += " | " + pair_report(np.asarray(res.matches_px, dtype=float), est, T_true, step, plane)
            print(line)
        ref = i
    print(f"{args.estimator} on {args.sequence}: {n_ok} ok, {n_wrong} of them wrong, {n_lost} lost")


if __name__ == "__main__":
    main()
