"""A folder of image files, or a text file listing them, as a recording.

* A folder: every PNG, JPEG, TIFF or BMP file in it (not in subfolders), in natural order
  (``img_2.jpg`` before ``img_10.jpg``).
* A list file (``.txt``): one image a line, a path relative to the list's folder, or
  ``TIMESTAMP PATH`` (seconds, as in a TUM ``rgb.txt``), in frame order; times that do not
  increase are refused naming the list and the line.

Frames may be 8- or 16-bit; colour frames are converted to mono. The folder states no
times: they come from the list, a ``--timestamps`` file or ``--fps``.
"""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from floorvo.errors import SequenceError, shown
from floorvo.importers.recording import FrameImages, Recording, natural_key, read_image_file, size_of
from floorvo.io import read_text
from floorvo.sequence import check_timestamps

__all__ = ["IMAGE_SUFFIXES", "detect", "read", "list_images"]

log = logging.getLogger(__name__)

#: File suffixes read as frames (case-insensitive).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".tif", ".tiff", ".bmp")
#: Suffixes of the other image formats OpenCV decodes: a folder holding such files is refused,
#: not read without them (its PGM frames were left out with exit code 0).
OTHER_IMAGE_SUFFIXES = (
    ".pgm",
    ".ppm",
    ".pbm",
    ".pnm",
    ".pfm",
    ".webp",
    ".exr",
    ".hdr",
    ".pic",
    ".sr",
    ".ras",
    ".jp2",
    ".avif",
)


def detect(source: Path) -> bool:
    """True for a folder holding image files or a ``.txt`` list file."""
    if source.is_file():
        return source.suffix.lower() == ".txt"
    return source.is_dir() and any(p.suffix.lower() in IMAGE_SUFFIXES for p in source.iterdir())


def list_images(source: Path) -> tuple[list[Path], np.ndarray | None]:
    """The frame files of ``source`` in frame order, and their times (s) when a list file gives them."""
    if source.is_dir():
        entries = sorted((p for p in source.iterdir() if p.is_file()), key=lambda p: natural_key(p.name))
        other = [p.name for p in entries if p.suffix.lower() in OTHER_IMAGE_SUFFIXES]
        if other:
            raise SequenceError(
                f"{source}: holds {len(other)} image file(s) of a format not read as frames ({shown(other[0])}"
                f"{', ...' if len(other) > 1 else ''}): frames are {', '.join(IMAGE_SUFFIXES)}; convert them, "
                "or list the frames to import in a text file"
            )
        files = [p for p in entries if p.suffix.lower() in IMAGE_SUFFIXES]
        if not files:
            raise SequenceError(f"{source}: holds no image files ({', '.join(IMAGE_SUFFIXES)})")
        return files, None
    if not source.is_file():
        raise SequenceError(f"{source}: does not exist")
    files, times, linenos = [], [], []
    for lineno, line in enumerate(read_text(source, SequenceError, what="a text file").splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split(maxsplit=1)
        if len(parts) == 2:
            try:
                times.append(float(parts[0]))
                linenos.append(lineno)
                name = parts[1].strip()
            except ValueError:
                name = line
        else:
            name = line
        path = Path(name)
        files.append(path if path.is_absolute() else source.parent / path)
        try:
            exists = files[-1].is_file()
        except OSError:  # a name longer than the file system allows
            exists = False
        if not exists:
            raise SequenceError(f"{source}:{lineno}: image {shown(name)} does not exist")
    if not files:
        raise SequenceError(f"{source}: lists no images")
    if times and len(times) != len(files):
        raise SequenceError(f"{source}: some lines have a timestamp and some do not (TIMESTAMP PATH or PATH)")
    return files, (check_timestamps(np.array(times), None, str(source), linenos) if times else None)


def read(source: Path, options=None) -> Recording:
    """The frames of ``source`` (a folder or a list file), read lazily."""
    files, times = list_images(source)
    first = read_image_file(files[0])
    size = size_of(first)
    frame0 = f"frame 0 is {size[0]}x{size[1]} px"

    def frames() -> Iterator[FrameImages]:
        for f in files:
            yield FrameImages(read_image_file(f, size, frame0))  # another size: refused before decoding

    log.info("%s: %d image files", source, len(files))
    return Recording(
        format="images",
        source=source,
        frame_count=len(files),
        size_px=(first.shape[1], first.shape[0]),
        bit_depth=8 * first.itemsize,
        frames=frames,
        timestamps_s=times,
        details={"first_file": files[0].name, "last_file": files[-1].name},
    )
