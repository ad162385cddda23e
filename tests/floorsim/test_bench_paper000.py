"""Paper-000 protocol on a synthetic strip, with a phase-correlation estimator double.

The strip is a random texture seen through a window that moves 2 px (one strip step) per
frame, so the measured distance of every run must equal the ground truth.
"""

import sys
import types
from dataclasses import dataclass, field

import numpy as np
import pytest

from floorsim.bench.protocols.paper000 import matching_modes, run_paper000
from floorsim.trajectories import paper000_subsequences
from floorvo.camera import CameraModel
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


@dataclass(frozen=True)
class Frame:
    index: int
    timestamp_s: float
    image: np.ndarray
    image_right: object = None
    depth_mm: object = None


@dataclass(frozen=True)
class StepResult:
    T_prev_cur: object
    status: str
    reason: str = ""
    timing_ms: dict = field(default_factory=dict)


class PhaseCorr:
    """Integer-pixel phase correlation along u; ``matching`` picks the timing label only."""

    name = "phasecorr"
    requires: set = set()

    @dataclass(frozen=True)
    class Config:
        matching: str = field(default="guided", metadata={"choices": ("guided", "brute_force")})

    def __init__(self, config, camera, *, height_mm, flatfield=None, **_):
        self.config, self.gsd = config, camera.gsd_mm_per_px(height_mm)

    def start(self):
        return {"prev": None}

    def step(self, state, frame):
        prev, state["prev"] = state["prev"], frame.image.astype(float)
        if prev is None:
            return StepResult(None, "init")
        F = np.fft.fft2(prev) * np.conj(np.fft.fft2(state["prev"]))
        corr = np.fft.ifft2(F / (np.abs(F) + 1e-9)).real
        du = int(np.argmax(corr.max(axis=0)))
        du = du - corr.shape[1] if du > corr.shape[1] // 2 else du
        ms = 1.0 if self.config.matching == "guided" else 3.0
        return StepResult(make_T(np.eye(3), [du * self.gsd, 0, 0]), "ok", timing_ms={"match": ms, "total": ms})


def test_protocol_measures_every_run_and_compares_matching_modes(tmp_path, monkeypatch):
    import floorvo

    est = types.ModuleType("floorvo.estimators")
    est.get_estimator = lambda n: PhaseCorr
    est.make_config = lambda n, over: PhaseCorr.Config(**over)
    base = types.ModuleType("floorvo.estimators.base")
    base.Frame = Frame
    monkeypatch.setitem(sys.modules, "floorvo.estimators", est)
    monkeypatch.setitem(sys.modules, "floorvo.estimators.base", base)
    monkeypatch.setattr(floorvo, "estimators", est, raising=False)

    seq, gsd, spacing = _strip(tmp_path / "strip")
    assert matching_modes("phasecorr") == ("matching", ["guided", "brute_force"])
    res = run_paper000(seq, ["phasecorr"], tmp_path / "p0")
    n_sig = len(paper000_subsequences("sigmoid_g125", 16, spacing))
    assert n_sig > 0 and len(paper000_subsequences("uniform", 16, spacing)) == 0  # too short a strip for model I
    assert len(res.runs) == 2 * 2 * n_sig  # two sigmoid models x two matching modes
    for r in res.runs:
        assert r["measured_mm"] == pytest.approx(r["true_mm"], abs=1e-5) and r["lost"] == 0
    by = {(s["estimator"], s["model"]): s for s in res.summary}
    assert by[("phasecorr (guided)", "sigmoid_g125")]["match_ms_mean"] == 1.0
    assert by[("phasecorr (brute_force)", "sigmoid_g175")]["match_ms_mean"] == 3.0
    assert (tmp_path / "p0" / "runs.csv").is_file() and (tmp_path / "p0" / "summary.csv").is_file()

    from floorsim.bench.report import Report

    rep = Report("t", tmp_path / "rep")
    res.report_section(rep)
    html, _ = rep.write()
    assert html.read_text().count("data:image/png;base64,") == 2  # Fig. 8 and Fig. 9
