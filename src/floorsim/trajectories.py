"""Scripted rig trajectories with exact, continuous-time ground truth.

A :class:`Trajectory` maps time to the camera pose ``T_world_cam`` (4x4, mm) through
:meth:`Trajectory.pose_at`, so motion blur can integrate sub-frame poses; the frame poses
are ``pose_at(i / fps)``. The planar path gives ``(x_mm, y_mm, yaw_rad)``; the height
(``height_mm`` above the mean floor) and the optional disturbances (height bounce, tilt,
vibration) complete the 6-DoF pose.

Types (registry :data:`TRAJECTORIES`, parameters validated by name):

* ``uniform``: paper 000 model I, 100 mm along x at 4 mm/frame.
* ``sigmoid``: paper 000 models II/III, x(f) = D / (1 + exp(-g (f - f0))), D = 10 mm,
  gains 1.25 and 1.75.
* ``line``: any length, speed and fps (paper 001: 3 m at 0.3 m/s, 30 fps).
* ``arc``: constant-curvature SE(2) motion, yaw following the tangent (eq. 2 of paper 000
  has theta).
* ``spin``: rotation in place about the optical axis.
* ``s_curve``: x at constant speed, y = A sin(2 pi x / wavelength), yaw along the tangent.
* ``turns``: straight legs joined by turns of ``turn_rad`` (90 degrees by default) on arcs,
  yaw along the tangent: a robot's path with corners.
* ``lawnmower``: back-and-forth lanes covering a rectangle (mapping, paper 003).
* ``kidnap``: straight segments joined by teleports; the first frame of each segment after
  the first is listed in ``events["teleport_frames"]`` (paper 003).
* ``strip``: the paper-000 capture, a 200 mm strip at 1 mm spacing; see
  :func:`paper000_subsequences` for the 100 uniform and 190 sigmoid runs drawn from it.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from floorvo.camera import CameraModel
from floorvo.config import Config, build, param, to_plain
from floorvo.errors import ConfigError, ConfigFieldError, shown
from floorvo.geometry import T_world_cam_down, position_problem
from floorvo.sequence_meta import MAX_FPS_HZ

__all__ = [
    "Trajectory",
    "Disturbance",
    "TRAJECTORIES",
    "TrajectoryType",
    "build_trajectory",
    "trajectory_param_fields",
    "footprint_bounds_mm",
    "image_border_px",
    "paper000_subsequences",
]

#: The most frames a trajectory may have (the poses of every frame are held in memory).
MAX_FRAMES = 1_000_000

PathFn = Callable[[np.ndarray], np.ndarray]  # t_s (M,) -> (M, 3): x_mm, y_mm, yaw_rad


# ----------------------------------------------------------------------------- disturbances
@dataclass(frozen=True)
class Disturbance(Config):
    """Rig disturbances added to any trajectory (all zero = none).

    Height bounce (suspension): ``bounce_amp_mm * sin(2 pi bounce_freq_hz t)``.
    Tilt: roll and pitch, each ``tilt_amp_rad * sin(2 pi tilt_freq_hz t + phase)``.
    Vibration: a seeded sum of sinusoids between ``vibration_band_hz`` with RMS
    ``vibration_rms_mm`` on x, y and z (continuous in time, so blur integrates it).
    Frequencies are at most :data:`~floorvo.sequence_meta.MAX_FPS_HZ`, the highest frame
    rate (1e308 Hz overflowed to a NaN pose, which ended the render in a traceback).
    """

    bounce_amp_mm: float = param(0.0, unit="mm", min=0.0, max=20.0, doc="amplitude of the height bounce (suspension)")
    bounce_freq_hz: float = param(2.0, unit="Hz", gt=0, max=MAX_FPS_HZ, doc="frequency of the height bounce")
    tilt_amp_rad: float = param(0.0, unit="rad", min=0.0, max=0.3, doc="amplitude of roll and pitch")
    tilt_freq_hz: float = param(1.5, unit="Hz", gt=0, max=MAX_FPS_HZ, doc="frequency of roll and pitch")
    vibration_rms_mm: float = param(0.0, unit="mm", min=0.0, max=5.0, doc="RMS of the vibration on x, y and z")
    vibration_band_hz: tuple[float, ...] = param((20.0, 80.0), unit="Hz", doc="[low, high] band of the vibration")

    def validate(self) -> None:
        band = self.vibration_band_hz
        if len(band) != 2 or not 0 < band[0] < band[1] <= MAX_FPS_HZ:
            raise ConfigFieldError(
                "vibration_band_hz", f" = {list(band)}: must be [low, high] with 0 < low < high <= {MAX_FPS_HZ:g} Hz"
            )

    @property
    def active(self) -> bool:
        return self.bounce_amp_mm > 0 or self.tilt_amp_rad > 0 or self.vibration_rms_mm > 0

    def offsets(self, t_s: np.ndarray, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(dxyz_mm (M, 3), roll_rad (M,), pitch_rad (M,)) at times ``t_s`` (M,)."""
        t = np.asarray(t_s, dtype=float)
        dxyz = np.zeros((len(t), 3))
        dxyz[:, 2] = self.bounce_amp_mm * np.sin(2 * np.pi * self.bounce_freq_hz * t)
        roll = self.tilt_amp_rad * np.sin(2 * np.pi * self.tilt_freq_hz * t)
        pitch = self.tilt_amp_rad * np.sin(2 * np.pi * self.tilt_freq_hz * t + np.pi / 2)
        if self.vibration_rms_mm > 0:
            rng = np.random.default_rng([seed, 0x7E1B])
            k = 8
            for axis in range(3):
                lo_hz, hi_hz = self.vibration_band_hz
                freqs = rng.uniform(lo_hz, hi_hz, size=k)
                phases = rng.uniform(0, 2 * np.pi, size=k)
                # Each unit sinusoid has RMS 1/sqrt(2); k of them with random phases sum to RMS sqrt(k/2).
                amp = self.vibration_rms_mm / np.sqrt(k / 2)
                dxyz[:, axis] += amp * np.sin(2 * np.pi * freqs[None, :] * t[:, None] + phases[None, :]).sum(axis=1)
        return dxyz, roll, pitch


