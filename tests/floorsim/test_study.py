"""Studies: breaking-point search, repetitions and their intervals, envelopes, study files, a lost Dask worker.

The collaborators are the doubles of ``_bench_doubles`` (estimator ``scaled`` drifts 0.1 %
per mm of LED height, ``lossy`` loses two frames), so every breaking point is known by
hand: with the criterion ``end_drift_pct > 0.52``, ``scaled`` fails above 5.2 mm.
``seeded`` (this module's runner) adds a per-seed shift to that height, so its breaking
point differs between seeds.
"""

from __future__ import annotations

import json
import math
import os
import signal
import tomllib
from functools import partial
from pathlib import Path

import _bench_doubles as D
import numpy as np
import pytest
from _bench_data import write_run

from floorsim.bench.estimators import DEFAULT_RUNNER
from floorsim.bench.results import read_results_csv
from floorsim.bench.search import (
    Bound,
    Criterion,
    bracket,
    dense_grid_bracket,
    mean_interval,
    search_grid,
)
from floorsim.bench.study import load_sweep, parse_criterion
from floorsim.bench.sweep import _check_study, run_sweep, sweep_jobs
from floorsim.bench.sweep_report import margin_text
from floorsim.cli import main
from floorsim.scene import load_scene
from floorvo.errors import ConfigError, FloorbenchError

REPO = Path(__file__).resolve().parents[2]

#: ``seeded``'s shift of the LED height (mm) per render seed: breaking points 5.2, 6.2 and 4.6 mm.
SHIFT_MM = {7: 0.0, 8: -1.0, 9: 0.6}


def seeded_render(scene, out, *, seed=None, **kw):
    """The doubles' renderer, writing the render seed into sequence.json for ``seeded``."""
    D.render(scene, out, seed=seed, **kw)
    meta_path = Path(out) / "sequence.json"
    meta = json.loads(meta_path.read_text())
    meta["seeds"] = {"render": seed}
    meta_path.write_text(json.dumps(meta))
    return Path(out)


class SeededRunner(D.FakeRunner):
    """The doubles' estimators and ``seeded``: steps 1 + 0.001 * (height + SHIFT_MM[seed]) too long."""

    def names(self):
        return [*super().names(), "seeded"]

    def requires(self, name):
        return set() if name == "seeded" else super().requires(name)

    def run(self, seq_dir, name, run_dir, overrides=None, scale_calibration=None, **kwargs):
        if name != "seeded":
            return super().run(seq_dir, name, run_dir, overrides, scale_calibration, **kwargs)
        meta = json.loads((Path(seq_dir) / "sequence.json").read_text())
        height = float(meta["scene"]["lights"]["height_mm"]) + SHIFT_MM[meta["seeds"]["render"]]
        write_run(Path(run_dir), Path(seq_dir), scale=1.0 + 0.001 * height, estimator=name)


SEEDED = {"load_scene": D.load_scene, "render": seeded_render, "runner": SeededRunner()}


def _study(tmp_path: Path, body: str, name: str = "study.toml") -> Path:
    D.write_scene(tmp_path / "base.toml", height=3.0)
    p = tmp_path / name
    p.write_text('base = "base.toml"\n' + body)
    return p


SEARCH_TABLES = """
[search]
key = "lights.height_mm"
low = 1.0
high = 10.0
fails = "above"
tolerance = 0.5
[criterion]
end_drift_pct = 0.52
lost_frames = 1
"""
SEARCH = 'estimators = ["scaled", "lossy"]\n' + SEARCH_TABLES


