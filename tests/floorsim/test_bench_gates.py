"""Regression gates: a worse run fails, an equal one passes (baselines from real scores)."""

import json

import pytest
from _bench_data import write_run, write_sequence

from floorsim.bench.gates import DEFAULT_TOLERANCES, compare, load_baseline, parse_baseline, save_baseline
from floorvo.errors import ConfigError
from floorvo.scoring import score_run


def _rows(tmp_path, tag, **run_kw):
    seq = tmp_path / "seq"
    if not seq.exists():
        write_sequence(seq)
    rows = []
    for rep in range(2):
        run = write_run(tmp_path / tag / f"rep{rep}", seq, **run_kw)
        rows.append({"scene": "demo", "estimator": "fake", "repetition": rep, **score_run(run, seq).flat()})
    return rows


def _baseline(tolerances, entries, **extra):
    """A baseline file's content."""
    return {"format": "floorbench-baseline", "version": 1, "tolerances": tolerances, "entries": entries, **extra}


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
    baseline = _baseline({"end_drift_pct": {"abs": 0.0, "rel": 0.1}}, {"s/e": {"end_drift_pct": 1.0}})
    assert compare([{**rows[0], "end_drift_pct": 1.099}], baseline).ok
    assert not compare([{**rows[0], "end_drift_pct": 1.101}], baseline).ok
    # A metric that was finite and is now missing (the run failed) is worse.
    assert not compare([{"scene": "s", "estimator": "e", "end_drift_pct": float("nan")}], baseline).ok
    r = compare([{"scene": "t", "estimator": "e", "end_drift_pct": 9.0}, *rows], baseline, allow_new=True)
    assert r.ok and r.only_in_baseline == [] and r.only_in_bench == ["t/e"]
    r = compare(
        [{"scene": "t", "estimator": "e", "end_drift_pct": 9.0}, *rows],
        _baseline(
            {"end_drift_pct": {"abs": 0.0, "rel": 0.1}}, {"s/e": {"end_drift_pct": 1.0}, "u/e": {"end_drift_pct": 1.0}}
        ),
        allow_new=True,
    )
    assert r.ok and r.only_in_baseline == ["u/e"] and r.only_in_bench == ["t/e"]


def test_direction_comes_from_the_metric_declaration():
    """tracked_fraction and fps are declared higher-is-better: falling is worse, rising is better."""
    tol = {"tracked_fraction": {"abs": 0.01, "rel": 0.0}, "fps": {"abs": 0.0, "rel": 0.5}}
    baseline = _baseline(tol, {"s/e": {"tracked_fraction": 1.0, "fps": 100.0}})
    row = {"scene": "s", "estimator": "e", "tracked_fraction": 1.0, "fps": 100.0}
    assert compare([row], baseline).ok
    assert compare([{**row, "tracked_fraction": 0.995, "fps": 51.0}], baseline).ok  # within the tolerances
    r = compare([{**row, "tracked_fraction": 0.9, "fps": 49.0}], baseline)
    assert {g.metric for g in r.regressions} == {"tracked_fraction", "fps"}
    assert "allowed down to 0.99" in r.summary()
    up = compare([{**row, "fps": 300.0}], baseline)
    assert up.ok and up.improved == ["s/e: fps 300 (baseline 100)"]
    # with no tolerance the limit is the baseline: still 'down to' for a higher-is-better metric
    exact = _baseline({"tracked_fraction": {"abs": 0.0, "rel": 0.0}}, {"s/e": {"tracked_fraction": 0.9}})
    r = compare([{**row, "tracked_fraction": 0.8}], exact)
    assert "tracked_fraction got worse: 0.8 against baseline 0.9 (allowed down to 0.9)" in r.summary(), r.summary()


def test_bad_baseline_files_are_refused_by_name(tmp_path):
    with pytest.raises(ConfigError, match="does not exist"):
        load_baseline(tmp_path / "none.json")
    p = tmp_path / "b.json"
    p.write_text(json.dumps({"format": "other"}))
    with pytest.raises(ConfigError, match="not a floorbench baseline"):
        load_baseline(p)


TOL = {"end_drift_pct": {"abs": 0.0, "rel": 0.1}, "lost_frames": {"abs": 0.0, "rel": 0.0}}
ROW = {"scene": "s", "estimator": "e", "end_drift_pct": 1.0, "lost_frames": 0.0}


