"""The bench's bookkeeping with test doubles for the renderer and the estimators (passed in
as collaborators): render cache, results.csv, skipping unsupported estimators, the CLI and
its gate."""

import csv
import json
from functools import partial
from pathlib import Path

import _bench_doubles as D
import pytest
from _bench_data import write_sequence

import floorsim.bench.bench as bench_module
from floorsim.bench import run_bench as real_run_bench
from floorsim.bench.bench import scene_cache_key
from floorsim.bench.results import TEXT_COLUMNS, read_results_csv
from floorsim.cli import main as real_main

run_bench = partial(real_run_bench, **D.COLLABORATORS)
main = partial(real_main, collaborators=D.COLLABORATORS)


@pytest.fixture
def doubles():
    D.reset()
    return D


def test_bench_scores_every_supported_estimator_and_reuses_renders(tmp_path, doubles):
    scene = D.write_scene(tmp_path / "tiny.toml", height=3.0)
    out = tmp_path / "out"
    res = run_bench([scene], None, out, repetitions=2)
    rows = read_results_csv(out / "results.csv")
    # mono sequence: the depth estimator is skipped, and the report says why
    assert sorted({r["estimator"] for r in rows}) == ["lossy", "scaled"]
    assert len(rows) == 2 * 2 and {r["repetition"] for r in rows} == {0, 1}
    assert any("needs_depth skipped (needs depth" in n for n in res.notes)
    assert "needs_depth skipped" in res.report_html.read_text()
    scaled = [r for r in rows if r["estimator"] == "scaled"]
    # steps 0.3 % too long (0.001 x 3 mm LED height): drift 0.3 % of the distance
    assert all(r["end_drift_pct"] == pytest.approx(0.3, rel=1e-4) for r in scaled)
    lossy = [r for r in rows if r["estimator"] == "lossy"]
    assert all(r["lost_frames"] == 2 and r["loss_events"] == 1 for r in lossy)
    # repetition k renders with seed + k: two sequences, each rendered once
    assert len(D.RENDER_CALLS) == 2 and {r["seed"] for r in rows} == {7, 8}
    # every number of results.csv is a plain decimal that csv + float read back
    with (out / "results.csv").open(newline="") as fh:
        for raw, typed in zip(csv.DictReader(fh), rows):
            for k, v in raw.items():
                if k not in TEXT_COLUMNS and v != "":
                    assert float(v) == pytest.approx(typed[k], nan_ok=True), (k, v)
    assert json.loads((out / "runs" / "tiny" / "scaled" / "rep1" / "score.json").read_text())["estimator"] == "scaled"
    # matched keypoints sampled for the report from the estimator that exposes them (repetition 0 only)
    assert len(list((out / "runs" / "tiny" / "scaled" / "rep0" / "matches").glob("*.npz"))) == 3
    assert not (out / "runs" / "tiny" / "lossy" / "rep0" / "matches").exists()
    assert "matched keypoints (circles" in res.report_html.read_text()
    # a second bench on the same scene reuses both sequences
    run_bench([scene], ["scaled"], tmp_path / "out2", repetitions=2, cache_dir=out / "sequences")
    assert len(D.RENDER_CALLS) == 2
    # another resolved scene renders anew
    run_bench(
        [scene], ["scaled"], tmp_path / "out3", cache_dir=out / "sequences", scene_overrides={"lights.height_mm": "5"}
    )
    assert len(D.RENDER_CALLS) == 3


def test_cache_key_follows_scene_seed_and_settings():
    s = {"name": "a", "lights": {"height_mm": 3.0}}
    k = scene_cache_key(s, seed=1, frames=None, scale=None, spp=None)
    assert k == scene_cache_key(json.loads(json.dumps(s)), seed=1, frames=None, scale=None, spp=None)
    assert k != scene_cache_key(s, seed=2, frames=None, scale=None, spp=None)
    assert k != scene_cache_key({**s, "lights": {"height_mm": 3.5}}, seed=1, frames=None, scale=None, spp=None)
    assert k != scene_cache_key(s, seed=1, frames=None, scale=0.5, spp=None)


