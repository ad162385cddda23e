"""A rolling shutter's readout: each estimator on a global-shutter render, on its rolling-shutter
twin with the readout left in, and with it undone.

    .venv/bin/python benchmarks/rolling_shutter.py --pair NAME=GLOBAL_SEQ,ROLLING_SEQ [--pair ...] -o OUT \
        [--estimators phase-corr,akaze-guided,...]

Each pair is two renders of one scene that differ only in ``sensor.readout_ms`` (0 and the
readout), e.g. ``floorsim render scenes/motion/motion_turn_arc_wood.toml -o G --set
sensor.readout_ms=0`` and ``... -o R --set sensor.readout_ms=15``. Each estimator runs
(:func:`floorvo.run.run_estimator`, into ``OUT/runs``) on the global-shutter render, on the
rolling-shutter one with ``undo_rolling_shutter = false``, and on it with the defaults (the readout
undone, :func:`floorvo.geometry.rolling_shutter_undone`), and is scored against the ground truth
(:func:`floorvo.scoring.score_run`: issue 14's wrong ok steps, 0.05 mm + 2 % of the step or 0.3
degrees, against the camera's step). It prints a markdown table: per pair and estimator, lost
frames / wrong ok steps / end drift % for each of the three runs, and the wrong ok steps summed.
An estimator without ``undo_rolling_shutter`` (orb-icp, stereo-sift) runs as it is in both
rolling-shutter columns.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from floorvo.estimators.registry import make_config  # noqa: E402
from floorvo.run import run_estimator  # noqa: E402
from floorvo.scoring import score_run  # noqa: E402

DEFAULT_ESTIMATORS = (
    "akaze-guided,akaze-bruteforce,akaze-guided-fast,akaze-bruteforce-fast,akaze-guided-subpixel,"
    "phase-corr,phase-corr-fast,homography-6dof"
)


def _pair(text: str) -> tuple[str, Path, Path]:
    name, _, seqs = text.partition("=")
    global_seq, _, rolling_seq = seqs.partition(",")
    if not (name and global_seq and rolling_seq):
        raise argparse.ArgumentTypeError(f"--pair {text!r}: expected NAME=GLOBAL_SEQ,ROLLING_SEQ")
    return name, Path(global_seq), Path(rolling_seq)


def _cell(summary: dict) -> str:
    drift = summary.get("end_drift_pct")
    shown = "-" if drift is None or drift != drift else f"{drift:.3f}"
    return f"{int(summary['lost_frames'])} / {int(summary['wrong_ok_steps'])} / {shown}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pair", type=_pair, action="append", required=True, metavar="NAME=GLOBAL_SEQ,ROLLING_SEQ")
    ap.add_argument("-o", "--out", type=Path, required=True)
    ap.add_argument("--estimators", default=DEFAULT_ESTIMATORS)
    args = ap.parse_args(argv)
    names = args.estimators.split(",")
    rows = []
    wrong = {"global": 0, "left in": 0, "undone": 0}
    for pair, global_seq, rolling_seq in args.pair:
        for name in names:
            undoes = hasattr(make_config(name), "undo_rolling_shutter")
            cells = []
            for column, seq, overrides in (
                ("global", global_seq, None),
                ("left in", rolling_seq, {"undo_rolling_shutter": "false"} if undoes else None),
                ("undone", rolling_seq, None),
            ):
                run = run_estimator(seq, name, args.out / "runs" / pair / column.replace(" ", "_") / name, overrides)
                s = score_run(run.run_dir, seq).flat()
                wrong[column] += int(s["wrong_ok_steps"])
                cells.append(_cell(s))
            rows.append((pair, name, *cells))
            print(f"{pair} {name}: " + " | ".join(cells), flush=True)
    print()
    print("| run | estimator | global shutter | readout left in | readout undone |")
    print("|---|---|---|---|---|")
    for row in rows:
        print("| " + " | ".join(row) + " |")
    print(f"| all | wrong ok steps | {wrong['global']} | {wrong['left in']} | {wrong['undone']} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
