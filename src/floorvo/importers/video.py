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

FFmpeg reports a damaged stream only in its log (OpenCV still returns the frame): a video whose
end was cut inside its last frame gave that frame half decoded, with exit code 0, and FFmpeg's
``[mjpeg @ 0x...] overread 8`` on standard error. The reader takes FFmpeg's messages while it
opens and decodes (:func:`_ffmpeg_messages`: they are written to the process's standard error,
file descriptor 2, by C code) and refuses a video whose frames gave any, naming the first frame
and the message; a file it cannot open is refused with FFmpeg's reason (``moov atom not found``).
With ``-v`` each message is logged too. FFmpeg's level is OpenCV's default (errors) unless
``OPENCV_FFMPEG_LOGLEVEL`` sets another.
"""

from __future__ import annotations

import contextlib
import logging
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterator
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


@contextlib.contextmanager
def _ffmpeg_messages(source: Path) -> Iterator[Callable[[], list[str]]]:
    """For the block, what is written to standard error (file descriptor 2: FFmpeg's log, through
    OpenCV) goes to a temporary file; yields a function that returns the lines written since it was
    last called (the decoder's address left out). Each is logged at debug level once the block
    ends (a log record written in the block would be taken as FFmpeg's): the block holds only
    OpenCV's calls."""
    sys.stderr.flush()
    said: list[str] = []
    with tempfile.TemporaryFile() as sink:
        saved = os.dup(2)
        os.dup2(sink.fileno(), 2)
        seen = 0

        def taken() -> list[str]:
            nonlocal seen
            sink.seek(seen)
            data = sink.read()
            seen += len(data)
            text = data.decode("utf-8", "replace").splitlines()
            lines = [re.sub(r" @ 0x[0-9a-fA-F]+\]", "]", " ".join(x.split())) for x in text if x.strip()]
            said.extend(lines)
            return lines

        try:
            yield taken
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            taken()
    for line in said:
        log.debug("%s: FFmpeg: %s", source, line)


def _open(source: Path, messages: Callable[[], list[str]]) -> cv2.VideoCapture:
    """``source`` opened (within :func:`_ffmpeg_messages`, whose ``messages`` give FFmpeg's reason)."""
    if not source.is_file():
        raise SequenceError(f"{source}: video file does not exist")
    cap = cv2.VideoCapture(str(source))
    if not cap.isOpened():
        why = messages()
        raise SequenceError(f"{source}: not a video OpenCV can decode" + (f" (FFmpeg: {why[0]})" if why else ""))
    messages()  # what opening a good file said (a stream's details) is no damage
    w, h = cap.get(cv2.CAP_PROP_FRAME_WIDTH), cap.get(cv2.CAP_PROP_FRAME_HEIGHT)
    problem = image_size_problem((int(w), int(h))) if np.isfinite(w) and np.isfinite(h) else None
    if problem:  # before a frame is decoded: a small file can state frames of gigabytes
        cap.release()
        raise SequenceError(f"{source}: video {problem.replace('header', 'container')}")
    return cap


def read(source: Path, options=None) -> Recording:
    """Count the frames of ``source`` and take their times; the images are decoded again when written."""
    damaged: list[tuple[int, str]] = []  # (frame, FFmpeg's first message) of each frame that gave any
    with _ffmpeg_messages(source) as messages:
        cap = _open(source, messages)
        fps = float(cap.get(cv2.CAP_PROP_FPS))
        stated = cap.get(cv2.CAP_PROP_FRAME_COUNT)  # the container's count (0 or less: it states none)
        times_ms: list[float] = []
        size: tuple[int, int] | None = None
        try:
            while True:
                ok, img = cap.read()
                said = messages()
                if not ok:
                    break
                if said:
                    damaged.append((len(times_ms), said[0]))
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
    if damaged:
        k, first = damaged[0]
        raise SequenceError(
            f"{source}: frame {k} did not decode cleanly (FFmpeg: {first}); {len(damaged)} of its {n} frames gave "
            "decoder errors: the file is damaged or truncated"
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
        with _ffmpeg_messages(source) as messages2:
            cap2 = _open(source, messages2)
        try:
            for i in range(n):
                with _ffmpeg_messages(source) as messages2:
                    ok, img = cap2.read()
                    said = messages2()
                if not ok or said:
                    why = f" (FFmpeg: {said[0]})" if said else ""
                    raise SequenceError(f"{source}: frame {i} of {n} could not be decoded the second time{why}")
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