# ----------------------------------------------------------------------------- the pure core
def test_search_grid_neighbours_are_within_the_tolerance():
    g = search_grid(1.0, 10.0, 0.5)
    assert g[0] == 1.0 and g[-1] == 10.0 and len(g) == 19 and max(np.diff(g)) <= 0.5 + 1e-12
    g = search_grid(0.2, 3.0, 0.3)  # 2.8 / 0.3 = 9.33: 0.2, 0.5, ..., 2.9, then 3.0
    assert len(g) == 11 and g[1] == 0.5 and g[-2] == 2.9 and max(np.diff(g)) <= 0.3 + 1e-12
    g = search_grid(0.01, 4.0, 0.25, "log")
    assert g[0] == 0.01 and g[-1] == 4.0 and max(np.array(g[1:]) / np.array(g[:-1])) <= 1.25 + 1e-9
    assert search_grid(1, 8, 3, integer=True) == [1.0, 4.0, 7.0, 8.0]
    assert search_grid(1, 2, 0.4, integer=True) == [1.0, 2.0]  # 1, 1.4, 1.8, 2 rounded
    # neighbours no further apart than the tolerance (rounding the real grid gave 0, 2, 5, 8, 10)
    assert search_grid(0, 10, 2.5, integer=True) == [0.0, 2.0, 4.0, 6.0, 8.0, 10.0]
    log = search_grid(1, 64, 0.3, scale="log", integer=True)
    assert log[0] == 1.0 and log[-1] == 64.0
    assert all(b <= a * 1.3 or b == a + 1 for a, b in zip(log, log[1:])), log


@pytest.mark.parametrize("fails_below", [True, False])
def test_bisection_finds_the_dense_grid_answer_on_every_single_crossing(fails_below):
    """For every grid size and every crossing (none, at either end, anywhere between), the
    search's bracket is the dense grid's, found in at most 2 + ceil(log2(n - 1)) evaluations."""
    for n in (2, 3, 5, 8, 19, 64):
        for threshold in range(-1, n + 1):
            # fails on one side of the crossing: below index `threshold` (fails_below) or above it
            truth = [(i <= threshold) if fails_below else (i >= n - 1 - threshold) for i in range(n)]
            dense = dense_grid_bracket(truth, fails_below)
            outcomes: dict[int, bool] = {}
            for i in (0, n - 1):
                outcomes[i] = truth[i]
            b = bracket(outcomes, n, fails_below)
            while b.state == "open":
                assert b.next_index not in outcomes
                outcomes[b.next_index] = truth[b.next_index]
                b = bracket(outcomes, n, fails_below)
            assert b == dense, (n, threshold)
            assert len(outcomes) <= 2 + math.ceil(math.log2(max(n - 1, 1)))
            if b.state == "found":
                assert truth[b.fail_index] and not truth[b.work_index] and abs(b.fail_index - b.work_index) == 1


def test_bisection_on_a_noisy_criterion_still_brackets_a_crossing():
    rng = np.random.default_rng(3)
    for _ in range(200):
        truth = list(rng.random(30) < 0.5)
        truth[0], truth[-1] = True, False  # fails below, works at the top
        outcomes = {0: truth[0], 29: truth[29]}
        b = bracket(outcomes, 30, True)
        while b.state == "open":
            outcomes[b.next_index] = truth[b.next_index]
            b = bracket(outcomes, 30, True)
        assert b.state == "found" and truth[b.fail_index] and not truth[b.work_index]
        assert b.work_index == b.fail_index + 1


def test_mean_interval_is_the_student_t_interval():
    m, lo, hi = mean_interval([5.25, 6.25, 4.75], 0.95)
    # s = 0.763763, t(0.975, 2 dof) = 4.302653 (tables): half width 1.897293
    assert m == pytest.approx(5.416667, abs=1e-6)
    assert (lo, hi) == pytest.approx((5.416667 - 1.897293, 5.416667 + 1.897293), abs=1e-5)
    m1, lo1, hi1 = mean_interval([2.0, float("nan")], 0.95)  # one seed with a value: no interval, not a zero-wide one
    assert m1 == 2.0 and math.isnan(lo1) and math.isnan(hi1)
    assert all(math.isnan(v) for v in mean_interval([float("nan")], 0.95))


