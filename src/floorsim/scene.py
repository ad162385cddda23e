"""Scene files: TOML -> frozen dataclasses, validated by name.

A scene file (``scenes/NAME.toml``)::

    schema_version = 1
    name = "paper000_uniform"
    seed = 0            # floor, sensor noise and pixel jitter derive from it
    fps = 30.0

    [camera]            # paper-000 rig defaults
    width_px = 648
    height_px = 494
    pixel_pitch_um = 7.4
    focal_length_mm = 6.0
    height_mm = 100.0

    [floor]
    material = "vinyl"  # floorsim list shows the materials
    [floor.params]      # the material's own parameters
    bump_amplitude_mm = 0.03

    [lights]
    height_mm = 3.0     # LED emitters above the floor
    distance_mm = 70.0  # from the image centre, along the camera's x axis
    count = 8           # LEDs per bar
    side = "both"       # "left", "right" or "both"

    [sensor]
    bit_depth = 8

    [render]
    spp = 4
    depth = false       # depth/NNNNNN.png (1/100 mm) or .npy (float32 mm)

    [stereo]
    enabled = false     # cam1, baseline_mm along cam0's x axis

    [depth_noise]
    model = "none"      # or "structured_light" (floorsim/depthnoise.py)

    [trajectory]
    type = "uniform"    # plus that type's parameters
    [trajectory.disturbance]
    bounce_amp_mm = 0.0

Unknown keys, wrong types and impossible values are refused with one line naming the
key, the value and the rule. ``--set section.key=value`` overrides any key.
"""

from __future__ import annotations

import copy
import os
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from floorsim.depthnoise import DepthNoise
from floorsim.materials import get_material
from floorsim.params import from_mapping, rule, to_plain
from floorsim.trajectories import Trajectory, build_trajectory
from floorvo.camera import CameraModel
from floorvo.errors import ConfigError

__all__ = [
    "SCENE_SCHEMA_VERSION",
    "Scene",
    "CameraSpec",
    "FloorSpec",
    "LightsSpec",
    "SensorSpec",
    "RenderSpec",
    "StereoSpec",
    "load_scene",
    "scene_from_dict",
    "apply_overrides",
    "scenes_dir",
    "list_scenes",
    "resolve_scene_path",
]

SCENE_SCHEMA_VERSION = 1


@dataclass(frozen=True)
class CameraSpec:
    """Camera of the rig (defaults: paper 000, 1/3" CCD, 6 mm lens, 100 mm above the floor).

    ``distortion``: OpenCV (k1, k2, p1, p2, k3), applied to the rays, written to
    sequence.json. ``vignetting``: strength v of the lens falloff: each pixel is scaled
    by ``1 - v (1 - cos^4 theta)`` (theta: the pixel ray's angle to the optical axis).
    """

    width_px: int = field(default=648, metadata=rule(">=1", "px", hi=8192))
    height_px: int = field(default=494, metadata=rule(">=1", "px", hi=8192))
    pixel_pitch_um: float = field(default=7.4, metadata=rule(">0", "um"))
    focal_length_mm: float = field(default=6.0, metadata=rule(">0", "mm"))
    height_mm: float = field(default=100.0, metadata=rule(">0", "mm", lo=5.0, hi=2000.0))
    distortion: tuple[float, ...] = ()
    vignetting: float = field(default=0.0, metadata=rule("[0,1]"))

    def model(self) -> CameraModel:
        dist = tuple(self.distortion) + (0.0,) * (5 - len(self.distortion))
        if len(self.distortion) > 5:
            raise ConfigError(
                f"camera.distortion = {list(self.distortion)}: at most 5 coefficients (k1, k2, p1, p2, k3)"
            )
        return CameraModel.from_sensor(self.width_px, self.height_px, self.pixel_pitch_um, self.focal_length_mm, dist)


@dataclass(frozen=True)
class FloorSpec:
    """The floor: a registered material, its parameters, overlays of dirt and dust (their
    densities: fraction of cells holding a speck or grain), and how finely it is meshed."""

    material: str = "vinyl"
    seed: int | None = None
    relief_scale: float = field(default=1.0, metadata=rule(">=0", "", hi=100.0))
    spacing_mm: float | None = field(default=None, metadata=rule(">0", "mm"))
    tile_length_mm: float = field(default=240.0, metadata=rule(">0", "mm", lo=20.0))
    dirt_density: float = field(default=0.0, metadata=rule("[0,1]"))
    dust_density: float = field(default=0.0, metadata=rule("[0,1]"))
    params: dict = field(default_factory=dict)


