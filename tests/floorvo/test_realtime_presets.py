"""The real-time presets (issue 14 item 5): listed, built from their own defaults, tracking as the defaults do.

Each ``NAME-fast`` is ``NAME``'s class with a Config whose defaults differ
(:func:`floorvo.config.with_defaults`); on a synthetic pair made in code it must recover the
motion within the tolerance the default estimator is held to in test_estimators.py and
test_estimators_rgbd_stereo.py.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from _synth import flat_floor_depth, frame_pair, stereo_pairs

from floorvo.camera import CameraModel
from floorvo.cli import main as floorvo_main
from floorvo.config import Config, param, with_defaults
from floorvo.errors import ConfigError, ConfigFieldError
from floorvo.estimators import Frame, get_estimator, list_estimators, make_config
from floorvo.geometry import T_world_cam_down, invert_T, yaw_of_R

CAM = CameraModel.from_sensor(324, 247, pixel_pitch_um=14.8, focal_length_mm=6.0)  # GSD 0.2467 mm at 100 mm
# stereo-sift-fast halves the frame before SIFT: it is meant for the full-size 648x494 camera
CAM_FULL = CameraModel.from_sensor(648, 494, pixel_pitch_um=7.4, focal_length_mm=6.0)
# preset -> (default estimator, the fields whose defaults differ, tolerance of the default: mm, deg)
PRESETS = {
    "akaze-guided-fast": (
        "akaze-guided",
        {
            "n_octaves": 1,
            "n_octave_layers": 1,
            "upright": True,
            "akaze_threshold": 0.001,
            "max_keypoints": 600,
            "describe_kept_only": True,
            "adapt_threshold": True,
            "fit_image_scale": True,
            "ransac_retry": False,
        },
        (0.03, 0.05),
    ),
    "akaze-bruteforce-fast": (
        "akaze-bruteforce",
        {
            "n_octaves": 1,
            "n_octave_layers": 1,
            "upright": True,
            "akaze_threshold": 0.001,
            "max_keypoints": 600,
            "describe_kept_only": True,
            "adapt_threshold": True,
            "fit_image_scale": True,
            "ransac_retry": False,
        },
        (0.03, 0.05),
    ),
    "orb-icp-fast": ("orb-icp", {"n_levels": 1, "per_cell": 15}, (0.03, 0.05)),
    "phase-corr-fast": ("phase-corr", {"downscale": 2, "impulse_ratio": 0.0, "converged_px": 0.2}, (0.03, 0.05)),
    "stereo-sift-fast": (
        "stereo-sift",
        {"detect_scale": 0.5, "contrast_blur_downscale": 2, "right_features": "flow"},
        (0.05, 0.05),
    ),
}


def _motion(dx_mm: float, dy_mm: float, yaw_deg: float) -> np.ndarray:
    """T_prev_cur of a downward camera moving (dx, dy) in its own x-y plane and yawing."""
    return invert_T(T_world_cam_down(0.0, 0.0, 100.0)) @ T_world_cam_down(dx_mm, -dy_mm, 100.0, np.radians(yaw_deg))


def test_presets_are_listed(capsys):
    assert set(PRESETS) <= set(list_estimators())
    assert floorvo_main(["list"]) == 0
    listed = capsys.readouterr().out
    for name, (base, _, _) in PRESETS.items():
        assert f"{name} " in listed
        assert f"{base}'s real-time preset" in listed
    assert floorvo_main(["list", "--config", "akaze-guided-fast"]) == 0
    rows = {line.split()[0]: line.split() for line in capsys.readouterr().out.splitlines()[2:] if line.strip()}
    assert rows["n_octaves"][2] == "1" and rows["max_keypoints"][2] == "600"


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_preset_is_the_default_class_with_other_defaults(name):
    base, changed, _ = PRESETS[name]
    cls, base_cls = get_estimator(name), get_estimator(base)
    assert issubclass(cls, base_cls) and cls.requires == base_cls.requires
    assert issubclass(cls.Config, base_cls.Config)
    fast, default = dataclasses.asdict(make_config(name)), dataclasses.asdict(make_config(base))
    assert set(fast) == set(default)
    assert {k for k in fast if fast[k] != default[k]} == set(changed)
    assert {k: fast[k] for k in changed} == changed
    # --set works on a preset as on its default, rules included
    key, value = next(iter(changed.items()))
    assert getattr(make_config(name, {key: str(getattr(make_config(base), key))}), key) != value
    with pytest.raises(ConfigError, match=rf"^{name}\.{key} = 0(\.0)?: must be "):
        make_config(name, {key: "0"})


def test_default_detectors_are_unchanged():
    """The new fields' defaults build the detectors the estimators built before them."""
    akaze = get_estimator("akaze-guided")(make_config("akaze-guided"), CAM, height_mm=100.0).detector
    assert (akaze.getNOctaves(), akaze.getNOctaveLayers(), akaze.getDescriptorType()) == (4, 4, 5)  # 5: MLDB
    fast = get_estimator("akaze-guided-fast")(make_config("akaze-guided-fast"), CAM, height_mm=100.0).detector
    assert (fast.getNOctaves(), fast.getNOctaveLayers(), fast.getDescriptorType()) == (1, 1, 4)  # 4: MLDB_UPRIGHT
    assert make_config("stereo-sift").detect_scale == 1.0 and make_config("stereo-sift").n_octave_layers == 3


