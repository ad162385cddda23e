"""Regression gates: a worse run fails, an equal one passes (baselines from real scores)."""

import json

import pytest
from _bench_data import write_run, write_sequence

from floorsim.bench.gates import DEFAULT_TOLERANCES, compare, load_baseline, save_baseline
from floorvo.errors import ConfigError
from floorvo.metrics import score_run


def _rows(tmp_path, tag, **run_kw):
    seq = tmp_path / "seq"
    if not seq.exists():
        write_sequence(seq)
    rows = []
    for rep in range(2):
        run = write_run(tmp_path / tag / f"rep{rep}", seq, **run_kw)
        rows.append({"scene": "demo", "estimator": "fake", "repetition": rep, **score_run(run, seq).flat()})
    return rows


def test_gate_passes_on_an_equal_run_and_fails_on_a_worse_one(tmp_path):
    base_rows = _rows(tmp_path, "base", scale=1.01)
    b = save_baseline(tmp_path / "baseline.json", base_rows)
    assert b["entries"]["demo/fake"]["end_drift_pct"] == pytest.approx(1.0, rel=1e-6)
    baseline = load_baseline(tmp_path / "baseline.json")

    same = compare(_rows(tmp_path, "same", scale=1.01), baseline)
    assert same.ok and same.checked == len(DEFAULT_TOLERANCES)  # every gated metric checked once

    worse = compare(_rows(tmp_path, "worse", scale=1.03, lost=(5,)), baseline)
    assert not worse.ok
    bad = {r.metric for r in worse.regressions}
    assert {"end_drift_pct", "ate_none_rmse_mm", "lost_frames"} <= bad
    assert "got worse" in worse.summary() and "FAILED" in worse.summary()

    better = compare(_rows(tmp_path, "better", scale=1.001), baseline)
    assert better.ok and better.improved


def test_tolerance_decides(tmp_path):
    rows = [{"scene": "s", "estimator": "e", "end_drift_pct": 1.0}]
    baseline = {"tolerances": {"end_drift_pct": {"abs": 0.0, "rel": 0.1}}, "entries": {"s/e": {"end_drift_pct": 1.0}}}
    assert compare([{**rows[0], "end_drift_pct": 1.099}], baseline).ok
    assert not compare([{**rows[0], "end_drift_pct": 1.101}], baseline).ok
    # A metric that was finite and is now missing (the run failed) is worse.
    assert not compare([{"scene": "s", "estimator": "e", "end_drift_pct": float("nan")}], baseline).ok
    r = compare([{"scene": "t", "estimator": "e", "end_drift_pct": 9.0}], baseline)
    assert r.ok and r.only_in_baseline == ["s/e"] and r.only_in_bench == ["t/e"]


def test_bad_baseline_files_are_refused_by_name(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_baseline(tmp_path / "none.json")
    p = tmp_path / "b.json"
    p.write_text(json.dumps({"format": "other"}))
    with pytest.raises(ConfigError, match="not a floorbench baseline"):
        load_baseline(p)
