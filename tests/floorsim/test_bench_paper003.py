"""The bench's paper-003 path: a map from the lawnmower scene, the kidnap scene relocalised on it.

The shipped paper003 scenes, shrunk (a 60 x 40 mm lawnmower, three 8 mm kidnap segments),
are "rendered" by a stand-in that writes exact views of one procedural floor texture at
each scene pose (:mod:`floorvo.synthetic`), so the truth of every frame is exact
and the test needs no Mitsuba.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

from floorsim.bench import run_bench
from floorsim.bench.results import read_results_csv
from floorvo import synthetic as syn
from floorvo.sequence import SequenceWriter

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def texture():
    return syn.floor_texture(1500, seed=5)  # 185 mm square at 0.1233 mm/px


def _shrunk_scene(tmp_path: Path, name: str, values: dict[str, str]) -> Path:
    text = (ROOT / "scenes" / f"{name}.toml").read_text()
    for key, value in values.items():
        text, n = re.subn(rf"(?m)^{key} = .*$", f"{key} = {value}", text)
        assert n == 1, key
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def _texture_render(texture):
    def render(scene, out, *, frames=None, scale=None, spp=None, seed=None, on_frame=None, overwrite=False):
        traj = scene.build_trajectory()
        cam = scene.camera_model()
        h = scene.camera.height_mm
        T = traj.T_world_cam
        meta = {
            "name": scene.name,
            "camera": cam.to_dict(),
            "fps": scene.fps,
            "frame_count": len(T),
            "rig": {"height_mm": h},
            "events": dict(traj.events),
            "scene": scene.to_dict(),
        }
        w = SequenceWriter(out, meta, overwrite=True)
        rng = np.random.default_rng(seed)
        for i, Ti in enumerate(T):
            w.write_frame(i, syn.view(texture, cam, Ti, h, noise_std=1.5, rng=rng, centre_mm=(30.0, 20.0)))
        w.write_groundtruth(np.arange(len(T)) / scene.fps, T)
        return Path(out)

    return render


def test_kidnap_scene_is_relocalised_on_the_map_of_the_lawnmower_scene(tmp_path, texture):
    area = {"width_mm": "60.0", "depth_mm": "40.0"}
    map_scene = _shrunk_scene(tmp_path, "paper003_map", area)
    kid_scene = _shrunk_scene(tmp_path, "paper003_kidnap", {**area, "segments": "3", "segment_length_mm": "8.0"})
    out = tmp_path / "bench"
    res = run_bench([map_scene, kid_scene], ["phase-corr"], out, render=_texture_render(texture))
    rows = {(r["scene"], r["estimator"]): r for r in read_results_csv(out / "results.csv")}
    assert set(rows) == {
        ("paper003_map", "phase-corr"),
        ("paper003_kidnap", "phase-corr"),
        ("paper003_kidnap", "relocalise"),
        ("paper003_kidnap", "map-fused"),
    }
    reloc = rows[("paper003_kidnap", "relocalise")]
    # every row says where its estimator came from (these two rows had an empty source)
    assert all(r["source"] == "built-in" and r["source_detail"] for r in rows.values())
    # 81 mapping frames (two 60 mm lanes and a 40 mm turn at 2 mm/frame); the 50 % rule keeps a few
    assert reloc["status"] == "ok" and reloc["map_scene"] == "paper003_map"
    assert 2 <= reloc["keyframes"] <= 20
    assert reloc["keyframe_fraction_pct"] == pytest.approx(100.0 * reloc["keyframes"] / 81)
    # exact views: every frame placed, sub-pixel accurate, both kidnaps recovered on landing
    assert reloc["frames"] == 15 and reloc["kidnaps"] == 2
    assert reloc["localised_pct"] == 100.0 and reloc["within_1mm_pct"] == 100.0
    assert reloc["loc_rmse_mm"] < 0.1 and reloc["ate_none_rmse_mm"] == pytest.approx(reloc["loc_rmse_mm"], rel=1e-6)
    assert str(reloc["frames_to_recover"]) == "0 0" and reloc["recovered_first_frame"] == 2
    assert reloc["query_ms_median"] > 0
    # Odometry across a teleport: in this shrunk area every view overlaps every other, and
    # phase-corr measures the jumps it can (a whole-region translation and a log-polar rotation
    # guess, then its blocks); whatever it cannot measure it must report lost, never a wrong step.
    odo = rows[("paper003_kidnap", "phase-corr")]
    assert int(odo["wrong_ok_steps"]) == 0
    assert (out / "paper003" / "paper003_map" / "map" / "map.json").is_file()
    # the paper's map: keyframe poses chained by eq. (24), not the mapping run's ground truth
    assert json.loads((out / "paper003" / "paper003_map" / "map" / "map.json").read_text())["pose_source"] == "chain"
    html = res.report_html.read_text()
    assert "Paper 003 reproduction" in html and "frames to recover" in html


def test_kidnap_scene_without_a_mapping_scene_says_so(tmp_path, texture):
    kid_scene = _shrunk_scene(tmp_path, "paper003_kidnap", {"segments": "2", "segment_length_mm": "4.0"})
    res = run_bench([kid_scene], ["phase-corr"], tmp_path / "bench", render=_texture_render(texture), report=False)
    assert any("paper003_kidnap: no relocalisation (no lawnmower scene" in n for n in res.notes)
    assert {r["estimator"] for r in res.rows} == {"phase-corr"}


@pytest.mark.parametrize("t0_s", [0.0, 5.0])
def test_relocalisation_scores_take_each_frame_by_its_own_time(tmp_path, t0_s):
    """The protocol's scores took frame k to be at k / fps: a sequence whose frame times start at
    5 s (a recording) scored 0 % localised where every fix was right. Six frames, a teleport at
    frame 3; the run places frames 0, 1 (0.3 mm off), 3 (2 mm off) and 4; its poses carry the frames' times."""
    from floorsim.bench.protocols.paper003 import relocalisation_metrics
    from floorvo.camera import CameraModel
    from floorvo.geometry import T_world_cam_down
    from floorvo.runfolder import RunFolder

    cam = CameraModel.from_sensor().scaled(0.1)
    T = np.stack([T_world_cam_down(2.0 * i, 0.0, 100.0) for i in range(6)])
    ts = t0_s + np.arange(6) / 30.0
    meta = {"camera": cam.to_dict(), "fps": 30.0, "frame_count": 6, "rig": {"height_mm": 100.0}}
    meta["events"] = {"teleport_frames": [3]}
    seq = tmp_path / "seq"
    with SequenceWriter(seq, meta) as w:
        for i in range(6):
            w.write_frame(i, np.full((cam.height_px, cam.width_px), 10 * i, np.uint8))
        w.write_timestamps(ts)
        w.write_groundtruth(ts, T)
    placed = [0, 1, 3, 4]
    est = T[placed].copy()
    est[1, 0, 3] += 0.3
    est[2, 1, 3] += 2.0
    RunFolder(ts[placed], est, None, {"estimator": "x"}).write(tmp_path / "run")
    m = relocalisation_metrics(seq, tmp_path / "run")
    assert m["localised_pct"] == pytest.approx(100.0 * 4 / 6) and m["within_1mm_pct"] == pytest.approx(100.0 * 3 / 6)
    assert m["loc_max_mm"] == pytest.approx(2.0) and m["frames_to_recover"] == [1]
