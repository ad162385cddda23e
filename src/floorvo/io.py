"""Atomic file writes and checked image reads.

Every output of the project goes through :func:`atomic_write_bytes` (write a temporary
file in the same folder, fsync, rename), so an interrupted render or run never leaves a
half-written file under the final name. Every number a JSON or CSV writer writes goes
through :func:`plain` first, so numpy scalars come out as ``100.0``, never as numpy 2's
repr ``np.float64(100.0)``, and text (a file name) as valid UTF-8 (:func:`path_text`).
"""

from __future__ import annotations

import contextlib
import csv
import errno
import hashlib
import importlib
import inspect
import io
import json
import math
import os
import re
import secrets
import tomllib
import zipfile
import zlib
from collections.abc import Callable, Iterable, Iterator, Mapping
from collections.abc import Sequence as SequenceT
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from floorvo.errors import SequenceError, shorten, shown

__all__ = [
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_write_json",
    "atomic_write_csv",
    "plain",
    "strict_json",
    "path_text",
    "csv_cell",
    "write_png",
    "read_png",
    "read_image",
    "read_text",
    "read_npy",
    "read_npz",
    "ArrayRule",
    "read_json",
    "read_toml",
    "json_sha256",
    "ensure_writable_dir",
    "remove_stale_temporaries",
    "checked_output_path",
    "checked_output_file",
    "sequence_folder_above",
    "file_in_the_way",
    "make_folders",
    "file_name_problem",
    "MAX_NAME_BYTES",
    "png_size",
    "png_header_size",
    "image_header_size",
    "IMAGE_FORMATS",
    "image_size_problem",
    "MAX_IMAGE_PIXELS",
    "TEMP_SUFFIX",
    "quiet_native_logs",
]


@contextlib.contextmanager
def quiet_native_logs() -> Iterator[None]:
    """For the block, OpenCV's own log is silent.

    A truncated PNG made OpenCV print ``[ WARN:0@0.29] global grfmt_png.cpp:793 ... PNG input
    buffer is incomplete`` on standard error before the reader's own one-line error: the CLIs run
    their commands in this block (``-v`` leaves the log on). OpenCV's level is set with
    ``cv2.utils.logging.setLogLevel`` and given back after; a library user who calls none of this
    keeps OpenCV's defaults. FFmpeg's messages (a damaged video's) are the video reader's to take:
    it reads them and says what they mean (:mod:`floorvo.importers.video`)."""
    level = cv2.utils.logging.getLogLevel()
    cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_SILENT)
    try:
        yield
    finally:
        cv2.utils.logging.setLogLevel(level)


#: Suffix of the temporary files of :func:`atomic_write_bytes`.
TEMP_SUFFIX = ".tmp"
#: Their names: 8 hex digits now, 8 of [a-z0-9_] from the ``tempfile.mkstemp`` of earlier versions.
_TEMP_NAME = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")


def _create_temporary(path: Path) -> tuple[int, Path]:
    """Create and open (write-only) a new temporary file ``.NAME.XXXXXXXX.tmp`` beside ``path``.

    Created with mode 0666 less the process umask, as ``open`` creates files
    (``tempfile.mkstemp`` creates them 0600, which hid rendered datasets from every other user).
    """
    while True:
        tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}{TEMP_SUFFIX}"
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666), tmp
        except FileExistsError:
            continue