def test_criterion_reads_directions_from_the_metric_declarations():
    c = parse_criterion({"end_drift_pct": 1.0, "tracked_fraction": 0.9})
    assert c == Criterion((Bound("end_drift_pct", 1.0, True, "%"), Bound("tracked_fraction", 0.9, False, "")))
    assert c.failure({"status": "ok", "end_drift_pct": 0.5, "tracked_fraction": 0.95}) is None
    assert c.failure({"status": "ok", "end_drift_pct": 1.5, "tracked_fraction": 0.95}) == "end_drift_pct 1.5 % > 1 %"
    assert c.failure({"status": "ok", "end_drift_pct": 0.5, "tracked_fraction": 0.5}) == "tracked_fraction 0.5 < 0.9"
    assert c.failure({"status": "ok", "end_drift_pct": None, "tracked_fraction": 1.0}) == "end_drift_pct missing"
    assert c.failure({"status": "failed: no frames"}) == "failed: no frames"
    for table, message in [
        ({"drift": 1.0}, "criterion.drift: not a declared metric"),
        ({"path_length_mm": 10.0}, "criterion.path_length_mm: length of the reference path has no better direction"),
        ({"lost_frames": "two"}, "criterion.lost_frames = 'two': must be a finite number"),
        # a bound outside the metric's range: every run failed end_drift_pct = -1, exit 0
        ({"end_drift_pct": -1}, r"criterion.end_drift_pct = -1: must be >= 0, the range of end-point error"),
        ({"lost_frames": -0.5}, r"criterion.lost_frames = -0.5: must be >= 0"),
        ({"tracked_fraction": 1.5}, r"criterion.tracked_fraction = 1.5: must be from 0 to 1"),
        ({"fps": -30}, r"criterion.fps = -30: must be >= 0"),
    ]:
        with pytest.raises(ConfigError, match=message):
            parse_criterion(table)
    # the ends of the range are bounds: no frame lost, every frame tracked
    assert parse_criterion({"lost_frames": 0, "tracked_fraction": 1}) is not None


def test_margin_to_the_nearest_breaking_point_along_a_key():
    heights = [1.0, 3.0, 5.0, 7.0]
    assert (
        margin_text(heights, [False, False, False, True], 3.0, True, "mm") == "3 mm above (breaks between 5 and 7 mm)"
    )
    assert margin_text(heights, [True, False, False, True], 3.0, True, "mm") == "1 mm below (breaks between 1 and 3 mm)"
    assert margin_text(heights, [False] * 4, 3.0, True, "mm") == "no breaking point in 1-7 mm"
    assert margin_text(heights, [False, True, False, False], 3.0, True) == "none: fails at the operating point"
    assert margin_text(["both", "left"], [False, True], "both", False) == "fails with left"