def test_cache_key_and_cache_follow_the_renderer_code(tmp_path, doubles, monkeypatch):
    """The renderer edited (floorsim's version number unchanged): the sequence cache rendered again.
    It reused the old render, so a gate passed on frames the new renderer never made."""
    s = {"name": "a", "lights": {"height_mm": 3.0}}
    k = scene_cache_key(s, seed=1, frames=None, scale=None, spp=None)
    scene = D.write_scene(tmp_path / "tiny.toml")
    run_bench([scene], ["scaled"], tmp_path / "out")
    assert len(D.RENDER_CALLS) == 1
    monkeypatch.setattr(bench_module, "render_code_sha256", lambda material=None: "0" * 64)
    assert scene_cache_key(s, seed=1, frames=None, scale=None, spp=None) != k
    run_bench([scene], ["scaled"], tmp_path / "out")
    assert len(D.RENDER_CALLS) == 2 and D.RENDER_CALLS[0] != D.RENDER_CALLS[1]


def test_a_gate_refuses_a_baseline_made_with_other_scenes_or_settings(tmp_path, doubles):
    """A baseline saved at --frames 4 was compared with a bench at --frames 5 or with another --set,
    metric by metric, and passed or failed on numbers of other runs. The baseline records each
    entry's inputs (made_with) and such an entry fails the gate as not comparable, naming why; another
    --est-set is what a gate measures (noted in the summary)."""
    scene = D.write_scene(tmp_path / "tiny.toml")
    base = tmp_path / "baseline.json"
    run_bench([scene], ["scaled"], tmp_path / "a", frames=4, save_baseline_to=base)
    saved = json.loads(base.read_text())
    assert set(saved["made_with"]) == {"tiny/scaled"} and saved["made_with"]["tiny/scaled"]["seeds"] == [7]
    same = run_bench([scene], ["scaled"], tmp_path / "b", frames=4, baseline=base).gate
    assert same.ok and same.checked >= 7 and not same.made_otherwise
    for i, kwargs in enumerate(
        (
            {"frames": 5},
            {"frames": 4, "scene_overrides": {"lights.height_mm": "3.5"}},
        )
    ):
        gate = run_bench([scene], ["scaled"], tmp_path / f"c{i}", baseline=base, **kwargs).gate
        assert not gate.ok and gate.checked == 0, kwargs
        assert gate.made_otherwise[0].startswith("tiny/scaled: not comparable, the baseline was made with other inputs")
    tuned = run_bench(
        [scene], ["scaled"], tmp_path / "t", frames=4, estimator_overrides={"scaled": {"scale": "1.02"}}, baseline=base
    ).gate
    assert not tuned.ok and tuned.regressions and not tuned.made_otherwise
    assert 'tiny/scaled: --est-set {"scale": "1.02"}, the baseline\'s none: the gate measures that change' in (
        tuned.summary()
    )
    gate = run_bench([scene], ["scaled"], tmp_path / "d", frames=4, repetitions=2, baseline=base).gate
    assert not gate.ok and "seeds [7], now [7, 8]" in gate.summary()
    # a scale calibration added since the baseline is noted like an --est-set (it passed without a word)
    from floorvo.calibration import ScaleCalibration, save_scale_calibration

    cal = tmp_path / "scale.json"
    save_scale_calibration(ScaleCalibration(scale_x=1.0, observed_x=True, travel_x_mm=100.0, steps=25), cal)
    calibrated = run_bench(
        [scene], ["scaled"], tmp_path / "k", frames=4, scale_calibrations={"scaled": cal}, baseline=base
    ).gate
    assert f"tiny/scaled: --scale-calibration {cal}, the baseline's none: the gate measures that change" in (
        calibrated.summary()
    )
    # a baseline saved before made_with: compared as before, and the summary says it was not checked
    del saved["made_with"]
    base.write_text(json.dumps(saved))
    gate = run_bench([scene], ["scaled"], tmp_path / "e", frames=5, baseline=base).gate
    assert gate.ok and gate.inputs_unchecked and "the baseline records no inputs" in gate.summary()


