"""``results.csv`` and the other row tables of the bench: one row per dict, read back typed.

The bench (``DIR/results.csv``: one row per scene x estimator x repetition), the
paper-000 protocol (``runs.csv``, ``summary.csv``) and sweeps (``DIR/results.csv`` with a
``job`` column) write their rows here. Columns: the given leading columns, then every
other key in the order first seen. Numbers are written as plain decimals
(:func:`floorvo.io.csv_cell`), so ``csv`` + ``float`` (or a spreadsheet) reads them back.
"""

from __future__ import annotations

import csv
import os
from collections.abc import Mapping
from collections.abc import Sequence as SequenceT
from pathlib import Path
from typing import Any

from floorvo.io import atomic_write_csv

__all__ = ["ID_COLUMNS", "TEXT_COLUMNS", "write_results_csv", "read_results_csv"]

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
        "sequence",
        "run_dir",
        "job",
        "ground_truth",
        "score_warnings",
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


def read_results_csv(path: str | os.PathLike) -> list[dict[str, Any]]:
    """Rows of a results.csv; numeric cells become floats (empty cells None), ``repetition`` an int."""
    path = Path(path)
    if not path.is_file():
        return []
    out = []
    with path.open(newline="") as fh:
        for r in csv.DictReader(fh):
            d: dict[str, Any] = {}
            for k, v in r.items():
                if k in TEXT_COLUMNS:
                    d[k] = v
                elif v == "":
                    d[k] = None
                else:
                    try:
                        d[k] = float(v)
                    except ValueError:
                        d[k] = v
            if d.get("repetition") is not None:
                d["repetition"] = int(d["repetition"])
            out.append(d)
    return out
