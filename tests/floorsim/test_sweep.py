"""Sweeps: a 2x2 grid on a two-worker local Dask cluster, streaming, restart, curves.

The scene loader, the renderer and the estimators are the test doubles of
``_bench_doubles``, passed in as collaborators (the ``scaled`` estimator's drift is 0.1 %
per mm of LED height), so the drift of every row is known."""

from functools import partial
from pathlib import Path

import _bench_doubles as D
import pytest

from floorsim.bench.results import read_results_csv, write_results_csv
from floorsim.bench.sweep import _as_override, load_sweep, sweep_jobs
from floorsim.bench.sweep import run_sweep as real_run_sweep
from floorsim.scene import load_scene
from floorvo.errors import ConfigError

run_sweep = partial(real_run_sweep, **D.COLLABORATORS)


def _sweep_file(tmp_path: Path) -> Path:
    base = D.write_scene(tmp_path / "base.toml", height=3.0)
    p = tmp_path / "sweep.toml"
    p.write_text(
        f'base = "{base.name}"\nestimators = ["scaled", "lossy"]\n\n[vary]\n'
        '"lights.height_mm" = [1.0, 10.0]\n"lights.power" = [0.5, 1.0]\n'
    )
    return p


def test_two_by_two_sweep_on_two_dask_workers_streams_and_restarts(tmp_path, monkeypatch):
    D.reset()
    sweep = _sweep_file(tmp_path)
    spec = load_sweep(sweep)
    assert len(sweep_jobs(spec)) == 4
    out = tmp_path / "out"
    # the workers' scratch space is the sweep's own and goes with it (Dask's default,
    # $TMPDIR/dask-scratch-space, outlived every sweep)
    import tempfile

    tmpdir = tmp_path / "tmpdir"
    tmpdir.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmpdir))
    res = run_sweep(sweep, out, workers=2, processes=False)
    assert res.errors == [] and res.ran == 4
    assert list(tmpdir.iterdir()) == []
    rows = read_results_csv(out / "results.csv")
    assert len(rows) == 4 * 2 and {r["job"] for r in rows} == {j["job"] for j in sweep_jobs(spec)}
    assert all(r["status"] == "ok" for r in rows)
    for r in rows:
        if r["estimator"] == "scaled":
            assert r["end_drift_pct"] == pytest.approx(0.1 * r["lights.height_mm"], rel=1e-4)
        else:
            assert r["lost_frames"] == 2
    # Each grid point is its own scene: four sequences rendered.
    assert len({r["sequence"] for r in rows}) == 4 and len(D.RENDER_CALLS) == 4
    html = (out / "sweep.html").read_text()
    assert html.count("data:image/png;base64,") == 2  # one robustness figure per varied key
    assert "operating point 3.0" in html  # the base scene's LED height is the paper rig's
    # Restart: nothing to do; drop one job's rows and only that job runs again.
    again = run_sweep(sweep, out, workers=2, processes=False)
    assert again.ran == 0 and again.skipped == 4
    first = rows[0]["job"]
    write_results_csv(out / "results.csv", [r for r in rows if r["job"] != first])
    third = run_sweep(sweep, out, workers=2, processes=False)
    assert third.ran == 1 and len(read_results_csv(out / "results.csv")) == len(rows)


def test_sweep_file_errors_name_the_key(tmp_path):
    base = D.write_scene(tmp_path / "base.toml")
    p = tmp_path / "s.toml"
    p.write_text(f'base = "{base.name}"\n[vary]\n"lights.height_mm" = []\n')
    with pytest.raises(ConfigError, match="vary.lights.height_mm"):
        load_sweep(p)
    p.write_text(f'base = "{base.name}"\nfoo = 1\n[vary]\n"a.b" = [1]\n')
    with pytest.raises(ConfigError, match="unknown key.*foo"):
        load_sweep(p)
    p.write_text('base = "missing.toml"\n[vary]\n"a.b" = [1]\n')
    with pytest.raises(ConfigError, match="does not exist"):
        load_sweep(p)


def test_shipped_sweep_files_vary_only_keys_the_scene_has():
    files = sorted((Path(__file__).resolve().parents[2] / "scenes" / "sweeps").glob("*.toml"))
    assert files
    for f in files:
        spec = load_sweep(f)
        for job in sweep_jobs(spec):
            scene = load_scene(spec.base, {**spec.fixed, **{k: _as_override(v) for k, v in job["params"].items()}})
            d = scene.to_dict()
            for key, value in job["params"].items():
                node = d
                for part in key.split("."):
                    node = node[part]
                assert node == value, (f.name, key)


