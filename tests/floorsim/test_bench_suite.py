"""Bench suites: ``floorsim bench --suite motion`` runs every scene the suite file lists through the
one bench loop (renderer and estimators are the bench's test doubles), and the shipped motion
suite covers what issue 14 asks for."""

import csv
import tomllib
from functools import partial

import _bench_doubles as D
import numpy as np
import pytest

from floorsim.bench.suites import SUITE_FILE, list_suites, suite_scenes
from floorsim.cli import main as real_main
from floorsim.scene import load_scene, scenes_dir
from floorvo.errors import ConfigError
from floorvo.geometry import se2_from_T

main = partial(real_main, collaborators=D.COLLABORATORS)


@pytest.fixture
def doubles():
    D.reset()
    return D


def _listed(suite: str = "motion") -> list[str]:
    return tomllib.loads((scenes_dir() / suite / SUITE_FILE).read_text())["scenes"]


def test_bench_runs_every_scene_of_the_motion_suite_in_one_command(tmp_path, doubles, capsys):
    out = tmp_path / "out"
    rc = main(
        ["bench", "--suite", "motion", "--estimators", "scaled,lossy", "--frames", "4", "--no-report", "-o", str(out)]
    )
    assert rc == 0, capsys.readouterr().err
    with open(out / "results.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    names = [tomllib.loads((scenes_dir() / "motion" / s).read_text())["name"] for s in _listed()]
    # One row per scene x estimator, in the suite file's order, every scene rendered once.
    assert [r["scene"] for r in rows] == [n for n in names for _ in range(2)]
    assert [r["estimator"] for r in rows] == ["scaled", "lossy"] * len(names)
    assert all(r["status"] == "ok" for r in rows)
    assert len(D.RENDER_CALLS) == len(names) == len(set(names))
    printed = capsys.readouterr().out
    assert all(n in printed for n in names)


def test_a_suite_file_and_scene_arguments_run_together(tmp_path, doubles):
    extra = D.write_scene(tmp_path / "extra.toml", name="extra")
    D.write_scene(tmp_path / "a.toml", name="a")
    D.write_scene(tmp_path / "b.toml", name="b")
    suite = tmp_path / "mine.toml"
    suite.write_text('name = "mine"\nscenes = ["b.toml", "a.toml"]\n')
    out = tmp_path / "out"
    assert (
        main(["bench", str(extra), "--suite", str(suite), "--estimators", "scaled", "--no-report", "-o", str(out)]) == 0
    )
    with open(out / "results.csv", newline="") as f:
        assert [r["scene"] for r in csv.DictReader(f)] == ["extra", "b", "a"]


@pytest.mark.parametrize(
    "text, message",
    [
        ('scenes = ["a.toml"]\nscene = "b.toml"\n', "scene: unknown key"),
        ("scenes = []\n", "at least one scene file"),
        ('scenes = ["missing.toml"]\n', "'missing.toml' is not a file"),
        ("scenes = [\n", "not valid TOML"),
    ],
)
def test_a_bad_suite_file_is_one_line_naming_it(tmp_path, doubles, capsys, text, message):
    D.write_scene(tmp_path / "a.toml", name="a")
    suite = tmp_path / "bad.toml"
    suite.write_text(text)
    assert main(["bench", "--suite", str(suite), "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err and "bad.toml" in err
    assert not D.RENDER_CALLS


@pytest.mark.parametrize("how", ["suite", "argument and suite", "arguments"])
def test_the_same_scene_twice_is_refused_in_one_line(tmp_path, doubles, capsys, how):
    """A scene listed twice ran twice, as 'a' and 'a-2', with the same seed: two rows of one run."""
    a = D.write_scene(tmp_path / "a.toml", name="a")
    suite = tmp_path / "mine.toml"
    suite.write_text('scenes = ["a.toml", "a.toml"]\n' if how == "suite" else 'scenes = ["a.toml"]\n')
    args = {"suite": ["--suite", str(suite)], "argument and suite": [str(a), "--suite", str(suite)]}.get(
        how, [str(a), str(a)]
    )
    assert main(["bench", *args, "--estimators", "scaled", "--no-report", "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "a.toml is given twice (as an argument or in a suite)" in err, err
    assert not D.RENDER_CALLS and not (tmp_path / "out").exists()


def test_an_unknown_suite_or_no_scene_at_all_is_refused_in_one_line(tmp_path, doubles, capsys):
    assert main(["bench", "--suite", "nope", "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "'nope'" in err and "motion" in err  # names the shipped suites
    assert main(["bench", "-o", str(tmp_path / "out")]) == 1
    assert "--suite" in capsys.readouterr().err
    with pytest.raises(ConfigError):
        suite_scenes(tmp_path / "nothing-here")


def test_the_motion_suite_covers_issue_14():
    """Turning (arc, S-curve, spin, a 90-degree corner), fast (10-30 mm/frame, blurred) and
    disturbed (bounce <= 2 mm, tilt <= 0.03 rad, vibration) scenes, each kind on more than
    one floor, every shipped material at least once; short enough to run here."""
    assert scenes_dir() / "motion" / SUITE_FILE in list_suites()
    scenes = [load_scene(p) for p in suite_scenes("motion")]
    kinds: dict[str, set[str]] = {}
    for s in scenes:
        d = s.to_dict()
        tr = s.build_trajectory()
        assert 15 <= tr.frame_count <= 60, s.name
        dist = d["trajectory"].get("disturbance", {})
        se2 = np.array([se2_from_T(T) for T in tr.T_world_cam])
        step = np.linalg.norm(np.diff(se2[:, :2], axis=0), axis=1).max()
        yaw = np.abs(np.diff(np.unwrap(se2[:, 2]))).max()
        kind = []
        if d["trajectory"]["type"] in ("arc", "s_curve", "spin", "turns"):
            kind.append(d["trajectory"]["type"])
        if d["trajectory"]["type"] == "turns":
            assert abs(se2[-1, 2] - se2[0, 2]) == pytest.approx(np.pi / 2)  # one corner of 90 degrees
        if step >= 10.0 - 1e-9:
            assert step <= 30.0 + 1e-9 and d["sensor"]["exposure_ms"] > 0, s.name  # fast runs are blurred
            kind.append("fast")
        for key, top in (("bounce_amp_mm", 2.0), ("tilt_amp_rad", 0.03), ("vibration_rms_mm", None)):
            if dist.get(key, 0) > 0:
                assert top is None or dist[key] <= top
                kind.append(key)
        assert kind or yaw > 0, s.name
        for k in kind:
            kinds.setdefault(k, set()).add(d["floor"]["material"])
    assert {"arc", "s_curve", "spin", "turns", "fast", "bounce_amp_mm", "tilt_amp_rad", "vibration_rms_mm"} <= set(
        kinds
    )
    assert all(len(m) >= 2 for m in kinds.values()), kinds
    shipped = {tomllib.loads(p.read_text())["floor"]["material"] for p in scenes_dir().glob("material_*.toml")}
    assert shipped <= {s.to_dict()["floor"]["material"] for s in scenes}
