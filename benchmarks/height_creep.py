"""A range sensor that creeps: the steps each estimator reports ok and wrong, and those it loses.

    .venv/bin/python benchmarks/height_creep.py SEQ [SEQ ...] -o OUT [--rates 0,0.5,0.8] [--from-frame 10] \
        [--estimators phase-corr,akaze-guided,...] [--per-run]

Each sequence folder SEQ must have a height signal (``height.csv``). For each rate (mm a frame)
a copy of SEQ is made under ``OUT/sequences`` whose readings from frame ``--from-frame`` on are
the recorded ones plus the rate times the frames since (a sensor drifting; the camera folders
are linked, not copied; rate 0 is the sequence as it is), and each estimator runs on it
(:func:`floorvo.run.run_estimator`, into ``OUT/runs``) and is scored against the ground truth
(:func:`floorvo.scoring.score_run`: issue 14's wrong ok steps, 0.05 mm + 2 % of the step or 0.3
degrees, against the camera's step). It prints a markdown table per rate and estimator, summed
over the sequences: the steps reported ok and wrong, the frames lost, and those lost as "height
signal drifts from the picture" (:func:`floorvo.estimators.base.height_signal_drift_problem`).
With ``--per-run`` one row per sequence too. To compare with older code, run it with that code's
``src`` first on ``PYTHONPATH`` (a ``git worktree`` of the commit).
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from floorvo.run import run_estimator  # noqa: E402
from floorvo.scoring import score_run  # noqa: E402
from floorvo.sequence import HEIGHT_FILE, SequenceWriter, read_height_csv  # noqa: E402

DRIFT_REASON = "height signal drifts from the picture"


def creeping_copy(seq: Path, dst: Path, rate_mm: float, from_frame: int) -> Path:
    """A copy of the sequence folder ``seq`` at ``dst`` whose height readings creep ``rate_mm`` a
    frame from ``from_frame`` on (frame ``from_frame`` reads ``rate_mm`` more, the next twice
    that, ...); its sub-folders (the cameras) linked. Made afresh each time."""
    if dst.exists():
        shutil.rmtree(dst)
    dst.mkdir(parents=True)
    for p in seq.iterdir():
        if p.name.startswith("."):
            continue
        if p.is_dir():
            os.symlink(p.resolve(), dst / p.name)
        elif p.name != HEIGHT_FILE:
            shutil.copy2(p, dst / p.name)
    h = read_height_csv(seq / HEIGHT_FILE)
    frames = np.arange(len(h))
    h = h + rate_mm * np.maximum(0, frames - from_frame + 1)
    meta = json.loads((dst / "sequence.json").read_text(encoding="utf-8"))
    meta = {k: v for k, v in meta.items() if k not in ("schema_version", "format")}
    with SequenceWriter(dst, meta) as w:
        w.write_heights(h)
    return dst


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sequences", nargs="+", type=Path)
    ap.add_argument("-o", "--out", type=Path, required=True)
    ap.add_argument("--rates", default="0,0.5,0.8", help="creep rates, mm a frame (0: the readings as they are)")
    ap.add_argument("--from-frame", type=int, default=10)
    ap.add_argument(
        "--estimators",
        default="phase-corr,phase-corr-fast,akaze-guided,akaze-guided-fast,akaze-bruteforce,akaze-bruteforce-fast,"
        "homography-6dof,akaze-guided-subpixel",
    )
    ap.add_argument("--per-run", action="store_true")
    args = ap.parse_args(argv)
    rates = [float(r) for r in args.rates.split(",")]
    names = args.estimators.split(",")
    rows: dict[tuple[float, str], list[tuple[str, int, int, int]]] = {}
    for seq in args.sequences:
        if not (seq / HEIGHT_FILE).is_file():
            ap.error(f"{seq}: has no {HEIGHT_FILE}")
        for rate in rates:
            target = (
                seq
                if rate == 0.0
                else creeping_copy(seq, args.out / "sequences" / f"{seq.name}_creep{rate:g}", rate, args.from_frame)
            )
            for name in names:
                run = run_estimator(target, name, args.out / "runs" / f"{seq.name}_creep{rate:g}" / name)
                s = score_run(run.run_dir, target).flat()
                drift = sum(1 for r, st in zip(run.reason, run.status) if st == "lost" and DRIFT_REASON in r)
                row = (seq.name, int(s["wrong_ok_steps"]), int(s["lost_frames"]), drift)
                rows.setdefault((rate, name), []).append(row)
                print(
                    f"{seq.name} creep {rate:g} {name}: wrong ok {row[1]}, lost {row[2]} ({drift} drifting)", flush=True
                )
    print()
    print("| creep (mm a frame) | estimator | runs | wrong ok | lost | lost: drifts from the picture |")
    print("|---|---|---|---|---|---|")
    for (rate, name), rs in rows.items():
        print(
            f"| {rate:g} | {name} | {len(rs)} | {sum(r[1] for r in rs)} | {sum(r[2] for r in rs)} | {sum(r[3] for r in rs)} |"
        )
    if args.per_run:
        print()
        print("| creep (mm a frame) | estimator | sequence | wrong ok | lost | lost: drifts from the picture |")
        print("|---|---|---|---|---|---|")
        for (rate, name), rs in rows.items():
            for r in rs:
                print(f"| {rate:g} | {name} | {r[0]} | {r[1]} | {r[2]} | {r[3]} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
