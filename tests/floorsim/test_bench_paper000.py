"""Paper-000 protocol on a synthetic strip, with two phase-correlation estimator doubles.

The strip is a random texture seen through a window that moves 2 px (one strip step) per
frame, so the measured distance of every run must equal the ground truth. The doubles, a
guided and a brute-force variant that differ only in the matching time they report, come
in through the protocol's ``runner`` (the bench's estimator collaborator).
"""

import csv

import numpy as np
import pytest

from floorsim.bench.estimators import EstimatorRunner
from floorsim.bench.protocols.paper000 import run_paper000
from floorsim.bench.report import Report
from floorsim.trajectories import paper000_subsequences
from floorvo.camera import CameraModel
from floorvo.estimators import StepResult
from floorvo.geometry import T_world_cam_down, make_T
from floorvo.sequence import SequenceWriter


def _strip(root, n=16):
    cam = CameraModel.from_sensor().scaled(0.125)  # 81 x 62 px
    gsd = cam.gsd_mm_per_px(100.0)
    spacing = 2 * gsd  # one strip step = 2 px
    w = SequenceWriter(root, {"camera": cam.to_dict(), "fps": 10.0, "frame_count": n, "rig": {"height_mm": 100.0}})
    tex = np.random.default_rng(0).integers(0, 255, (cam.height_px, cam.width_px + 2 * n + 4), dtype=np.uint8)
    for i in range(n):
        # moving the camera +x shifts the content toward -u
        w.write_frame(i, np.ascontiguousarray(tex[:, 2 * i : 2 * i + cam.width_px]))
    w.write_groundtruth(np.arange(n) / 10.0, np.stack([T_world_cam_down(i * spacing, 0, 100.0) for i in range(n)]))
    return root, gsd, spacing


class PhaseCorr:
    """Integer-pixel phase correlation along u; ``match_ms`` is the matching time it reports."""

    requires: frozenset = frozenset()

    def __init__(self, camera, height_mm, match_ms):
        self.gsd, self.match_ms = camera.gsd_mm_per_px(height_mm), match_ms

    def start(self):
        return {"prev": None}

    def step(self, state, frame):
        prev, state["prev"] = state["prev"], frame.image.astype(float)
        if prev is None:
            return StepResult("init")
        F = np.fft.fft2(prev) * np.conj(np.fft.fft2(state["prev"]))
        corr = np.fft.ifft2(F / (np.abs(F) + 1e-9)).real
        du = int(np.argmax(corr.max(axis=0)))
        du = du - corr.shape[1] if du > corr.shape[1] // 2 else du
        ms = self.match_ms
        return StepResult("ok", make_T(np.eye(3), [du * self.gsd, 0, 0]), timing_ms={"match": ms, "total": ms})


class PhaseCorrRunner(EstimatorRunner):
    """Builds the doubles by name: guided matching reports 1 ms, brute force 3 ms."""

    MATCH_MS = {"phasecorr-guided": 1.0, "phasecorr-bruteforce": 3.0}

    def names(self):
        return list(self.MATCH_MS)

    def build(self, seq, name, overrides=None):
        return PhaseCorr(seq.camera, seq.height_mm, self.MATCH_MS[name]), None


def test_protocol_measures_every_run_and_compares_matching_modes(tmp_path):
    seq, gsd, spacing = _strip(tmp_path / "strip")
    res = run_paper000(seq, ["phasecorr-guided", "phasecorr-bruteforce"], tmp_path / "p0", runner=PhaseCorrRunner())
    n_sig = len(paper000_subsequences("sigmoid_g125", 16, spacing))
    assert n_sig > 0 and len(paper000_subsequences("uniform", 16, spacing)) == 0  # too short a strip for model I
    assert len(res.runs) == 2 * 2 * n_sig  # two sigmoid models x two matching modes
    for r in res.runs:
        assert r["measured_mm"] == pytest.approx(r["true_mm"], abs=1e-5) and r["lost"] == 0
    by = {(s["estimator"], s["model"]): s for s in res.summary}
    assert by[("phasecorr-guided", "sigmoid_g125")]["match_ms_mean"] == 1.0
    assert by[("phasecorr-bruteforce", "sigmoid_g175")]["match_ms_mean"] == 3.0
    assert (tmp_path / "p0" / "runs.csv").is_file() and (tmp_path / "p0" / "summary.csv").is_file()
    # numbers written as plain decimals (numpy 2 wrote np.float64(...)): csv + float reads them back
    for name, text in (("runs.csv", {"scene", "estimator", "model"}), ("summary.csv", {"estimator", "model"})):
        with (tmp_path / "p0" / name).open(newline="") as fh:
            rows = list(csv.DictReader(fh))
        assert len(rows) == len(res.runs if name == "runs.csv" else res.summary)
        for row, mem in zip(rows, res.runs if name == "runs.csv" else res.summary):
            for k, v in row.items():
                assert (v == mem[k]) if k in text else float(v) == pytest.approx(mem[k], nan_ok=True), (name, k, v)

    rep = Report("t", tmp_path / "rep")
    res.report_section(rep)
    html, _ = rep.write()
    assert html.read_text().count("data:image/png;base64,") == 2  # Fig. 8 and Fig. 9


def test_a_strip_without_camera_height_is_refused(tmp_path):
    """The distance scale comes from the camera height: a strip that does not state it is refused, not run at 100 mm."""
    import json

    from floorsim.bench.protocols.paper000 import run_subsequence
    from floorvo.errors import SequenceError
    from floorvo.sequence import Sequence

    root, _, _ = _strip(tmp_path / "strip")
    meta = json.loads((root / "sequence.json").read_text())
    del meta["rig"]["height_mm"]
    (root / "sequence.json").write_text(json.dumps(meta))
    with pytest.raises(SequenceError, match="rig.height_mm is missing"):
        run_subsequence(Sequence.open(root), "phase-corr", [0, 1])
    res = run_paper000(root, ["phase-corr"], tmp_path / "p0")
    assert res.runs == [] and len(res.skipped) == 1 and "rig.height_mm is missing" in res.skipped[0]