def _refused(tmp_path, content, *words):
    """The baseline file holding ``content`` is refused by load_baseline in one line with ``words``."""
    p = tmp_path / "b.json"
    p.write_text(content if isinstance(content, str) else json.dumps(content))
    with pytest.raises(ConfigError) as info:
        load_baseline(p)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"--baseline {p}: ")
    for w in words:
        assert w in msg
    return msg


def test_malformed_baselines_are_refused_in_one_line(tmp_path):
    entries = {"s/e": {"end_drift_pct": 1.0, "lost_frames": 0.0}}
    # a NaN tolerance would pass a metric that got worse (NaN comparisons are false)
    _refused(
        tmp_path,
        '{"format": "floorbench-baseline", "version": 1, "tolerances": '
        '{"end_drift_pct": {"abs": NaN, "rel": 0.1}}, "entries": {"s/e": {"end_drift_pct": 1.0}}}',
        "tolerances.end_drift_pct.abs = nan",
        "finite",
    )
    _refused(tmp_path, _baseline({"end_drift_pct": {"abs": -1}}, entries), "must be a finite number >= 0")
    _refused(tmp_path, _baseline({"end_drift_pct": {"abs": "0.1"}}, entries), "end_drift_pct.abs = '0.1'")
    _refused(tmp_path, _baseline({"end_drift_pct": {"abs": 0.1, "rell": 0.1}}, entries), "end_drift_pct")
    _refused(tmp_path, _baseline({"end_drift_pct": 0.1}, entries), "tolerances.end_drift_pct = 0.1")
    # nothing to check: no tolerances, no entries, entries as a list
    _refused(tmp_path, _baseline({}, entries), "tolerances: empty")
    _refused(tmp_path, {k: v for k, v in _baseline(TOL, entries).items() if k != "tolerances"}, "tolerances: missing")
    _refused(tmp_path, {**_baseline(TOL, entries), "tolerances": None}, "tolerances = null")
    _refused(tmp_path, {k: v for k, v in _baseline(TOL, entries).items() if k != "entries"}, "entries: missing")
    _refused(tmp_path, _baseline(TOL, {}), "entries: empty")
    _refused(tmp_path, _baseline(TOL, [["s/e", {"end_drift_pct": 1.0}]]), "entries = [[", "must be a table")
    # values that are text, lists, NaN, or an entry that is a number
    for bad, shown_as in (("0.3", "'0.3'"), ([0.3], "[0.3]"), (float("nan"), "nan"), (True, "true")):
        msg = _refused(tmp_path, _baseline(TOL, {"s/e": {"end_drift_pct": bad, "lost_frames": 0}}), "must be a finite")
        assert f"entries.s/e.end_drift_pct = {shown_as}" in msg
    _refused(tmp_path, _baseline(TOL, {"s/e": 1.5}), "entries.s/e = 1.5: must be a table")
    _refused(tmp_path, _baseline(TOL, {"s/e": {"end_drift_pct": 1.0}}), "entries.s/e: lacks lost_frames")
    _refused(tmp_path, _baseline(TOL, {"s/e": {**entries["s/e"], "ate": 1}}), "entries.s/e.ate: not a gated metric")
    _refused(tmp_path, _baseline(TOL, {"se": entries["s/e"]}), "entries.se: an entry is named SCENE/ESTIMATOR")
    _refused(tmp_path, [1], "not a floorbench baseline")
    _refused(tmp_path, _baseline(TOL, entries, version=2), "version 2 is not supported")
    _refused(tmp_path, _baseline(TOL, entries, extra=1), "unknown key 'extra'")
    # a 100,000-character value is not echoed whole
    msg = _refused(tmp_path, _baseline(TOL, {"s/e": {"end_drift_pct": "x" * 100_000, "lost_frames": 0}}), "...")
    assert len(msg) < 300
    # a well-formed one loads, and null (no value in the baseline run) is kept as None
    p = tmp_path / "ok.json"
    p.write_text(json.dumps(_baseline(TOL, {"s/e": {"end_drift_pct": None, "lost_frames": 2}})))
    b = load_baseline(p)
    assert b.entries == {"s/e": {"end_drift_pct": None, "lost_frames": 2.0}}
    assert b.tolerances["end_drift_pct"].rel == 0.1 and b.tolerances["lost_frames"].abs == 0.0