@dataclass(frozen=True)
class LightsSpec:
    """Two LED bars on opposite sides of the hood (camera x axis), parallel to the floor.

    ``power`` is each bar's total radiant intensity (relative units, split evenly over
    its ``count`` LEDs); 0 turns the lights off, ``side`` turns one bar off. ``flicker``:
    the LED power of frame i is multiplied by ``max(0, 1 + flicker * N(0, 1))`` (seeded
    per frame; the flat-field frame has none). ``ambient_leak``: light leaking under the
    hood, a uniform unshadowed irradiance given as a fraction of the LEDs' irradiance on a
    flat floor under the camera. ``aim_offset_mm`` / ``aim_elevation_deg``: where the LEDs
    point (default: the floor under the camera centre). ``colour_temperature_k``: the LEDs'
    spectrum as a black body; the mono camera's response to it relative to 5000 K scales
    the power (:func:`floorsim.spectral.mono_response`), at equal luminous power.
    """

    height_mm: float = field(default=3.0, metadata=rule(">0", "mm"))
    distance_mm: float = field(default=70.0, metadata=rule(">0", "mm", hi=1000.0))
    count: int = field(default=8, metadata=rule(">=1", "LEDs per bar", hi=256))
    bar_length_mm: float = field(default=40.0, metadata=rule(">=0", "mm"))
    power: float = field(default=1.0, metadata=rule(">=0", ""))
    side: str = field(default="both", metadata=rule(choices=("both", "left", "right")))
    lobe_exponent: float = field(default=1.0, metadata=rule(">0", ""))
    flicker: float = field(default=0.0, metadata=rule(">=0", "relative std", hi=1.0))
    ambient_leak: float = field(default=0.0, metadata=rule(">=0", "", hi=10.0))
    aim_offset_mm: float = field(default=0.0, metadata=rule("any", "mm", lo=-500.0, hi=500.0))
    aim_elevation_deg: float = field(default=0.0, metadata=rule("any", "deg", lo=-45.0, hi=45.0))
    colour_temperature_k: float = field(default=5000.0, metadata=rule(">0", "K", lo=1500.0, hi=20000.0))


@dataclass(frozen=True)
class SensorSpec:
    """Sensor: exposure (0 = auto from the first frame), noise and quantisation.

    ``exposure_ms`` > 0 adds motion blur: the frame integrates ``blur_samples`` sub-frame
    renders at poses spread evenly over the exposure, centred on the frame time (the
    ground-truth pose is the one at the centre).
    """

    bit_depth: int = field(default=8, metadata=rule(choices=(8, 16)))
    exposure_gain: float = field(default=0.0, metadata=rule(">=0", "electrons per radiance unit"))
    target_percentile: float = field(default=99.0, metadata=rule(">0", "%", hi=100.0))
    target_level: float = field(default=0.8, metadata=rule("[0,1]"))
    full_well_e: float = field(default=10000.0, metadata=rule(">0", "e-"))
    read_noise_e: float = field(default=5.0, metadata=rule(">=0", "e-"))
    shot_noise: bool = True
    noise: bool = True
    exposure_ms: float = field(default=0.0, metadata=rule(">=0", "ms", hi=1000.0))
    blur_samples: int = field(default=8, metadata=rule(">=1", "", hi=256))


@dataclass(frozen=True)
class RenderSpec:
    """Render quality: samples per pixel (stratified), the flat-field calibration frame,
    the depth output (exact depth along the optical axis at each pixel centre), and
    ``shadows``: False drops the relief's cast shadows (shading only; for studies that
    separate what the shadows do to an estimator from what the shading does)."""

    spp: int = field(default=4, metadata=rule(">=1", "", hi=4096))
    shadows: bool = True
    flatfield: bool = True
    flatfield_albedo: float = field(default=0.5, metadata=rule("[0,1]"))
    depth: bool = False
    depth_format: str = field(default="png16", metadata=rule(choices=("png16", "npy_float32_mm")))


@dataclass(frozen=True)
class StereoSpec:
    """A second camera (cam1) under the same hood, ``baseline_mm`` along cam0's +x axis,
    same intrinsics and orientation (a rectified pair)."""

    enabled: bool = False
    baseline_mm: float = field(default=20.0, metadata=rule(">0", "mm", hi=200.0))