@pytest.mark.parametrize("name", sorted(PRESETS))
@pytest.mark.parametrize("dx, dy, yaw", [(4.0, 0.0, 0.0), (2.5, -1.2, 1.5)])
def test_preset_tracks_a_synthetic_motion_as_the_default(name, dx, dy, yaw):
    base, _, (t_tol, yaw_tol) = PRESETS[name]
    T_true = _motion(dx, dy, yaw)
    for est_name in (base, name):
        est_cls = get_estimator(est_name)
        if "stereo" in est_cls.requires:
            (L0, R0), (L1, R1), flat, T01 = stereo_pairs(CAM_FULL, T_true, baseline_mm=20.0)
            est = est_cls(
                make_config(est_name),
                CAM_FULL,
                height_mm=100.0,
                flatfield=flat,
                camera_right=CAM_FULL,
                T_cam0_cam1=T01,
                flatfield_right=flat,
            )
            frames = [Frame(0, 0.0, L0, image_right=R0), Frame(1, 0.1, L1, image_right=R1)]
        else:
            prev, cur, flat = frame_pair(CAM, T_true)
            depth = flat_floor_depth(CAM) if "depth" in est_cls.requires else None
            est = est_cls(make_config(est_name), CAM, height_mm=100.0, flatfield=flat)
            frames = [Frame(0, 0.0, prev, depth_mm=depth), Frame(1, 0.1, cur, depth_mm=depth)]
        st = est.start()
        assert est.step(st, frames[0]).status == "init"
        r = est.step(st, frames[1])
        assert r.status == "ok", f"{est_name}: {r.reason}"
        np.testing.assert_allclose(r.T_prev_cur[:2, 3], T_true[:2, 3], atol=t_tol, err_msg=est_name)
        yaw_err = np.degrees(yaw_of_R(r.T_prev_cur[:3, :3] @ T_true[:3, :3].T))
        assert yaw_err == pytest.approx(0.0, abs=yaw_tol), est_name


@dataclasses.dataclass(frozen=True)
class _Probe(Config):
    count: int = param(3, min=1, doc="a count")
    size_mm: float = param(2.0, unit="mm", gt=0.0, doc="a size")


def test_with_defaults_changes_defaults_only():
    Sub = with_defaults(_Probe, "SubProbe", count=5)
    assert Sub().count == 5 and Sub().size_mm == 2.0 and issubclass(Sub, _Probe)
    assert [f.name for f in dataclasses.fields(Sub)] == ["count", "size_mm"]
    with pytest.raises(ConfigFieldError, match=r"count = 0: must be >= 1"):
        Sub(count=0)  # the field's rule is kept
    with pytest.raises(ConfigFieldError, match=r"count = -1: must be >= 1"):
        with_defaults(_Probe, "Bad", count=-1)  # a default breaking the rule is refused
    with pytest.raises(TypeError, match="no field 'colour'"):
        with_defaults(_Probe, "Bad", colour=1)


def test_describing_the_kept_keypoints_only_gives_the_same_features():
    """``describe_kept_only`` (the AKAZE presets) describes only the ``max_keypoints`` strongest
    keypoints: the same keypoints and bit-identical descriptors as describing all of them and
    keeping the strongest, on a synthetic floor frame with more keypoints than kept."""
    prev, _, flat = frame_pair(CAM_FULL, _motion(1.0, 0.0, 0.0))
    both = {}
    for kept_only in (False, True):
        cfg = make_config("akaze-guided-fast", {"describe_kept_only": str(kept_only).lower()})
        est = get_estimator("akaze-guided-fast")(cfg, CAM_FULL, height_mm=100.0, flatfield=flat)
        both[kept_only] = est._detect(prev)[:2]
    (pts_all, desc_all), (pts_kept, desc_kept) = both[False], both[True]
    assert len(pts_all) == 600
    order_all, order_kept = np.lexsort(pts_all.T), np.lexsort(pts_kept.T)
    assert np.array_equal(pts_all[order_all], pts_kept[order_kept])
    assert np.array_equal(desc_all[order_all], desc_kept[order_kept])


