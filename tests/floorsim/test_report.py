"""The bench report: self-contained HTML whose plots render in headless Chromium."""

import base64
import re
import shutil
import subprocess

import pytest
from _bench_data import write_run, write_sequence

from floorsim.bench.report import (
    GROUND_TRUTH_COLUMNS,
    GROUND_TRUTH_REASON_COLUMN,
    RunRecord,
    build_bench_report,
    display_rows,
    format_table,
)
from floorvo.scoring import NO_GROUND_TRUTH, NO_TRACK, score_run

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]

# Appended to a copy of the report: after load, list every image's decoded size.
PROBE = (
    "<script>window.addEventListener('load',function(){var r=[];document.querySelectorAll('img').forEach("
    "function(i){r.push(i.complete+':'+i.naturalWidth+'x'+i.naturalHeight)});var d=document.createElement('pre');"
    "d.id='imgcheck';d.textContent=r.join(' ');document.body.appendChild(d);});</script>"
)


def _chromium():
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    pytest.skip("headless Chromium is not installed (scripts/setup --test installs Debian's chromium)")


def _bench_dirs(tmp_path):
    seq = write_sequence(tmp_path / "seq")
    good = write_run(tmp_path / "runs" / "good", seq, scale=1.0, matches=True)
    bad = write_run(
        tmp_path / "runs" / "bad", seq, scale=1.05, y_drift_mm=0.05, lost=(3, 4), total_ms=9.0, estimator="bad"
    )
    rows, recs = [], []
    for name, run in (("good", good), ("bad", bad)):
        rows.append({"scene": "demo", "estimator": name, "repetition": 0, "status": "ok", **score_run(run, seq).flat()})
        recs.append(RunRecord("demo", name, 0, seq, run))
    return rows, recs


