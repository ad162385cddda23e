#!/usr/bin/env python3
"""An external estimator for floorbench: a program that reads a sequence folder and writes a trajectory.

    fft_vo.py SEQUENCE OUTPUT CAMERA_YAML

It knows nothing of floorbench's Python API, as a C++ binary or a ROS node would not: it reads
``SEQUENCE/sequence.json`` (frame count and rate), ``SEQUENCE/timestamps.txt`` when there is one
(frame times; else frame i is at i / fps), the frames ``SEQUENCE/cam0/NNNNNN.png`` and the OpenCV
calibration YAML the bench writes (``camera_matrix``, ``camera_height_mm``), measures the shift
between consecutive frames by phase correlation (Hann window, normalised cross-power spectrum,
a parabola through the peak), and writes

* ``OUTPUT/trajectory.txt``: TUM (``t tx ty tz qx qy qz qw``, seconds and metres), the camera
  pose of every frame starting at the identity (the bench places it at the run's start pose);
* ``OUTPUT/timing.csv``: ``frame,total_ms,status`` per frame.

Translation only (no yaw): a floor shift of d px is a camera motion of -d * height / f mm.
"""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path

import cv2
import numpy as np


def shift_px(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, float]:
    """Shift (du, dv) px of the content of ``b`` relative to ``a`` (spectra given), and the peak height."""
    cross = a * np.conj(b)
    corr = np.fft.ifft2(cross / np.maximum(np.abs(cross), 1e-12)).real
    h, w = corr.shape
    v, u = np.unravel_index(int(np.argmax(corr)), corr.shape)

    def vertex(m: float, c: float, p: float) -> float:
        den = m - 2 * c + p
        return 0.0 if den == 0 else float(np.clip(0.5 * (m - p) / den, -0.5, 0.5))

    du = u + vertex(corr[v, u - 1], corr[v, u], corr[v, (u + 1) % w])
    dv = v + vertex(corr[v - 1, u], corr[v, u], corr[(v + 1) % h, u])
    return -np.array([(du + w / 2) % w - w / 2, (dv + h / 2) % h - h / 2]), float(corr[v, u])


def main(argv: list[str]) -> int:
    if len(argv) != 3:
        print("usage: fft_vo.py SEQUENCE OUTPUT CAMERA_YAML", file=sys.stderr)
        return 2
    seq, out, camera = Path(argv[0]), Path(argv[1]), argv[2]
    meta = json.loads((seq / "sequence.json").read_text())
    n, fps = int(meta["frame_count"]), float(meta["fps"])
    stamps = seq / "timestamps.txt"
    times = np.loadtxt(stamps, ndmin=1) if stamps.is_file() else np.arange(n) / fps
    fs = cv2.FileStorage(camera, cv2.FILE_STORAGE_READ)
    fx = fs.getNode("camera_matrix").mat()[0, 0]
    height_mm = fs.getNode("camera_height_mm").real()
    fs.release()
    mm_per_px = height_mm / fx
    window = None
    xy_mm = np.zeros(2)
    prev = None
    lines, timing = [], ["frame,total_ms,status"]
    for i in range(n):
        t0 = time.perf_counter()
        img = cv2.imread(str(seq / "cam0" / f"{i:06d}.png"), cv2.IMREAD_UNCHANGED)
        if img is None:
            print(f"fft_vo: cannot read frame {i}", file=sys.stderr)
            return 1
        img = img.astype(float)
        if window is None:
            window = np.outer(np.hanning(img.shape[0]), np.hanning(img.shape[1]))
        spec = np.fft.fft2((img - img.mean()) * window)
        status = "init"
        if prev is not None:
            d_px, peak = shift_px(prev, spec)
            status = "ok"
            xy_mm -= d_px * mm_per_px  # the floor moved by d px: the camera moved the other way
        prev = spec
        # camera looking straight down: x along world x, y along world -y (OpenCV camera frame), q = (1, 0, 0, 0)
        lines.append(f"{times[i]:.9f} {xy_mm[0] / 1000:.9f} {-xy_mm[1] / 1000:.9f} {height_mm / 1000:.9f} 1 0 0 0")
        timing.append(f"{i},{(time.perf_counter() - t0) * 1000:.3f},{status}")
    out.mkdir(parents=True, exist_ok=True)
    (out / "trajectory.txt").write_text("# fft_vo: T_world_cam, metres\n" + "\n".join(lines) + "\n")
    (out / "timing.csv").write_text("\n".join(timing) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