def test_adapted_threshold_finds_the_same_features_in_one_pass():
    """``adapt_threshold`` (the AKAZE presets): from the second frame on, AKAZE detects and
    describes once at a threshold taken from the previous frame's keypoints, and keeps the same
    keypoints with bit-identical descriptors as detecting at the config's threshold and
    describing the strongest; a frame that yields fewer than ``max_keypoints`` above the adapted
    threshold (here a blurred one) is detected again at the config's threshold, and after a frame
    with fewer than ``max_keypoints`` in all (a strongly blurred one) the next is detected and
    described whole in one pass, as the first is."""
    f0, f1, flat = frame_pair(CAM_FULL, _motion(1.0, 0.0, 0.0))
    blur = [cv2.GaussianBlur(f, (0, 0), s) for f, s in ((f1, 4.0), (f1, 6.0), (f0, 6.0))]
    frames = [f0, f1, *blur]
    name = "akaze-guided-fast"
    adapted = get_estimator(name)(make_config(name), CAM_FULL, height_mm=100.0, flatfield=flat)
    fixed = get_estimator(name)(
        make_config(name, {"adapt_threshold": "false"}), CAM_FULL, height_mm=100.0, flatfield=flat
    )
    state = adapted.start()
    calls = {"detect": 0, "compute": 0, "detectAndCompute": 0}
    adapted.detector = _CountingDetector(adapted.detector, calls)
    thresholds, counts, n_kept = [], [], []
    for i, img in enumerate(frames):
        thresholds.append(state.threshold)
        pts_a, desc_a, _ = adapted._detect(img, state)
        counts.append(dict(calls))
        pts_f, desc_f, _ = fixed._detect(img)
        n_kept.append(len(pts_f))
        oa, of = np.lexsort(pts_a.T), np.lexsort(pts_f.T)
        assert len(pts_a) == len(pts_f) and len(pts_a) > 0, i
        assert np.array_equal(pts_a[oa], pts_f[of]), i
        assert np.array_equal(desc_a[oa], desc_f[of]), i
    assert n_kept[:3] == [600, 600, 600] and n_kept[3] < 600  # sigma 6 px: fewer keypoints than are kept
    base = make_config(name).akaze_threshold
    assert thresholds[0] is None and thresholds[1] > base and thresholds[2] > base and thresholds[4] is None
    assert [(c["detect"], c["compute"], c["detectAndCompute"]) for c in counts] == [
        (0, 0, 1),  # the first frame: one pass at the config's threshold
        (0, 0, 2),  # the adapted threshold: one pass, one scale space
        (1, 1, 3),  # too few above the adapted threshold: detected again, the strongest described
        (2, 2, 4),  # the same, and fewer than max_keypoints in all
        (2, 2, 5),  # so the next frame is one pass at the config's threshold
    ]


class _CountingDetector:
    """An AKAZE detector that counts its detect / compute / detectAndCompute calls."""

    def __init__(self, detector, calls: dict):
        self._d, self._calls = detector, calls

    def __getattr__(self, key):
        attr = getattr(self._d, key)
        if key in self._calls:

            def counted(*a, **k):
                self._calls[key] += 1
                return attr(*a, **k)

            return counted
        return attr


def test_stereo_flow_finds_the_left_keypoints_in_the_right_frame():
    """``right_features = "flow"`` (stereo-sift-fast): SIFT runs on the left frame only, and the
    left keypoints are aligned in the right frame from a floor-plane guess 1.5 mm off (2.5 px of
    disparity): on a flat floor 100 mm below a 20 mm rig the right position of a left pixel is
    ``u - fx b / 100`` on the same row, so the triangulated depths are 100 mm."""
    (L0, R0), _, flat, T01 = stereo_pairs(CAM_FULL, _motion(1.0, 0.0, 0.0), baseline_mm=20.0)
    name = "stereo-sift-fast"
    est = get_estimator(name)(
        make_config(name),
        CAM_FULL,
        height_mm=100.0,
        flatfield=flat,
        camera_right=CAM_FULL,
        T_cam0_cam1=T01,
        flatfield_right=flat,
    )
    detected = []
    sift_detect = est._detect
    est._detect = lambda img8: detected.append(img8) or sift_detect(img8)
    side = est._stereo(L0, R0, (np.array([0.0, 0.0, 1.0]), 98.5))
    assert len(detected) == 1  # the left frame's SIFT only
    assert len(side.uv) >= 100
    depth_err_mm = np.abs(side.xyz[:, 2] - 100.0)
    assert np.median(depth_err_mm) < 0.05 and np.percentile(depth_err_mm, 90) < 0.15
    n, d = side.plane
    assert d == pytest.approx(100.0, abs=0.05) and abs(n[2]) > 0.9999