def test_sweep_runs_sequence_folders_and_external_programs_in_every_job(tmp_path):
    """A sweep file's ``sequences`` are jobs beside the grid (not rendered); an external program runs
    in every job, grid and recording alike, on Dask workers, its rows naming where it came from."""
    import shlex
    import sys

    from floorvo.external import parse_external

    D.reset()
    sweep = _sweep_file(tmp_path)
    rec = D.render(D.load_scene(D.write_scene(tmp_path / "rec.toml", name="rec", height=2.0)), tmp_path / "rec")
    sweep.write_text(sweep.read_text().replace("[vary]", 'sequences = ["rec"]\n\n[vary]'))
    copy_gt = "import shutil, sys; shutil.copy(sys.argv[1] + '/groundtruth.txt', sys.argv[2] + '/trajectory.txt')"
    ext = parse_external(f"{shlex.quote(sys.executable)} -c {shlex.quote(copy_gt)} {{sequence}} {{output}}", "copy-gt")
    assert [j["job"] for j in sweep_jobs(load_sweep(sweep))][-1] == "sequence=rec"
    res = run_sweep(sweep, tmp_path / "out", workers=2, processes=False, externals=[ext])
    assert res.errors == [] and res.ran == 5
    rows = read_results_csv(tmp_path / "out" / "results.csv")
    by_job: dict[str, dict] = {}
    for r in rows:
        by_job.setdefault(r["job"], {})[r["estimator"]] = r
    assert set(by_job) == {j["job"] for j in sweep_jobs(load_sweep(sweep))}
    for job, runs in by_job.items():
        assert set(runs) == {"scaled", "lossy", "copy-gt"}, job
        assert runs["copy-gt"]["status"] == "ok" and runs["copy-gt"]["source"] == "external"
        assert runs["copy-gt"]["ate_none_rmse_mm"] == pytest.approx(0.0, abs=1e-6)
    recorded = by_job["sequence=rec"]
    assert recorded["scaled"]["sequence"] == str(rec.resolve()) and recorded["scaled"]["scene"] == "rec"
    # the recording was not rendered again: 4 grid renders and the one made above
    assert len(D.RENDER_CALLS) == 5
    assert recorded["scaled"]["end_drift_pct"] == pytest.approx(0.2, rel=1e-4)  # its LED height is 2 mm


def test_a_sweep_file_of_sequence_folders_needs_no_grid_and_refuses_a_grid_without_base(tmp_path):
    rec = D.render(D.load_scene(D.write_scene(tmp_path / "rec.toml", name="rec")), tmp_path / "rec")
    p = tmp_path / "s.toml"
    p.write_text('sequences = ["rec"]\n')
    spec = load_sweep(p)
    assert spec.base is None and spec.vary == {} and spec.sequences == [rec.resolve()]
    assert sweep_jobs(spec) == [{"job": "sequence=rec", "params": {}, "repetition": 0, "sequence": str(rec.resolve())}]
    p.write_text('sequences = ["rec"]\n[vary]\n"lights.height_mm" = [1.0, 2.0]\n')
    with pytest.raises(ConfigError, match=r"s\.toml: \[vary\] needs base = the scene file"):
        load_sweep(p)
    p.write_text('sequences = ["nowhere"]\n')
    with pytest.raises(ConfigError, match=r"sequences: 'nowhere': not a sequence folder"):
        load_sweep(p)
    p.write_text("estimators = []\n")
    with pytest.raises(ConfigError, match=r"base is missing: must name the base scene file"):
        load_sweep(p)


