"""The GPU's renders against the CPU's, across two machines, and the GPU's renders against themselves.

    .venv/bin/python benchmarks/gpu_agreement.py refs REFS       # on the CPU machine: llvm_ad_mono
    .venv/bin/python benchmarks/gpu_agreement.py compare REFS    # on the GPU machine: the variant chosen by itself

The scenes are those of ``tests/floorsim/test_gpu.py`` (the tiny 162x124 rig of
``tests/floorsim/_tiny.py``, point LEDs, 3 mm LEDs and the bar emitter), 12 mm in 4 mm steps
(4 frames each). ``refs`` renders them with ``llvm_ad_mono`` into ``REFS/<case>/``; ``compare``
renders each twice, each time in a fresh process, and prints per case: the variant, the seconds
of a render (process start excluded), the smallest PSNR of a frame against the reference (8-bit
DN, peak 255), the largest difference in DN, the mean DN of both, and whether the two renders
are the same to the bit. ``pytest -m gpu`` checks the same on one machine with a threshold;
this prints the figures.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from floorvo.sequence import Sequence

TESTS = Path(__file__).resolve().parents[1] / "tests" / "floorsim"
CASES = {"point-leds": {}, "3mm-leds": {"lights.led_size_mm": 3.0}, "bar": {"lights.emitter": "bar"}}
_RENDER = """
import json, sys, time
sys.path.insert(0, {tests!r})
from _tiny import tiny_scene
from floorsim.render import backend_info
from floorsim.simulate import render_sequence
overrides = {{"sensor.exposure_gain": 600000.0, "trajectory.distance_mm": 12.0, **json.loads(sys.argv[2])}}
t = time.perf_counter()
render_sequence(tiny_scene(**overrides), sys.argv[1])
print(json.dumps({{**backend_info(), "seconds": time.perf_counter() - t}}))
"""


def _render(out: Path, overrides: dict, variant: str | None) -> dict:
    env = {k: v for k, v in os.environ.items() if k != "FLOORSIM_VARIANT"}
    if variant:
        env["FLOORSIM_VARIANT"] = variant
    code = _RENDER.format(tests=str(TESTS))
    proc = subprocess.run(
        [sys.executable, "-c", code, str(out), json.dumps(overrides)], env=env, capture_output=True, text=True
    )
    if proc.returncode:
        raise SystemExit(f"render into {out} failed: {proc.stderr.strip().splitlines()[-1]}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _frames(root: Path) -> list[np.ndarray]:
    seq = Sequence.open(root)
    return [seq.image(i).astype(np.float64) for i in range(seq.frame_count)]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("mode", choices=["refs", "compare"])
    ap.add_argument("refs", type=Path, help="folder of the CPU machine's renders")
    ap.add_argument(
        "--work", type=Path, default=None, help="compare: where the GPU renders go (default: a temporary folder)"
    )
    args = ap.parse_args()
    if args.mode == "refs":
        for case, overrides in CASES.items():
            print(case, json.dumps(_render(args.refs / case, overrides, "llvm_ad_mono")), flush=True)
        return
    import tempfile

    with tempfile.TemporaryDirectory(prefix="gpu-agreement-") as tmp:
        work = args.work or Path(tmp)
        for case, overrides in CASES.items():
            a = _render(work / f"{case}-a", overrides, None)
            b = _render(work / f"{case}-b", overrides, None)
            fa, fb, ref = _frames(work / f"{case}-a"), _frames(work / f"{case}-b"), _frames(args.refs / case)
            if len(fa) != len(ref):
                raise SystemExit(f"{case}: {len(fa)} frames here, {len(ref)} in {args.refs / case}")
            mse = [float(np.mean((x - r) ** 2)) for x, r in zip(fa, ref)]
            row = {
                "variant": a["variant"],
                "render_s": [round(a["seconds"], 2), round(b["seconds"], 2)],
                "psnr_db_min": min(float("inf") if m == 0 else 10 * np.log10(255.0**2 / m) for m in mse),
                "max_abs_dn": max(float(np.abs(x - r).max()) for x, r in zip(fa, ref)),
                "mean_dn": [float(np.mean(fa)), float(np.mean(ref))],
                "repeat_bit_identical": all(np.array_equal(x, y) for x, y in zip(fa, fb)),
            }
            print(case, json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
