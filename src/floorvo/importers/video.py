"""A video file as a recording (OpenCV ``VideoCapture``: whatever its FFmpeg build decodes).

Frame times are the decoder's presentation times (``CAP_PROP_POS_MSEC`` of each frame);
when a container gives none that increase, ``i / fps`` of its stated rate. Frames are
converted to mono (8-bit). The file is decoded twice (counting, then writing), so a long
video is never held in memory.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from floorvo.errors import SequenceError
from floorvo.importers.recording import FrameImages, Recording, to_mono

__all__ = ["VIDEO_SUFFIXES", "detect", "read"]

log = logging.getLogger(__name__)

#: File suffixes taken for videos when no --format is given (case-insensitive).
VIDEO_SUFFIXES = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm", ".mpg", ".mpeg", ".wmv")


def detect(source: Path) -> bool:
    return source.is_file() and source.suffix.lower() in VIDEO_SUFFIXES


def _open(source: Path) -> cv2.VideoCapture:
    if not source.is_file():
        raise SequenceError(f"{source}: video file does not exist")
    cap = cv2.VideoCapture(str(source))
    if not cap.isOpened():
        raise SequenceError(f"{source}: not a video OpenCV can decode")
    return cap


def read(source: Path, options=None) -> Recording:
    """Count the frames of ``source`` and take their times; the images are decoded again when written."""
    cap = _open(source)
    fps = float(cap.get(cv2.CAP_PROP_FPS))
    stated = cap.get(cv2.CAP_PROP_FRAME_COUNT)  # the container's count (0 or less: it states none)
    times_ms, size = [], None
    try:
        while True:
            ok, img = cap.read()
            if not ok:
                break
            times_ms.append(float(cap.get(cv2.CAP_PROP_POS_MSEC)))
            if size is None:
                size = (img.shape[1], img.shape[0])
    finally:
        cap.release()
    if not times_ms or size is None:
        raise SequenceError(f"{source}: no frame could be decoded")
    n = len(times_ms)
    if np.isfinite(stated) and n < int(stated):
        # a truncated file: the decoder stops early, and the last frame it gave may be half a frame
        raise SequenceError(
            f"{source}: {n} of the {int(stated)} frames the container states could be decoded "
            "(the file is truncated or damaged; the last frame decoded may be incomplete)"
        )
    fps_ok = np.isfinite(fps) and fps > 0
    ts = np.round(np.array(times_ms) * 1000.0) / 1e6  # to the microsecond: decoders add float noise
    if n > 1 and np.any(np.diff(ts) <= 0):
        if not fps_ok:
            raise SequenceError(f"{source}: states neither frame times nor a frame rate; give --fps or --timestamps")
        log.warning("%s: frame times do not increase; taking i / %.6g fps", source, fps)
        ts = np.arange(n) / fps

    def frames() -> Iterator[FrameImages]:
        cap2 = _open(source)
        try:
            for i in range(n):
                ok, img = cap2.read()
                if not ok:
                    raise SequenceError(f"{source}: frame {i} of {n} could not be decoded the second time")
                yield FrameImages(to_mono(img, f"{source} frame {i}"))
        finally:
            cap2.release()

    return Recording(
        format="video",
        source=source,
        frame_count=n,
        size_px=size,
        bit_depth=8,
        frames=frames,
        timestamps_s=ts,
        fps=fps if fps_ok else None,
        details={"stated_fps": fps if fps_ok else None},
    )
