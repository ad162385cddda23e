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
    readout_ms = 0.0    # rolling shutter (0: global)
    exposure_mode = "fixed"   # or "auto" (per frame)

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

    [bench]             # what `floorsim bench` runs on it besides the estimators
    protocols = ["paper000-strip"]   # paper protocols (floorsim list); default: by trajectory type

Unknown keys, wrong types and impossible values are refused with one line naming the
key, the value and the rule. ``--set section.key=value`` overrides any key.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from floorsim.depthnoise import DepthNoise
from floorsim.materials import get_material
from floorsim.sensor import FixedPattern, SensorModel
from floorsim.trajectories import Disturbance, Trajectory, build_trajectory, image_border_px
from floorvo.camera import CameraModel
from floorvo.config import MAX_SEED, Config, apply_overrides, build, param, to_plain
from floorvo.errors import ConfigError, ConfigFieldError, shown, shown_number
from floorvo.geometry import T_world_cam_down
from floorvo.io import file_name_problem, read_toml
from floorvo.sequence import DEPTH_PNG_SCALE_PER_MM
from floorvo.sequence_meta import MAX_FPS_HZ, MIN_FPS_HZ

__all__ = [
    "SCENE_SCHEMA_VERSION",
    "Scene",
    "CameraSpec",
    "FloorSpec",
    "LightsSpec",
    "SensorSpec",
    "RenderSpec",
    "StereoSpec",
    "BenchSpec",
    "load_scene",
    "scene_from_dict",
    "apply_overrides",
    "scenes_dir",
    "list_scenes",
    "resolve_scene_path",
]

SCENE_SCHEMA_VERSION = 1
#: The most floor one frame may see (longer side of the image footprint, mm): the floor's
#: scratches, veins and dirt are drawn per unit area, so a camera that sees hectares
#: (``camera.pixel_pitch_um = 8193``) would allocate tens of gigabytes before the first frame.
MAX_FOOTPRINT_MM = 4000.0
#: The most mesh vertices one floor tile may hold (a tile of the default rig at full size
#: holds about 4.2 M; 11 M triangles took 1.8 GB, DESIGN.md).
MAX_TILE_VERTICES = 80e6
#: How far (px) the ray the renderer casts through a pixel of a distorted lens may project from it.
MAX_DISTORTION_ERROR_PX = 0.1


@dataclass(frozen=True)
class CameraSpec(Config):
    """Camera of the rig (defaults: paper 000, 1/3" CCD, 6 mm lens, 100 mm above the floor).

    ``distortion``: OpenCV (k1, k2, p1, p2, k3), applied to the rays, written to
    sequence.json. ``vignetting``: strength v of the lens falloff: each pixel is scaled
    by ``1 - v (1 - cos^4 theta)`` (theta: the pixel ray's angle to the optical axis).
    """

    width_px: int = param(648, unit="px", min=1, max=8192, doc="image width")
    height_px: int = param(494, unit="px", min=1, max=8192, doc="image height")
    # bounds: a sensor's pixels (0.56 um in phones) to those of a render at --scale 8/8192 of the
    # largest image (pitch x 1024), and lenses (fisheye to telephoto); 1e308 made an infinite focal
    # length. How much floor a frame sees is bounded by MAX_FOOTPRINT_MM.
    pixel_pitch_um: float = param(7.4, unit="um", gt=0, min=0.1, max=1e5, doc="pixel size (square pixels)")
    focal_length_mm: float = param(6.0, unit="mm", gt=0, min=0.1, max=1000.0, doc="lens focal length")
    height_mm: float = param(100.0, unit="mm", gt=0, min=5.0, max=2000.0, doc="camera above the mean floor plane")
    distortion: tuple[float, ...] = param((), doc="OpenCV k1, k2, p1, p2, k3 (at most 5)")
    vignetting: float = param(0.0, min=0, max=1, doc="strength v of the cos^4 lens falloff")

    def validate(self) -> None:
        if len(self.distortion) > 5:
            raise ConfigFieldError(
                "distortion", f" = {list(self.distortion)}: at most 5 coefficients (k1, k2, p1, p2, k3)"
            )
        if any(self.distortion):
            self._check_distortion()

    def _check_distortion(self) -> None:
        """Refuse a distortion the renderer cannot invert over the image: the ray it casts through a
        pixel (OpenCV's undistortPoints) must project back to that pixel within
        :data:`MAX_DISTORTION_ERROR_PX`. A barrel lens of k1 = -1 folds back inside a 648x494 frame
        (no ray reaches its corners) and rays came back 620 px off; the frames rendered, exit 0."""
        cam = self.model()
        u, v = np.meshgrid(np.linspace(-0.5, cam.width_px - 0.5, 17), np.linspace(-0.5, cam.height_px - 0.5, 13))
        uv = np.stack([u.ravel(), v.ravel()], axis=1)
        with np.errstate(all="ignore"):
            err = np.abs(cam.project(cam.unproject(uv, 1.0)) - uv).max()
        if not err <= MAX_DISTORTION_ERROR_PX:  # NaN too
            raise ConfigFieldError(
                "distortion",
                f" = {list(self.distortion)}: the rays cast through the {cam.width_px}x{cam.height_px} image "
                f"project back up to {shown_number(float(err), '.3g')} px from their pixels (at most "
                f"{MAX_DISTORTION_ERROR_PX:g} px: the lens folds back or is too strong to invert)",
            )

    def model(self) -> CameraModel:
        dist = tuple(self.distortion) + (0.0,) * (5 - len(self.distortion))
        return CameraModel.from_sensor(self.width_px, self.height_px, self.pixel_pitch_um, self.focal_length_mm, dist)


