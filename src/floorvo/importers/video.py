"""A video file as a recording (OpenCV ``VideoCapture``: whatever its FFmpeg build decodes).

Frame times are the decoder's presentation times (``CAP_PROP_POS_MSEC`` of each frame). Times
that do not increase (a damaged or variable-rate container; a frame at the time of the one
before it) are refused in one line naming the first such frame and both times, unless the
user gives the times: ``--fps HZ`` (``ImportOptions.fps``) takes ``i / HZ`` instead, said in one
warning line, and ``--timestamps FILE`` replaces them. Taking ``i / fps`` of the container's
stated rate without being asked put every frame after a duplicate at a time it was not
recorded at, with exit code 0. A frame size the container states beyond
:data:`floorvo.io.MAX_IMAGE_PIXELS` is refused before a frame is decoded. Frames are
converted to mono (8-bit). The file is decoded twice (counting, then writing), so a long
video is never held in memory.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np

from floorvo.errors import SequenceError, shown_number
from floorvo.importers.recording import FrameImages, Recording, to_mono
from floorvo.io import image_size_problem

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
    w, h = cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)
    problem = image_size_problem((int(w), int(h))) if np.isfinite(w) and np.isfinite(h) else None
    if problem:  # before a frame is decoded: a small file can state frames of gigabytes
        cap.release()
        raise SequenceError(f"{source}: video {problem.replace('header', 'container')}")
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
    by_fps = False  # the container's times replaced by i / --fps
    if n > 1 and np.any(np.diff(ts) <= 0):
        k = int(np.argmax(np.diff(ts) <= 0)) + 1
        where = (
            f"frame {k} at {shown_number(ts[k], '.6f')} s follows frame {k - 1} at {shown_number(ts[k - 1], '.6f')} s"
        )
        if getattr(options, "timestamps_s", None) is not None:
            pass  # --timestamps replaces them
        elif getattr(options, "fps", None) is not None:
            log.warning("%s: frame times do not increase (%s); taking i / %s fps (--fps)", source, where, options.fps)
            by_fps = True
        else:
            rate = f"the container states {fps:.6g} fps" if fps_ok else "the container states no rate"
            raise SequenceError(
                f"{source}: frame times must increase, but {where}; give --fps HZ to take i / HZ instead "
                f"({rate}) or --timestamps FILE"
            )

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
        timestamps_s=None if by_fps else ts,
        fps=fps if fps_ok else None,
        details={"stated_fps": fps if fps_ok else None},
    )