def atomic_write_bytes(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` atomically (temporary file in the same folder, fsync, rename).

    The file gets the permissions any new file gets (0666 less the umask). An ``OSError``
    (a full disk: ``[Errno 28]``, a read-only folder) leaves no temporary file behind and
    names ``path`` in its ``filename``, so the CLIs report it in one line. The temporary is
    named ``.NAME.XXXXXXXX.tmp``; one left behind by a killed process is removed by
    :func:`remove_stale_temporaries`. A path that names no file (``""``, ``/``, ``..``) is a
    one-line :class:`SequenceError` (``-o ""`` said ``.: Device or resource busy``).
    """
    if not os.fspath(path).strip() or Path(path).name in ("", ".", ".."):
        raise SequenceError(f"output file {shown(os.fspath(path))}: names no file; give a file name")
    path = Path(path)
    tmp = None
    try:
        make_folders(path.parent)
        fd, tmp = _create_temporary(path)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException as exc:
        if tmp is not None:
            try:
                os.unlink(tmp)
            except FileNotFoundError:
                pass
        if isinstance(exc, OSError):
            exc.filename, exc.filename2 = str(path), None  # the file the user asked for, not the temporary
        raise


def remove_stale_temporaries(folder: str | os.PathLike) -> list[Path]:
    """Delete the temporaries of :func:`atomic_write_bytes` directly in ``folder`` (``.NAME.XXXXXXXX.tmp``).

    Call it only on a folder this process writes alone: a temporary is left behind only when
    its writer was killed between creating and renaming it. Returns the paths removed.
    """
    folder = Path(folder)
    removed = []
    if folder.is_dir():
        for p in folder.iterdir():
            if _TEMP_NAME.fullmatch(p.name) and p.is_file():
                p.unlink(missing_ok=True)
                removed.append(p)
    return removed


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write UTF-8 ``text`` to ``path`` atomically (a file name in it that is not UTF-8
    escaped by :func:`path_text`)."""
    atomic_write_bytes(path, path_text(text).encode("utf-8"))


def path_text(value: str | os.PathLike) -> str:
    """``value`` (a path, a file name, any text) as valid UTF-8 text, as the project writes it
    into JSON, CSV and text files.

    A file name need not be UTF-8: Python holds each byte that is not as a lone surrogate
    (``b"f\\xff0.png"`` is ``"f\\udcff0.png"``), which ``json.dumps`` writes as the escape
    ``\\udcff``, a string that strict JSON readers refuse, and which cannot be encoded as UTF-8
    at all. Such a byte is written as the four characters ``\\xff`` instead
    (``os.fsencode(name).decode("utf-8", "backslashreplace")``); other lone surrogates as
    ``\\udXXX``. Text that is valid already is returned as it is. The escaped name is for
    people and tools to read; :func:`os.fsencode` of it does not give the original bytes back.
    """
    raw = os.fspath(value)
    text = os.fsdecode(raw) if isinstance(raw, bytes) else str(raw)
    if text.isascii():
        return text
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        pass
    try:
        return text.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
    except UnicodeEncodeError:  # a surrogate that is no escaped byte (U+D800-U+DC7F)
        return text.encode("utf-8", "backslashreplace").decode("utf-8")


def plain(obj: Any) -> Any:
    """``obj`` as plain Python data for a JSON or CSV writer.

    numpy scalars become ``int`` / ``float`` / ``bool`` / ``str`` (``np.float64(100.0)``
    -> ``100.0``), arrays and tuples become lists, paths become strings; mappings and
    lists are converted item by item; text (keys too) is made valid UTF-8 by
    :func:`path_text` (a file name that is not). Anything else is returned as it is.
    """
    if isinstance(obj, str):
        return path_text(obj)
    if isinstance(obj, np.generic):
        return plain(obj.item())
    if isinstance(obj, np.ndarray):
        return [plain(v) for v in obj.tolist()]
    if isinstance(obj, Mapping):
        return {plain(k): plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [plain(v) for v in obj]
    if isinstance(obj, os.PathLike):
        return path_text(obj)
    return obj


def strict_json(obj: Any) -> Any:
    """``obj`` as :func:`plain` data whose non-finite floats are None (``null``): strict JSON,
    which ``json.dumps`` would otherwise write as ``NaN`` or ``Infinity`` (not JSON; a strict
    parser refuses the file). For numbers that may be undefined (a score of a run that tracked
    nothing) and for data this project did not write (an external program's ``result.json``)."""
    obj = plain(obj)
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, list):
        return [strict_json(v) for v in obj]
    return obj


def csv_cell(value: Any) -> str:
    """One CSV cell: numbers as plain decimals that ``float()`` reads back exactly
    (``repr`` of the Python float: ``100.0``, ``nan``, ``inf``), None as an empty cell."""
    value = plain(value)
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else str(value)
    return str(value)


def atomic_write_json(path: str | os.PathLike, obj: Any) -> None:
    """Write ``obj`` as indented JSON to ``path`` atomically (numbers made plain by :func:`plain`)."""
    atomic_write_text(path, json.dumps(plain(obj), indent=2, sort_keys=False) + "\n")


def atomic_write_csv(path: str | os.PathLike, header: SequenceT[str], rows: Iterable[Iterable[Any]]) -> None:
    """Write a CSV file atomically: the ``header`` row, then ``rows`` (sequences of cells,
    each written by :func:`csv_cell`)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(header)
    w.writerows([csv_cell(v) for v in row] for row in rows)
    atomic_write_text(path, buf.getvalue())


def write_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write a uint8 or uint16 image (H, W) or (H, W, 3) as PNG, atomically."""
    image = np.asarray(image)
    if image.dtype not in (np.uint8, np.uint16):
        raise TypeError(f"write_png: dtype must be uint8 or uint16, got {image.dtype}")
    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise OSError(f"{path}: PNG encoding failed")
    atomic_write_bytes(path, buf.tobytes())


_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


#: The most pixels an image file may state (a PNG's header), checked before it is decoded:
#: 8192 x 8192, 8 times a 12-megapixel camera's frame, 400 MB decoded as 16-bit colour. A PNG of
#: 389 kB stating 20000 x 20000 pixels decoded to 400 MB (or 2.4 GB as 16-bit colour).
MAX_IMAGE_PIXELS = 8192 * 8192


def png_header_size(head: bytes) -> tuple[int, int] | None:
    """``(width_px, height_px)`` the PNG header (IHDR) at the start of ``head`` states; None when
    ``head`` does not start like a PNG."""
    if len(head) < 24 or head[:8] != _PNG_SIGNATURE or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def png_size(path: str | os.PathLike) -> tuple[int, int] | None:
    """``(width_px, height_px)`` a PNG file's header (IHDR) states, read without decoding; None when
    the file cannot be read or does not start like a PNG. A reader that knows the size it expects
    refuses another before decoding: a small file can state a picture of gigabytes."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(24)
    except OSError:
        return None
    return png_header_size(head)


#: The image formats :func:`read_image` decodes: those whose header :func:`image_header_size` reads.
IMAGE_FORMATS = "PNG, JPEG, TIFF or BMP"
#: JPEG start-of-frame markers (every coding process; C4, C8 and CC are other segments).
_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
#: JPEG markers that stand alone (no length field): TEM, RST0-7, SOI, EOI.
_JPEG_STANDALONE = frozenset([0x01, *range(0xD0, 0xDA)])


def _jpeg_header_size(data: bytes) -> tuple[int, int] | None:
    """``(width_px, height_px)`` of a JPEG's first start-of-frame segment, walking the segments
    as libjpeg does (bytes before a marker skipped, ``FF`` fill bytes and ``FF 00`` too); None
    when no start-of-frame comes before the first scan or the end of ``data``."""
    if data[:2] != b"\xff\xd8":
        return None
    i, n = 2, len(data)
    while i < n:
        i = data.find(b"\xff", i)  # bytes before a marker: libjpeg skips them with a warning
        if i < 0:
            return None
        while i < n and data[i] == 0xFF:  # fill bytes
            i += 1
        if i >= n:
            return None
        marker = data[i]
        i += 1
        if marker == 0 or marker in _JPEG_STANDALONE:  # FF 00: a stuffed byte, no marker
            continue
        if i + 2 > n:
            return None
        length = int.from_bytes(data[i : i + 2], "big")
        if marker in _JPEG_SOF:
            if i + 7 > n:
                return None
            return int.from_bytes(data[i + 5 : i + 7], "big"), int.from_bytes(data[i + 3 : i + 5], "big")
        if marker == 0xDA or length < 2:  # a scan before any frame header, or a broken length
            return None
        i += length
    return None


def _bmp_header_size(data: bytes) -> tuple[int, int] | None:
    """``(width_px, height_px)`` of a BMP's info header (the 12-byte OS/2 one: 16-bit sizes;
    the others: signed 32-bit, a negative height meaning top-down rows)."""
    if data[:2] != b"BM" or len(data) < 26:
        return None
    if int.from_bytes(data[14:18], "little") == 12:
        return int.from_bytes(data[18:20], "little"), int.from_bytes(data[20:22], "little")
    w = int.from_bytes(data[18:22], "little", signed=True)
    h = int.from_bytes(data[22:26], "little", signed=True)
    return abs(w), abs(h)


def _tiff_header_size(data: bytes) -> tuple[int, int] | None:
    """``(width_px, height_px)`` of a TIFF's (or BigTIFF's) first image directory: its
    ImageWidth (256) and ImageLength (257) tags; None when either is missing or out of ``data``."""
    if data[:2] == b"II":
        order: Any = "little"
    elif data[:2] == b"MM":
        order = "big"
    else:
        return None

    def u(at: int, size: int) -> int | None:
        return int.from_bytes(data[at : at + size], order) if 0 <= at and at + size <= len(data) else None

    magic = u(2, 2)
    if magic == 42:  # classic TIFF: 4-byte offsets, 12-byte entries
        ifd, count_size, entry_size, value_at, offset_size = u(4, 4), 2, 12, 8, 4
    elif magic == 43 and u(4, 2) == 8:  # BigTIFF: 8-byte offsets, 20-byte entries
        ifd, count_size, entry_size, value_at, offset_size = u(8, 8), 8, 20, 12, 8
    else:
        return None
    entries = None if ifd is None else u(ifd, count_size)
    if ifd is None or entries is None:
        return None
    tags: dict[int, int] = {}
    for k in range(entries):
        at = ifd + count_size + k * entry_size
        tag, kind = u(at, 2), u(at + 2, 2)
        if tag is None or kind is None:
            return None
        if tag in (256, 257):
            size = {3: 2, 4: 4, 16: 8}.get(kind)  # SHORT, LONG, LONG8
            value = None if size is None or size > offset_size else u(at + value_at, size)
            if value is None:
                return None
            tags[tag] = value
        if len(tags) == 2:
            return tags[256], tags[257]
    return None


def image_header_size(data: bytes) -> tuple[int, int] | None:
    """``(width_px, height_px)`` the header of the image file ``data`` (its bytes) states, read
    without decoding: a PNG's IHDR, a JPEG's start of frame, a BMP's info header, a TIFF's first
    image directory (the one OpenCV decodes). None for another format or a header that cannot be
    read: :func:`read_image` decodes only an image whose size it has checked (a JPEG of 700
    bytes can state 65535 x 65535 pixels, 4 GB decoded)."""
    for parse in (png_header_size, _jpeg_header_size, _bmp_header_size, _tiff_header_size):
        size = parse(data)
        if size is not None:
            return size
    return None


def image_size_problem(stated: tuple[int, int] | None) -> str | None:
    """Why an image whose header states ``stated`` = ``(width_px, height_px)`` (:func:`png_size`,
    :func:`image_header_size`; None: not known) must not be decoded, or None: more than
    :data:`MAX_IMAGE_PIXELS`."""
    if stated is None or stated[0] * stated[1] <= MAX_IMAGE_PIXELS:
        return None
    return f"states {stated[0]}x{stated[1]} px in its header, more than the {MAX_IMAGE_PIXELS} px (8192 x 8192) an image may have"


def read_png(path: str | os.PathLike, size_px: tuple[int, int] | None = None, size_source: str = "") -> np.ndarray:
    """Read a PNG unchanged (8- or 16-bit, mono or colour).

    Raises :class:`SequenceError` with a one-line message if the file is missing, is not a
    readable PNG, or states in its header another size than ``size_px`` or too many pixels
    (:func:`read_image`).
    """
    return read_image(path, "frame file", "PNG", size_px, size_source)


def read_image(
    path: str | os.PathLike,
    noun: str = "image file",
    kind: str = "image",
    size_px: tuple[int, int] | None = None,
    size_source: str = "",
) -> np.ndarray:
    """Read a PNG, JPEG, TIFF or BMP file unchanged (8- or 16-bit, mono or colour).

    A missing file raises :class:`SequenceError` "PATH: NOUN is missing", an undecodable
    one "PATH: not a readable KIND (corrupt or truncated)". The size the file's header states
    (:func:`image_header_size`) is checked before it is decoded: another size than ``size_px``
    (``(width_px, height_px)``, when given; ``size_source`` says where it comes from:
    ``frame 0 is 648x494 px``) or more than :data:`MAX_IMAGE_PIXELS` is refused
    (:func:`image_size_problem`), since a small file can state gigabytes; a file whose header
    states no size this reader can read (another format that OpenCV would decode: WebP, PPM,
    OpenEXR, ...) is refused as well.
    """
    path = Path(path)
    if not path.is_file():
        raise SequenceError(f"{path}: {noun} is missing")
    try:
        data = np.fromfile(path, dtype=np.uint8)
    except OSError as exc:
        raise SequenceError(f"{path}: {noun} cannot be read ({exc.strerror or exc})") from None
    stated = image_header_size(data.tobytes())
    if stated is None:
        raise SequenceError(
            f"{path}: not a readable {kind} (corrupt or truncated, or not a {IMAGE_FORMATS} file: "
            "no header stating its size)"
        )
    if size_px is not None and stated != tuple(size_px):
        expected = size_source or f"need {size_px[0]}x{size_px[1]} px"
        raise SequenceError(f"{path}: image is {stated[0]}x{stated[1]}, {expected}")
    problem = image_size_problem(stated)
    if problem:
        raise SequenceError(f"{path}: {kind} {problem}")
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED)
    if img is None:
        raise SequenceError(f"{path}: not a readable {kind} (corrupt or truncated)")
    return img


#: A rule on an array's header: ``(shape, dtype)`` -> why the array is refused, or None.
ArrayRule = Callable[[tuple[int, ...], np.dtype], "str | None"]


def _read_array(fh: Any, stored_bytes: int | None, rule: ArrayRule | None, what: str) -> np.ndarray:
    """The array of the ``.npy`` stream ``fh``, its header checked before any data is read.

    Refused with an :class:`_ArrayRefused` whose message names ``what``: an object dtype
    (pickled Python objects: never loaded), what ``rule`` refuses, and a shape that the data
    after the header (``stored_bytes``, when known) does not hold: a header of 100 bytes can
    state an array of terabytes, and ``np.load`` allocates what it states before reading. A
    header numpy cannot read raises numpy's ValueError."""
    fmt = np.lib.format
    version = fmt.read_magic(fh)
    if version == (1, 0):
        shape, fortran, dtype = fmt.read_array_header_1_0(fh)
    elif version == (2, 0):
        shape, fortran, dtype = fmt.read_array_header_2_0(fh)
    else:
        raise _ArrayRefused(f"{what} is .npy format version {version[0]}.{version[1]}; only 1.0 and 2.0 are read")
    if dtype.hasobject:
        raise _ArrayRefused(f"{what} holds Python objects (dtype {dtype}); only arrays of numbers are read")
    problem = rule(tuple(shape), dtype) if rule else None
    if problem:
        raise _ArrayRefused(f"{what} has shape {tuple(shape)} and dtype {dtype}: {problem}")
    count = math.prod(shape)
    size = count * dtype.itemsize
    if stored_bytes is not None and stored_bytes - fh.tell() != size:
        raise _ArrayRefused(
            f"{what} states shape {tuple(shape)} of {dtype} ({size} bytes) in its header; "
            f"the file holds {max(stored_bytes - fh.tell(), 0)} bytes of data"
        )
    data = fh.read(size)  # grows with the data there is, not with what the header states
    if len(data) != size:
        raise _ArrayRefused(f"{what} is cut short: {len(data)} of the {size} bytes its header states")
    array = np.frombuffer(data, dtype=dtype, count=count).reshape(shape, order="F" if fortran else "C")
    return array.copy()  # writable, as np.load's


class _ArrayRefused(ValueError):
    """An array whose header a reader's rule refuses (its message is the rule, shown as it is)."""


def read_npy(
    path: str | os.PathLike,
    rule: ArrayRule | None = None,
    what: str = ".npy array",
    error: type[Exception] = SequenceError,
) -> np.ndarray:
    """The array of the ``.npy`` file ``path``, read as ``np.load(path, allow_pickle=False)`` would,
    but its header checked first (:func:`_read_array`): ``rule(shape, dtype)`` (e.g. a depth
    map's size and dtype), and the file must hold the bytes the header states. Every refusal is
    a one-line ``error`` naming ``path``: "PATH: not a readable WHAT (...)", "PATH: WHAT has
    shape ... and dtype ...: RULE", ..."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            return _read_array(fh, os.fstat(fh.fileno()).st_size, rule, what)
    except _ArrayRefused as exc:
        raise error(f"{path}: {exc}") from None
    except (OSError, ValueError, EOFError) as exc:
        reason = exc.strerror if isinstance(exc, OSError) and exc.strerror else str(exc)
        raise error(f"{path}: not a readable {what} ({shorten(reason)})") from None


def read_npz(
    source: str | os.PathLike | bytes,
    rules: Mapping[str, ArrayRule | None],
    label: str,
    what: str = ".npz archive",
    error: type[Exception] = SequenceError,
) -> dict[str, np.ndarray]:
    """The arrays named by ``rules`` of the ``.npz`` archive ``source`` (a path, or its bytes),
    as ``np.load(allow_pickle=False)`` gives them, each header checked before its data is read
    (:func:`read_npy`): its rule, and the bytes the archive's directory states for the member.
    A missing array, a damaged archive or a refused header is a one-line ``error`` starting
    with ``label`` (the file's name)."""
    try:
        with zipfile.ZipFile(io.BytesIO(source) if isinstance(source, bytes) else source) as zf:
            names = {n.removesuffix(".npy"): n for n in zf.namelist()}
            out = {}
            for name, rule in rules.items():
                if name not in names:
                    raise _ArrayRefused(f"array {name!r} is missing (has: {shorten(', '.join(names))})")
                info = zf.getinfo(names[name])
                with zf.open(info) as fh:
                    try:
                        out[name] = _read_array(fh, info.file_size, rule, f"array {name!r}")
                    except _ArrayRefused:  # a ValueError with its own message
                        raise
                    except (ValueError, EOFError) as exc:
                        raise _ArrayRefused(f"array {name!r} is not readable ({shorten(str(exc))})") from None
            return out
    except _ArrayRefused as exc:
        raise error(f"{label}: {exc}") from None
    except (OSError, zipfile.BadZipFile, zlib.error, EOFError, ValueError, NotImplementedError) as exc:
        raise error(f"{label}: not a readable {what} ({type(exc).__name__}: {shorten(str(exc))})") from None


def read_text(
    path: str | os.PathLike, error: type[Exception] = SequenceError, label: str | None = None, what: str = "text"
) -> str:
    """The UTF-8 text of a file; an unreadable file or one that is not UTF-8 text (a binary
    file where a TUM, JSON or TOML file belongs) raises ``error`` with one line naming
    ``label`` (default: the path) and ``what`` the file should be (``a TUM text file``).

    A leading byte-order mark (Windows editors write one) is not part of the text: a scene file
    saved so was 'not valid TOML (Invalid statement (at line 1, column 1))'.
    """
    path = Path(path)
    name = label or str(path)
    try:
        return path.read_bytes().decode("utf-8-sig")
    except OSError as exc:
        raise error(f"{name}: cannot be read ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise error(f"{name}: not {what} (byte {exc.start} is not UTF-8 text)") from None


class _DuplicateKey(ValueError):
    """A key given twice in one JSON object (see :func:`read_json`)."""


def _unique_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    obj: dict[str, Any] = {}
    for key, value in pairs:
        if key in obj:
            raise _DuplicateKey(key)
        obj[key] = value
    return obj


def read_json(path: str | os.PathLike, error: type[Exception] = SequenceError, label: str | None = None) -> Any:
    """Parse a JSON file; a missing, unreadable or malformed file raises ``error`` with one line.

    ``label`` names the file in the message (default: its path). A key given twice in one
    object is refused (JSON parsers keep the last one silently: ``"fps": 30, "fps": 7``).
    """
    name = label or str(path)
    text = read_text(path, error, label, "valid JSON")
    try:
        return json.loads(text, object_pairs_hook=_unique_keys)
    except _DuplicateKey as exc:
        raise error(f"{name}: key {shown(str(exc))} is given twice in one object") from None
    except json.JSONDecodeError as exc:
        raise error(f"{name}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    except (ValueError, RecursionError) as exc:  # an integer of 5000 digits, arrays nested 100,000 deep
        raise error(f"{name}: not valid JSON ({shorten(str(exc))})") from None


def read_toml(path: str | os.PathLike, error: type[Exception] = SequenceError, label: str | None = None) -> dict:
    """Parse a TOML file (a scene, a sweep); a missing, unreadable or malformed file raises
    ``error`` with one line. ``label`` names the file in the message (default: its path)."""
    name = label or str(path)
    text = read_text(path, error, label, "valid TOML")
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise error(f"{name}: not valid TOML ({shorten(str(exc))})") from None
    except RecursionError:
        raise error(f"{name}: not valid TOML (nested too deeply)") from None


def json_sha256(obj: Any) -> str:
    """SHA-256 (hex) of ``obj``'s canonical JSON (keys sorted, no spaces, numbers made plain):
    the same for an object and for that object written by :func:`atomic_write_json` and read back."""
    text = json.dumps(plain(obj), sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


def code_sha256(*code: Any) -> str:
    """SHA-256 (hex) of the source of ``code``, in the order given: the one fingerprint of code
    that cached results are keyed by or recorded with (the tile cache's tiles, the bench's rendered
    sequences, a study's rows). Each item is a module, a module's name, or a function or class; a
    package is its every ``*.py`` file (sorted by path, each path hashed with its bytes), so an edit
    anywhere in it changes the fingerprint. Code without source (a frozen or compiled plugin)
    counts as its name and ``__version__``."""
    h = hashlib.sha256()
    for item in code:
        obj = importlib.import_module(item) if isinstance(item, str) else item
        folders = list(getattr(obj, "__path__", None) or [])
        if folders:
            root = Path(folders[0])
            for f in sorted(root.rglob("*.py")):
                h.update(f.relative_to(root).as_posix().encode())
                h.update(f.read_bytes())
            continue
        try:
            h.update(inspect.getsource(obj).encode())
        except (OSError, TypeError):
            h.update(f"{getattr(obj, '__name__', obj)} {getattr(obj, '__version__', '')}".encode())
    return h.hexdigest()


def checked_output_path(path: str | os.PathLike, error: type[Exception] = SequenceError) -> Path:
    """``path`` as a Path, refusing the empty path, the root of a file system and a path under a
    file (one line, ``error``).

    ``-o ""`` would write into the current folder and ``-o /`` into the file-system root;
    ``-o FILE/out`` can never be created (:func:`file_in_the_way`).
    """
    raw = os.fspath(path)
    if str(raw).strip() == "":
        raise error("output folder '': the path is empty; name a folder")
    p = Path(raw)
    try:
        resolved = p.resolve()
    except (RuntimeError, OSError) as exc:  # a loop of symbolic links (RuntimeError before Python 3.13)
        raise error(f"{raw}: cannot be resolved ({shorten(str(exc))}); name a folder") from None
    if resolved == Path(resolved.anchor):
        raise error(f"{raw}: is the root of a file system; name a folder below it")
    _refuse_file_in_the_way(p, error)
    return p


def sequence_folder_above(path: str | os.PathLike) -> Path | None:
    """The sequence folder (one holding ``sequence.json``) that ``path`` lies inside (its parents,
    symbolic links followed), or None. Nothing but a sequence's own writer writes into one."""
    for parent in Path(os.path.realpath(path)).parents:
        if (parent / "sequence.json").is_file():
            return parent
    return None


def checked_output_file(
    path: str | os.PathLike, error: type[Exception] = SequenceError, *, reads: Iterable[str | os.PathLike] = ()
) -> Path:
    """``path`` as the Path of an output file, refused in one line (``error``) before any work when
    it names no file (``""``, ``.``, ``..``), is a folder, or lies under a file
    (``--save-baseline FILE/base.json`` was found out only after the whole bench had run); and,
    for a command that reads the files ``reads``, when it is one of them or lies inside a
    sequence folder (``floorvo score RUN -o RUN/trajectory.txt`` wrote the score over the run
    it scored, ``floorvo plot ... -o SEQ/cam0/000003.png`` over a frame, with exit code 0)."""
    raw = os.fspath(path)
    if not str(raw).strip() or Path(raw).name in ("", ".", ".."):
        raise error(f"output file {shown(raw)}: names no file; give a file name")
    p = Path(raw)
    if p.is_dir():
        raise error(f"{raw}: is a folder; give a file name")
    _refuse_file_in_the_way(p, error)
    real = os.path.realpath(p)
    for f in reads:
        if os.path.realpath(f) == real:
            raise error(f"{raw}: this command reads that file ({f}); write the output elsewhere")
    seq = sequence_folder_above(p)
    if seq is not None:
        raise error(f"{raw}: inside the sequence folder {seq} (sequence.json); write the output elsewhere")
    return p


def file_in_the_way(path: str | os.PathLike) -> Path | None:
    """The file (anything but a folder) that stands where a folder above ``path`` would have to
    be, or None: the nearest existing folder above ``path`` is what the path needs."""
    p = Path(os.path.abspath(path)).parent
    while True:
        if p.exists():
            return None if p.is_dir() else p
        if p == p.parent:
            return None
        p = p.parent


def _refuse_file_in_the_way(path: Path, error: type[Exception]) -> None:
    blocker = file_in_the_way(path)
    if blocker is not None:
        raise error(f"{os.fspath(path)}: not a directory ({blocker} is a file)")


def make_folders(path: str | os.PathLike) -> Path:
    """Create the folder ``path`` and its missing parents (``mkdir -p``). A path that is, or lies
    under, a file raises :class:`NotADirectoryError` (errno 20) naming ``path``, as opening such a
    path does: ``Path.mkdir(exist_ok=True)`` said ``File exists (errno 17)`` of ``FILE/out``."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except (FileExistsError, NotADirectoryError):
        if not (path.exists() and not path.is_dir()) and file_in_the_way(path) is None:
            raise  # something else: a folder made and removed again meanwhile
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(path)) from None
    return path


def file_name_problem(name: str) -> str:
    """Why ``name`` cannot name a file or folder inside another (the rule, for an error message);
    "" when it can: not empty, not ``.`` or ``..``, no ``/`` or ``\\``, no control character.
    A name the project makes a path of (a scene's, a map's arrays file) is checked with it: a
    scene named ``../../x`` made the bench write its sequence and runs outside its output folder."""
    if not isinstance(name, str) or name.strip() == "":
        return "must be a name (not empty)"
    if name in (".", "..") or "/" in name or "\\" in name or any(ord(c) < 32 or ord(c) == 127 for c in name):
        return "must be a file name: not . or .., no / or \\, no control characters"
    if len(name.encode("utf-8", "surrogateescape")) > MAX_NAME_BYTES:
        # the file systems' 255 bytes, less what the project adds (a cache folder's -HASH, a temporary's
        # suffix): a scene of 300 characters failed after its render started, 'File name too long'
        return f"must be a file name of at most {MAX_NAME_BYTES} bytes (this one has {len(name.encode('utf-8', 'surrogateescape'))})"
    return ""


#: The longest name :func:`file_name_problem` accepts, in UTF-8 bytes.
MAX_NAME_BYTES = 200


def ensure_writable_dir(path: str | os.PathLike) -> Path:
    """Create ``path`` (and parents) and check that files can be written there."""
    path = Path(path)
    try:
        make_folders(path)
        fd, tmp = _create_temporary(path / "write-test")
        os.close(fd)
        os.unlink(tmp)
    except OSError as exc:
        raise SequenceError(f"{path}: output folder is not writable ({exc.strerror or exc})") from None
    return path