# ----------------------------------------------------------------------------- study files
@pytest.mark.parametrize(
    "body, message",
    [
        (
            '[search]\nkey = "lights.height_mm"\nlow = 1\nhigh = 2\nfails = "below"\ntolerance = 0.1\n',
            "a \\[search\\] needs a \\[criterion\\]",
        ),
        ("[criterion]\nend_drift_pct = 1\n", "vary: give \\[vary\\] .* or \\[search\\]"),
        (
            '[vary]\n"lights.power" = [1.0]\n[search]\nkey = "lights.power"\nlow = 1\nhigh = 2\nfails = "below"\ntolerance = 0.1\n[criterion]\nlost_frames = 0\n',
            "search.key = 'lights.power': is varied in \\[vary\\] too",
        ),
        (
            '[search]\nkey = "lights.height_mm"\nlow = 2\nhigh = 1\nfails = "below"\ntolerance = 0.1\n[criterion]\nlost_frames = 0\n',
            "search.high = 1.0: must be > low",
        ),
        (
            '[search]\nkey = "lights.height_mm"\nlow = 0\nhigh = 1\nfails = "below"\ntolerance = 0.1\nscale = "log"\n[criterion]\nlost_frames = 0\n',
            "search.low = 0.0: must be > 0 on a log scale",
        ),
        (
            '[search]\nkey = "lights.height_mm"\nlow = 1\nhigh = 2\nfails = "under"\ntolerance = 0.1\n[criterion]\nlost_frames = 0\n',
            "search.fails = 'under': must be one of 'below', 'above'",
        ),
        ('seeds = [7, 7]\n[vary]\n"lights.power" = [1.0]\n', "seeds = \\[7, 7\\]: must be distinct"),
        # one estimator twice: two rows of one run folder per job
        (
            'estimators = ["scaled", "scaled"]\n[vary]\n"lights.power" = [1.0]\n',
            "estimators = \\['scaled', 'scaled'\\]: must name each estimator once",
        ),
        # a fixed value the grid or the search replaces: the study ran with the varied values, silently
        (
            '[set]\n"lights.power" = 2.0\n[vary]\n"lights.power" = [1.0, 3.0]\n',
            "set.lights.power = 2.0: is varied in \\[vary\\] too",
        ),
        (
            '[set]\n"lights.height_mm" = 2.0\n[search]\nkey = "lights.height_mm"\nlow = 1\nhigh = 3\nfails = "below"\n'
            "tolerance = 0.1\n[criterion]\nlost_frames = 0\n",
            "set.lights.height_mm = 2.0: is searched in \\[search\\] too",
        ),
        (
            '[vary]\n"lights.power" = [1.0]\n[operating_point]\n"lights.height_mm" = 3\n',
            "operating_point.lights.height_mm: not a varied or searched key",
        ),
        (
            'estimators = ["scaled"]\n[estimator_config.lossy]\nx = 1\n[vary]\n"lights.power" = [1.0]\n',
            "estimator_config.lossy: 'lossy' is not among estimators",
        ),
        ('[render]\nspp = 0\n[vary]\n"lights.power" = [1.0]\n', "render.spp = 0: must be >= 1"),
        # one-frame sequences: nothing to estimate, every job an empty 'ok' row
        ('[render]\nframes = 1\n[vary]\n"lights.power" = [1.0]\n', "render.frames = 1 frames: must be >= 2 frames"),
        (
            '[search]\nkey = "lights.height_mm"\nlow = 1\nhigh = 2\nfails = "below"\ntolerance = 1e-9\n'
            "[criterion]\nlost_frames = 0\n",
            "search.tolerance = 1e-09: the grid would hold more than 1000000 values",
        ),
        (
            'repetitions = 1000\n[vary]\n"lights.power" = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11]\n',
            "vary: the study holds 11000 jobs \\(values x repetitions\\); at most 10000",
        ),
        ('name = ""\n[vary]\n"lights.power" = [1.0]\n', "name = '': must be a non-empty string"),
    ],
)
def test_study_file_refusals_name_the_key_in_one_line(tmp_path, body, message):
    p = _study(tmp_path, body)
    with pytest.raises(ConfigError, match=message) as exc:
        load_sweep(p)
    assert "\n" not in str(exc.value) and str(exc.value).startswith(str(p))


def test_refusals_before_any_job(tmp_path):
    """Unknown estimators, config keys and scene keys stop the study before it renders."""
    D.reset()
    cases = [
        ('estimators = ["nope"]\n[vary]\n"lights.power" = [1.0]\n', "estimators: 'nope': unknown estimator"),
        (
            'estimators = ["scaled"]\n[estimator_config.scaled]\nfoo = 1\n[vary]\n"lights.power" = [1.0]\n',
            "estimator_config.scaled.foo: unknown config key",
        ),
    ]
    for body, message in cases:
        with pytest.raises(ConfigError, match=message):
            run_sweep(_study(tmp_path, body), tmp_path / "out", workers=1, processes=False, **D.COLLABORATORS)
    assert D.RENDER_CALLS == []
    # The real scene refuses a value: the study says which key and value before rendering.
    real = tmp_path / "real.toml"
    real.write_text(f'base = "{REPO / "scenes" / "demo.toml"}"\n[vary]\n"lights.height_mm" = [3.0, 200.0]\n')
    with pytest.raises(ConfigError, match=r"real.toml: lights.height_mm = 200.0: .*LEDs must be below the camera"):
        _check_study(load_sweep(real), load_scene, DEFAULT_RUNNER)


