"""How an estimator's turn and step scales depend on the floor texture's orientation, per run.

    .venv/bin/python benchmarks/orientation_bias.py RUN SEQ [RUN SEQ ...] [--bin-deg 15] [--axis yaw|x]

For each run folder RUN (``floorvo run``) and its sequence SEQ: every step the run reported ok
against the true one from the frame it was measured from (:func:`floorvo.calibration.run_steps`,
the pairing a calibration is fitted on), with the step's texture orientation theta
(:func:`floorvo.imaging.texture_orientation`, the mean of its two frames': the floor's dominant
gradient direction in the image, from its x axis, degrees in (-90, 90]). One Markdown row per
run: the frames' mean coherence and, per ``--bin-deg`` bin of theta, the median of the step's
scale error in % (``--axis yaw``: estimated over true yaw change, minus 1, over steps turning
0.3 degrees or more; ``--axis x``: the same of the camera-x translation, over steps moving 1 mm
or more along it) and the number of steps in brackets. A floor whose picture's scales depend on
the grain's angle to the rig's lights (BENCHMARKS.md, "Wood: the turn and the step depend on
the grain's angle to the lights") shows the same function of theta in every run, whatever the
path (an arc of any radius, a spin, a straight run at any heading); the calibration's
texture-orientation terms (:mod:`floorvo.calibration`) are fitted to it.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from floorvo.calibration import run_steps
from floorvo.geometry import yaws_of_T


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pairs", nargs="+", metavar="RUN SEQ", help="run folders, each followed by its sequence folder")
    ap.add_argument("--bin-deg", type=float, default=15.0, help="width of a bin of theta (default 15)")
    ap.add_argument("--axis", choices=("yaw", "x"), default="yaw", help="the scale to show (default yaw)")
    args = ap.parse_args()
    if len(args.pairs) % 2:
        ap.error("give each run folder with its sequence folder: RUN SEQ [RUN SEQ ...]")
    edges = np.arange(-90.0, 90.0 + 1e-9, args.bin_deg)
    print("| run | coherence | " + " | ".join(f"[{lo:+.0f}, {lo + args.bin_deg:+.0f})" for lo in edges[:-1]) + " |")
    print("|" + "---|" * (len(edges) + 1))
    for run, seq in zip(args.pairs[::2], args.pairs[1::2]):
        steps = run_steps(run, seq)
        if steps.theta_rad is None:
            print(f"| {run} | no frames to measure the orientation in |")
            continue
        if args.axis == "yaw":
            true, est, least = np.degrees(yaws_of_T(steps.true)), np.degrees(yaws_of_T(steps.est)), 0.3
        else:
            true, est, least = steps.true[:, 0, 3], steps.est[:, 0, 3], 1.0
        use = np.abs(true) >= least
        err_pct = 100.0 * (est[use] / true[use] - 1.0)
        theta = np.degrees(steps.theta_rad[use])
        cells = []
        for lo in edges[:-1]:
            m = (theta >= lo) & (theta < lo + args.bin_deg)
            cells.append(f"{np.median(err_pct[m]):+.2f} ({int(m.sum())})" if m.any() else "")
        print(f"| {Path(run).name} | {steps.coherence:.2f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