def test_a_scene_estimator_without_baseline_entry_fails_unless_allowed():
    baseline = parse_baseline(_baseline(TOL, {"s/e": {"end_drift_pct": 1.0, "lost_frames": 0}}))
    new = {**ROW, "estimator": "f"}
    r = compare([ROW, new], baseline)
    assert not r.ok and r.only_in_bench == ["s/f"] and r.checked == 2 and r.expected == 4
    text = r.summary()
    assert "s/f: no baseline entry" in text and "--allow-new" in text
    assert text.splitlines()[-1] == "regression gate FAILED: 0 metric(s) worse; checked 2 of 4 expected"
    r = compare([ROW, new], baseline, allow_new=True)
    assert r.ok and "checked 2 of 4 expected" in r.summary() and "s/f: new, no baseline" in r.summary()
    # a baseline of other scenes only: nothing checked, which fails even with --allow-new
    for allow in (False, True):
        r = compare([{**ROW, "scene": "t"}], baseline, allow_new=allow)
        assert not r.ok and r.checked == 0 and r.expected == 2 and r.only_in_baseline == ["s/e"]
        assert "checked 0 of 2 expected" in r.summary() and "FAILED" in r.summary()


def test_null_baseline_values_are_counted_and_named_not_dropped():
    baseline = parse_baseline(_baseline(TOL, {"s/e": {"end_drift_pct": None, "lost_frames": 0}}))
    r = compare([{**ROW, "end_drift_pct": 50.0}], baseline)
    assert r.ok and r.checked == 1 and r.expected == 2 and r.no_baseline_value == [("s/e", "end_drift_pct")]
    assert "s/e: 1 metric(s) not checked, the baseline run had no value (end_drift_pct)" in r.summary()
    assert "checked 1 of 2 expected" in r.summary()
    # the one that is checked still fails when it gets worse
    assert not compare([{**ROW, "lost_frames": 1.0}], baseline).ok


def test_worse_metric_fails_whatever_the_tolerance_written():
    """Property: for any valid tolerance, a value beyond baseline + max(abs, rel |b|) fails and
    the baseline value itself passes (hand computation of the rule in the module doc)."""
    m = "ate_se2_rmse_mm"  # lower is better
    for abs_, rel, base in ((0.0, 0.0, 1.0), (0.5, 0.0, -2.0), (0.0, 1e6, 3.0), (1e-9, 0.25, 0.0)):
        b = parse_baseline(_baseline({m: {"abs": abs_, "rel": rel}}, {"s/e": {m: base}}))
        allowed = base + max(abs_, rel * abs(base))
        assert compare([{"scene": "s", "estimator": "e", m: base}], b).ok
        assert compare([{"scene": "s", "estimator": "e", m: allowed}], b).ok
        worse = compare([{"scene": "s", "estimator": "e", m: allowed + 1e-6 * max(1.0, abs(allowed))}], b)
        assert not worse.ok and worse.regressions[0].allowed == pytest.approx(allowed)


def test_a_baseline_that_is_a_folder_is_said_so(tmp_path):
    """--baseline on a folder said "file does not exist"."""
    from floorsim.bench.gates import load_baseline

    with pytest.raises(ConfigError, match=r"is a folder, not a baseline file"):
        load_baseline(tmp_path)


@pytest.mark.parametrize("metric", ["lost_frame", "lost_reasons"])
def test_a_tolerance_on_no_metric_is_refused(tmp_path, metric):
    """A misspelt metric (``lost_frame``) or a text column (``lost_reasons``) as a tolerance was
    stored, never checked, and the gate passed ("not checked, the baseline run had no value").
    Now it is refused in one line, by --save-baseline and in a baseline file; a figure of the
    run (wall_ms_per_frame) is a metric a gate may hold."""
    with pytest.raises(ConfigError, match=rf"tolerances\.{metric}: metric '{metric}': unknown \(known: .*lost_frames"):
        save_baseline(tmp_path / "b.json", [ROW], {metric: {"abs": 1.0}})
    assert not (tmp_path / "b.json").exists()
    with pytest.raises(ConfigError, match=rf"tolerances\.{metric}: metric '{metric}': unknown"):
        parse_baseline(_baseline({metric: {"abs": 1.0}}, {"s/e": {"end_drift_pct": 1.0}}))
    assert parse_baseline(_baseline({"wall_ms_per_frame": {"rel": 0.5}}, {"s/e": {"wall_ms_per_frame": 10.0}}))