def test_paper001_scene_is_compared_with_0783_percent(tmp_path, doubles):
    extra = '\n[trajectory]\ntype = "line"\n\n[bench]\nprotocols = ["paper001-line"]\n'
    scene = D.write_scene(tmp_path / "p1.toml", name="line_3m", height=3.0, extra=extra)
    res = run_bench([scene], ["scaled"], tmp_path / "out")
    assert res.rows[0]["paper_ref_error_pct"] == 0.783
    page = res.report_html.read_text()
    assert "Paper 001 reproduction" in page and "0.783" in page


def test_cli_prints_table_and_report_and_gates(tmp_path, doubles, capsys):
    scene = D.write_scene(tmp_path / "tiny.toml")
    base = tmp_path / "baseline.json"
    assert (
        main(["bench", str(scene), "--estimators", "scaled", "-o", str(tmp_path / "a"), "--save-baseline", str(base)])
        == 0
    )
    out = capsys.readouterr().out.strip().splitlines()
    assert out[-2].startswith("report: ") and out[-2].split()[1].endswith("report.html")
    assert any(line.split()[:2] == ["tiny", "scaled"] for line in out)
    assert base.is_file()
    # the same estimator again: passes
    assert (
        main(["bench", str(scene), "--estimators", "scaled", "-o", str(tmp_path / "b"), "--baseline", str(base)]) == 0
    )
    assert "regression gate passed" in capsys.readouterr().out
    # a deliberately worse configuration: 2 % scale error instead of 0.3 %
    rc = main(
        [
            "bench",
            str(scene),
            "--estimators",
            "scaled",
            "--est-set",
            "scaled.scale=1.02",
            "-o",
            str(tmp_path / "c"),
            "--baseline",
            str(base),
        ]
    )
    text = capsys.readouterr().out
    assert rc == 1 and "end_drift_pct got worse" in text and "FAILED" in text
    # an unknown estimator is one line on stderr, exit 1
    assert main(["bench", str(scene), "--estimators", "nope", "-o", str(tmp_path / "d")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "nope" in err


def test_cli_gate_fails_on_a_new_estimator_unless_allowed_and_refuses_a_bad_baseline(tmp_path, doubles, capsys):
    scene = D.write_scene(tmp_path / "tiny.toml")
    base = tmp_path / "baseline.json"
    bench = ["bench", str(scene), "-o", str(tmp_path / "a")]
    assert main([*bench, "--estimators", "scaled", "--save-baseline", str(base)]) == 0
    capsys.readouterr()
    # lossy has no baseline entry: the gate fails and says so, and how much it checked
    assert main([*bench, "--estimators", "scaled,lossy", "--baseline", str(base)]) == 1
    text = capsys.readouterr().out
    assert "tiny/lossy: no baseline entry" in text and "checked 8 of 16 expected" in text and "FAILED" in text
    assert main([*bench, "--estimators", "scaled,lossy", "--baseline", str(base), "--allow-new"]) == 0
    assert "regression gate passed: 0 metric(s) worse; checked 8 of 16 expected" in capsys.readouterr().out
    # a malformed baseline is refused in one line before anything is rendered
    b = json.loads(base.read_text())
    b["tolerances"]["end_drift_pct"]["rel"] = "5%"
    base.write_text(json.dumps(b))
    calls = len(D.RENDER_CALLS)
    assert main([*bench, "--estimators", "scaled", "-o", str(tmp_path / "c"), "--baseline", str(base)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "tolerances.end_drift_pct.rel = '5%': must be a finite number >= 0" in err
    assert len(D.RENDER_CALLS) == calls and not (tmp_path / "c").exists()


def test_bench_divides_a_scale_calibration_out_of_its_estimator(tmp_path, doubles, capsys):
    """--scale-calibration NAME=FILE reaches that estimator's runs (only), and the row names the file."""
    from floorvo.calibration import ScaleCalibration, save_scale_calibration

    scene = D.write_scene(tmp_path / "tiny.toml", height=3.0)  # 'scaled' reads 0.3 % long
    cal = tmp_path / "scale.json"
    save_scale_calibration(ScaleCalibration(scale_x=1.003, observed_x=True, travel_x_mm=100.0, steps=25), cal)
    out = tmp_path / "out"
    assert (
        main(
            [
                "bench",
                str(scene),
                "--estimators",
                "scaled,lossy",
                "-o",
                str(out),
                "--no-report",
                "--scale-calibration",
                f"scaled={cal}",
            ]
        )
        == 0
    )
    rows = {r["estimator"]: r for r in read_results_csv(out / "results.csv")}
    assert rows["scaled"]["scale_calibration"] == str(cal)
    assert abs(rows["scaled"]["end_drift_pct"]) < 1e-3  # 0.3 % divided out
    assert not rows["lossy"].get("scale_calibration")
    given = dict(D.CALIBRATIONS)
    assert given["scaled"].scale_x == pytest.approx(1.003) and given["lossy"] is None
    capsys.readouterr()
    # bad input: one line on stderr, exit 1
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    for args, words in (
        ([f"nope={cal}"], "unknown estimator"),
        ([f"lossy={cal}"], "not among --estimators"),
        ([f"scaled={bad}"], "bad.json"),
        (["scaled"], "expected ESTIMATOR=FILE"),
    ):
        rc = main(
            [
                "bench",
                str(scene),
                "--estimators",
                "scaled",
                "-o",
                str(tmp_path / "x"),
                "--no-report",
                *[a for v in args for a in ("--scale-calibration", v)],
            ]
        )
        err = capsys.readouterr().err
        assert rc == 1 and err.count("\n") == 1 and words in err, err


def test_cli_a_crashing_external_program_is_a_failed_row_and_the_bench_exits_0(tmp_path, doubles, capsys):
    import shlex
    import sys

    scene = D.write_scene(tmp_path / "tiny.toml")
    crash = (
        f"{shlex.quote(sys.executable)} -c 'import sys; print(\"segfault in tracker\", file=sys.stderr); sys.exit(7)'"
    )
    efile = tmp_path / "copy-gt.toml"
    copy_gt = "import shutil, sys; shutil.copy(sys.argv[1] + '/groundtruth.txt', sys.argv[2] + '/trajectory.txt')"
    efile.write_text(f'name = "copy-gt"\ncommand = ["{{python}}", "-c", "{copy_gt}", "{{sequence}}", "{{output}}"]\n')
    out = tmp_path / "out"
    argv = ["bench", str(scene), "--estimators", "scaled", "--external", f"crash={crash}"]
    assert main([*argv, "--estimator-file", str(efile), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    rows = {r["estimator"]: r for r in read_results_csv(out / "results.csv")}
    assert set(rows) == {"scaled", "crash", "copy-gt"}
    assert rows["crash"]["status"] == "failed: exit code 7" and rows["crash"]["stderr_tail"] == "segfault in tracker"
    assert rows["crash"]["source"] == "external" and rows["crash"]["source_detail"].startswith("sha256:")
    assert rows["copy-gt"]["status"] == "ok" and rows["copy-gt"]["ate_none_rmse_mm"] == pytest.approx(0, abs=1e-6)
    assert rows["scaled"]["status"] == "ok"
    assert "failed: exit code 7" in printed
    page = (out / "report.html").read_text()
    assert "segfault in tracker" in page and "Estimators compared" in page


def test_a_bench_of_one_frame_is_refused_before_it_renders(tmp_path, doubles, capsys):
    """--frames 1 benched one-frame sequences: nothing to estimate, every row 'ok' and empty, exit 0."""
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    argv = ["bench", str(scene), "--frames", "1", "--estimators", "scaled", "--no-report", "-o", str(tmp_path / "out")]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--frames 1: a bench needs at least 2 frames" in err
    assert not D.RENDER_CALLS and not (tmp_path / "out").exists()


def test_an_estimator_listed_twice_is_refused_before_it_renders(tmp_path, doubles, capsys):
    """--estimators scaled,scaled ran it twice into one run folder: two rows of one run, exit 0."""
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    argv = ["bench", str(scene), "--estimators", "scaled,lossy,scaled", "--no-report", "-o", str(tmp_path / "out")]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--estimators: 'scaled' given twice; give each estimator once" in err
    assert not D.RENDER_CALLS and not (tmp_path / "out").exists()


@pytest.mark.parametrize("repeat", ["0", "1001", "1000000000"])
def test_a_repeat_count_out_of_range_is_refused_before_it_renders(tmp_path, doubles, capsys, repeat):
    """--repeat 1000000000 started on a billion renders (a study allows 1000 repetitions)."""
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    argv = ["bench", str(scene), "--repeat", repeat, "--estimators", "scaled", "--no-report", "-o", str(tmp_path / "o")]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--repeat {repeat}: must be from 1 to 1000 (renders per scene)" in err
    assert not D.RENDER_CALLS and not (tmp_path / "o").exists()


def _refused_before_it_renders(capsys, argv, words, out):
    """``floorsim bench ARGV`` exits 1 with one line holding ``words``, renders nothing, leaves no ``out``."""
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err and words in err, err
    assert not D.RENDER_CALLS and not out.exists()


def test_a_save_baseline_path_that_cannot_be_written_is_refused_before_it_renders(tmp_path, doubles, capsys):
    """--save-baseline FILE/base.json ran the whole bench, then said 'File exists (errno 17)'."""
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    afile = tmp_path / "afile"
    afile.write_text("x")
    out = tmp_path / "out"
    argv = ["bench", str(scene), "--estimators", "scaled", "--no-report", "-o", str(out), "--save-baseline"]
    for path, words in (
        (afile / "base.json", f"--save-baseline {afile / 'base.json'}: not a directory ({afile} is a file)"),
        (tmp_path, f"--save-baseline {tmp_path}: is a folder; give a file name"),
    ):
        _refused_before_it_renders(capsys, [*argv, str(path)], words, out)


@pytest.mark.parametrize(
    "args, words",
    [
        # rendered, ran, and wrote a row 'failed: scaled.foo: unknown config key', exit 0
        (["--estimators", "scaled", "--est-set", "scaled.foo=1"], "--est-set scaled.foo: unknown config key"),
        (["--est-set", "scaled.foo=1"], "--est-set scaled.foo: unknown config key"),
        # a config of an estimator that does not run was ignored
        (
            ["--estimators", "scaled", "--est-set", "lossy.x=1"],
            "--est-set lossy: 'lossy' is not among --estimators (scaled), so its config would be ignored",
        ),
        (["--est-set", "nope.x=1"], "--est-set nope: unknown estimator (known: lossy, needs_depth, scaled)"),
        # ran nothing, printed 'results: DIR/results.csv' and wrote none, exit 0
        (["--estimators", ",,"], "--estimators: names no estimator; name at least one"),
        (["--estimators", ""], "--estimators: names no estimator; name at least one"),
    ],
)
def test_an_estimator_choice_that_cannot_run_as_given_is_refused_before_it_renders(
    tmp_path, doubles, capsys, args, words
):
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    out = tmp_path / "out"
    _refused_before_it_renders(capsys, ["bench", str(scene), *args, "--no-report", "-o", str(out)], words, out)


def test_a_bench_where_no_estimator_ran_is_an_error_saying_why(tmp_path, doubles, capsys):
    """Every estimator skipped (depth needed on a mono sequence): it printed 'results: DIR/results.csv',
    wrote none, and exited 0."""
    rec = D.render(D.load_scene(D.write_scene(tmp_path / "rec.toml", name="rec")), tmp_path / "rec")
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    for inputs, out in (([rec], tmp_path / "o1"), ([rec, scene], tmp_path / "o2")):
        argv = ["bench", *map(str, inputs), "--estimators", "needs_depth", "--no-report", "-o", str(out)]
        assert main(argv) == 1
        captured = capsys.readouterr()
        assert "results:" not in captured.out and "Traceback" not in captured.err
        (line,) = captured.err.splitlines()  # the skips in it, not as warnings before it too
        why = "rec: needs_depth needs depth" + ("; a: needs_depth needs depth" if scene in inputs else "")
        assert (
            line == f"floorsim: error: bench: no estimator ran on any scene: every estimator was skipped ({why}); "
            "nothing to score"
        )
        assert not (out / "results.csv").exists()
    assert not (tmp_path / "o1").exists()  # a sequence folder alone: nothing was written


def test_a_scene_override_given_with_sequence_folders_is_refused_or_said_to_skip_them(tmp_path, doubles, capsys):
    """--set with a sequence folder (run as recorded, not rendered) was silently ignored."""
    rec = D.render(D.load_scene(D.write_scene(tmp_path / "rec.toml", name="rec", height=2.0)), tmp_path / "rec")
    D.reset()
    out = tmp_path / "out"
    argv = ["bench", "--estimators", "scaled", "--set", "lights.height_mm=5", "--no-report", "-o", str(out)]
    words = f"--set lights.height_mm=5: sets how scene files are rendered, and {rec} is a sequence folder (run as"
    _refused_before_it_renders(capsys, [*argv, str(rec)], words, out)
    # the render settings too (--frames, --scale, --spp were as silently ignored)
    words = f"--frames 3, --spp 2: set how scene files are rendered, and {rec} is a sequence folder (run as recorded"
    _refused_before_it_renders(capsys, [*argv[:3], "--frames", "3", "--spp", "2", *argv[5:], str(rec)], words, out)
    # beside a scene file it applies to the scene: a note says the folder runs as recorded
    scene = D.write_scene(tmp_path / "a.toml", name="a", height=3.0)
    assert main([*argv, str(rec), str(scene)]) == 0
    note = f"--set lights.height_mm=5: applies to the scene files only, not to the sequence folder(s) {rec}"
    assert note in capsys.readouterr().out.splitlines()
    drift = {r["scene"]: r["end_drift_pct"] for r in read_results_csv(out / "results.csv")}
    assert drift == pytest.approx({"rec": 0.2, "a": 0.5}, rel=1e-4)  # 0.1 % per mm of the LED height


def test_a_gate_on_a_recording_sees_its_frames_and_a_refreshed_baseline_keeps_its_tolerances(tmp_path):
    """A sequence folder's inputs held its sequence.json and ground truth only: frames changed
    since the baseline (blurred) were blamed on the estimators. --save-baseline wrote the default
    tolerances over those edited into the file, and over the baseline a gate had just failed
    against, with the regressed numbers (the same command then passed). phase-corr for real."""
    import cv2

    from floorsim.bench.gates import load_baseline

    seq = write_sequence(tmp_path / "rec")
    base = tmp_path / "baseline.json"
    bench = partial(real_run_bench, [seq], ["phase-corr"], report=False)
    first = bench(tmp_path / "a", save_baseline_to=base)
    saved = json.loads(base.read_text())
    saved["tolerances"]["tracked_fraction"] = {"abs": 0.0, "rel": 0.0}
    saved["entries"]["rec/phase-corr"]["tracked_fraction"] = first.rows[0]["tracked_fraction"]
    base.write_text(json.dumps(saved))
    res = bench(tmp_path / "b", baseline=base, save_baseline_to=base)
    assert res.gate.ok and "tracked_fraction" in load_baseline(base).tolerances  # refreshed, its edits kept
    saved = json.loads(base.read_text())
    saved["entries"]["rec/phase-corr"]["tracked_fraction"] = 1.0  # a baseline no run meets
    base.write_text(json.dumps(saved))
    before = base.read_bytes()
    worse = bench(tmp_path / "c", baseline=base, save_baseline_to=base)
    assert not worse.gate.ok and worse.baseline_saved is None and base.read_bytes() == before
    assert any("not saved, the gate against it failed" in n for n in worse.notes)
    frame = seq / "cam0" / "000003.png"
    cv2.imwrite(str(frame), cv2.GaussianBlur(cv2.imread(str(frame), cv2.IMREAD_UNCHANGED), (0, 0), 3))
    gate = bench(tmp_path / "d", baseline=base).gate
    assert not gate.ok and gate.checked == 0 and gate.made_otherwise[0].startswith("rec/phase-corr: not comparable")


def test_a_scale_calibration_is_taken_for_a_module_class_estimator(tmp_path):
    """--estimators mod:Class ran, and --scale-calibration mod:Class=FILE was refused as an unknown estimator."""
    from floorsim.bench.bench import _load_scales
    from floorvo.calibration import ScaleCalibration, save_scale_calibration

    save_scale_calibration(ScaleCalibration(scale_x=1.01, observed_x=True, estimator="mymod:Vo"), tmp_path / "c.json")
    cals = _load_scales({"mymod:Vo": tmp_path / "c.json"}, ["mymod:Vo"], ["phase-corr"])
    assert cals["mymod:Vo"][1].scale_x == 1.01
    with pytest.raises(Exception, match="--scale-calibration nope=.*unknown estimator"):
        _load_scales({"nope": tmp_path / "c.json"}, None, ["phase-corr"])


def test_a_bench_of_a_one_frame_recording_is_refused_and_a_failed_run_is_not_drawn(tmp_path, monkeypatch):
    """A sequence folder of 1 frame gave 'ok' rows that tracked nothing (a render of --frames 1 is
    refused). A run that failed in a bench run again was drawn and timed from the files of the run
    before it, which its folder keeps (an interrupted or failed run loses nothing written)."""
    from floorvo.errors import ConfigError

    one = write_sequence(tmp_path / "one", n=1)
    with pytest.raises(ConfigError, match=r"holds 1 frame\(s\): a bench needs at least 2"):
        real_run_bench([one], ["phase-corr"], tmp_path / "b1", report=False)
    (tmp_path / "flaky_vo_for_tests.py").write_text(
        "import os\n"
        "from floorvo.estimators.phase_corr import PhaseCorr\n"
        "class Flaky(PhaseCorr):\n"
        "    name = 'flaky'\n"
        "    def step(self, state, frame):\n"
        "        if os.environ.get('FLAKY_FOR_TESTS'):\n"
        "            raise RuntimeError('flaky failure')\n"
        "        return super().step(state, frame)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    seq = write_sequence(tmp_path / "rec")
    bench = partial(real_run_bench, [seq], ["phase-corr", "flaky_vo_for_tests:Flaky"], tmp_path / "b2", report=False)
    first = bench()
    assert {r.estimator for r in first.records} == {"phase-corr", "flaky_vo_for_tests:Flaky"}
    monkeypatch.setenv("FLAKY_FOR_TESTS", "1")
    again = bench()
    rows = {r["estimator"]: r for r in again.rows}
    assert rows["flaky_vo_for_tests:Flaky"]["status"].startswith("failed: ")
    assert {r.estimator for r in again.records} == {"phase-corr"}  # its folder still holds the run before
    assert (Path(rows["flaky_vo_for_tests:Flaky"]["run_dir"]) / "trajectory.txt").exists()


def test_a_calibration_fitted_on_the_benched_sequence_is_noted_in_the_results_and_the_report(tmp_path):
    """A scale calibration fitted on the very sequence a bench scores was said in result.json's
    ``scale_calibration_problems`` and on standard error only: results.csv and the report showed
    its calibrated drift, tuned on that sequence, without a word. The row's ``score_warnings``
    holds it now, and the report lists it under "Notes"."""
    import numpy as np

    from floorvo.camera import CameraModel
    from floorvo.cli import main as floorvo_main
    from floorvo.geometry import T_world_cam_down
    from floorvo.synthetic import write_synthetic_sequence

    cam = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)
    seq = write_synthetic_sequence(
        tmp_path / "seq", cam, np.stack([T_world_cam_down(3.0 * i, 2.0 * i, 100.0) for i in range(8)])
    )
    assert floorvo_main(["run", str(seq), "-e", "phase-corr", "-o", str(tmp_path / "run"), "-q"]) == 0
    cal = tmp_path / "cal.json"
    assert floorvo_main(["calibrate", str(tmp_path / "run"), "--gt", str(seq), "-o", str(cal), "-q"]) == 0
    out = tmp_path / "bench"
    argv = ["bench", str(seq), "--estimators", "phase-corr", "-o", str(out), "--scale-calibration", f"phase-corr={cal}"]
    assert real_main([*argv, "-q"]) == 0
    row = read_results_csv(out / "results.csv")[0]
    assert "the scale calibration was fitted on this sequence" in row["score_warnings"]
    report = (out / "report.md").read_text()
    assert "## Notes" in report and "fitted on this sequence" in report
