"""Estimator benchmark: time per frame on one core, matching time, drift in % of distance.

    .venv/bin/python benchmarks/estimators.py [--scale 1.0] [--line-scale 0.5] [--out out/bench-estimators]
    .venv/bin/python benchmarks/estimators.py --sequence paper000_uniform=PATH --sequence line=PATH
    .venv/bin/python benchmarks/estimators.py --synthetic   # no renderer: floorvo.synthetic sequences
    .venv/bin/python benchmarks/estimators.py --line-scale 1 --calibrate-on paper000_uniform   # + scale calibration
    taskset -c 1 .venv/bin/python benchmarks/estimators.py --sequence straight=S1 --sequence s_curve=S2 \
        --estimators akaze-guided akaze-guided-fast ...   # real-time presets on one core (BENCHMARKS.md)

Renders (or reuses) ``paper000_uniform`` and the paper-001 3 m line with depth
(``paper001_line3m_rgbd``), or uses the sequence folders given with ``--sequence``, or with
``--synthetic`` writes code-made sequences (floorvo.synthetic: a 100 mm line at 4 mm/frame
and a 3 m line at 10 mm/frame, 648x494, with depth and a 20 mm stereo pair, so every
estimator runs), and runs every registered estimator each sequence supports with
OpenCV and drjit held to one thread, and prints a table: median ms per frame (wall clock,
total and matching; and the thread CPU time of a step, which other jobs on a shared machine
barely change), the whole run loop per frame (``floorvo.runner``: frame reading, the step,
chaining; wall clock from ``result.json``'s ``fps``, and thread CPU time of the whole
``run_estimator`` call, files included), frames per second (from the wall clock), end-point drift and distance error in % of the distance
travelled. The guided/brute-force matching-time ratio (paper 000's claim) is measured
in the same run on the same frames, and so is each real-time preset ``NAME-fast`` against
``NAME`` (issue 14 item 5): frames/s from the wall clock and from the thread CPU time, their
fast/default ratios, and the end drift of both; and each phase-corr variant's frames/s over the
fastest feature estimator's (issue 14: at least 10x).
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import platform
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from floorvo.errors import FloorbenchError  # noqa: E402
from floorvo.estimators import get_estimator, list_estimators  # noqa: E402
from floorvo.run import run_estimator  # noqa: E402
from floorvo.scoring import score_run  # noqa: E402
from floorvo.sequence import Sequence  # noqa: E402


def _timing(run: Path) -> dict:
    rows = [r for r in csv.DictReader(open(run / "timing.csv")) if r["status"] == "ok"]
    return {
        "total_ms": float(np.median([float(r["total_ms"]) for r in rows])) if rows else float("nan"),
        "match_ms": float(np.median([float(r["match_ms"]) for r in rows])) if rows else float("nan"),
    }


def _cpu_ms(seq: Sequence, name: str, max_frames: int = 60) -> tuple[float, float]:
    """Median and mean thread CPU time (ms) of an ok ``step`` over the first frames: insensitive to
    other jobs on the machine. Where a run's steps take one of two costs (phase-corr's turning
    steps take one warp-and-measure round or two) the median is the more common one's, so the
    mean is given beside it."""
    from floorvo.estimators import Frame
    from floorvo.run import build_estimator

    est, _ = build_estimator(seq, name)
    state = est.start()
    times = []
    for i in range(min(seq.frame_count, max_frames)):
        frame = Frame(
            i,
            i / seq.fps,
            seq.image(i),
            image_right=seq.image(i, "cam1") if "stereo" in est.requires else None,
            depth_mm=seq.depth_mm(i) if "depth" in est.requires else None,
        )
        c0 = time.thread_time()
        res = est.step(state, frame)
        if res.status == "ok":
            times.append((time.thread_time() - c0) * 1e3)
    return (float(np.median(times)), float(np.mean(times))) if times else (float("nan"), float("nan"))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scale", type=float, default=1.0, help="resolution scale of paper000_uniform (1 = 648x494)")
    ap.add_argument("--line-scale", type=float, default=0.5, help="resolution scale of the 3 m line")
    ap.add_argument("--line-frames", type=int, default=None, help="render only the first N frames of the line")
    ap.add_argument("--estimators", nargs="*", default=None)
    ap.add_argument(
        "--sequence", action="append", metavar="NAME=PATH", help="use an existing sequence folder (repeatable)"
    )
    ap.add_argument(
        "--synthetic", action="store_true", help="code-made sequences (floorvo.synthetic) instead of renders"
    )
    ap.add_argument("--out", default="out/bench-estimators")
    ap.add_argument(
        "--calibrate-on",
        metavar="NAME",
        default=None,
        help="fit each estimator's scale calibration (floorvo calibrate) on sequence NAME and run it again, "
        "calibrated, on the other sequences: a table of end drift raw and calibrated",
    )
    args = ap.parse_args()
    cv2.setNumThreads(1)
    out = Path(args.out)
    if args.sequence:
        seqs = {k: Path(v) for k, v in (a.split("=", 1) for a in args.sequence)}
    elif args.synthetic:
        from floorvo.camera import CameraModel
        from floorvo.synthetic import line_poses, write_synthetic_sequence

        cam = CameraModel.from_sensor(648, 494, pixel_pitch_um=7.4, focal_length_mm=6.0)
        seqs = {
            "synthetic_uniform_100mm": write_synthetic_sequence(
                out / "seq" / "synthetic_uniform_100mm",
                cam,
                line_poses(100.0, 4.0, 100.0),
                depth=True,
                stereo_baseline_mm=20.0,
                seed=0,
            ),
            "synthetic_line_3m": write_synthetic_sequence(
                out / "seq" / "synthetic_line_3m",
                cam,
                line_poses(3000.0, 10.0, 100.0),
                depth=True,
                stereo_baseline_mm=20.0,
                seed=1,
            ),
        }
    else:
        from floorsim.scene import load_scene
        from floorsim.simulate import render_sequence

        seqs = {
            "paper000_uniform": render_sequence(
                load_scene("paper000_uniform"), out / "seq" / "paper000_uniform", scale=args.scale
            ),
            "paper001_line3m_rgbd": render_sequence(
                load_scene("paper001_line3m_rgbd"),
                out / "seq" / "paper001_line3m_rgbd",
                scale=args.line_scale,
                frames=args.line_frames,
            ),
        }
    names = args.estimators or [n for n in list_estimators() if n != "map-fused"]
    rows = []
    for sname, sdir in seqs.items():
        seq = Sequence.open(sdir)
        for name in names:
            req = set(get_estimator(name).requires)
            if ("depth" in req and not seq.has_depth) or ("stereo" in req and not seq.has_stereo):
                continue
            run = out / "runs" / sname / name
            c0 = time.thread_time()
            run_estimator(seq, name, run)
            run_cpu_ms = (time.thread_time() - c0) * 1e3 / seq.frame_count
            loop_fps = json.loads((run / "result.json").read_text())["fps"]
            sc = score_run(run, sdir).flat()
            t = _timing(run)
            cpu_median_ms, cpu_mean_ms = _cpu_ms(seq, name)
            rows.append(
                {
                    "sequence": sname,
                    "size": f"{seq.camera.width_px}x{seq.camera.height_px}",
                    "frames": seq.frame_count,
                    "estimator": name,
                    "ms_per_frame": round(t["total_ms"], 2),
                    "cpu_ms_per_frame": round(cpu_median_ms, 2),
                    "cpu_ms_mean_per_frame": round(cpu_mean_ms, 2),
                    "match_ms": round(t["match_ms"], 3),
                    "loop_ms_per_frame": round(1000.0 / loop_fps, 2) if loop_fps > 0 else None,
                    "run_cpu_ms_per_frame": round(run_cpu_ms, 2),
                    "frames_per_s": round(1000.0 / t["total_ms"], 1) if t["total_ms"] > 0 else None,
                    # None when the run tracked too little for pose metrics (every step lost)
                    "end_drift_pct": _rounded(sc.get("end_drift_pct")),
                    "distance_error_pct": _rounded(sc.get("distance_error_pct")),
                    "lost": int(sc.get("lost_frames", 0) or 0),
                }
            )
            print(json.dumps(rows[-1]))
    ratios = {}
    for sname in seqs:
        g = next((r for r in rows if r["sequence"] == sname and r["estimator"] == "akaze-guided"), None)
        b = next((r for r in rows if r["sequence"] == sname and r["estimator"] == "akaze-bruteforce"), None)
        if g and b and g["match_ms"] > 0:
            ratios[sname] = round(b["match_ms"] / g["match_ms"], 2)
    print()
    cols = [
        "sequence",
        "size",
        "estimator",
        "ms_per_frame",
        "cpu_ms_per_frame",
        "cpu_ms_mean_per_frame",
        "match_ms",
        "loop_ms_per_frame",
        "run_cpu_ms_per_frame",
        "frames_per_s",
        "end_drift_pct",
        "distance_error_pct",
        "lost",
    ]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in rows:
        print("| " + " | ".join(str(r[c]) for c in cols) + " |")
    print(f"\nmatching-time ratio brute-force / guided (same run): {ratios}")
    presets = _preset_rows(rows)
    if presets:
        print("\nreal-time presets against their defaults (same run, same frames):")
        pcols = list(presets[0])
        print("| " + " | ".join(pcols) + " |")
        print("|" + "---|" * len(pcols))
        for r in presets:
            print("| " + " | ".join(str(r[c]) for c in pcols) + " |")
    dense = _dense_ratio_rows(rows)
    if dense:
        print("\nphase-corr against the fastest feature estimator (frames/s from thread CPU time, same run):")
        dcols = list(dense[0])
        print("| " + " | ".join(dcols) + " |")
        print("|" + "---|" * len(dcols))
        for r in dense:
            print("| " + " | ".join(str(r[c]) for c in dcols) + " |")
    print(f"machine: {platform.machine()}, {os.cpu_count()} cores; OpenCV {cv2.__version__} with 1 thread")
    calibrated = _calibrated_rows(seqs, rows, args.calibrate_on, out) if args.calibrate_on else []
    (out / "estimators.json").write_text(
        json.dumps(
            {"rows": rows, "match_ratio": ratios, "presets": presets, "dense": dense, "calibrated": calibrated},
            indent=2,
        )
    )


def _preset_rows(rows: list[dict]) -> list[dict]:
    """Each real-time preset ``NAME-fast`` beside ``NAME`` on the same sequence: frames/s from the
    median wall clock of a step and from its thread CPU time, their fast/default ratios, end drift.
    A run that lost every step has no frames/s (None) and no step times (NaN): its ratios are None."""
    out = []
    by = {(r["sequence"], r["estimator"]): r for r in rows}
    for (sname, name), f in by.items():
        d = by.get((sname, name.removesuffix("-fast"))) if name.endswith("-fast") else None
        if d is None:
            continue
        cpu_fps = {k: _per_s(r["cpu_ms_per_frame"]) for k, r in (("d", d), ("f", f))}
        out.append(
            {
                "sequence": sname,
                "estimator": name.removesuffix("-fast"),
                "fps_default": d["frames_per_s"],
                "fps_fast": f["frames_per_s"],
                "ratio_wall": _ratio(f["frames_per_s"], d["frames_per_s"]),
                "cpu_fps_default": _rounded(cpu_fps["d"], 1),
                "cpu_fps_fast": _rounded(cpu_fps["f"], 1),
                "ratio_cpu": _ratio(cpu_fps["f"], cpu_fps["d"]),
                "drift_pct_default": d["end_drift_pct"],
                "drift_pct_fast": f["end_drift_pct"],
                "lost_default": d["lost"],
                "lost_fast": f["lost"],
            }
        )
    return out


def _per_s(ms: float) -> float | None:
    """Frames per second of ``ms`` milliseconds a frame; None where there is no time (NaN, 0)."""
    return 1000.0 / ms if ms > 0 else None


def _ratio(a: float | None, b: float | None) -> float | None:
    """``a / b`` to two decimals; None where either is missing (a run that lost every step)."""
    return None if a is None or b is None or not b > 0 else round(a / b, 2)


def _dense_ratio_rows(rows: list[dict]) -> list[dict]:
    """Per sequence, each phase-corr variant's frames/s (thread CPU time) over that of the fastest
    feature estimator of the same run (issue 14 item 5: at least 10x): from the median step
    (``ratio``) and from the mean (``ratio_mean``)."""
    out = []
    for sname in dict.fromkeys(r["sequence"] for r in rows):
        seq_rows = [r for r in rows if r["sequence"] == sname and r["cpu_ms_per_frame"] > 0]
        feats = [r for r in seq_rows if not r["estimator"].startswith("phase-corr")]
        if not feats:
            continue
        fastest = min(feats, key=lambda r: r["cpu_ms_per_frame"])
        for r in seq_rows:
            if r["estimator"].startswith("phase-corr"):
                out.append(
                    {
                        "sequence": sname,
                        "estimator": r["estimator"],
                        "cpu_fps": round(1000.0 / r["cpu_ms_per_frame"], 1),
                        "fastest_feature": fastest["estimator"],
                        "its_cpu_fps": round(1000.0 / fastest["cpu_ms_per_frame"], 1),
                        "ratio": round(fastest["cpu_ms_per_frame"] / r["cpu_ms_per_frame"], 2),
                        "ratio_mean": round(fastest["cpu_ms_mean_per_frame"] / r["cpu_ms_mean_per_frame"], 2),
                        "end_drift_pct": r["end_drift_pct"],
                    }
                )
    return out


def _calibrated_rows(seqs: dict, rows: list[dict], cal_name: str, out: Path) -> list[dict]:
    """Per estimator: the scale fitted on ``cal_name``'s run, then each other sequence run with it."""
    from floorvo.calibration import calibrate_run

    if cal_name not in seqs:
        raise SystemExit(f"--calibrate-on {cal_name}: no such sequence (have {', '.join(seqs)})")
    table = []
    for r in rows:
        if r["sequence"] == cal_name:
            continue
        name, sname = r["estimator"], r["sequence"]
        cal_run = out / "runs" / cal_name / name
        if not (cal_run / "trajectory.txt").is_file():
            continue
        try:
            cal = calibrate_run(cal_run, seqs[cal_name])
        except FloorbenchError as exc:  # a run that lost its track, or a scale no calibration may have
            print(f"{name}: no calibration on {cal_name}: {exc}")
            continue
        run = out / "runs" / sname / f"{name}-calibrated"
        run_estimator(Sequence.open(seqs[sname]), name, run, scale_calibration=cal)
        sc = score_run(run, seqs[sname]).flat()
        table.append(
            {
                "sequence": sname,
                "estimator": name,
                "scale_x": round(cal.scale_x, 5),
                "scale_y": round(cal.scale_y, 5),
                "end_drift_pct_raw": r["end_drift_pct"],
                "end_drift_pct_calibrated": _rounded(sc.get("end_drift_pct")),
                "distance_error_pct_calibrated": _rounded(sc.get("distance_error_pct")),
            }
        )
    if table:
        cols = list(table[0])
        print(f"\nscale calibration fitted on {cal_name}, applied to the others:")
        print("| " + " | ".join(cols) + " |")
        print("|" + "---|" * len(cols))
        for t in table:
            print("| " + " | ".join(str(t[c]) for c in cols) + " |")
    return table


def _rounded(value, digits: int = 4) -> float | None:
    """``value`` rounded, or None when the score has no such metric."""
    return None if value is None else round(float(value), digits)


if __name__ == "__main__":
    main()
