"""``results.csv`` and the other row tables of the bench: one row per dict, read back typed.

The bench (``DIR/results.csv``: one row per scene x estimator x repetition), the
paper-000 protocol (``runs.csv``, ``summary.csv``) and sweeps (``DIR/results.csv`` with a
``job`` column) write their rows here. Columns: the given leading columns, then every
other key in the order first seen. Numbers are written as plain decimals
(:func:`floorvo.io.csv_cell`), so ``csv`` + ``float`` (or a spreadsheet) reads them back.
"""

from __future__ import annotations

import csv
import io
import os
import re
from collections.abc import Mapping
from collections.abc import Sequence as SequenceT
from pathlib import Path
from typing import Any

from floorvo.errors import SequenceError, shorten, shown
from floorvo.io import atomic_write_csv, read_text

__all__ = [
    "ID_COLUMNS",
    "TEXT_COLUMNS",
    "RESULTS_CSV",
    "STUDY_RECORD",
    "write_results_csv",
    "read_results_csv",
    "other_results_problem",
]

#: The rows of a bench or a study, in its output folder.
RESULTS_CSV = "results.csv"
#: The record a study writes into its folder before any job (:func:`floorsim.bench.study.write_study_record`):
#: a folder holding it is a study's; a ``results.csv`` without it, a bench's.
STUDY_RECORD = "study.json"

#: Leading columns of results.csv; metric columns follow.
ID_COLUMNS = [
    "scene",
    "scene_file",
    "estimator",
    "source",
    "source_detail",
    "repetition",
    "seed",
    "status",
    "sequence",
    "run_dir",
]
#: Columns read back as text even when a cell looks like a number.
TEXT_COLUMNS = frozenset(
    {
        "scene",
        "scene_file",
        "estimator",
        "source",
        "source_detail",
        "status",
        "stderr_tail",
        "lost_reasons",
        "sequence",
        "run_dir",
        "job",
        "ground_truth",
        "score_warnings",
        "est_config",
        "inputs",
    }
)


def _columns(rows: SequenceT[Mapping[str, Any]], first: SequenceT[str]) -> list[str]:
    cols = list(first)
    for r in rows:
        for k in r:
            if k not in cols:
                cols.append(k)
    return cols


def write_results_csv(
    path: str | os.PathLike, rows: SequenceT[Mapping[str, Any]], first_columns: SequenceT[str] = ID_COLUMNS
) -> None:
    """Write rows (dicts) as CSV atomically; columns: ``first_columns``, then every other key seen."""
    cols = _columns(rows, first_columns)
    atomic_write_csv(path, cols, ([r.get(c) for c in cols] for r in rows))


#: A cell that is a whole number as written (no point, no exponent): read back as an int.
_WHOLE = re.compile(r"[+-]?[0-9]+")


def read_results_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Rows of a results.csv; numeric cells become numbers (empty cells None), ``repetition`` an int:
    a cell written as a whole number (``7``, a seed) an int, any other (``7.0``, ``0.25``, ``nan``)
    a float, so that rows read and written again keep their text (a resumed sweep wrote the
    earlier rows' seed 7 back as 7.0).

    A file that is not CSV text, or a ``repetition`` that is not a whole number, is a
    one-line :class:`~floorvo.errors.SequenceError` (a sweep that resumes reads its results.csv).
    """
    path = Path(path)
    if not path.is_file():
        return []
    text = read_text(path, SequenceError, what="a CSV text file")
    reader = csv.DictReader(io.StringIO(text, newline=""))
    try:
        rows = [(reader.line_num, r) for r in reader]
    except csv.Error as exc:  # a NUL byte, a field beyond the csv module's limit
        raise SequenceError(f"{path}: not a readable CSV file ({shorten(str(exc))})") from None
    width = len(reader.fieldnames or ())
    out = []
    for lineno, r in rows:
        if None in r or None in r.values():  # cells beyond the header's, or fewer (a row cut short, a stray line)
            cells = width + len(r.get(None) or ()) - sum(v is None for k, v in r.items() if k is not None)
            raise SequenceError(f"{path}:{lineno}: a row of {cells} cells under a header of {width}")
        d: dict[str, Any] = {}
        for k, v in r.items():
            if k in TEXT_COLUMNS:
                d[k] = v
            elif v == "":
                d[k] = None
            elif _WHOLE.fullmatch(v):
                d[k] = int(v)
            else:
                try:
                    d[k] = float(v)
                except (ValueError, TypeError):
                    d[k] = v
        rep = d.get("repetition")
        if rep is not None:
            if not isinstance(rep, (int, float)) or not float(rep).is_integer() or rep < 0:
                raise SequenceError(f"{path}:{lineno}: repetition = {shown(rep)}: must be a whole number >= 0")
            d["repetition"] = int(rep)
        out.append(d)
    return out


def other_results_problem(out_dir: str | os.PathLike, writer: str) -> str:
    """Why ``writer`` (``"bench"`` or ``"sweep"``) must not write into ``out_dir``: it holds the
    results of the other kind; "" when it does not. A sweep into a bench's folder merged the
    bench's rows into the study's results and report; a bench into a study's folder replaced
    the study's ``results.csv`` with its own."""
    out = Path(out_dir)
    if writer == "bench" and (out / STUDY_RECORD).is_file():
        return (
            f"{out}: holds a study's results ({STUDY_RECORD}, written by floorsim sweep); a bench writes a "
            "folder of its own: choose another output folder"
        )
    if writer == "sweep" and (out / RESULTS_CSV).is_file() and not (out / STUDY_RECORD).is_file():
        return (
            f"{out}: holds a bench's results ({RESULTS_CSV} without a {STUDY_RECORD}); a sweep writes a folder "
            "of its own: choose another output folder"
        )
    return ""
