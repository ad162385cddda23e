"""Paper protocols as plugins: chosen by what a scene declares, refused by name when they
do not fit, and given the scenes, rows and context the bench promises (test doubles for
the renderer and the estimators, passed in as collaborators)."""

from functools import partial
from typing import ClassVar

import _bench_doubles as D
import pytest

from floorsim.bench import run_bench as real_run_bench
from floorsim.bench.protocols import PROTOCOLS, BenchProtocol, ProtocolOutput
from floorsim.bench.results import read_results_csv
from floorsim.cli import main as real_main

run_bench = partial(real_run_bench, **D.COLLABORATORS)
main = partial(real_main, collaborators=D.COLLABORATORS)


@pytest.fixture(autouse=True)
def _reset():
    D.reset()


def _bench_table(protocols=None, trajectory=None) -> str:
    text = "" if trajectory is None else f'\n[trajectory]\ntype = "{trajectory}"\n'
    if protocols is not None:
        text += "\n[bench]\nprotocols = [" + ", ".join(f'"{p}"' for p in protocols) + "]\n"
    return text


class Tally(BenchProtocol):
    """Records what the bench gives each hook and adds a column, a row, a section and a note."""

    name: ClassVar[str] = "tally"
    description: ClassVar[str] = "test protocol"
    default_for: ClassVar[tuple[str, ...]] = ("tally_path",)

    def __init__(self):
        self.scene_calls, self.bench_calls = [], []

    def row_columns(self, scene):
        return {"tally_scene": scene.label}

    def run_scene(self, ctx, scene):
        self.scene_calls.append((scene.label, scene.seed, scene.seq_dir, list(scene.estimators), len(scene.rows)))
        return ProtocolOutput(
            sections=[lambda rep, _l=scene.label: rep.text(f"tally section of {_l}")],
            notes=[f"tally saw {scene.label}"],
        )

    def run_bench(self, ctx, scenes):
        self.bench_calls.append([s.label for s in scenes])
        return ProtocolOutput(rows=[{"scene": "tally", "estimator": "tally", "status": "ok", "count": len(scenes)}])


def test_a_registered_protocol_runs_on_the_scenes_that_ask_for_it(tmp_path, monkeypatch):
    tally = Tally()
    monkeypatch.setitem(PROTOCOLS, tally.name, tally)
    asks = D.write_scene(tmp_path / "a.toml", name="asks", extra=_bench_table(["tally"], trajectory="uniform"))
    default = D.write_scene(tmp_path / "b.toml", name="by_default", extra=_bench_table(trajectory="tally_path"))
    off = D.write_scene(tmp_path / "c.toml", name="off", extra=_bench_table([], trajectory="tally_path"))
    out = tmp_path / "out"
    res = run_bench([asks, default, off], ["scaled", "lossy"], out, repetitions=2)
    rows = read_results_csv(out / "results.csv")
    # a column on every estimator row of the scenes that run the protocol (both repetitions), none elsewhere
    for r in rows:
        if r["scene"] in ("asks", "by_default"):
            assert r["tally_scene"] == r["scene"]
        elif r["scene"] == "off":
            assert r["tally_scene"] is None
    # run_scene: once per scene, after all its repetitions, on repetition 0's sequence
    assert [c[0] for c in tally.scene_calls] == ["asks", "by_default"]
    for label, seed, seq_dir, estimators, n_rows in tally.scene_calls:
        assert seed == 7 and estimators == ["scaled", "lossy"] and n_rows == 2 * 2
        assert str(seq_dir) == next(r["sequence"] for r in rows if r["scene"] == label and r["repetition"] == 0)
    # run_bench: once, with those scenes in bench order; its rows go into results.csv
    assert tally.bench_calls == [["asks", "by_default"]]
    assert rows[-1]["scene"] == "tally" and rows[-1]["count"] == 2.0
    assert "tally saw asks" in res.notes and "tally saw by_default" in res.notes
    page = res.report_html.read_text()
    assert "tally section of asks" in page and "tally section of by_default" in page


def test_protocols_follow_the_scene_declaration_not_its_name(tmp_path):
    # Named like a paper-001 scene, but it does not ask for the protocol: no paper-001 column.
    scene = D.write_scene(tmp_path / "p1.toml", name="paper001_line", extra=_bench_table(trajectory="line"))
    res = run_bench([scene], ["scaled"], tmp_path / "out")
    assert "paper_ref_error_pct" not in res.rows[0]
    assert "Paper 001 reproduction" not in res.report_html.read_text()


def test_an_unknown_or_unfitting_protocol_is_refused_before_rendering(tmp_path, capsys):
    for protocols, trajectory, words in (
        (["nope"], "uniform", "'nope' is not a bench protocol"),
        (["paper001-line"], "uniform", "'paper001-line' runs on a trajectory of type line, not 'uniform'"),
        (["paper000-strip"], "line", "of type strip"),
    ):
        scene = D.write_scene(tmp_path / "s.toml", extra=_bench_table(protocols, trajectory))
        rc = main(["bench", str(scene), "--estimators", "scaled", "-o", str(tmp_path / "out")])
        err = capsys.readouterr().err
        assert rc == 1 and err.count("\n") == 1 and "s.toml: bench.protocols" in err and words in err, err
    assert D.RENDER_CALLS == []


def test_shipped_paper_scenes_declare_their_protocols():
    from floorsim.bench.protocols import protocols_for_scene
    from floorsim.scene import load_scene

    expect = {
        "paper000_strip": ["paper000-strip"],
        "paper001_line": ["paper001-line"],
        "paper001_line3m_rgbd": ["paper001-line"],
        "paper003_map": ["paper003-relocalisation"],
        "paper003_kidnap": ["paper003-relocalisation"],
        "paper000_uniform": [],
        "demo": [],
    }
    for name, protocols in expect.items():
        scene = load_scene(name)
        assert [p.name for p in protocols_for_scene(scene)] == protocols, name
        if protocols:  # declared in the file, not left to the trajectory-type default
            assert list(scene.bench.protocols) == protocols, name