def test_a_sweep_into_the_folder_of_another_study_is_refused_and_a_grown_grid_resumes(tmp_path, capsys):
    """Another base scene into the same folder kept the first study's rows for every job name the
    two shared ('lights.height_mm=1.0 lights.power=0.5', ...), ran nothing and reported them as its
    own. It is refused in one line naming what differs; the same study with a larger grid resumes."""
    D.reset()
    sweep = _sweep_file(tmp_path)
    out = tmp_path / "out"
    assert run_sweep(sweep, out, workers=2, processes=False).ran == 4
    rows_before = (out / "results.csv").read_bytes()
    D.write_scene(tmp_path / "base.toml", height=3.0, seed=9)  # another floor
    with pytest.raises(ConfigError, match=r"out: holds the results of another study \(its study.json differs in "):
        run_sweep(sweep, out, workers=2, processes=False)
    D.write_scene(tmp_path / "base.toml", height=3.0)  # the study as it was
    sweep.write_text(sweep.read_text().replace('"lights.power" = [0.5, 1.0]', '"lights.power" = [0.5, 1.0, 2.0]'))
    with_more = run_sweep(sweep, out, workers=2, processes=False)
    assert with_more.ran == 2 and with_more.skipped == 4  # only the new grid points ran
    assert (out / "results.csv").read_bytes().startswith(rows_before.split(b"\n")[0])
    sweep.write_text(sweep.read_text().replace('estimators = ["scaled", "lossy"]', 'estimators = ["scaled"]'))
    with pytest.raises(ConfigError, match=r"differs in estimators"):
        run_sweep(sweep, out, workers=2, processes=False)


def test_a_sweep_resumed_after_the_code_or_a_recording_changed_is_refused(tmp_path, monkeypatch, caplog):
    """phase-corr's step made 1 % longer and the study run again into its folder: every job already
    in results.csv was kept, the old code's rows reported as the new code's (a grown grid mixed
    both). study.json now records what made the rows (``made_by``: floorvo's and the bench's code,
    each estimator's source, library versions, each sequence folder's content) and such a resume
    is refused in one line naming what changed; a record without it resumes with a warning."""
    import json

    from floorsim.bench import study

    D.reset()
    sweep = _sweep_file(tmp_path)
    rec = D.render(D.load_scene(D.write_scene(tmp_path / "rec.toml", name="rec")), tmp_path / "rec")
    sweep.write_text(sweep.read_text().replace("[vary]", 'sequences = ["rec"]\n\n[vary]'))
    out = tmp_path / "out"
    assert run_sweep(sweep, out, workers=2, processes=False).ran == 5
    record = json.loads((out / "study.json").read_text())
    assert set(record["made_by"]) == set(study.MADE_BY_KEYS)
    assert run_sweep(sweep, out, workers=2, processes=False).ran == 0  # the same code: resumed, nothing to do
    real = study.code_sha256
    monkeypatch.setattr(study, "code_sha256", lambda *m: "edited" if m == ("floorvo",) else real(*m))
    with pytest.raises(
        ConfigError,
        match=r"out: its rows were made by other code or inputs \(study.json's made_by differs in floorvo\)",
    ):
        run_sweep(sweep, out, workers=2, processes=False)
    monkeypatch.setattr(study, "code_sha256", real)
    gt = rec / "groundtruth.txt"
    gt.write_text(gt.read_text().replace("0.000000", "0.000001", 1))  # the recording's ground truth corrected
    with pytest.raises(ConfigError, match=r"made_by differs in sequences\."):
        run_sweep(sweep, out, workers=2, processes=False)
    del record["made_by"]  # a study.json written before made_by was
    (out / "study.json").write_text(json.dumps(record))
    assert run_sweep(sweep, out, workers=2, processes=False).ran == 0
    assert "not checked that this code made them" in caplog.text