@dataclass(frozen=True)
class Scene:
    """A resolved scene. ``trajectory`` holds ``type``, its parameters and ``disturbance``."""

    name: str
    schema_version: int = SCENE_SCHEMA_VERSION
    description: str = ""
    seed: int = field(default=0, metadata=rule(">=0"))
    fps: float = field(default=30.0, metadata=rule(">0", "Hz"))
    camera: CameraSpec = field(default_factory=CameraSpec)
    floor: FloorSpec = field(default_factory=FloorSpec)
    lights: LightsSpec = field(default_factory=LightsSpec)
    sensor: SensorSpec = field(default_factory=SensorSpec)
    render: RenderSpec = field(default_factory=RenderSpec)
    stereo: StereoSpec = field(default_factory=StereoSpec)
    depth_noise: DepthNoise = field(default_factory=DepthNoise)
    trajectory: dict = field(default_factory=lambda: {"type": "uniform"})

    # ------------------------------------------------------------------ derived
    def camera_model(self) -> CameraModel:
        return self.camera.model()

    @property
    def floor_seed(self) -> int:
        return self.seed if self.floor.seed is None else self.floor.seed

    def floor_spacing_mm(self) -> float:
        """Mesh vertex spacing: the scene's, or half the ground-sample distance."""
        if self.floor.spacing_mm is not None:
            return self.floor.spacing_mm
        return 0.5 * self.camera_model().gsd_mm_per_px(self.camera.height_mm)

    def build_trajectory(self) -> Trajectory:
        t = dict(self.trajectory)
        ttype = t.pop("type")
        dist = t.pop("disturbance", None)
        return build_trajectory(
            ttype, t, height_mm=self.camera.height_mm, fps=self.fps, seed=self.seed, disturbance=dist
        )

    def led_positions_cam(self) -> tuple[np.ndarray, np.ndarray]:
        """LED positions (N, 3) in the camera frame (mm) and their bar side (+1 right, -1 left).

        The bars lie along the camera's y axis at x = -distance (left) and +distance
        (right), ``lights.height_mm`` above the floor, i.e. at camera depth
        ``camera.height_mm - lights.height_mm``.
        """
        L = self.lights
        z = self.camera.height_mm - L.height_mm
        ys = np.zeros(1) if L.count == 1 else np.linspace(-L.bar_length_mm / 2, L.bar_length_mm / 2, L.count)
        pos, side = [], []
        for s, on in ((-1, L.side in ("both", "left")), (1, L.side in ("both", "right"))):
            if not on:
                continue
            for y in ys:
                pos.append((s * L.distance_mm, y, z))
                side.append(s)
        return np.array(pos, dtype=float).reshape(-1, 3), np.array(side)

    def T_cam0_cam1(self) -> np.ndarray | None:
        """Pose of the right camera in the left camera's frame (mm), or None when mono."""
        if not self.stereo.enabled:
            return None
        T = np.eye(4)
        T[0, 3] = self.stereo.baseline_mm
        return T

    def to_dict(self) -> dict:
        """The resolved scene as plain data (written into sequence.json)."""
        return to_plain(self)


def _check_scene(scene: Scene) -> None:
    if scene.schema_version != SCENE_SCHEMA_VERSION:
        raise ConfigError(
            f"schema_version = {scene.schema_version}: this floorsim reads scene schema version {SCENE_SCHEMA_VERSION}"
        )
    if scene.lights.height_mm >= scene.camera.height_mm:
        raise ConfigError(
            f"lights.height_mm = {scene.lights.height_mm} mm: LEDs must be below the camera (camera.height_mm = {scene.camera.height_mm} mm)"
        )
    mat = get_material(scene.floor.material)
    from_mapping(mat.Params, scene.floor.params, "floor.params")
    scene.camera.model()
    if not isinstance(scene.trajectory, Mapping) or "type" not in scene.trajectory:
        raise ConfigError('trajectory.type: missing (e.g. type = "uniform")')
    scene.build_trajectory()  # validates the type's parameters


