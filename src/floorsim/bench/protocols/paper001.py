"""Paper 001's table in the bench: a 3 m straight line against the paper's 0.783 % error.

Li et al. (JSER 2020) report an error of 0.783 % over a 3 m line at 0.3 m/s (abstract and
section 6.3). Every estimator row of a scene that asks for this protocol gets the paper's
figure as the column ``paper_ref_error_pct``, and the report a table of each run's distance
error and end-point error in % of the distance travelled beside it.

The paper does not define its error: section 6.1 says the algorithm was tested "by comparing
the side deviation error of ICP-SVD algorithm in linear motion" (a lateral deviation, it
seems), section 6.3 that "the error range is maintained at 0.783%". The report's "beats
paper" compares the absolute distance error (measured against true path length) with it;
the end-point error, which holds the lateral deviation too, is in the table beside it.
"""

from __future__ import annotations

import math
from typing import Any, ClassVar

from floorsim.bench.protocols.base import BenchContext, BenchProtocol, ProtocolOutput, SceneRun
from floorsim.bench.report import Report

__all__ = ["PAPER001_ERROR_PCT", "Paper001Line"]

#: Paper 001's reported error over its 3 m straight line (abstract and section 6.3).
PAPER001_ERROR_PCT = 0.783


class Paper001Line(BenchProtocol):
    """``paper001-line``: the paper's reference error beside each run's (see the module doc)."""

    name: ClassVar[str] = "paper001-line"
    description: ClassVar[str] = "paper 001: distance error over a straight line against the paper's 0.783 %"
    trajectory_types: ClassVar[tuple[str, ...]] = ("line",)

    def row_columns(self, scene: SceneRun) -> dict[str, Any]:
        return {"paper_ref_error_pct": PAPER001_ERROR_PCT}

    def run_scene(self, ctx: BenchContext, scene: SceneRun) -> ProtocolOutput:
        return ProtocolOutput(sections=[_section(list(scene.rows))])


def _section(rows: list[dict[str, Any]]):
    def section(rep: Report) -> None:
        rep.heading("Paper 001 reproduction: 3 m straight line")
        rep.text(
            f"Li et al. (JSER 2020) report an error of {PAPER001_ERROR_PCT} % over a 3 m line at 0.3 m/s. "
            "Here: the measured against the true distance (distance error) and the end-point error, each in % "
            "of the distance travelled; 'beats paper' compares the absolute distance error with the paper's."
        )
        table = []
        for r in rows:
            de = r.get("distance_error_pct")
            beats = "-"
            if isinstance(de, float) and math.isfinite(de):
                beats = "yes" if abs(de) <= PAPER001_ERROR_PCT else "no"
            table.append({**r, "paper": PAPER001_ERROR_PCT, "beats": beats})
        rep.table(
            table,
            [
                ("estimator", "estimator"),
                ("repetition", "rep"),
                ("path_length_mm", "path mm"),
                ("measured_mm", "measured mm"),
                ("distance_error_pct", "distance error %"),
                ("end_drift_pct", "end-point error %"),
                ("paper", "paper 001 %"),
                ("beats", "beats paper"),
            ],
        )

    return section