def test_shipped_studies_load_and_name_keys_the_scene_has():
    files = sorted((REPO / "scenes" / "studies").glob("*.toml"))
    assert {f.name for f in files} >= {
        "led_height_breaking.toml",
        "led_power_breaking.toml",
        "led_side.toml",
        "ambient_leak_breaking.toml",
        "sensor_noise_breaking.toml",
        "material_x_led_height.toml",
        "motion_blur_x_speed.toml",
    }
    for f in files:
        spec = load_sweep(f)
        base = _check_study(spec, load_scene, DEFAULT_RUNNER)  # estimators, configs and every key's values
        assert spec.criterion is not None, f.name
        for job in sweep_jobs(spec)[:1]:
            assert load_scene(spec.base, {**spec.fixed, **{k: str(v) for k, v in job["params"].items()}})
        assert base.name


# ----------------------------------------------------------------------------- end to end with doubles
def test_search_agrees_with_the_dense_grid_and_takes_fewer_renders(tmp_path, capsys):
    D.reset()
    study = _study(tmp_path, SEARCH)
    out = tmp_path / "search"
    res = run_sweep(study, out, workers=2, processes=False, **D.COLLABORATORS)
    assert res.errors == [] and res.search is not None
    by = {p.estimator: p for p in res.search.points}
    assert by["scaled"].point.state == "found"
    assert by["scaled"].point.bracket == (5.0, 5.5) and by["scaled"].point.value == pytest.approx(5.25)
    assert by["lossy"].point.state == "fails_everywhere"  # two lost frames > 1 at every height
    renders = res.search.renders["all"]
    assert renders == len(D.RENDER_CALLS) == 6 and res.search.grid_renders == 19
    rows = read_results_csv(out / "results.csv")
    assert len(rows) == 2 * renders and len({(r["job"], r["estimator"]) for r in rows}) == len(rows)

    # The dense grid over the same values, in another folder: its first failing value from the working end.
    grid = search_grid(1.0, 10.0, 0.5)
    dense_file = _study(
        tmp_path,
        f'estimators = ["scaled", "lossy"]\n[criterion]\nend_drift_pct = 0.52\n[vary]\n"lights.height_mm" = {grid}\n',
        name="dense.toml",
    )
    dense = run_sweep(dense_file, tmp_path / "dense", workers=2, processes=False, report=False, **D.COLLABORATORS)
    fails = {r["lights.height_mm"]: r["end_drift_pct"] > 0.52 for r in dense.rows if r["estimator"] == "scaled"}
    first_failing = min(v for v, f in fails.items() if f)
    last_working = max(v for v, f in fails.items() if not f and v < first_failing)
    assert (last_working, first_failing) == by["scaled"].point.bracket
    assert abs(by["scaled"].point.value - 5.2) <= 0.5  # the stated tolerance, against the true 5.2 mm

    # Report, breaking_points.csv, the study record.
    html = (out / "sweep.html").read_text()
    assert "Breaking points: lights.height_mm" in html and "scaled: fails above 5.25 mm (bracket 5-5.5)" in html
    bp = {r["estimator"]: r for r in read_results_csv(out / "breaking_points.csv")}
    assert bp["scaled"]["bracket_low"] == 5.0 and bp["scaled"]["renders"] == 6 and bp["scaled"]["grid_renders"] == 19
    assert bp["scaled"]["margin"] == pytest.approx(2.25)  # operating point 3 mm, 2.25 mm below the breaking point
    assert (out / "study.toml").read_bytes() == study.read_bytes()
    record = json.loads((out / "study.json").read_text())
    assert record["study"]["search"]["key"] == "lights.height_mm" and record["study"]["criterion"] == {
        "end_drift_pct": 0.52,
        "lost_frames": 1.0,
    }
    assert {"floorsim", "floorvo", "numpy", "dask"} <= set(record["versions"])
    assert record["base_scene"]["lights"]["height_mm"] == 3.0

    # Started again: every value is in results.csv, nothing renders, the same answer.
    again = run_sweep(study, out, workers=1, processes=False, report=False, **D.COLLABORATORS)
    assert again.ran == 0 and again.skipped == 6 and len(D.RENDER_CALLS) == 6 + 19
    assert again.search.summary_lines() == res.search.summary_lines()


