"""The bench end to end on a tiny real render with the registered estimators."""

import pytest

from floorsim.bench import run_bench
from floorsim.bench.results import read_results_csv
from floorvo.estimators import get_estimator, list_estimators

pytestmark = pytest.mark.render


def test_bench_on_a_tiny_render_scores_every_mono_estimator(tmp_path):
    out = tmp_path / "out"
    res = run_bench(["scenes/demo.toml"], None, out, frames=4, spp=2)
    rows = read_results_csv(out / "results.csv")
    mono = [n for n in list_estimators() if not get_estimator(n).requires]
    not_default = [
        n for n in mono if any(f"{n} skipped (not runnable with its default configuration" in t for t in res.notes)
    ]
    assert sorted(r["estimator"] for r in rows) == sorted(set(mono) - set(not_default))
    assert {"phase-corr", "akaze-guided", "akaze-bruteforce"} <= {r["estimator"] for r in rows}
    # estimators that need depth or stereo are skipped on this mono sequence, and say why
    for n in set(list_estimators()) - set(mono):
        assert any(t.startswith(f"demo: {n} skipped (needs ") for t in res.notes)
    by = {r["estimator"]: r for r in rows}
    # 12 mm in three 4 mm steps; the phase correlation of paper-rig frames is good to a few tenths of a percent
    assert by["phase-corr"]["status"] == "ok"
    assert by["phase-corr"]["path_length_mm"] == pytest.approx(12.0, abs=1e-6)
    assert abs(by["phase-corr"]["end_drift_pct"]) < 2.0
    assert res.report_html.is_file()
    seq_dirs = list((out / "sequences").iterdir())
    assert len(seq_dirs) == 1
    stamp = (seq_dirs[0] / "cam0" / "000000.png").stat().st_mtime_ns
    run_bench(
        ["scenes/demo.toml"],
        ["phase-corr"],
        tmp_path / "again",
        frames=4,
        spp=2,
        cache_dir=out / "sequences",
        report=False,
    )
    assert (seq_dirs[0] / "cam0" / "000000.png").stat().st_mtime_ns == stamp  # reused, not rendered again
