"""Where phase-corr's frame time goes: wall time and calls per frame of each stage.

    OMP_NUM_THREADS=1 taskset -c 1 .venv/bin/python benchmarks/phase_corr_stages.py SEQ [SEQ ...] \\
        [--estimator phase-corr-fast] [--repeats 5] [--set KEY=VALUE ...]

Each sequence's frames are read into memory, the estimator runs over them once to warm up and
then ``--repeats`` times, and each stage's time is summed by wrapping the methods and
functions of :mod:`floorvo.estimators.phase_corr` that make a step (their times nest:
``_measure`` holds the rounds' warps, spectra, block shifts and fits; ``_warp_spread`` the
warp-spread round's). The wrappers cost about a microsecond a call, so the total is a little
above an unwrapped run's. OpenCV on one thread.
"""

from __future__ import annotations

import argparse
import collections
import os
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402

from floorvo.estimators import Frame  # noqa: E402
from floorvo.estimators import phase_corr as pc  # noqa: E402
from floorvo.run import build_estimator  # noqa: E402
from floorvo.sequence import Sequence  # noqa: E402

METHODS = ["_normalised", "_measure", "_warp_spread", "_blocks", "_warp_into_prev", "_settled_px"]
FUNCTIONS = ["block_shifts", "block_shifts_near", "similarity_fit_2d", "rigid_fit_precision"]


def _wrap(owner, name: str, spent: collections.Counter, calls: collections.Counter) -> None:
    inner = getattr(owner, name)

    def timed(*args, **kwargs):
        t0 = time.perf_counter()
        try:
            return inner(*args, **kwargs)
        finally:
            spent[name] += time.perf_counter() - t0
            calls[name] += 1

    setattr(owner, name, timed)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sequences", nargs="+", type=Path)
    ap.add_argument("--estimator", default="phase-corr-fast", choices=["phase-corr", "phase-corr-fast"])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="an estimator config key")
    args = ap.parse_args()
    overrides = dict(kv.split("=", 1) for kv in args.set)
    cv2.setNumThreads(1)
    spent: collections.Counter = collections.Counter()
    calls: collections.Counter = collections.Counter()
    for name in METHODS:
        _wrap(pc.PhaseCorr, name, spent, calls)
    for name in FUNCTIONS:
        _wrap(pc, name, spent, calls)
    for path in args.sequences:
        seq = Sequence.open(path)
        est, _ = build_estimator(seq, args.estimator, overrides)
        frames = [Frame(i, float(ts), seq.image(i)) for i, ts in enumerate(seq.timestamps_s)]

        def run(est=est, frames=frames) -> None:
            state = est.start()
            for f in frames:
                est.step(state, f)

        run()
        spent.clear()
        calls.clear()
        t0 = time.perf_counter()
        for _ in range(args.repeats):
            run()
        n = args.repeats * len(frames)
        print(f"\n{path.name}, {args.estimator}: {1e3 * (time.perf_counter() - t0) / n:.3f} ms a frame (wall)")
        print("| stage | ms a frame | calls a frame |")
        print("|---|---|---|")
        for name, s in spent.most_common():
            print(f"| `{name}` | {1e3 * s / n:.3f} | {calls[name] / n:.2f} |")


if __name__ == "__main__":
    main()