def test_cli_prints_the_breaking_point_per_estimator(tmp_path, capsys):
    D.reset()
    study = _study(tmp_path, SEARCH)
    assert main(["sweep", str(study), "-o", str(tmp_path / "out"), "--workers", "1"], collaborators=_threads()) == 0
    out = capsys.readouterr().out
    assert "  scaled: fails above 5.25 mm (bracket 5-5.5), 2.25 mm above the operating point (3 mm)" in out
    assert "  lossy: fails over the whole range (fails at 1 mm already, the working end)" in out
    assert "renders: 6 (a grid at the same tolerance: 19)" in out


def _threads():
    """Collaborators for the CLI whose Dask workers are threads (the doubles are in this process)."""
    return {**D.COLLABORATORS, "processes": False}


def test_repetitions_give_the_breaking_point_an_interval(tmp_path):
    study = _study(tmp_path, 'estimators = ["seeded"]\nseeds = [7, 8, 9]\n' + SEARCH_TABLES)
    res = run_sweep(study, tmp_path / "out", workers=2, processes=False, **SEEDED)
    assert res.errors == []
    (p,) = res.search.points
    # seeds 7, 8, 9 break at 5.2, 6.2, 4.6 mm: brackets 5-5.5, 6-6.5, 4.5-5
    assert [(p.brackets[k].fail_index, p.brackets[k].work_index) for k in range(3)] == [(9, 8), (11, 10), (8, 7)]
    assert p.seeds == (7, 8, 9)
    bp = p.point
    assert bp.state == "found" and bp.noisy and bp.bracket == (4.5, 6.5)
    assert bp.value == pytest.approx(5.416667, abs=1e-6)
    assert bp.interval == pytest.approx((5.416667 - 1.897293, 5.416667 + 1.897293), abs=1e-5)
    line = res.search.describe(p)
    assert "95 % interval 3.519 to 7.314 over 3 of 3 seeds" in line and "noisy: the seeds disagree" in line
    # Curves of the searched values show each point's interval over the seeds.
    md = (tmp_path / "out" / "sweep.md").read_text()
    assert "bands: 95 % interval over the seeds" in md


def test_grid_points_state_their_interval_over_repetitions(tmp_path):
    study = _study(tmp_path, 'estimators = ["seeded"]\nseeds = [7, 8, 9]\n[vary]\n"lights.height_mm" = [2.0]\n')
    res = run_sweep(study, tmp_path / "out", workers=1, processes=False, **SEEDED)
    drifts = sorted(r["end_drift_pct"] for r in res.rows)
    # 0.1 % per mm of 2 mm + shift: 0.1, 0.2 and 0.26 %
    assert drifts == pytest.approx([0.1, 0.2, 0.26], abs=1e-6)
    m, lo, hi = mean_interval(drifts)
    assert lo < 0.0  # a drift is never negative: the table's interval starts at 0 (its Student t one below it)
    table = (tmp_path / "out" / "sweep.md").read_text()
    assert f"| seeded | 2 | {m:.4g} | 0 to {hi:.4g} |" in table


def test_envelope_of_two_keys_with_the_margin_per_key(tmp_path):
    study = _study(
        tmp_path,
        'estimators = ["scaled", "lossy"]\n[vary]\n"lights.height_mm" = [1.0, 3.0, 5.0, 7.0]\n'
        '"lights.power" = [0.5, 1.0]\n[criterion]\nend_drift_pct = 0.52\n[operating_point]\n"lights.power" = 1.0\n',
    )
    run_sweep(study, tmp_path / "out", workers=2, processes=False, **D.COLLABORATORS)
    md = (tmp_path / "out" / "sweep.md").read_text()
    assert "## Envelope: lights.height_mm x lights.power" in md
    # scaled fails above 5.2 mm whatever the power: 3 mm above the operating point's 3 mm (between 5 and 7 mm).
    assert "| scaled | 3 mm above (breaks between 5 and 7 mm) | no breaking point in 0.5-1 |" in md
    assert "| lossy | no breaking point in 1-7 mm | no breaking point in 0.5-1 |" in md
    html = (tmp_path / "out" / "sweep.html").read_text()
    # two maps (one figure), the comparison, and one curve figure per key
    assert html.count("data:image/png;base64,") == 4