def test_report_is_self_contained_and_its_plots_render_in_chromium(tmp_path):
    rows, recs = _bench_dirs(tmp_path)
    html_path, md_path = build_bench_report(tmp_path / "out", rows, recs)
    page = html_path.read_text()
    # Self-contained: no reference to another file or a server.
    assert not re.search(r'src="(?!data:)', page) and "http" not in page
    imgs = re.findall(r'src="data:image/png;base64,([^"]+)"', page)
    assert len(imgs) == 4  # trajectory, error against distance, timing, matched keypoints
    assert all(base64.b64decode(b)[:8] == b"\x89PNG\r\n\x1a\n" for b in imgs)
    md = md_path.read_text()
    assert "| demo | bad |" in md and all(
        (md_path.parent / p).is_file() for p in re.findall(r"\]\((plots/[^)]+)\)", md)
    )

    chromium = _chromium()
    probe = tmp_path / "out" / "probe.html"
    probe.write_text(page.replace("</body>", PROBE + "</body>"))
    out = subprocess.run(
        [
            chromium,
            *CHROMIUM_FLAGS,
            f"--user-data-dir={tmp_path / 'chromium-profile'}",
            "--virtual-time-budget=5000",
            "--dump-dom",
            probe.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    found = re.search(r'<pre id="imgcheck">([^<]*)</pre>', out.stdout)
    assert found, out.stderr[-2000:]
    sizes = found.group(1).split()
    assert len(sizes) == 4
    for s in sizes:
        complete, wh = s.split(":")
        w, h = (int(v) for v in wh.split("x"))
        assert complete == "true" and w > 200 and h > 150, sizes


def test_report_says_when_no_keypoints_are_exposed(tmp_path):
    seq = write_sequence(tmp_path / "seq")
    run = write_run(tmp_path / "run", seq)
    rows = [{"scene": "demo", "estimator": "fake", "repetition": 0, "status": "ok", **score_run(run, seq).flat()}]
    html_path, _ = build_bench_report(tmp_path / "out", rows, [RunRecord("demo", "fake", 0, seq, run)])
    page = html_path.read_text()
    assert "No run wrote matched keypoints" in page
    assert page.count("data:image/png;base64,") == 3


def test_format_table_lists_every_row():
    rows = [
        {
            "scene": "a",
            "estimator": "x",
            "repetition": 0,
            "status": "ok",
            "ate_se2_rmse_mm": 0.123456,
            "lost_frames": 2.0,
        },
        {"scene": "b", "estimator": "y", "repetition": 1, "status": "failed: lost", "ate_se2_rmse_mm": float("nan")},
    ]
    t = format_table(rows).splitlines()
    assert len(t) == 4 and "0.1235" in t[2] and t[3].split()[0] == "b" and " - " in t[3]


def test_table_cells_of_a_run_scored_without_pose_metrics_say_why():
    """A run that tracked fewer than two frames of a sequence with ground truth says so in the
    first pose-metric cell (it said "no ground truth" whatever the reason), once (the other
    pose cells show "-"); a run of a recording without ground truth still says that."""
    rows = [
        {"estimator": "a", "status": "ok", "ground_truth": NO_TRACK, **{c: "" for c in GROUND_TRUTH_COLUMNS}},
        {"estimator": "b", "status": "ok", "ground_truth": NO_GROUND_TRUTH, **{c: "" for c in GROUND_TRUTH_COLUMNS}},
        {"estimator": "c", "status": "ok", "ground_truth": "ok", **{c: 0.1 for c in GROUND_TRUTH_COLUMNS}},
    ]
    a, b, c = display_rows(rows)
    others = GROUND_TRUTH_COLUMNS - {GROUND_TRUTH_REASON_COLUMN}
    assert a[GROUND_TRUTH_REASON_COLUMN] == "fewer than two frames tracked" and all(a[k] == "-" for k in others)
    assert b[GROUND_TRUTH_REASON_COLUMN] == "no ground truth" and all(b[k] == "-" for k in others)
    assert all(c[k] == 0.1 for k in GROUND_TRUTH_COLUMNS)
    table = format_table(rows).splitlines()
    assert table[2].count("fewer than two frames tracked") == 1 and table[3].count("no ground truth") == 1


def test_markdown_cells_stay_in_their_columns_and_text_columns_are_shown_as_written(tmp_path):
    """A plugin's message or a program's stderr tail (lines joined by ' | ') split a Markdown row
    into more cells than its header; '*', '_' and '<b>' in names rendered as emphasis or HTML; a
    scene folder named 1.50 or nan was shown as 1.5 and -. A gate's lines ran into one paragraph."""
    from floorsim.bench.report import Report

    rep = Report("t", tmp_path / "rep")
    rows = [
        {"scene": "1.50", "estimator": "mod:Cls", "status": "failed: kaboom | col2\nx", "end_drift_pct": 0.25},
        {"scene": "nan", "estimator": "sc|ene *u* <b>", "status": "ok", "end_drift_pct": float("nan")},
    ]
    cols = [("scene", "scene"), ("estimator", "estimator"), ("status", "status"), ("end_drift_pct", "drift %")]
    rep.table(rows, cols)
    rep.lines(["a: end_drift_pct got worse", "regression gate FAILED: 1 metric(s) worse"])
    html_path, md_path = rep.write()
    md = md_path.read_text().splitlines()
    table = [line for line in md if line.startswith("| ")]
    assert all(len(re.findall(r"(?<!\\)\|", line)) == len(cols) + 1 for line in table), table
    assert "| 1.50 | mod:Cls | failed: kaboom \\| col2 x | 0.25 |" in table
    assert "| nan | sc\\|ene \\*u\\* \\<b\\> | ok | - |" in table
    assert "- a: end\\_drift\\_pct got worse" in md and "- regression gate FAILED: 1 metric(s) worse" in md
    page = html_path.read_text()
    assert "<td>1.50</td>" in page and "sc|ene *u* &lt;b&gt;" in page
    assert "a: end_drift_pct got worse<br>regression gate FAILED" in page


def test_the_accuracy_figure_draws_each_estimator_its_own_way():
    """With 21 estimators the figure took matplotlib's ten-colour cycle: ext01, ext11 and a third
    were the same blue circles. Each now has its own colour and marker (floorvo.plots.run_styles)."""
    from floorsim.bench.report import _accuracy_time_figure

    rows = [
        {
            "scene": "s",
            "estimator": f"e{i:02d}",
            "status": "ok",
            "ate_se2_rmse_mm": 0.1 + i,
            "wall_ms_per_frame": 1.0 + i,
        }
        for i in range(21)
    ]
    fig = _accuracy_time_figure(rows)
    looks = {(tuple(line.get_color()), line.get_marker()) for line in fig.axes[0].get_lines()}
    assert len(looks) == 21