def scene_from_dict(d: Mapping[str, Any], default_name: str = "scene") -> Scene:
    """Build and validate a :class:`Scene` from a plain dict (a parsed TOML file)."""
    d = dict(d)
    d.setdefault("name", default_name)
    nested = {
        "camera": CameraSpec,
        "floor": FloorSpec,
        "lights": LightsSpec,
        "sensor": SensorSpec,
        "render": RenderSpec,
        "stereo": StereoSpec,
        "depth_noise": DepthNoise,
    }
    if "trajectory" in d and not isinstance(d["trajectory"], Mapping):
        raise ConfigError(f"trajectory: must be a table, got {d['trajectory']!r}")
    floor = d.get("floor")
    if isinstance(floor, Mapping) and "params" in floor and not isinstance(floor["params"], Mapping):
        raise ConfigError(f"floor.params: must be a table, got {floor['params']!r}")
    scene = from_mapping(Scene, d, "", nested)
    _check_scene(scene)
    return scene


def _parse_value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_overrides(d: dict, overrides: Mapping[str, str] | None) -> dict:
    """Apply ``{"camera.height_mm": "80"}`` style overrides to a scene dict (a copy)."""
    d = copy.deepcopy(d)
    for key, raw in (overrides or {}).items():
        parts = key.split(".")
        node = d
        for p in parts[:-1]:
            nxt = node.setdefault(p, {})
            if not isinstance(nxt, dict):
                raise ConfigError(f"--set {key}: {p!r} is not a table")
            node = nxt
        node[parts[-1]] = _parse_value(raw) if isinstance(raw, str) else raw
    return d


def scenes_dir() -> Path:
    """The folder of shipped scenes (``$FLOORSIM_SCENES`` or the repository's ``scenes/``)."""
    env = os.environ.get("FLOORSIM_SCENES")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[2] / "scenes"


def list_scenes() -> list[Path]:
    d = scenes_dir()
    return sorted(d.glob("*.toml")) if d.is_dir() else []


def resolve_scene_path(path_or_name: str | os.PathLike) -> Path:
    """A scene file path, or the name of a shipped scene (``demo`` -> scenes/demo.toml)."""
    p = Path(path_or_name)
    if p.is_file():
        return p
    cand = scenes_dir() / (p.name if p.suffix == ".toml" else f"{p.name}.toml")
    if cand.is_file():
        return cand
    raise ConfigError(f"{path_or_name}: no such scene file or shipped scene (floorsim list shows them)")


def load_scene(path: str | os.PathLike, overrides: Mapping[str, str] | None = None) -> Scene:
    """Read a scene TOML file (or a shipped scene name), apply overrides, validate."""
    p = resolve_scene_path(path)
    try:
        d = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{p}: not valid TOML ({exc})") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{p}: cannot read scene file ({exc})") from None
    d = apply_overrides(d, overrides)
    try:
        return scene_from_dict(d, default_name=p.stem)
    except ConfigError as exc:
        raise ConfigError(f"{p.name}: {exc}") from None


def scene_T_world_leds(scene: Scene, T_world_cam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """LED world positions (N, 3) and unit aims (N, 3) for camera pose ``T_world_cam``.

    LEDs ride on the rig; each is aimed at the floor point under the camera centre, moved
    ``lights.aim_offset_mm`` along the camera's x axis away from the LED's own bar
    (positive: beyond the centre), and ``lights.aim_elevation_deg`` above that line.
    """
    p_cam, side = scene.led_positions_cam()
    T = np.asarray(T_world_cam, dtype=float)
    p_world = p_cam @ T[:3, :3].T + T[:3, 3]
    # Target: where the optical axis meets the mean floor plane.
    axis = T[:3, 2]
    s = -T[2, 3] / axis[2] if axis[2] < 0 else T[2, 3]
    target = T[:3, 3] + s * axis
    # Each bar aims away from its own side: a left LED (side -1) aims towards +x.
    target = target[None, :] - side[:, None] * scene.lights.aim_offset_mm * T[:3, 0][None, :]
    aim = target - p_world
    aim /= np.linalg.norm(aim, axis=1, keepdims=True)
    if scene.lights.aim_elevation_deg:
        up = np.array([0.0, 0.0, 1.0])
        horiz = aim - (aim @ up)[:, None] * up
        horiz /= np.maximum(np.linalg.norm(horiz, axis=1, keepdims=True), 1e-12)
        el = np.arcsin(np.clip(aim @ up, -1, 1)) + np.radians(scene.lights.aim_elevation_deg)
        aim = np.cos(el)[:, None] * horiz + np.sin(el)[:, None] * up
    aim /= np.linalg.norm(aim, axis=1, keepdims=True)
    return p_world, aim


__all__.append("scene_T_world_leds")