def test_search_per_combination_of_a_varied_key(tmp_path):
    study = _study(
        tmp_path,
        'estimators = ["seeded"]\nseeds = [8]\n[vary]\n"lights.power" = [0.5, 1.0]\n' + SEARCH_TABLES,
    )
    res = run_sweep(study, tmp_path / "out", workers=2, processes=False, **SEEDED)
    assert [p.context for p in res.search.points] == [{"lights.power": 0.5}, {"lights.power": 1.0}]
    assert all(p.point.bracket == (6.0, 6.5) for p in res.search.points)  # seed 8: 6.2 mm at any power
    assert res.search.renders == {"lights.power=0.5": 7, "lights.power=1": 7}  # 2 + ceil(log2(18))
    html = (tmp_path / "out" / "sweep.html").read_text()
    assert "envelope: breaking lights.height_mm against lights.power" in html


# ----------------------------------------------------------------------------- a worker lost mid-job
def killing_render(scene, out, *, marker: str, **kw):
    """The doubles' renderer; the first render at 10 mm kills its own worker process (SIGKILL)."""
    with open(marker + ".log", "a") as fh:
        fh.write(f"{scene.data['lights']['height_mm']}\n")
    if scene.data["lights"]["height_mm"] == 10.0 and not os.path.exists(marker):
        Path(marker).write_text("killed")
        os.kill(os.getpid(), signal.SIGKILL)
    return D.render(scene, out, **kw)


def test_a_worker_killed_mid_job_is_retried_without_duplicate_rows(tmp_path):
    study = _study(tmp_path, 'estimators = ["scaled", "lossy"]\n[vary]\n"lights.height_mm" = [1.0, 4.0, 10.0]\n')
    marker = tmp_path / "killed"

    def too_long(*_):
        raise TimeoutError("the killed-worker sweep took more than 180 s")

    old = signal.signal(signal.SIGALRM, too_long)
    signal.alarm(180)
    try:
        res = run_sweep(
            study,
            tmp_path / "out",
            workers=2,
            report=False,
            render=partial(killing_render, marker=str(marker)),
            load_scene=D.load_scene,
            runner=D.FakeRunner(),
        )
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    assert marker.read_text() == "killed"
    calls = Path(str(marker) + ".log").read_text().split()
    assert sorted(calls) == ["1.0", "10.0", "10.0", "4.0"]  # the killed job ran again
    assert res.errors == [] and res.ran == 3
    rows = read_results_csv(tmp_path / "out" / "results.csv")
    assert sorted((r["lights.height_mm"], r["estimator"]) for r in rows) == [
        (h, e) for h in (1.0, 4.0, 10.0) for e in ("lossy", "scaled")
    ]
    assert all(r["status"] == "ok" for r in rows)


def test_shipped_study_files_are_toml_with_a_comment_saying_how_to_run_them():
    for f in sorted((REPO / "scenes" / "studies").glob("*.toml")):
        text = f.read_text()
        tomllib.loads(text)
        assert f"floorsim sweep scenes/studies/{f.name} -o " in text, f.name


def refusing_render(scene, out, **kw):
    """A renderer that refuses every scene, as a broken backend would."""
    raise FloorbenchError(f"renderer unavailable for {scene.name}")


def test_a_search_whose_renders_fail_says_so_and_exits_1(tmp_path, capsys):
    study = _study(tmp_path, SEARCH)
    collaborators = {**_threads(), "render": refusing_render}
    assert main(["sweep", str(study), "-o", str(tmp_path / "out"), "--workers", "1"], collaborators=collaborators) == 1
    out = capsys.readouterr().out
    assert (
        "  search stopped: all, repetition 0: lights.height_mm=1.0;rep=0: failed: renderer unavailable for tiny" in out
    )