@dataclass(frozen=True)
class FloorSpec(Config):
    """The floor: a registered material, its parameters, overlays of dirt and dust (their
    densities: fraction of cells holding a speck or grain), and how finely it is meshed."""

    material: str = param("vinyl", doc="a registered material (floorsim list)")
    seed: int | None = param(None, min=0, max=MAX_SEED, doc="the floor's seed (none: the scene's)")
    relief_scale: float = param(1.0, min=0, max=100.0, doc="multiplies the material's relief")
    spacing_mm: float | None = param(
        None, unit="mm", gt=0, max=10.0, doc="mesh vertex spacing (none: half the ground sample distance)"
    )
    tile_length_mm: float = param(
        240.0, unit="mm", min=20.0, max=100_000.0, doc="length of the floor tile built per stretch of trajectory"
    )
    dirt_density: float = param(0.0, min=0, max=1, doc="fraction of 1 mm cells holding a dark speck")
    dust_density: float = param(0.0, min=0, max=1, doc="fraction of 0.25 mm cells holding a dust grain")
    params: dict = param(default_factory=dict, doc="the material's own parameters (see below)")


@dataclass(frozen=True)
class LightsSpec(Config):
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

    Emitter extent: ``led_size_mm`` (with ``led_shape`` rectangle or disc, and
    ``led_size_z_mm`` for a rectangle that is not square) gives each LED an emitting area
    facing its aim, with the LED's intensity spread evenly over it; ``emitter = "bar"``
    replaces the row of LEDs by one continuous diffuse window ``bar_length_mm`` x
    ``bar_window_mm`` per bar (default 4 mm, what a window centred ``height_mm`` = 3 mm
    above the floor allows; paper 000's OPTEX bar suggests 15 mm), facing the image centre (rendered as ``count`` adjacent
    rectangles, each sampled per sample; :mod:`floorsim.render`). 0 and "leds" are point LEDs.
    """

    height_mm: float = param(3.0, unit="mm", gt=0, doc="LED emitters above the floor")
    distance_mm: float = param(
        70.0, unit="mm", gt=0, max=1000.0, doc="bar from the image centre, along the camera's x axis"
    )
    count: int = param(8, unit="LEDs", min=1, max=256, doc="LEDs per bar")
    bar_length_mm: float = param(40.0, unit="mm", min=0, max=1000.0, doc="length of a bar (along the camera's y axis)")
    power: float = param(1.0, min=0, max=1e6, doc="radiant intensity of each bar (relative; 0 = off)")
    side: str = param("both", choices=("both", "left", "right"), doc="which bars are lit")
    lobe_exponent: float = param(1.0, gt=0, max=1e6, doc="cos^n emission lobe of an LED")
    flicker: float = param(0.0, min=0, max=1.0, doc="per-frame relative standard deviation of the LED power")
    ambient_leak: float = param(
        0.0, min=0, max=10.0, doc="light leaking under the hood, relative to the LEDs' irradiance"
    )
    aim_offset_mm: float = param(
        0.0, unit="mm", min=-500.0, max=500.0, doc="aim point beyond the image centre, away from the bar"
    )
    aim_elevation_deg: float = param(
        0.0, unit="deg", min=-45.0, max=45.0, doc="aim raised above the line to the aim point"
    )
    colour_temperature_k: float = param(
        5000.0, unit="K", min=1500.0, max=20000.0, doc="black-body spectrum of the LEDs"
    )
    emitter: str = param("leds", choices=("leds", "bar"), doc="a row of LEDs, or a continuous diffuse bar window")
    led_size_mm: float = param(
        0.0, unit="mm", min=0, max=50.0, doc="LED emitting side along the bar, or disc diameter (0: point LEDs)"
    )
    led_size_z_mm: float | None = param(
        None, unit="mm", gt=0, max=50.0, doc="a rectangular LED's other side (none: square)"
    )
    led_shape: str = param("rectangle", choices=("rectangle", "disc"), doc="shape of an LED's emitting area")
    bar_window_mm: float = param(
        4.0, unit="mm", gt=0, max=100.0, doc="emitter = bar: height of the window (its length: bar_length_mm)"
    )

    def validate(self) -> None:
        if self.led_shape == "disc" and self.led_size_z_mm is not None:
            raise ConfigFieldError("led_size_z_mm", f" = {self.led_size_z_mm} mm: a disc LED has one size, led_size_mm")
        if self.emitter == "bar" and self.bar_length_mm <= 0:
            raise ConfigFieldError("bar_length_mm", " = 0 mm: a bar emitter needs a window length > 0")

    def emitter_size_mm(self) -> tuple[float, float, str]:
        """(side along the bar, side across it, shape) of each emitting element: an LED's area, or
        for a bar its window cut into ``count`` adjacent rectangles; (0, 0, ...) for point LEDs."""
        if self.emitter == "bar":
            return self.bar_length_mm / self.count, self.bar_window_mm, "rectangle"
        if self.led_shape == "disc":
            return self.led_size_mm, self.led_size_mm, "disc"
        side_z = self.led_size_mm if self.led_size_z_mm is None else self.led_size_z_mm
        return self.led_size_mm, (side_z if self.led_size_mm > 0 else 0.0), "rectangle"


@dataclass(frozen=True)
class SensorSpec(Config):
    """Sensor: exposure, noise, fixed pattern, response and quantisation (:mod:`floorsim.sensor`).

    ``exposure_gain``: electrons per radiance unit; 0 chooses it from the first frame
    (``target_percentile`` at ``target_level``). ``exposure_mode = "auto"`` then adjusts it
    per frame from the brightness of frame i - ``ae_delay_frames``
    (:class:`floorsim.sensor.AutoExposure`); each frame's gain is written to
    ``calib/exposure.csv``. ``noise = false`` drops the temporal noise; the fixed pattern
    (``prnu``, ``dsnu_e``, hot and dead pixels, seeded by the scene seed and the same in
    every frame) has its own keys. ``exposure_ms`` > 0 adds motion blur: the frame
    integrates ``blur_samples`` sub-frame renders at poses spread evenly over the exposure,
    centred on the frame time (the ground-truth pose is the one at the centre).
    ``readout_ms`` > 0 is a rolling shutter: row r is exposed
    (r - (H - 1) / 2) / (H - 1) x readout after the frame time, along the continuous
    trajectory; the ground truth is the pose of the centre row
    (:func:`floorsim.sensor.rolling_row_offsets_s`).
    """

    bit_depth: int = param(8, choices=(8, 16), doc="bits per pixel of the PNG frames")
    exposure_gain: float = param(
        0.0, unit="e-/radiance", min=0, doc="electrons per unit radiance; 0 = auto-exposure from the first frame"
    )
    target_percentile: float = param(99.0, unit="%", gt=0, max=100.0, doc="auto-exposure puts this percentile ...")
    target_level: float = param(0.8, min=0, max=1, doc="... at this fraction of full scale")
    full_well_e: float = param(10000.0, unit="e-", gt=0, max=1e7, doc="full-well capacity")
    read_noise_e: float = param(5.0, unit="e-", min=0, max=1e7, doc="read noise")
    shot_noise: bool = param(True, doc="Poisson photon noise")
    noise: bool = param(True, doc="false: a noiseless sensor")
    exposure_ms: float = param(0.0, unit="ms", min=0, max=1000.0, doc="exposure time; > 0 adds motion blur")
    blur_samples: int = param(8, min=1, max=256, doc="sub-frame renders integrated over the exposure")
    readout_ms: float = param(
        0.0, unit="ms", min=0, max=1000.0, doc="rolling-shutter readout, first to last row (0: global shutter)"
    )
    exposure_mode: str = param("fixed", choices=("fixed", "auto"), doc="fixed per sequence, or auto per frame")
    ae_loop_gain: float = param(0.5, gt=0, max=1.0, doc="auto exposure: fraction of the log error corrected")
    ae_delay_frames: int = param(1, unit="frames", min=1, max=100, doc="auto exposure: frames before it reacts")
    prnu: float = param(0.0, min=0, max=0.5, doc="fixed pattern: relative spread of the pixel gains (PRNU)")
    dsnu_e: float = param(0.0, unit="e-", min=0, max=1e7, doc="fixed pattern: spread of the pixel offsets (DSNU)")
    hot_pixel_fraction: float = param(0.0, min=0, max=0.1, doc="fixed pattern: pixels stuck at full scale")
    dead_pixel_fraction: float = param(0.0, min=0, max=0.1, doc="fixed pattern: pixels stuck at zero")
    gamma: float = param(1.0, min=0.1, max=10.0, doc="response curve DN ~ (e / full well)^(1/gamma); 1: linear")

    def validate(self) -> None:
        if self.exposure_mode == "auto" and self.target_level <= 0:
            raise ConfigFieldError(
                "target_level", f" = {self.target_level}: auto exposure needs a target level > 0 (exposure_mode = auto)"
            )

    def fixed_pattern(self) -> FixedPattern:
        return FixedPattern(self.prnu, self.dsnu_e, self.hot_pixel_fraction, self.dead_pixel_fraction)

    def model(self, gain_e_per_unit: float) -> SensorModel:
        """The sensor model of a frame captured with exposure ``gain_e_per_unit``."""
        return SensorModel(
            gain_e_per_unit,
            self.full_well_e,
            self.read_noise_e,
            self.shot_noise,
            self.bit_depth,
            self.fixed_pattern(),
            self.gamma,
        )


@dataclass(frozen=True)
class RenderSpec(Config):
    """Render quality: samples per pixel (stratified), the flat-field calibration frame,
    the depth output (exact depth along the optical axis at each pixel centre), and
    ``shadows``: False drops the relief's cast shadows (shading only; for studies that
    separate what the shadows do to an estimator from what the shading does)."""

    spp: int = param(4, min=1, max=4096, doc="samples per pixel (stratified)")
    shadows: bool = param(True, doc="cast shadows of the relief (false: shading only)")
    flatfield: bool = param(True, doc="render the flat-field calibration frame")
    flatfield_albedo: float = param(0.5, min=0, max=1, doc="albedo of the flat floor of the flat-field frame")
    depth: bool = param(False, doc="write depth/NNNNNN (exact depth along the optical axis)")
    depth_format: str = param(
        "png16", choices=("png16", "npy_float32_mm"), doc="png16: 1/100 mm; npy_float32_mm: float mm"
    )


@dataclass(frozen=True)
class StereoSpec(Config):
    """A second camera (cam1) under the same hood, ``baseline_mm`` along cam0's +x axis,
    same intrinsics and orientation (a rectified pair)."""

    enabled: bool = param(False, doc="render cam1 as well")
    baseline_mm: float = param(20.0, unit="mm", gt=0, max=200.0, doc="cam1 along cam0's +x axis")


@dataclass(frozen=True)
class RangeSensorSpec(Config):
    """A simulated range sensor on the rig (issue 14 item 4): the camera's height above the
    floor per frame, written to the sequence's ``height.csv`` (the mono estimators convert
    pixels to mm at it). The ground truth's height plus seeded Gaussian noise of ``noise_mm``
    (from the scene seed); a fraction ``dropout`` of the frames has no reading."""

    enabled: bool = param(False, doc="write height.csv: a range sensor's camera height per frame")
    noise_mm: float = param(0.02, unit="mm", min=0.0, max=10.0, doc="standard deviation of its Gaussian noise")
    dropout: float = param(0.0, min=0.0, max=1.0, doc="fraction of frames without a reading")


@dataclass(frozen=True)
class AttitudeSensorSpec(Config):
    """A simulated IMU attitude filter on the rig (issue 14, "6-DoF where the sensors allow it"):
    the camera's roll and pitch against gravity per frame (:func:`floorvo.geometry.attitude_of_T`),
    written to the sequence's ``attitude.csv`` (the runner turns a planar mono estimator's
    footprint poses into the tilted camera's with it). The ground truth's attitude plus seeded
    Gaussian noise of ``noise_rad`` on each angle (from the scene seed, a stream of its own); a
    fraction ``dropout`` of the frames has no reading. It changes no image."""

    enabled: bool = param(False, doc="write attitude.csv: an IMU's camera roll and pitch per frame")
    noise_rad: float = param(
        0.0, unit="rad", min=0.0, max=0.1, doc="standard deviation of its Gaussian noise on roll and on pitch"
    )
    dropout: float = param(0.0, min=0.0, max=1.0, doc="fraction of frames without a reading")


@dataclass(frozen=True)
class BenchSpec(Config):
    """What ``floorsim bench`` does with the scene besides running the estimators.

    ``protocols``: names of paper protocols (:mod:`floorsim.bench.protocols`, ``floorsim
    list``) to run on it; None (the key left out): those registered as the default for the
    scene's trajectory type; ``[]``: none. The bench checks the names; the renderer ignores
    this section.
    """

    protocols: tuple[str, ...] | None = param(
        None, doc="paper protocols floorsim bench runs on it (floorsim list); default: by trajectory type"
    )


@dataclass(frozen=True)
class Scene(Config):
    """A resolved scene. ``trajectory`` holds ``type``, its parameters and ``disturbance``."""

    name: str = param(doc="the scene's name (default: the file name); a file name: the bench names folders after it")
    schema_version: int = param(SCENE_SCHEMA_VERSION, doc="scene file format version")
    description: str = param("", doc="one line shown by floorsim list")
    seed: int = param(0, min=0, max=MAX_SEED, doc="floor, sensor noise and pixel jitter derive from it")
    fps: float = param(30.0, unit="Hz", min=MIN_FPS_HZ, max=MAX_FPS_HZ, doc="frame rate (sequence.json's rule)")
    camera: CameraSpec = param(default_factory=CameraSpec)
    floor: FloorSpec = param(default_factory=FloorSpec)
    lights: LightsSpec = param(default_factory=LightsSpec)
    sensor: SensorSpec = param(default_factory=SensorSpec)
    render: RenderSpec = param(default_factory=RenderSpec)
    stereo: StereoSpec = param(default_factory=StereoSpec)
    depth_noise: DepthNoise = param(default_factory=DepthNoise)
    range_sensor: RangeSensorSpec = param(default_factory=RangeSensorSpec)
    attitude_sensor: AttitudeSensorSpec = param(default_factory=AttitudeSensorSpec)
    trajectory: dict = param(
        default_factory=lambda: {"type": "uniform"}, doc="type = a trajectory type, plus its parameters (see below)"
    )
    bench: BenchSpec = param(default_factory=BenchSpec)

    def validate(self) -> None:
        problem = file_name_problem(self.name)
        if problem:
            raise ConfigFieldError("name", f" = {shown(self.name)}: {problem} (the bench names folders after it)")
        if self.schema_version != SCENE_SCHEMA_VERSION:
            raise ConfigFieldError(
                "schema_version",
                f" = {self.schema_version}: this floorsim reads scene schema version {SCENE_SCHEMA_VERSION}",
            )
        if self.sensor.readout_ms > 1000.0 / self.fps:
            raise ConfigFieldError(
                "sensor.readout_ms",
                f" = {self.sensor.readout_ms} ms: a rolling shutter reads out within a frame period "
                f"(1000 / fps = {1000.0 / self.fps:.4g} ms)",
            )
        if self.sensor.exposure_ms > 1000.0 / self.fps:  # 1 s at 30 fps rendered, exit 0
            raise ConfigFieldError(
                "sensor.exposure_ms",
                f" = {self.sensor.exposure_ms} ms: an exposure fits within a frame period "
                f"(1000 / fps = {1000.0 / self.fps:.4g} ms)",
            )
        _, across_mm, _ = self.lights.emitter_size_mm()
        if across_mm / 2 >= self.lights.height_mm:
            which = "lights.bar_window_mm" if self.lights.emitter == "bar" else "the LED size"
            raise ConfigFieldError(
                "lights.height_mm",
                f" = {self.lights.height_mm} mm: an emitter {across_mm:g} mm tall ({which}) would reach the floor; "
                "at least half its height is needed",
            )
        if self.lights.height_mm >= self.camera.height_mm:
            raise ConfigFieldError(
                "lights.height_mm",
                f" = {self.lights.height_mm} mm: LEDs must be below the camera (camera.height_mm = {self.camera.height_mm} mm)",
            )
        self._check_clearance()
        self._check_depth_range()
        self._check_depth_noise()
        self._check_floor_size()

    def _check_depth_range(self) -> None:
        """Refuse png16 depth maps that cannot hold the depth the camera sees (they were clipped
        to 655.35 mm without a word: a camera 1000 mm up wrote 65535 at every pixel)."""
        if not self.render.depth or self.render.depth_format != "png16":
            return
        limit_mm = 65535 / DEPTH_PNG_SCALE_PER_MM
        deepest = self.deepest_mm()
        if deepest > limit_mm:
            raise ConfigFieldError(
                "render.depth_format",
                f" = 'png16': holds depths up to {limit_mm:g} mm, but the camera (camera.height_mm = "
                f"{self.camera.height_mm:g} mm) sees the floor up to {shown_number(deepest, '.1f')} mm away; "
                "use depth_format = 'npy_float32_mm'",
            )

    def _check_depth_noise(self) -> None:
        """Refuse a structured-light depth model whose disparity ``f B / z`` at the farthest floor
        the camera sees is under one quantisation step (``1 / subpixel`` px): the depth there
        rounds to no measurement (a baseline of 1e-3 mm wrote depth maps of zeros, exit 0)."""
        dn = self.depth_noise
        if not self.render.depth or dn.model != "structured_light":
            return
        deepest = self.deepest_mm()
        disparity_px = dn.focal_px * dn.baseline_mm / deepest
        if not disparity_px * dn.subpixel >= 1.0:
            raise ConfigFieldError(
                "depth_noise",
                f": focal_px x baseline_mm / depth = {shown_number(disparity_px, '.3g')} px at the farthest floor the "
                f"camera sees ({shown_number(deepest, '.1f')} mm), under one disparity step (1 / subpixel = "
                f"{shown_number(1.0 / dn.subpixel, '.3g')} px): the depth there would read 0, no measurement",
            )

    def deepest_mm(self) -> float:
        """The largest depth along the optical axis at which the camera sees the mean floor plane, at
        any time: its image corners at the highest the disturbance takes it (the bounce's crest, 4 x the
        vibration RMS) and every attitude on the tilt's circle (as :meth:`lowest_mm`); inf where a
        corner ray misses the floor."""
        dist = self.disturbance() or Disturbance()
        high_mm = self.camera.height_mm + (dist.bounce_amp_mm + 4.0 * dist.vibration_rms_mm if dist.active else 0.0)
        cam = self.camera.model()
        w, h = cam.width_px, cam.height_px
        rays = cam.unproject(np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]]), 1.0)
        phi = np.linspace(0.0, 2 * np.pi, 721) if dist.active and dist.tilt_amp_rad > 0 else np.zeros(1)
        down = min(
            float(np.min(-(T_world_cam_down(0.0, 0.0, 0.0, 0.0, r, q)[2, :3] @ rays.T)))
            for r, q in zip(dist.tilt_amp_rad * np.sin(phi), dist.tilt_amp_rad * np.cos(phi))
        )
        return high_mm / down if down > 0 else float("inf")

    def _check_clearance(self) -> None:
        """Refuse a disturbance that takes the LEDs or the camera down to the floor (:meth:`lowest_mm`)."""
        dist = self.disturbance()
        if dist is None or not dist.active:
            return
        led_mm, cam_mm = self.lowest_mm(dist)
        what = (
            f"bounce_amp_mm = {dist.bounce_amp_mm:g} mm, 4 x vibration_rms_mm = {4 * dist.vibration_rms_mm:g} mm, "
            f"tilt_amp_rad = {dist.tilt_amp_rad:g}"
        )
        if cam_mm <= 0:
            raise ConfigFieldError(
                "trajectory.disturbance",
                f": {what} lower the camera (camera.height_mm = {self.camera.height_mm:g} mm) to "
                f"{cam_mm:.3g} mm above the mean floor plane at its lowest; it must stay above the floor",
            )
        if led_mm <= 0:
            raise ConfigFieldError(
                "trajectory.disturbance",
                f": {what} lower the LEDs (lights.height_mm = {self.lights.height_mm:g} mm) to "
                f"{led_mm:.3g} mm above the mean floor plane at their lowest; they must stay above the floor",
            )

    def disturbance(self) -> Disturbance | None:
        """The trajectory's disturbance, or None when its table is not valid (building the
        trajectory then says why)."""
        d = self.trajectory.get("disturbance")
        if isinstance(d, Disturbance):
            return d
        try:
            return build(Disturbance, d if isinstance(d, Mapping) else None, "trajectory.disturbance")
        except ConfigError:
            return None

    def lowest_mm(self, dist: Disturbance) -> tuple[float, float]:
        """(LEDs, camera): the lowest either comes above the mean floor plane under ``dist``, at any time.

        A bound, the same for every seed and duration: the bounce at its trough, the vibration at
        4 x its RMS (the most its eight sinusoids of amplitude RMS / 2 can sum to) and every
        attitude on the tilt's circle (roll and pitch of ``tilt_amp_rad`` a quarter period apart);
        an LED counts half its emitter's height (:meth:`LightsSpec.emitter_size_mm`) below its centre.
        """
        drop = dist.bounce_amp_mm + 4.0 * dist.vibration_rms_mm
        phi = np.linspace(0.0, 2 * np.pi, 721) if dist.tilt_amp_rad > 0 else np.zeros(1)
        p_cam, _ = self.led_positions_cam()
        led_z = min(
            float(np.min(T_world_cam_down(0.0, 0.0, 0.0, 0.0, r, q)[2, :3] @ p_cam.T))
            for r, q in zip(dist.tilt_amp_rad * np.sin(phi), dist.tilt_amp_rad * np.cos(phi))
        )
        _, across_mm, _ = self.lights.emitter_size_mm()
        cam_mm = self.camera.height_mm - drop
        return cam_mm + led_z - across_mm / 2, cam_mm

    def _check_floor_size(self) -> None:
        """Refuse a scene whose floor could not be held in memory (see :data:`MAX_FOOTPRINT_MM`)."""
        c = self.camera
        xy = c.model().unproject(image_border_px(c.model()), c.height_mm)[:, :2]  # the lens's distortion too
        if not np.isfinite(xy).all():
            raise ConfigFieldError(
                "camera.distortion", f" = {list(c.distortion)}: the lens maps no ray to an image corner"
            )
        fp_w, fp_h = (
            float(v) for v in np.ptp(xy, axis=0)
        )  # a strong distortion ([0, 0, 5, 5]) saw kilometres: a traceback
        if max(fp_w, fp_h) > MAX_FOOTPRINT_MM:
            raise ConfigFieldError(
                "camera",
                f": {c.width_px} x {c.height_px} px of {c.pixel_pitch_um:g} um behind a {c.focal_length_mm:g} mm lens "
                f"at height_mm = {c.height_mm:g} see {shown_number(fp_w, '.0f')} x {shown_number(fp_h, '.0f')} mm of floor; at most {MAX_FOOTPRINT_MM:g} mm",
            )
        spacing = self.floor_spacing_mm()
        margin = 2.0 + 2.0 * spacing
        long_mm = max(self.floor.tile_length_mm, fp_w, fp_h) + 2 * margin
        short_mm = min(fp_w, fp_h) + 2 * margin + (self.stereo.baseline_mm if self.stereo.enabled else 0.0)
        vertices = long_mm / spacing * (short_mm / spacing)  # spacing**2 of 1e-300 mm underflowed to 0
        if vertices > MAX_TILE_VERTICES:
            which = "floor.spacing_mm" if self.floor.spacing_mm is not None else "floor.spacing_mm (none: half the GSD)"
            raise ConfigFieldError(
                "floor",
                f": a floor tile of {shown_number(long_mm, '.0f')} x {shown_number(short_mm, '.0f')} mm at {which} = {spacing:.3g} mm holds "
                f"{vertices:.2g} mesh vertices; at most {MAX_TILE_VERTICES:.2g} (a larger spacing or a shorter "
                "floor.tile_length_mm)",
            )

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
        ``camera.height_mm - lights.height_mm``. A bar emitter: the centres of its ``count``
        window pieces.
        """
        L = self.lights
        z = self.camera.height_mm - L.height_mm
        ys = np.zeros(1) if L.count == 1 else np.linspace(-L.bar_length_mm / 2, L.bar_length_mm / 2, L.count)
        if L.emitter == "bar":  # the centres of count rectangles tiling the window
            ys = np.asarray((np.arange(L.count) + 0.5) * (L.bar_length_mm / L.count) - L.bar_length_mm / 2, np.float64)
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
        """The resolved scene as plain data (written into sequence.json).

        Without ``attitude_sensor`` while it is off: the sensor writes a CSV and changes no
        image, and a scene that does not use it resolves to what it did before the key
        existed, so the renders cached under that scene's key (:func:`floorsim.bench.bench.scene_cache_key`)
        and a sequence being resumed stay valid."""
        d = to_plain(self)
        if not self.attitude_sensor.enabled:
            d.pop("attitude_sensor", None)
        return d