def test_a_worker_count_beyond_the_machine_is_refused_in_one_line(tmp_path, capsys, monkeypatch):
    """--jobs 1000000 tried to start a million processes; --workers as many Dask workers."""
    import floorsim.bench.sweep as sweep_module
    from floorsim.cli import main

    monkeypatch.setattr(sweep_module, "usable_cpus", lambda: 2)
    sweep = _sweep_file(tmp_path)
    for flag, n in (("--jobs", 10**6), ("--workers", 9), ("--jobs", 0), ("--workers", -1)):
        out = tmp_path / f"out{flag}{n}"
        assert main(["sweep", str(sweep), "-o", str(out), flag, str(n)]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "Traceback" not in err, err
        assert f"{flag} {n}: must be from 1 to 8 (4 per CPU of the 2 this process may use)" in err, err
        assert not out.exists()
    assert sweep_module.local_workers_problem(8) is None


def test_a_scheduler_address_that_is_not_one_is_refused_before_anything_is_written(tmp_path, capsys):
    """--scheduler notaurl was a 62-line traceback from inside Dask, after study.json and
    study.toml were written into the output folder."""
    from floorsim.cli import main

    sweep = _sweep_file(tmp_path)
    out = tmp_path / "out"
    assert main(["sweep", str(sweep), "-o", str(out), "--scheduler", "notaurl"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "--scheduler 'notaurl': not a Dask scheduler address, e.g. tcp://HOST:PORT" in err
    assert not out.exists()


def test_a_sweep_whose_workers_do_not_start_leaves_no_study_record(tmp_path, monkeypatch):
    """A scheduler that did not answer was refused in one line, but left study.json and
    study.toml behind in the folder it created: a refused command writes nothing."""
    import contextlib

    import floorsim.bench.sweep as sweep_module
    from floorvo.errors import FloorbenchError

    @contextlib.contextmanager
    def no_workers(*args, **kwargs):
        raise FloorbenchError("--scheduler tcp://127.0.0.1:1: cannot connect to a Dask scheduler there")
        yield

    monkeypatch.setattr(sweep_module, "job_pool", no_workers)
    D.reset()
    out = tmp_path / "out"
    with pytest.raises(FloorbenchError, match="cannot connect"):
        run_sweep(_sweep_file(tmp_path), out, scheduler="tcp://127.0.0.1:1")
    assert not out.exists()


def test_a_bench_and_a_sweep_refuse_each_others_results_folder(tmp_path, capsys):
    """A sweep into a bench's folder merged the bench's row into the study's results and report
    ('2 job(s) run ... 3 row(s)'); a bench into a study's folder replaced its results.csv."""
    from floorsim.cli import main

    D.reset()
    sweep = _sweep_file(tmp_path)
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    bench_dir, study_dir = tmp_path / "bench", tmp_path / "study"
    assert (
        main(["bench", str(scene), "--estimators", "scaled", "-o", str(bench_dir)], collaborators=D.COLLABORATORS) == 0
    )
    run_sweep(sweep, study_dir, workers=1, processes=False)
    before = {d: sorted(p.name for p in d.iterdir()) for d in (bench_dir, study_dir)}
    csvs = {d: (d / "results.csv").read_bytes() for d in (bench_dir, study_dir)}
    capsys.readouterr()
    renders = len(D.RENDER_CALLS)
    assert main(["sweep", str(sweep), "-o", str(bench_dir)], collaborators=D.COLLABORATORS) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{bench_dir}: holds a bench's results (results.csv without a study.json)" in err
    bench = ["bench", str(scene), "--estimators", "scaled", "-o", str(study_dir)]
    assert main(bench, collaborators=D.COLLABORATORS) == 1
    err = capsys.readouterr().err
    assert (
        err.count("\n") == 1 and f"{study_dir}: holds a study's results (study.json, written by floorsim sweep)" in err
    )
    assert len(D.RENDER_CALLS) == renders
    for d in (bench_dir, study_dir):  # nothing written
        assert sorted(p.name for p in d.iterdir()) == before[d] and (d / "results.csv").read_bytes() == csvs[d]


def test_a_sweep_refuses_what_the_bench_refuses_before_any_job(tmp_path, capsys):
    """--cache FILE ran every job into a failed row ('not a directory'), exit 0; a sequence folder
    of an unknown schema version a failed row, exit 0. Both are refused up front, as the bench
    refuses them (before it renders a scene given beside)."""
    import json

    from floorsim.cli import main

    D.reset()
    sweep = _sweep_file(tmp_path)
    afile = tmp_path / "afile"
    afile.write_text("x")
    rec = D.render(D.load_scene(D.write_scene(tmp_path / "rec.toml", name="rec")), tmp_path / "rec")
    meta = json.loads((rec / "sequence.json").read_text())
    (rec / "sequence.json").write_text(json.dumps({**meta, "schema_version": 3}))
    D.reset()
    unsupported = f"{rec / 'sequence.json'}: schema_version 3 is not supported"
    scene = D.write_scene(tmp_path / "a.toml", name="a")
    with_rec = tmp_path / "with_rec.toml"
    with_rec.write_text(sweep.read_text().replace("[vary]", 'sequences = ["rec"]\n\n[vary]'))
    out = tmp_path / "out"
    for argv, words in (
        (["sweep", str(sweep), "--cache", str(afile)], f"--cache {afile}: is a file, not a folder"),
        (["sweep", str(sweep), "--cache", str(afile / "c")], f"--cache {afile / 'c'}: not a directory ({afile} is"),
        (["bench", str(scene), "--cache", str(afile)], f"--cache {afile}: is a file, not a folder"),
        (["sweep", str(with_rec)], f"with_rec.toml: sequences: {unsupported}"),
        (["bench", str(scene), str(rec)], unsupported),
    ):
        assert main([*argv, "-o", str(out)], collaborators=D.COLLABORATORS) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, err
        assert not out.exists() and not D.RENDER_CALLS


def test_a_study_or_bench_refuses_these_before_it_renders(tmp_path, capsys):
    """Each was found out after the renders or not at all (the real scene loader and runner)."""
    from floorsim.cli import main

    demo = Path(__file__).resolve().parents[2] / "scenes" / "demo.toml"
    at_nan = tmp_path / "at_nan.toml"  # reported as "operating point nan", a search's margins from it
    at_nan.write_text(
        f'base = "{demo}"\nestimators = ["phase-corr"]\n[vary]\n"lights.height_mm" = [3.0]\n'
        '[operating_point]\n"lights.height_mm" = nan\n'
    )
    out = tmp_path / "out"
    for argv, words in (
        (["sweep", str(at_nan)], "at_nan.toml: operating_point.lights.height_mm = nan: demo.toml: lights.height_mm"),
        # a module:Class that does not import: a failed row after the renders, exit 0
        (["bench", str(demo), "--estimators", "no_such_module_for_tests:X"], "cannot be imported: ModuleNotFoundError"),
        # 0: empty paper-000 tables, exit 0; -1: a traceback after the renders
        (["bench", str(demo), "--paper000-runs", "0"], "--paper000-runs 0: must be >= 1"),
        # a disturbance that is no table: a traceback from the trajectory's builder
        (["bench", str(demo), "--set", "trajectory.disturbance=1"], "trajectory.disturbance = 1: must be a table"),
        (["render", str(demo), "--set", "trajectory.disturbance=[1]"], "trajectory.disturbance = [1]: must be a table"),
        # --jobs 1 is --jobs's default: argparse took it as not given beside --workers
        (
            ["sweep", str(at_nan), "--jobs", "1", "--workers", "1"],
            "argument --workers: not allowed with argument --jobs",
        ),
    ):
        assert main([*argv, "-o", str(out)]) == 1, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, err
        assert not out.exists()


@pytest.mark.parametrize("row", ["garbage", ",,,,", "s,e,a,7,0,2,0.25,extra"])
def test_a_results_csv_row_of_another_width_is_one_line(tmp_path, row):
    """A row cut short or a stray line in a sweep's results.csv (read back when it resumes) was a
    TypeError from the number parser (DictReader fills the missing cells with None)."""
    from floorvo.errors import SequenceError

    path = tmp_path / "results.csv"
    path.write_text("scene,estimator,job,seed,repetition,lights.count,end_drift_pct\ns,e,a,7,0,2,0.25\n" + row + "\n")
    with pytest.raises(SequenceError, match=r"results\.csv:3: a row of \d+ cells under a header of 7"):
        read_results_csv(path)


def test_results_csv_read_and_written_again_keeps_its_bytes(tmp_path):
    """A resumed sweep reads its results.csv and writes the earlier rows back: every number came
    back a float, so an integer column (the seed, an integer [vary] key) went from 7 to 7.0."""
    rows = [
        {
            "scene": "s",
            "estimator": "e",
            "job": "a",
            "seed": 7,
            "repetition": 0,
            "lights.count": 2,
            "end_drift_pct": 0.25,
        },
        {
            "scene": "s",
            "estimator": "e",
            "job": "b",
            "seed": 8,
            "repetition": 1,
            "lights.count": 4,
            "end_drift_pct": 1.0,
        },
        {
            "scene": "s",
            "estimator": "f",
            "job": "c",
            "seed": 9,
            "repetition": 0,
            "lights.count": 4,
            "end_drift_pct": None,
        },
    ]
    first, again = tmp_path / "a.csv", tmp_path / "b.csv"
    write_results_csv(first, rows)
    back = read_results_csv(first)
    write_results_csv(again, back)
    assert again.read_bytes() == first.read_bytes()
    assert back[0]["seed"] == 7 and isinstance(back[0]["seed"], int) and back[1]["end_drift_pct"] == 1.0
    assert isinstance(back[1]["end_drift_pct"], float) and back[2]["end_drift_pct"] is None