@pytest.mark.parametrize(
    "listed, words", [(["a/rec", "a/rec"], "is listed twice"), (["a/rec", "b/rec"], "has the name of")]
)
def test_a_sequence_folder_twice_or_two_of_one_name_are_refused(tmp_path, listed, words):
    """Two listed folders named alike became two jobs 'sequence=rec' writing one run folder: the
    second run replaced the first's, and a resumed study counted them as one job done."""
    D.reset()
    for sub in ("a", "b"):
        D.render(D.load_scene(D.write_scene(tmp_path / f"{sub}.toml", name="rec")), tmp_path / sub / "rec")
    p = tmp_path / "s.toml"
    p.write_text(f'estimators = ["scaled"]\nsequences = {json.dumps(listed)}\n')
    with pytest.raises(ConfigError, match=f"s.toml: sequences: '{listed[1]}' {words}") as exc:
        load_sweep(p)
    assert "each sequence folder once, with a name of its own" in str(exc.value)


def test_a_study_of_sequence_folders_alone_runs_and_is_recorded(tmp_path):
    D.reset()
    rec = D.render(D.load_scene(D.write_scene(tmp_path / "rec.toml", name="rec", height=2.0)), tmp_path / "rec")
    p = tmp_path / "s.toml"
    p.write_text('estimators = ["scaled"]\nsequences = ["rec"]\n')
    res = run_sweep(p, tmp_path / "out", workers=1, processes=False, **D.COLLABORATORS)
    assert res.errors == [] and [(r["job"], r["sequence"]) for r in res.rows] == [("sequence=rec", str(rec.resolve()))]
    assert res.rows[0]["end_drift_pct"] == pytest.approx(0.2, rel=1e-4)  # recorded at 2 mm: 0.1 % per mm
    record = json.loads((tmp_path / "out" / "study.json").read_text())
    assert record["study"]["base"] is None and record["base_scene"] is None
    assert record["study"]["sequences"] == [str(rec.resolve())]
    assert "Sequence folders only (no base scene)" in (tmp_path / "out" / "sweep.md").read_text()


def test_a_seed_failing_over_the_whole_range_is_said_to_make_the_value_optimistic():
    """Seeds breaking at 1.0 and 2.5 mm and one failing over the whole range (0.05-3 mm, at the
    operating point too): the value (1.75 mm) and its margin left that seed out, with the words
    used for a seed that works everywhere, which makes them pessimistic instead."""
    from floorsim.bench.search import Bracket, EstimatorBreakingPoint, SearchResult, combine_brackets

    grid = [0.05 + 0.1 * k for k in range(30)]  # 0.05 ... 2.95
    brackets = (Bracket("found", 9, 10), Bracket("found", 24, 25), Bracket("fails_everywhere"))
    point = EstimatorBreakingPoint({}, "e", combine_brackets(grid, brackets), brackets, (7, 8, 9), {})
    res = SearchResult("lights.height_mm", "mm", "below", "linear", 0.1, "lost_frames > 0", grid, [point], {}, 0, 3.0)
    line = res.describe(point)
    assert point.point.state == "mixed"
    assert "1 of 3 seeds fail over the whole range (at 2.95 mm, the working end, too)" in line
    assert "this value and margin are optimistic" in line
    assert "works over" not in line and "pessimistic" not in line
    works = (Bracket("found", 9, 10), Bracket("works_everywhere"))
    point = EstimatorBreakingPoint({}, "e", combine_brackets(grid, works), works, (7, 8), {})
    assert "1 of 2 seeds work over the whole range" in res.describe(point) and "pessimistic" in res.describe(point)


def test_a_study_value_read_back_from_its_results_csv_matches_its_declared_value():
    """A boolean read back from results.csv is the text True (the study's is true), and an
    integer grid value 100 is the base scene's 100.0: the report of a study run again lost its
    curves and crashed on an empty envelope, and a search's margin and star went missing."""
    from floorsim.bench.sweep_report import _same

    assert _same("True", True) and _same("False", False) and not _same("True", False)
    assert _same(100, 100.0) and _same("100.0", 100) and _same("both", "both") and not _same("both", "left")
