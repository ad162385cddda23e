"""The turning scenes with a translation-only scale calibration against one that fits the yaw too.

    .venv/bin/python benchmarks/yaw_calibration.py --from-cache CACHE --spins SPINS -o OUT \\
        [--estimators akaze-guided,akaze-guided-fast,phase-corr,phase-corr-fast]

For each floor material with turning scenes in the motion suite (wood: the arc; vinyl: the
S-curve and the 90-degree corner; asphalt: the arc; concrete: the S-curve), each estimator
runs on the material's straight run (``material_MATERIAL``, for x and y) and on a spin in
place over the same floor (the suite's ``motion_turn_spin_concrete`` scene with
``floor.material`` set: 2 rad at 5.7 degrees a frame, rendered into ``SPINS/MATERIAL`` at the
cache's size when it is not there; concrete's is the suite's own), and
:func:`floorvo.calibration.calibrate_runs` fits one calibration on both. Each turning scene
then runs uncalibrated, with the translation's scales alone (the yaw's set to 1: what a
straight run gives) and with both, and the table gives the end drift in % of the path of
each (scored against the ground truth, :func:`floorvo.scoring.score_run`). ``CACHE``: the
bench render cache holding the suite's scenes and the material runs
(``floorsim bench --suite motion scenes/material_*.toml --cache CACHE``); OpenCV on one thread.
"""

from __future__ import annotations

import argparse
import os
import shutil
from dataclasses import replace
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import cv2  # noqa: E402

from floorsim.scene import load_scene  # noqa: E402
from floorsim.simulate import render_sequence  # noqa: E402
from floorvo.calibration import calibrate_runs  # noqa: E402
from floorvo.run import run_estimator  # noqa: E402
from floorvo.scoring import score_run  # noqa: E402
from floorvo.sequence import Sequence  # noqa: E402

SCENES = Path(__file__).resolve().parents[1] / "scenes" / "motion"
#: material -> the turning scenes of the suite over it.
TURNING = {
    "wood": ["motion_turn_arc_wood"],
    "vinyl": ["motion_turn_s_curve_vinyl", "motion_turn_corner_vinyl"],
    "asphalt": ["motion_turn_arc_asphalt"],
    "concrete": ["motion_turn_s_curve_concrete"],
}


def _cached(cache: Path, name: str) -> Path:
    found = sorted(cache.glob(f"{name}-*"))
    if not found:
        raise SystemExit(f"--from-cache {cache}: no sequence of scene {name}")
    return found[-1]


def _spin(material: str, cache: Path, spins: Path) -> Path:
    """The spin in place over ``material`` at the cache's frame size (rendered when missing)."""
    if material == "concrete":
        return _cached(cache, "motion_turn_spin_concrete")
    out = spins / material
    if not (out / "sequence.json").is_file():
        width = Sequence.open(_cached(cache, f"material_{material}")).camera.width_px
        scene = load_scene(SCENES / "motion_turn_spin_concrete.toml", {"floor.material": f'"{material}"'})
        full = scene.camera_model().width_px
        render_sequence(scene, out, scale=None if width == full else width / full)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from-cache", type=Path, required=True, help="bench render cache of the suite and material runs")
    ap.add_argument("--spins", type=Path, required=True, help="folder for the spin renders (kept and reused)")
    ap.add_argument("--estimators", default="akaze-guided,akaze-guided-fast,phase-corr,phase-corr-fast")
    ap.add_argument("-o", "--output", type=Path, required=True, help="folder for the runs")
    args = ap.parse_args()
    cv2.setNumThreads(1)
    print("| material | estimator | scale x | scale yaw | scene | end drift %: none | x, y | x, y and yaw |")
    print("|---|---|---|---|---|---|---|---|")
    for material, scenes in TURNING.items():
        straight, spin = _cached(args.from_cache, f"material_{material}"), _spin(material, args.from_cache, args.spins)
        for est in args.estimators.split(","):
            base = args.output / material / est
            shutil.rmtree(base, ignore_errors=True)  # this script's own runs of a previous call
            run_estimator(straight, est, base / "straight")
            run_estimator(spin, est, base / "spin")
            cal = calibrate_runs([(base / "straight", straight), (base / "spin", spin)])
            cal_xy = replace(cal, scale_yaw=1.0, observed_yaw=False)
            for name in scenes:
                seq = _cached(args.from_cache, name)
                drift = []
                for tag, c in (("none", None), ("xy", cal_xy), ("xy-yaw", cal)):
                    run_estimator(seq, est, base / f"{name}-{tag}", scale_calibration=c)
                    drift.append(score_run(base / f"{name}-{tag}", seq).drift.get("end_drift_pct", float("nan")))
                print(
                    f"| {material} | {est} | {cal.scale_x:.4f} | {cal.scale_yaw:.4f} | {name} | {drift[0]:.3f} | "
                    f"{drift[1]:.3f} | {drift[2]:.3f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