def scene_from_dict(d: Mapping[str, Any], default_name: str = "scene") -> Scene:
    """Build and validate a :class:`Scene` from a plain dict (a parsed TOML file, overrides applied).

    Each section loads into its dataclass (:func:`floorvo.config.build`); the floor's
    ``params`` into its material's parameter class and the trajectory table into its type's,
    so every key of the file is checked.
    """
    d = dict(d)
    d.setdefault("name", default_name)
    scene = build(Scene, d)
    build(get_material(scene.floor.material).Params, scene.floor.params, "floor.params")
    if "type" not in scene.trajectory:
        raise ConfigError('trajectory.type: missing (e.g. type = "uniform")')
    scene.camera.model()
    scene.build_trajectory()  # validates the type's parameters
    return scene


def scenes_dir() -> Path:
    """The folder of shipped scenes (``$FLOORSIM_SCENES`` or the repository's ``scenes/``).

    A ``FLOORSIM_SCENES`` that is no folder is refused in one line (every shipped scene was
    'no such scene file or shipped scene', the variable unnamed, and ``floorsim list`` showed none)."""
    env = os.environ.get("FLOORSIM_SCENES")
    if env:
        if not Path(env).is_dir():
            raise ConfigError(f"FLOORSIM_SCENES = {shown(env)}: not a folder (the folder of the shipped scenes)")
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
    d = apply_overrides(read_toml(p, ConfigError), overrides)
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
    if scene.lights.emitter == "bar":  # one flat window per bar: every piece faces as the bar's centre does
        p_aim = p_cam.copy()
        p_aim[:, 1] = 0.0
        p_aim = p_aim @ T[:3, :3].T + T[:3, 3]
    else:
        p_aim = p_world
    aim = target - p_aim
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