# ----------------------------------------------------------------------------- trajectory
@dataclass(frozen=True)
class Trajectory:
    """A rig trajectory sampled at ``fps``.

    Attributes: ``name`` (type), ``fps``, ``frame_count``, ``height_mm`` (nominal camera
    height above the mean floor), ``events`` (e.g. ``{"teleport_frames": [...]}``),
    ``params`` (the resolved type parameters, plain dict).
    """

    name: str
    fps: float
    frame_count: int
    height_mm: float
    path: PathFn = field(repr=False)
    disturbance: Disturbance = field(default_factory=Disturbance)
    seed: int = 0
    events: Mapping[str, Any] = field(default_factory=dict)
    params: Mapping[str, Any] = field(default_factory=dict)

    @property
    def timestamps_s(self) -> np.ndarray:
        """(N,) frame times in seconds, ``i / fps``."""
        return np.arange(self.frame_count) / self.fps

    @property
    def duration_s(self) -> float:
        return (self.frame_count - 1) / self.fps

    def se2_at(self, t_s: np.ndarray | float) -> np.ndarray:
        """(M, 3) planar pose ``(x_mm, y_mm, yaw_rad)`` of the undisturbed path."""
        return self.path(np.atleast_1d(np.asarray(t_s, dtype=float)))

    def pose_at(self, t_s: np.ndarray | float) -> np.ndarray:
        """(M, 4, 4) camera poses ``T_world_cam`` (mm) at times ``t_s`` (M,)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        xyyaw = self.path(t)
        dxyz, roll, pitch = self.disturbance.offsets(t, self.seed)
        out = np.empty((len(t), 4, 4))
        for i in range(len(t)):
            out[i] = T_world_cam_down(
                xyyaw[i, 0] + dxyz[i, 0],
                xyyaw[i, 1] + dxyz[i, 1],
                self.height_mm + dxyz[i, 2],
                xyyaw[i, 2],
                roll[i],
                pitch[i],
            )
        return out

    @property
    def T_world_cam(self) -> np.ndarray:
        """(N, 4, 4) frame poses."""
        return self.pose_at(self.timestamps_s)

    def path_length_mm(self) -> float:
        """Length of the planar path over the frames (teleports excluded)."""
        xy = self.se2_at(self.timestamps_s)[:, :2]
        steps = np.linalg.norm(np.diff(xy, axis=0), axis=1)
        for f in self.events.get("teleport_frames", []):
            if 0 < f < self.frame_count:
                steps[f - 1] = 0.0
        return float(steps.sum())

    def to_dict(self) -> dict:
        return {
            "type": self.name,
            **dict(self.params),
            "disturbance": to_plain(self.disturbance),
            "frame_count": self.frame_count,
            "events": dict(self.events),
        }


# ----------------------------------------------------------------------------- parameter sets
@dataclass(frozen=True)
class UniformParams(Config):
    """Paper 000 model I: constant speed along ``direction_rad``."""

    distance_mm: float = param(100.0, unit="mm", gt=0, doc="path length")
    step_mm: float = param(4.0, unit="mm", gt=0, doc="motion per frame")
    direction_rad: float = param(0.0, unit="rad", doc="direction of travel from the x axis")
    start_x_mm: float = param(0.0, unit="mm", doc="start x")
    start_y_mm: float = param(0.0, unit="mm", doc="start y")
    yaw_rad: float = param(0.0, unit="rad", doc="camera yaw (fixed)")

    def validate(self) -> None:
        n = round(self.distance_mm / self.step_mm)
        if abs(n * self.step_mm - self.distance_mm) > 1e-9 * self.distance_mm:
            raise ConfigFieldError(
                "distance_mm", f" = {self.distance_mm}: must be a whole multiple of step_mm = {self.step_mm}"
            )


@dataclass(frozen=True)
class SigmoidParams(Config):
    """Paper 000 models II and III: x(f) = total_mm / (1 + exp(-gain (f - f0)))."""

    total_mm: float = param(10.0, unit="mm", gt=0, doc="total displacement")
    gain: float = param(1.25, unit="1/frame", gt=0, doc="slope g of the sigmoid")
    frames: int = param(20, unit="frames", min=2, doc="frames in the sequence")
    f0: float | None = param(None, unit="frame", doc="midpoint frame of the sigmoid (none: the middle)")
    direction_rad: float = param(0.0, unit="rad", doc="direction of travel from the x axis")
    start_x_mm: float = param(0.0, unit="mm", doc="start x")
    start_y_mm: float = param(0.0, unit="mm", doc="start y")


@dataclass(frozen=True)
class LineParams(Config):
    """Straight line at constant speed (paper 001: 3 m at 0.3 m/s)."""

    length_mm: float = param(3000.0, unit="mm", gt=0, doc="path length")
    speed_mm_s: float = param(300.0, unit="mm/s", gt=0, doc="ground speed")
    direction_rad: float = param(0.0, unit="rad", doc="direction of travel from the x axis")
    start_x_mm: float = param(0.0, unit="mm", doc="start x")
    start_y_mm: float = param(0.0, unit="mm", doc="start y")


@dataclass(frozen=True)
class ArcParams(Config):
    """Constant-curvature arc; positive radius turns left (counter-clockwise)."""

    radius_mm: float = param(200.0, unit="mm", doc="turn radius, positive turns left; |radius| >= 1 mm")
    length_mm: float = param(100.0, unit="mm", gt=0, doc="arc length")
    speed_mm_s: float = param(120.0, unit="mm/s", gt=0, doc="ground speed")
    start_yaw_rad: float = param(0.0, unit="rad", doc="heading at the start")

    def validate(self) -> None:
        if abs(self.radius_mm) < 1.0:
            raise ConfigFieldError(
                "radius_mm", f" = {self.radius_mm} mm: |radius| must be >= 1 mm (use spin for rotation in place)"
            )


@dataclass(frozen=True)
class SpinParams(Config):
    """Rotation in place about the optical axis."""

    angle_rad: float = param(float(np.pi / 2), unit="rad", doc="total rotation, non-zero; positive turns left")
    rate_rad_s: float = param(1.0, unit="rad/s", gt=0, doc="rotation speed")
    x_mm: float = param(0.0, unit="mm", doc="centre x")
    y_mm: float = param(0.0, unit="mm", doc="centre y")

    def validate(self) -> None:
        if self.angle_rad == 0:
            raise ConfigFieldError("angle_rad", " = 0: must be non-zero")


@dataclass(frozen=True)
class SCurveParams(Config):
    """x at constant ground speed, y = amplitude sin(2 pi x / wavelength)."""

    length_mm: float = param(300.0, unit="mm", gt=0, doc="length along x")
    amplitude_mm: float = param(20.0, unit="mm", min=0, doc="lateral amplitude of the sine")
    wavelength_mm: float = param(200.0, unit="mm", gt=0, doc="period of the sine along x")
    speed_mm_s: float = param(120.0, unit="mm/s", gt=0, doc="ground speed")


@dataclass(frozen=True)
class TurnsParams(Config):
    """Straight legs of ``leg_mm`` joined by turns of ``turn_rad`` on arcs of ``turn_radius_mm``."""

    legs: int = param(2, min=1, max=1000, doc="straight legs; a turn joins each leg to the next")
    leg_mm: float = param(60.0, unit="mm", gt=0, doc="length of each straight leg")
    turn_rad: float = param(float(np.pi / 2), unit="rad", doc="heading change of each turn, positive turns left")
    turn_radius_mm: float = param(30.0, unit="mm", min=1.0, doc="radius of each turn (on the floor)")
    speed_mm_s: float = param(120.0, unit="mm/s", gt=0, doc="ground speed")
    start_yaw_rad: float = param(0.0, unit="rad", doc="heading at the start")

    def validate(self) -> None:
        if self.turn_rad == 0 or abs(self.turn_rad) > 2 * np.pi:
            raise ConfigFieldError("turn_rad", f" = {self.turn_rad}: must be non-zero and at most 2 pi in magnitude")


@dataclass(frozen=True)
class LawnmowerParams(Config):
    """Back-and-forth lanes along x covering ``width_mm`` x ``depth_mm`` from (x0, y0).

    ``heading``: ``fixed`` keeps yaw 0 (a holonomic scan); ``follow`` turns the rig to
    face its motion (yaw 0 on even lanes, pi on odd lanes, a quarter turn on each step).
    """

    width_mm: float = param(200.0, unit="mm", gt=0, doc="lane length along x")
    depth_mm: float = param(120.0, unit="mm", gt=0, doc="extent of the lanes along y")
    lane_spacing_mm: float = param(40.0, unit="mm", gt=0, doc="distance between lanes")
    speed_mm_s: float = param(120.0, unit="mm/s", gt=0, doc="ground speed")
    start_x_mm: float = param(0.0, unit="mm", doc="start x")
    start_y_mm: float = param(0.0, unit="mm", doc="start y")
    heading: str = param("fixed", choices=("fixed", "follow"), doc="fixed: yaw 0; follow: face the motion")


@dataclass(frozen=True)
class KidnapParams(Config):
    """``segments`` straight segments of ``segment_length_mm`` with random start, heading and
    yaw inside the rectangle [x0, x0+width] x [y0, y0+depth], joined by teleports (seeded)."""

    segments: int = param(4, min=1, max=1000, doc="straight segments, joined by teleports")
    segment_length_mm: float = param(40.0, unit="mm", gt=0, doc="length of each segment")
    speed_mm_s: float = param(120.0, unit="mm/s", gt=0, doc="ground speed")
    width_mm: float = param(200.0, unit="mm", gt=0, doc="extent of the start region along x")
    depth_mm: float = param(120.0, unit="mm", gt=0, doc="extent of the start region along y")
    start_x_mm: float = param(0.0, unit="mm", doc="start x")
    start_y_mm: float = param(0.0, unit="mm", doc="start y")
    max_yaw_rad: float = param(
        float(np.pi), unit="rad", min=0.0, max=float(np.pi), doc="largest random yaw of a segment"
    )


@dataclass(frozen=True)
class StripParams(Config):
    """Paper-000 capture: ``count`` frames at ``spacing_mm`` along x."""

    count: int = param(200, unit="frames", min=2, doc="frames in the strip")
    spacing_mm: float = param(1.0, unit="mm", gt=0, doc="distance between frames along x")
    start_x_mm: float = param(0.0, unit="mm", doc="start x")
    start_y_mm: float = param(0.0, unit="mm", doc="start y")


@dataclass(frozen=True)
class TrajectoryType:
    """A registered trajectory type: its parameter class and a builder.

    ``build(params, fps, seed) -> (frame_count, path_fn, events)``.
    """

    name: str
    Params: type
    description: str
    build: Callable[[Any, float, int], tuple[int, PathFn, dict]]


def _frame_count(n: float, what: str = "frames") -> int:
    """``n`` frames (or lanes) as an int, refused beyond :data:`MAX_FRAMES` before anything is allocated."""
    if not n <= MAX_FRAMES:  # NaN and inf too
        raise ConfigError(f"trajectory: these parameters give {n:.3g} {what}; at most {MAX_FRAMES}")
    return int(n)


def _n_frames(duration_s: float, fps: float) -> int:
    return _frame_count(np.floor(duration_s * fps + 1e-9) + 1)


def _straight(x0: float, y0: float, direction: float, speed: float, yaw: float = 0.0) -> PathFn:
    c, s = np.cos(direction), np.sin(direction)

    def path(t: np.ndarray) -> np.ndarray:
        d = speed * t
        return np.stack([x0 + c * d, y0 + s * d, np.full_like(t, yaw)], axis=1)

    return path


def _build_uniform(p: UniformParams, fps: float, seed: int):
    n = _frame_count(round(p.distance_mm / p.step_mm) + 1)
    return n, _straight(p.start_x_mm, p.start_y_mm, p.direction_rad, p.step_mm * fps, p.yaw_rad), {}


def _build_sigmoid(p: SigmoidParams, fps: float, seed: int):
    f0 = (p.frames - 1) / 2.0 if p.f0 is None else p.f0
    c, s = np.cos(p.direction_rad), np.sin(p.direction_rad)

    def path(t: np.ndarray) -> np.ndarray:
        f = t * fps
        with np.errstate(over="ignore"):  # far before a midpoint far away exp overflows: 1 / (1 + inf) = 0, exact
            d = p.total_mm / (1.0 + np.exp(-p.gain * (f - f0)))
        return np.stack([p.start_x_mm + c * d, p.start_y_mm + s * d, np.zeros_like(t)], axis=1)

    return p.frames, path, {}


def _build_line(p: LineParams, fps: float, seed: int):
    n = _n_frames(p.length_mm / p.speed_mm_s, fps)
    return n, _straight(p.start_x_mm, p.start_y_mm, p.direction_rad, p.speed_mm_s), {}


def _build_arc(p: ArcParams, fps: float, seed: int):
    n = _n_frames(p.length_mm / p.speed_mm_s, fps)
    r = p.radius_mm

    def path(t: np.ndarray) -> np.ndarray:
        phi = p.speed_mm_s * t / r  # signed turned angle
        yaw = p.start_yaw_rad + phi
        # Centre of the circle is r to the left of the start heading.
        cx, cy = -r * np.sin(p.start_yaw_rad), r * np.cos(p.start_yaw_rad)
        x = cx + r * np.sin(yaw)
        y = cy - r * np.cos(yaw)
        return np.stack([x, y, yaw], axis=1)

    return n, path, {}


def _build_spin(p: SpinParams, fps: float, seed: int):
    n = _n_frames(abs(p.angle_rad) / p.rate_rad_s, fps)
    sign = np.sign(p.angle_rad)

    def path(t: np.ndarray) -> np.ndarray:
        return np.stack([np.full_like(t, p.x_mm), np.full_like(t, p.y_mm), sign * p.rate_rad_s * t], axis=1)

    return n, path, {}


def _arc_length_table(k: float, amplitude_mm: float, x0: float, x1: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """``(xs, s)``: ``n`` points from ``x0`` to ``x1`` mm along y = A sin(k x) and the arc length
    from ``x0`` to each (negative where ``x1 < x0``), by the trapezoid rule."""
    xs = np.linspace(x0, x1, n)
    ds = np.sqrt(1.0 + (amplitude_mm * k * np.cos(k * xs)) ** 2)
    return xs, np.concatenate([[0.0], np.cumsum((ds[1:] + ds[:-1]) / 2 * np.diff(xs))])


def _build_s_curve(p: SCurveParams, fps: float, seed: int):
    # Arc length of y = A sin(k x) by dense tabulation, so the ground speed is constant.
    k = 2 * np.pi / p.wavelength_mm
    xs, s = _arc_length_table(k, p.amplitude_mm, 0.0, p.length_mm, 20001)
    n = _n_frames(s[-1] / p.speed_mm_s, fps)
    # Before its start and after its end the curve goes on (tables of their own, so that the
    # frames' poses are those of the one table): an exposure or a rolling shutter's rows around
    # the first and the last frame see the camera moving, not held where it starts (a readout's
    # first frame had shown the camera at rest in its upper rows, and was lost).
    reach_mm = p.wavelength_mm + p.speed_mm_s * 1.0  # beyond any exposure (1 s at most) and readout
    xs_before, s_before = _arc_length_table(k, p.amplitude_mm, 0.0, -reach_mm, 2001)
    xs_after, s_after = _arc_length_table(k, p.amplitude_mm, p.length_mm, p.length_mm + reach_mm, 2001)

    def path(t: np.ndarray) -> np.ndarray:
        d = p.speed_mm_s * t
        x = np.where(
            d < 0.0,
            np.interp(d, s_before[::-1], xs_before[::-1]),
            np.where(d > s[-1], np.interp(d - s[-1], s_after, xs_after), np.interp(d, s, xs)),
        )
        y = p.amplitude_mm * np.sin(k * x)
        yaw = np.arctan(p.amplitude_mm * k * np.cos(k * x))
        return np.stack([x, y, yaw], axis=1)

    return n, path, {}


def _build_turns(p: TurnsParams, fps: float, seed: int):
    # Pieces by arc length s: leg, turn, leg, ..., leg. A turn of signed angle a on radius r
    # moves the heading by a over r |a| mm, about a centre r to the left (a > 0) or right.
    arc_mm = p.turn_radius_mm * abs(p.turn_rad)
    pieces = []  # (s_start, length_mm, x0, y0, yaw0, turn: bool)
    x, y, yaw, s0 = 0.0, 0.0, p.start_yaw_rad, 0.0
    sign = float(np.sign(p.turn_rad))
    for leg in range(p.legs):
        pieces.append((s0, p.leg_mm, x, y, yaw, False))
        x, y, s0 = x + p.leg_mm * np.cos(yaw), y + p.leg_mm * np.sin(yaw), s0 + p.leg_mm
        if leg == p.legs - 1:
            break
        pieces.append((s0, arc_mm, x, y, yaw, True))
        cx, cy = x - sign * p.turn_radius_mm * np.sin(yaw), y + sign * p.turn_radius_mm * np.cos(yaw)
        yaw += p.turn_rad
        x, y, s0 = cx + sign * p.turn_radius_mm * np.sin(yaw), cy - sign * p.turn_radius_mm * np.cos(yaw), s0 + arc_mm
    total_mm = s0
    r = p.turn_radius_mm

    def path(t: np.ndarray) -> np.ndarray:
        # Before the start and after the end the first and the last leg go on (an exposure or a
        # rolling shutter's rows around the first and the last frame see the camera moving).
        d = p.speed_mm_s * t
        out = np.empty((len(d), 3))
        for i, (start, length, x0, y0, yaw0, turn) in enumerate(pieces):
            sel = ((d >= start) | (i == 0)) & ((d <= start + length) | (i == len(pieces) - 1))
            u = d[sel] - start
            if turn:
                h = yaw0 + sign * u / r
                cx, cy = x0 - sign * r * np.sin(yaw0), y0 + sign * r * np.cos(yaw0)
                out[sel] = np.stack([cx + sign * r * np.sin(h), cy - sign * r * np.cos(h), h], axis=1)
            else:
                out[sel] = np.stack([x0 + u * np.cos(yaw0), y0 + u * np.sin(yaw0), np.full_like(u, yaw0)], axis=1)
        return out

    return _n_frames(total_mm / p.speed_mm_s, fps), path, {}


def _polyline_path(vertices: np.ndarray, yaws: np.ndarray, speed: float) -> tuple[float, PathFn]:
    seg = np.linalg.norm(np.diff(vertices, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    # the first and the last segment's directions: before the start and after the end the path goes
    # on along them (an exposure or a rolling shutter's rows around the first and the last frame)
    first = (vertices[1] - vertices[0]) / max(seg[0], 1e-12)
    last = (vertices[-1] - vertices[-2]) / max(seg[-1], 1e-12)

    def path(t: np.ndarray) -> np.ndarray:
        d_all = speed * t
        d = np.clip(d_all, 0.0, s[-1])
        x = np.interp(d, s, vertices[:, 0])
        y = np.interp(d, s, vertices[:, 1])
        yaw = np.interp(d, s, yaws)
        beyond = (np.minimum(d_all, 0.0) * first[:, None] + np.maximum(d_all - s[-1], 0.0) * last[:, None]).T
        return np.stack([x + beyond[:, 0], y + beyond[:, 1], yaw], axis=1)

    return float(s[-1]), path


def _build_lawnmower(p: LawnmowerParams, fps: float, seed: int):
    lanes = _frame_count(np.floor(p.depth_mm / p.lane_spacing_mm + 1e-9) + 1, "lanes")
    verts, yaws = [], []
    for i in range(lanes):
        y = p.start_y_mm + i * p.lane_spacing_mm
        xa, xb = (p.start_x_mm, p.start_x_mm + p.width_mm) if i % 2 == 0 else (p.start_x_mm + p.width_mm, p.start_x_mm)
        yaw = 0.0 if (p.heading == "fixed" or i % 2 == 0) else np.pi
        verts += [(xa, y), (xb, y)]
        yaws += [yaw, yaw]
    length, path = _polyline_path(np.array(verts), np.array(yaws), p.speed_mm_s)
    return _n_frames(length / p.speed_mm_s, fps), path, {"lanes": lanes}


def _build_kidnap(p: KidnapParams, fps: float, seed: int):
    rng = np.random.default_rng([seed, 0x51D])
    per_seg = _n_frames(p.segment_length_mm / p.speed_mm_s, fps)
    if per_seg < 2:  # every frame a teleport: no step to estimate, a path of length 0
        raise ConfigError(
            f"trajectory: segment_length_mm = {p.segment_length_mm:g} mm at speed_mm_s = {p.speed_mm_s:g} "
            f"(fps = {fps:g}) gives 1 frame per segment: must give at least 2 (a longer segment or a lower speed)"
        )
    starts, dirs, yaws = [], [], []
    for _ in range(p.segments):
        d = rng.uniform(-np.pi, np.pi)
        # Keep the whole segment inside the rectangle.
        dx, dy = p.segment_length_mm * np.cos(d), p.segment_length_mm * np.sin(d)
        lo_x, hi_x = p.start_x_mm + max(0.0, -dx), p.start_x_mm + p.width_mm - max(0.0, dx)
        lo_y, hi_y = p.start_y_mm + max(0.0, -dy), p.start_y_mm + p.depth_mm - max(0.0, dy)
        if lo_x > hi_x or lo_y > hi_y:
            raise ConfigError(
                f"trajectory.segment_length_mm = {p.segment_length_mm}: a segment must fit in the {p.width_mm} x {p.depth_mm} mm area"
            )
        starts.append((rng.uniform(lo_x, hi_x), rng.uniform(lo_y, hi_y)))
        dirs.append(d)
        yaws.append(rng.uniform(-p.max_yaw_rad, p.max_yaw_rad))
    n = per_seg * p.segments
    seg_dt = (per_seg - 1) / fps  # motion time within a segment
    frame_dt = 1.0 / fps

    def path(t: np.ndarray) -> np.ndarray:
        # Segment k occupies frames [k * per_seg, (k + 1) * per_seg). The teleport falls half a frame
        # before its first frame, between two frames: an exposure (motion blur) or a rolling
        # shutter's rows around a frame's time lie in its own segment (the teleport frame's early
        # rows showed the last segment's floor, and black where no tile was planned), still
        # before the segment starts to move.
        k = np.clip(np.floor((t * fps + 0.5) / per_seg + 1e-9).astype(int), 0, p.segments - 1)
        tau = np.clip(t - k * per_seg * frame_dt, 0.0, seg_dt + frame_dt)
        sx = np.array(starts)[k]
        d = np.array(dirs)[k]
        dist = p.speed_mm_s * tau
        return np.stack([sx[:, 0] + np.cos(d) * dist, sx[:, 1] + np.sin(d) * dist, np.array(yaws)[k]], axis=1)

    events = {"teleport_frames": [k * per_seg for k in range(1, p.segments)], "segment_frames": per_seg}
    return n, path, events


def _build_strip(p: StripParams, fps: float, seed: int):
    return p.count, _straight(p.start_x_mm, p.start_y_mm, 0.0, p.spacing_mm * fps), {}


TRAJECTORIES: dict[str, TrajectoryType] = {
    t.name: t
    for t in (
        TrajectoryType("uniform", UniformParams, "paper 000 model I: 100 mm along x at 4 mm/frame", _build_uniform),
        TrajectoryType(
            "sigmoid", SigmoidParams, "paper 000 models II/III: 10 mm sigmoid, gain 1.25 or 1.75", _build_sigmoid
        ),
        TrajectoryType("line", LineParams, "straight line at constant speed (paper 001: 3 m at 0.3 m/s)", _build_line),
        TrajectoryType("arc", ArcParams, "constant-curvature arc, yaw along the tangent", _build_arc),
        TrajectoryType("spin", SpinParams, "rotation in place about the optical axis", _build_spin),
        TrajectoryType("s_curve", SCurveParams, "sinusoidal S-curve at constant ground speed", _build_s_curve),
        TrajectoryType(
            "turns", TurnsParams, "straight legs joined by turns (90 degrees by default) on arcs", _build_turns
        ),
        TrajectoryType(
            "lawnmower", LawnmowerParams, "back-and-forth lanes covering a rectangle (mapping)", _build_lawnmower
        ),
        TrajectoryType("kidnap", KidnapParams, "straight segments joined by teleports (relocalisation)", _build_kidnap),
        TrajectoryType("strip", StripParams, "paper 000 capture: 200 frames at 1 mm spacing", _build_strip),
    )
}


def trajectory_param_fields(type_name: str) -> list[str]:
    """Names of the parameters of trajectory type ``type_name``."""
    return [f.name for f in dataclasses.fields(_get_type(type_name).Params)]


def _get_type(type_name: str) -> TrajectoryType:
    if not isinstance(type_name, str) or type_name not in TRAJECTORIES:
        raise ConfigError(f"trajectory.type = {shown(type_name)}: unknown type (known: {', '.join(TRAJECTORIES)})")
    return TRAJECTORIES[type_name]


def build_trajectory(
    type_name: str,
    params: Mapping[str, Any] | None = None,
    *,
    height_mm: float,
    fps: float,
    seed: int = 0,
    disturbance: Mapping[str, Any] | Disturbance | None = None,
) -> Trajectory:
    """Build a trajectory of registered type ``type_name`` from a parameter table.

    ``params`` may not contain ``type`` or ``disturbance`` (pass those separately).
    Unknown keys, wrong types and impossible values raise :class:`ConfigError`.
    """
    ttype = _get_type(type_name)
    if height_mm <= 0:
        raise ConfigError(f"camera.height_mm = {height_mm}: must be > 0 (the camera is above the floor)")
    if fps <= 0:
        raise ConfigError(f"fps = {fps}: must be > 0")
    p = build(ttype.Params, params, "trajectory")
    dist = (
        disturbance
        if isinstance(disturbance, Disturbance)
        else build(Disturbance, disturbance, "trajectory.disturbance")
    )
    n, path, events = ttype.build(p, float(fps), int(seed))
    if n < 2:  # one frame is a picture, not a trajectory: no step to estimate or score
        raise ConfigError(
            f"trajectory: type {type_name!r} with these parameters (at fps = {fps:g}) gives {n} frame"
            f"{'' if n == 1 else 's'}: must give at least 2 (a shorter step, a lower speed or a longer path)"
        )
    _frame_count(n)
    xy = np.asarray(path(np.arange(int(n)) / float(fps)), dtype=float)[:, :2]
    far = position_problem(np.append(xy[np.argmax(np.max(np.abs(xy), axis=1))], 0.0)) if len(xy) else None
    if far:  # x_mm = 1e300 ended in a ValueError from the floor's mesh; 1e15 mm rendered a floor float64 quantised
        raise ConfigError(f"trajectory: type {type_name!r} with these parameters reaches {far}")
    return Trajectory(type_name, float(fps), int(n), float(height_mm), path, dist, int(seed), events, to_plain(p))


def image_border_px(camera: CameraModel, per_side: int = 64) -> np.ndarray:
    """(M, 2) pixel positions on the image's outer edge: its 4 corners, and with lens distortion
    ``per_side`` points along each side too. A pincushion lens sees further through the middle of a
    side than through its corners: a tile planned on the corners alone left those rays without
    floor (``camera.distortion = [100]``: 17 % of the pixels black)."""
    w, h = camera.width_px, camera.height_px
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [w - 0.5, h - 0.5], [-0.5, h - 0.5]])
    if not camera.has_distortion:
        return corners
    t = np.linspace(0.0, 1.0, per_side + 2)[1:-1, None]
    sides = [a + t * (b - a) for a, b in zip(corners, np.roll(corners, -1, axis=0))]
    return np.concatenate([corners, *sides])


def footprint_bounds_mm(
    T_world_cam: np.ndarray, camera: CameraModel, margin_mm: float = 0.0
) -> tuple[float, float, float, float]:
    """Bounding box ``(xmin, xmax, ymin, ymax)`` of the floor (z = 0) seen by ``camera`` at poses (N, 4, 4)."""
    Ts = np.asarray(T_world_cam, dtype=float).reshape(-1, 4, 4)
    rays = camera.unproject(image_border_px(camera), 1.0)  # (M, 3) in the camera frame
    pts = []
    for T in Ts:
        d = rays @ T[:3, :3].T
        o = T[:3, 3]
        if np.any(d[:, 2] >= 0):
            raise ConfigError("camera: a corner ray does not hit the floor (tilt too large)")
        s = -o[2] / d[:, 2]
        pts.append(o[None, :2] + s[:, None] * d[:, :2])
    xy = np.concatenate(pts)
    return (
        float(xy[:, 0].min() - margin_mm),
        float(xy[:, 0].max() + margin_mm),
        float(xy[:, 1].min() - margin_mm),
        float(xy[:, 1].max() + margin_mm),
    )


def paper000_subsequences(model: str, strip_count: int = 200, spacing_mm: float = 1.0) -> list[np.ndarray]:
    """Strip frame indices of every run of paper 000's protocol.

    ``model``: ``uniform`` (4 mm/frame over 100 mm: 26 frames per run, one run per start
    frame that fits: 100 runs on a 200-frame strip at 1 mm), ``sigmoid_g125`` or
    ``sigmoid_g175`` (10 mm sigmoid sampled at the strip's nearest frame per step: one run
    per start frame that fits, 190 runs). Ground truth of strip frame i is i * spacing_mm.
    """
    if model == "uniform":
        step = int(round(4.0 / spacing_mm))
        span = int(round(100.0 / spacing_mm))
        offsets = np.arange(0, span + 1, step)
    elif model in ("sigmoid_g125", "sigmoid_g175"):
        gain = 1.25 if model.endswith("125") else 1.75
        frames = 20
        f = np.arange(frames)
        x_mm = 10.0 / (1.0 + np.exp(-gain * (f - (frames - 1) / 2.0)))
        offsets = np.round(x_mm / spacing_mm).astype(int)
        span = int(round(10.0 / spacing_mm))
    else:
        raise ConfigError(f"paper-000 model {model!r}: must be uniform, sigmoid_g125 or sigmoid_g175")
    # The paper draws 100 uniform and 190 sigmoid runs from a 200-frame strip.
    return [start + offsets for start in range(max(0, strip_count - span))]
