"""Where a run's end drift comes from: its yaws against its translations, chained apart.

    .venv/bin/python benchmarks/drift_sources.py RUN SEQ [RUN SEQ ...]

For each run folder RUN (``floorvo run``, calibrated with ``--scale-calibration`` or not) and
its sequence SEQ: the steps the run reported ok against the true ones from the frame each was
measured from (:func:`floorvo.calibration.run_steps`, the pairing a calibration is fitted on;
a run that loses no step, so the steps chain from its first frame to its last). Three planar
paths are chained from the first frame: the run's steps (its yaws and its translations), its
yaws with the true translations, and the true yaws with its translations. One Markdown row per
run gives each path's end error in % of the true path length, and the per-step yaw error's mean
and standard deviation. The first is the run's own end drift (planar); the other two say
whether a yaw's random walk (a few hundredths of a degree a step, which bends the rest of the
path) or the steps' lengths limit it. The two parts do not add: their errors are vectors.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from floorvo.calibration import run_steps
from floorvo.geometry import yaws_of_T


def chained_end_mm(yaws_rad: np.ndarray, steps_xy_mm: np.ndarray) -> np.ndarray:
    """The end (2,) mm of the planar path that starts at the origin with yaw 0 and makes the steps
    ``(yaws_rad[k], steps_xy_mm[k])`` (K,), (K, 2) in turn, each in the frame of the one before."""
    heading, end = 0.0, np.zeros(2)
    for yaw, (dx, dy) in zip(yaws_rad, steps_xy_mm):
        c, s = np.cos(heading), np.sin(heading)
        end += (c * dx - s * dy, s * dx + c * dy)
        heading += yaw
    return end


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pairs", nargs="+", metavar="RUN SEQ", help="run folders, each followed by its sequence folder")
    args = ap.parse_args()
    if len(args.pairs) % 2:
        ap.error("give each run folder with its sequence folder: RUN SEQ [RUN SEQ ...]")
    print(
        "| run | steps | end drift % (its steps) | its yaws, true translations | true yaws, its translations "
        "| yaw error a step, mean / sd (deg) |"
    )
    print("|---|---|---|---|---|---|")
    for run, seq in zip(args.pairs[::2], args.pairs[1::2]):
        steps = run_steps(run, seq, orientation=False)
        yaw_true, yaw_est = yaws_of_T(steps.true), yaws_of_T(steps.est)
        xy_true, xy_est = steps.true[:, :2, 3], steps.est[:, :2, 3]
        length_mm = float(np.linalg.norm(steps.true[:, :3, 3], axis=1).sum())
        end_true = chained_end_mm(yaw_true, xy_true)
        drift = [
            f"{100.0 * float(np.linalg.norm(chained_end_mm(yaws, xy) - end_true)) / length_mm:.3f}"
            for yaws, xy in ((yaw_est, xy_est), (yaw_est, xy_true), (yaw_true, xy_est))
        ]
        err_deg = np.degrees(yaw_est - yaw_true)
        print(
            f"| {Path(run).name} | {len(err_deg)} | {' | '.join(drift)} "
            f"| {err_deg.mean():+.4f} / {err_deg.std(ddof=1):.4f} |"
        )


if __name__ == "__main__":
    main()