def test_save_baseline_refuses_rows_that_give_nothing_to_check(tmp_path):
    with pytest.raises(ConfigError, match="entries: empty"):
        save_baseline(tmp_path / "b.json", [])
    assert not (tmp_path / "b.json").exists()
    with pytest.raises(ConfigError, match="must be a finite number >= 0"):
        save_baseline(tmp_path / "b.json", [ROW], {"end_drift_pct": {"abs": float("nan"), "rel": 0}})
    assert not (tmp_path / "b.json").exists()


def test_a_signed_error_is_gated_by_its_size_and_a_quantity_without_direction_is_refused():
    """distance_error_pct (signed: its magnitude counts) was gated as lower-is-better: -10.6 %
    passed against -0.65 % and +0.19 % failed. The length of a path has no better direction at
    all: a tolerance on it is refused."""
    tol = {"distance_error_pct": {"abs": 0.5, "rel": 0.0}}
    baseline = _baseline(tol, {"s/e": {"distance_error_pct": -0.652}})
    worse = compare([{"scene": "s", "estimator": "e", "distance_error_pct": -10.59}], baseline)
    assert not worse.ok and "allowed up to 1.152 in size" in worse.summary()
    better = compare([{"scene": "s", "estimator": "e", "distance_error_pct": 0.19}], baseline)
    assert better.ok and better.improved
    assert not compare([{"scene": "s", "estimator": "e", "distance_error_pct": 1.2}], baseline).ok
    with pytest.raises(ConfigError, match="tolerances.path_length_mm: length of the reference path has no better"):
        parse_baseline(_baseline({"path_length_mm": {"abs": 1.0}}, {"s/e": {"path_length_mm": 100.0}}))


def test_an_estimator_missing_from_a_bench_of_the_default_estimators_fails_the_gate():
    """Without --estimators the bench runs what each sequence supports: a plugin that broke on
    import, or whose construction fails, was skipped and its baseline entry 'not checked', and
    the gate passed. Where the bench was given its estimators, an entry of another is not run
    by choice; and an entry whose scene did not run at all is not checked either way."""
    tol = {"end_drift_pct": {"abs": 0.0, "rel": 0.1}}
    baseline = _baseline(
        tol, {"s/e": {"end_drift_pct": 1.0}, "s/plug": {"end_drift_pct": 1.0}, "u/e": {"end_drift_pct": 1.0}}
    )
    rows = [{"scene": "s", "estimator": "e", "end_drift_pct": 1.0}]
    default = compare(rows, baseline, estimators_chosen=False)
    assert not default.ok and default.missing_now == ["s/plug"] and default.only_in_baseline == ["u/e"]
    assert "s/plug: in the baseline, and its scene ran, but not this estimator" in default.summary()
    assert default.expected == 2
    chosen = compare(rows, baseline, estimators_chosen=True)
    assert chosen.ok and chosen.only_in_baseline == ["s/plug", "u/e"]


def test_a_baseline_entry_without_a_value_is_no_baseline_entry():
    """An entry saved from a run that failed is null throughout: it exempted the estimator from
    every later gate ('not checked'). It counts as no entry: a failure unless --allow-new."""
    tol = {"end_drift_pct": {"abs": 0.0, "rel": 0.1}, "lost_frames": {"abs": 0.0, "rel": 0.0}}
    baseline = _baseline(
        tol, {"s/e": {"end_drift_pct": None, "lost_frames": None}, "s/f": {"end_drift_pct": 1.0, "lost_frames": 0}}
    )
    rows = [
        {"scene": "s", "estimator": "e", "end_drift_pct": 39.0, "lost_frames": 3},
        {"scene": "s", "estimator": "f", "end_drift_pct": 1.0, "lost_frames": 0},
    ]
    r = compare(rows, baseline)
    assert not r.ok and r.only_in_bench == ["s/e"]
    assert compare(rows, baseline, allow_new=True).ok
