"""The breaking-point search on real renders agrees with a dense grid over the same range.

A small fast scene: the demo rig at quarter size (81 x 62 px), 4 frames, 4 spp (what
``spp = 1`` rendered before the renderer took exactly the samples asked for; at 1 spp
phase-corr loses every frame at this size, at any LED height). Below about 0.1 mm the
LEDs are so low that the relief's shadows cover the floor and phase-corr loses frames;
above, it tracks. The dense grid renders every value of the
search grid; the search renders both ends and bisects, and shares the render cache. At this size a pixel is
0.5 mm of floor, and no step can be shown to lie within issue 14's 0.13 mm bound: phase-corr's
precision check (``precision_sigmas``) would lose every one, at any LED height, so the study
turns it off (``[estimator_config.phase-corr]``); what is tested is the search.
"""

from pathlib import Path

import pytest

from floorsim.bench.search import search_grid
from floorsim.bench.sweep import run_sweep

pytestmark = pytest.mark.render

DEMO = Path(__file__).resolve().parents[2] / "scenes" / "demo.toml"
COMMON = f"""base = "{DEMO}"
estimators = ["phase-corr"]
[render]
frames = 4
scale = 0.25
spp = 4
[estimator_config.phase-corr]
precision_sigmas = 0
[criterion]
end_drift_pct = 5.0
lost_frames = 0
"""
LOW, HIGH, TOLERANCE = 0.02, 0.5, 0.06


def test_search_on_renders_agrees_with_the_dense_grid_within_the_tolerance(tmp_path):
    cache = tmp_path / "sequences"
    search_file = tmp_path / "search.toml"
    search_file.write_text(
        COMMON + f'[search]\nkey = "lights.height_mm"\nlow = {LOW}\nhigh = {HIGH}\nfails = "below"\n'
        f"tolerance = {TOLERANCE}\n"
    )
    res = run_sweep(search_file, tmp_path / "search", cache_dir=cache, report=False)
    assert res.errors == []
    (p,) = res.search.points
    assert p.point.state == "found"

    grid = search_grid(LOW, HIGH, TOLERANCE)
    dense_file = tmp_path / "dense.toml"
    dense_file.write_text(COMMON + f'[vary]\n"lights.height_mm" = {grid}\n')
    dense = run_sweep(dense_file, tmp_path / "dense", cache_dir=cache, report=False)
    assert dense.errors == [] and len(dense.rows) == len(grid)
    fails = {
        r["lights.height_mm"]: r["status"] != "ok" or r["lost_frames"] > 0 or r["end_drift_pct"] > 5.0
        for r in dense.rows
    }
    # The dense grid's answer: the first failing value coming down from the working end (0.5 mm).
    first_failing = max(v for v, f in fails.items() if f)
    assert fails[LOW] and not fails[HIGH] and first_failing < HIGH
    next_working = min(v for v in fails if v > first_failing)
    dense_breaking = 0.5 * (first_failing + next_working)
    assert abs(p.point.value - dense_breaking) <= TOLERANCE
    assert p.point.bracket == (first_failing, next_working)
    assert res.search.renders["all"] < len(grid)
    print(f"search: {res.search.describe(p)}; {res.search.renders['all']} renders, dense grid {len(grid)}")
