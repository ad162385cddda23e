"""What levelling with an attitude signal costs each estimator: CPU time per step with and without it.

    OMP_NUM_THREADS=1 taskset -c 1 .venv/bin/python benchmarks/attitude_cost.py SEQ \\
        [--estimators phase-corr,phase-corr-fast,akaze-guided-fast] [--repeats 5]

SEQ: a sequence with ``attitude.csv`` (``scenes/attitude/``). Its frames are read into memory,
then each estimator steps over them with ``use_attitude_signal`` true (each frame levelled:
phase-corr resamples its region, the AKAZE estimators move their keypoints) and false, the
two alternating, ``--repeats`` times; a step's cost is the thread CPU time of
``Estimator.step`` (what other jobs on a shared machine barely change), its median over the
frames after the first, and the table gives the median over the repeats and the ratio of
the two in the same run. OpenCV on one thread.
"""

from __future__ import annotations

import argparse
import os
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from floorvo.run import build_estimator  # noqa: E402
from floorvo.runner import sequence_frames  # noqa: E402
from floorvo.sequence import Sequence  # noqa: E402


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sequence", help="a sequence folder with attitude.csv")
    ap.add_argument("--estimators", default="phase-corr,phase-corr-fast,akaze-guided-fast")
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    cv2.setNumThreads(1)
    seq = Sequence.open(args.sequence)
    if seq.attitude_signal_rad is None:
        ap.error(f"{args.sequence}: no attitude.csv (render a scene of scenes/attitude/)")
    frames = list(sequence_frames(seq, range(seq.frame_count)))
    names = [n.strip() for n in args.estimators.split(",") if n.strip()]
    ms: dict[tuple[str, str], list[float]] = {}
    for _ in range(args.repeats):
        for name in names:
            for levelled in ("true", "false"):
                est, _cfg = build_estimator(seq, name, {"use_attitude_signal": levelled})
                state = est.start()
                times = []
                for frame in frames:
                    t0 = time.thread_time()
                    est.step(state, frame)
                    times.append(time.thread_time() - t0)
                ms.setdefault((name, levelled), []).append(1e3 * float(np.median(times[1:])))
    print("| estimator | levelled: CPU ms a step | not levelled | ratio |")
    print("|---|---|---|---|")
    for name in names:
        on, off = float(np.median(ms[(name, "true")])), float(np.median(ms[(name, "false")]))
        print(f"| {name} | {on:.3f} | {off:.3f} | {on / off:.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
