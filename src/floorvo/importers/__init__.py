"""Import recordings into the sequence format: ``floorvo import SOURCE -o SEQ``.

One reader per format, each in its own module, each returning a
:class:`~floorvo.importers.recording.Recording`; one writer,
:func:`~floorvo.importers.recording.write_recording`, turns any of them into a sequence
folder through :class:`floorvo.sequence.SequenceWriter`:

========  =====================================================================
images    a folder of PNG/JPEG/TIFF/BMP files (natural order) or a list file
video     a video file OpenCV decodes (frame times from the container)
euroc     a EuRoC/ASL folder (``mav0/cam0``, ``cam1``, ground truth)
rosbag2   a ROS 2 bag (image, right, depth, camera_info, ground-truth topics)
========  =====================================================================

In Python::

    from floorvo.importers import ImportOptions, import_sequence
    import_sequence("recording.mp4", "out/seq", options=ImportOptions(height_mm=100.0))
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from floorvo.errors import ConfigError, SequenceError
from floorvo.importers import euroc, images, rosbag2, video
from floorvo.importers.recording import ImportOptions, ImportResult, Recording, write_recording

__all__ = ["READERS", "ImportOptions", "ImportResult", "detect_format", "import_sequence", "read_recording"]

#: Format name -> (detect(source) -> bool, read(source, options) -> Recording), in detection order.
READERS: dict[str, tuple[Callable[[Path], bool], Callable[..., Recording]]] = {
    "euroc": (euroc.detect, euroc.read),
    "rosbag2": (rosbag2.detect, rosbag2.read),
    "video": (video.detect, video.read),
    "images": (images.detect, images.read),
}


def detect_format(source: str | os.PathLike) -> str:
    """The format of ``source`` (see :data:`READERS`); one-line error when none fits."""
    src = Path(source)
    if not src.exists():
        raise SequenceError(f"{src}: does not exist")
    for name, (detect, _) in READERS.items():
        if detect(src):
            return name
    raise SequenceError(
        f"{src}: format not recognised (an image folder or list, a video, a EuRoC folder with mav0/, "
        "a ROS 2 bag folder); give --format"
    )


def read_recording(
    source: str | os.PathLike, fmt: str | None = None, options: ImportOptions | None = None
) -> Recording:
    """Open ``source`` with the reader of ``fmt`` (detected when None)."""
    src = Path(source)
    if fmt is not None and fmt not in READERS:
        raise ConfigError(f"--format {fmt!r}: unknown (known: {', '.join(sorted(READERS))})")
    if not src.exists():
        raise SequenceError(f"{src}: does not exist")
    name = fmt or detect_format(src)
    return READERS[name][1](src, options)


def import_sequence(
    source: str | os.PathLike, out: str | os.PathLike, fmt: str | None = None, options: ImportOptions | None = None
) -> ImportResult:
    """Import ``source`` (format ``fmt``, detected when None) as the sequence folder ``out``."""
    return write_recording(read_recording(source, fmt, options), out, options)
