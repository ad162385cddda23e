"""Render a scene into a floorvo sequence folder (resumable, tiled, deterministic).

Floor tiles: the frames are grouped so that the floor seen by each group fits in a tile
of at most ``floor.tile_length_mm`` along its longer side; each tile's mesh is built
once, used for its frames and released before the next, so memory stays flat however
long the trajectory (a 3 m line never holds a 3 m mesh).

Seeds: the scene seed (or ``--seed``) drives the floor (unless ``floor.seed`` is set),
the pixel jitter of frame i (``[seed, i]``) and the sensor noise of frame i, so any
frame can be re-rendered alone and comes out bit-identical.
"""

from __future__ import annotations

import dataclasses
import functools
import gc
import logging
import os
import platform
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

import floorsim
import floorvo
from floorsim.depthnoise import apply_depth_noise
from floorsim.materials import get_material, sample_material
from floorsim.render import FloorRenderer, LedArray, backend_info, stratified_spp
from floorsim.scene import AttitudeSensorSpec, RangeSensorSpec, Scene, scene_T_world_leds
from floorsim.sensor import AutoExposure, SensorModel, exposure_gain, image_level, rolling_row_offsets_s
from floorsim.spectral import mono_response
from floorsim.tilecache import TileCache, default_cache
from floorsim.trajectories import Disturbance, Trajectory, footprint_bounds_mm
from floorvo.camera import CameraModel
from floorvo.config import build as build_config
from floorvo.config import to_plain
from floorvo.errors import ConfigError, ConfigFieldError
from floorvo.geometry import attitude_of_T
from floorvo.io import atomic_write_csv, atomic_write_json, checked_output_path, code_sha256, read_json, read_text
from floorvo.locking import locks_folder
from floorvo.sequence import SequenceWriter
from floorvo.sequence_meta import ROW_TIME_CONVENTION

__all__ = [
    "render_sequence",
    "prepare_scene",
    "plan_tiles",
    "package_versions",
    "range_sensor_heights",
    "attitude_sensor_angles",
    "LED_INTENSITY_UNIT",
    "EXPOSURE_FILE",
    "read_exposure_log",
]

log = logging.getLogger(__name__)

#: Radiant intensity of a bar of power 1 (arbitrary units; exposure normalises it).
LED_INTENSITY_UNIT = 1000.0


#: The fewest pixels a side of a camera scaled by ``--scale`` may have.
MIN_SCALED_SIDE_PX = 8


def prepare_scene(
    scene: Scene,
    *,
    frames: int | None = None,
    scale: float | None = None,
    spp: int | None = None,
    seed: int | None = None,
) -> Scene:
    """Apply the command-line knobs to a scene (validated like the file).

    ``render.spp`` becomes the count the renderer really takes (:func:`floorsim.render.stratified_spp`:
    5 -> 6, with a warning), so the scene recorded in ``sequence.json`` is the one rendered.
    """
    if frames is not None and frames < 1:
        raise ConfigError(f"--frames = {frames}: must be >= 1")
    if scale is not None and not 0 < scale <= 4:
        raise ConfigError(f"--scale = {scale}: must be within (0, 4]")
    if spp is not None and spp < 1:
        raise ConfigError(f"--spp = {spp}: must be >= 1")
    if seed is not None and seed < 0:
        raise ConfigError(f"--seed = {seed}: must be >= 0")
    cam = scene.camera
    if scale is not None and scale != 1.0:
        w, h = int(round(cam.width_px * scale)), int(round(cam.height_px * scale))
        if min(w, h) < MIN_SCALED_SIDE_PX:  # was raised to 8 px each: another aspect and field of view, silently
            raise ConfigError(
                f"--scale = {scale:g}: makes the {cam.width_px}x{cam.height_px} px camera {w}x{h} px; "
                f"a side must keep at least {MIN_SCALED_SIDE_PX} px (--scale >= "
                f"{MIN_SCALED_SIDE_PX / min(cam.width_px, cam.height_px):.3g})"
            )
        # Keep the field of view: the pixel pitch grows as the resolution shrinks.
        cam = dataclasses.replace(cam, width_px=w, height_px=h, pixel_pitch_um=cam.pixel_pitch_um * cam.width_px / w)
    render = scene.render if spp is None else dataclasses.replace(scene.render, spp=spp)
    rendered_spp = stratified_spp(render.spp)
    if rendered_spp != render.spp:
        # Record what is rendered: sequence.json's scene then says how many samples each pixel has.
        log.warning(
            "%s: render.spp = %d is not a sampler grid; rendering and recording %d samples per pixel",
            scene.name,
            render.spp,
            rendered_spp,
        )
        render = dataclasses.replace(render, spp=rendered_spp)
    out = dataclasses.replace(scene, camera=cam, render=render, seed=scene.seed if seed is None else seed)
    if frames is not None:
        out = dataclasses.replace(out, trajectory={**out.trajectory, "max_frames": frames})
    return out


def _trajectory_of(scene: Scene, *, whole: bool = False) -> Trajectory:
    """The scene's trajectory, cut to ``trajectory.max_frames`` (``frames=`` of
    :func:`prepare_scene`) unless ``whole``."""
    t = dict(scene.trajectory)
    max_frames = t.pop("max_frames", None)
    traj = dataclasses.replace(scene, trajectory=t).build_trajectory()
    if not whole and max_frames is not None and max_frames < traj.frame_count:
        traj = dataclasses.replace(traj, frame_count=int(max_frames))
    return traj


def plan_tiles(
    T_world_cam: np.ndarray, camera: CameraModel, tile_length_mm: float, margin_mm: float
) -> list[tuple[list[int], tuple[float, float, float, float]]]:
    """Group frame indices into floor tiles: ``[(frame_indices, (xmin, xmax, ymin, ymax)), ...]``.

    Consecutive frames join a tile while the union of their footprints (plus margin)
    stays within ``tile_length_mm`` on its longer side (a single frame always fits).
    """
    tiles: list = []
    cur: list[int] = []
    box = None
    for i, T in enumerate(T_world_cam):
        b = footprint_bounds_mm(T[None], camera, margin_mm)
        if box is None:
            cur, box = [i], b
            continue
        nb = (min(box[0], b[0]), max(box[1], b[1]), min(box[2], b[2]), max(box[3], b[3]))
        if max(nb[1] - nb[0], nb[3] - nb[2]) <= tile_length_mm:
            cur.append(i)
            box = nb
        else:
            tiles.append((cur, box))
            cur, box = [i], b
    if cur:
        tiles.append((cur, box))
    return tiles


def _leds(scene: Scene, T_world_cam: np.ndarray, frame_index: int | None = None):
    """The rig's LEDs at pose ``T_world_cam``; ``frame_index`` applies that frame's flicker."""
    pos, aim = scene_T_world_leds(scene, T_world_cam)
    n_per_bar = scene.lights.count
    power = scene.lights.power * mono_response(scene.lights.colour_temperature_k)
    if frame_index is not None and scene.lights.flicker > 0:
        rng = np.random.default_rng([int(scene.seed), int(frame_index), 0xF11C])
        power *= max(0.0, 1.0 + scene.lights.flicker * float(rng.standard_normal()))
    inten = np.full(len(pos), power * LED_INTENSITY_UNIT / n_per_bar)
    w_mm, h_mm, shape = scene.lights.emitter_size_mm()
    if w_mm <= 0 and h_mm <= 0:
        return LedArray(pos, aim, inten, scene.lights.lobe_exponent)
    along = np.broadcast_to(np.asarray(T_world_cam, dtype=float)[:3, 1], pos.shape)  # the bars lie along camera y
    return LedArray(pos, aim, inten, scene.lights.lobe_exponent, size_mm=(w_mm, h_mm), shape=shape, along=along)


def ambient_irradiance(scene: Scene, T_world_cam: np.ndarray) -> float:
    """Irradiance of the ambient leak: ``lights.ambient_leak`` x the LEDs' irradiance on a
    flat floor at the point under the camera (unshadowed, same units as the renderer)."""
    if scene.lights.ambient_leak <= 0:
        return 0.0
    leds = _leds(scene, T_world_cam)
    T = np.asarray(T_world_cam, dtype=float)
    target = np.array([T[0, 3], T[1, 3], 0.0])
    d = leds.positions_mm - target
    r = np.linalg.norm(d, axis=1)
    w = d / r[:, None]
    cos_surf = np.maximum(w[:, 2], 0.0)
    cos_led = np.maximum(-(w * leds.aim).sum(axis=1), 0.0) ** leds.lobe_exponent
    return float(scene.lights.ambient_leak * np.sum(leds.intensity * cos_led * cos_surf / r**2))


def vignetting_factor(cam: CameraModel, strength: float) -> np.ndarray | None:
    """(H, W) lens falloff ``1 - v (1 - cos^4 theta)``, or None when ``strength`` is 0."""
    if strength <= 0:
        return None
    u, v = np.meshgrid(np.arange(cam.width_px, dtype=float), np.arange(cam.height_px, dtype=float))
    d = cam.unproject(np.stack([u.ravel(), v.ravel()], 1), 1.0)
    cos4 = (1.0 / np.linalg.norm(d, axis=1)) ** 4
    return (1.0 - strength * (1.0 - cos4)).reshape(cam.height_px, cam.width_px).astype(np.float32)


def _render_frame(
    renderer, scene: Scene, traj: Trajectory, i: int, T_cam_rig: np.ndarray | None, seed: int
) -> np.ndarray:
    """Radiance of frame i for the camera at ``T_rig_cam`` from cam0 (None: cam0), with motion blur."""
    t_i = i / traj.fps
    exp_s = scene.sensor.exposure_ms / 1000.0
    n = scene.sensor.blur_samples if exp_s > 0 else 1
    times = [t_i] if n == 1 else list(t_i + exp_s * ((np.arange(n) + 0.5) / n - 0.5))
    acc: np.ndarray | None = None  # radiance summed over the exposure's times, float64
    for k, t in enumerate(times):
        T0 = traj.pose_at(t)[0]
        Tc = T0 if T_cam_rig is None else T0 @ T_cam_rig
        leds = _leds(scene, T0, i)
        if scene.sensor.readout_ms > 0:
            # Rolling shutter: row r from the rig pose (and its LEDs) at its own time; the centre row's time is t.
            T_rows = traj.pose_at(t + rolling_row_offsets_s(renderer.camera.height_px, scene.sensor.readout_ms))
            Tc = T_rows if T_cam_rig is None else T_rows @ T_cam_rig
            rows = [scene_T_world_leds(scene, T_r) for T_r in T_rows]
            leds = dataclasses.replace(
                leds,
                positions_mm=np.stack([p for p, _ in rows]),
                aim=np.stack([a for _, a in rows]),
                along=None if leds.along is None else np.repeat(T_rows[:, None, :3, 1], len(rows[0][0]), axis=1),
            )
        rad = renderer.render(
            Tc,
            leds,
            scene.render.spp,
            seed=_frame_seed(seed, i * 1009 + k if n > 1 else i),
            ambient=ambient_irradiance(scene, T0),
            shadows=scene.render.shadows,
        )
        acc = rad.astype(np.float64) if acc is None else acc + rad
    assert acc is not None  # times holds at least one time
    return (acc / len(times)).astype(np.float32)


#: The modules whose code makes a rendered sequence's bytes (:func:`render_code_sha256`): a change
#: to any of them (or to a plugin material's module) is a change of the render, whatever the
#: package's version number says.
RENDER_CODE = (
    "floorsim.simulate",
    "floorsim.render",
    "floorsim.sensor",
    "floorsim.scene",
    "floorsim.trajectories",
    "floorsim.materials",
    "floorsim.spectral",
    "floorsim.depthnoise",
    "floorvo.camera",
    "floorvo.geometry",
    "floorvo.sequence",
    "floorvo.sequence_meta",
)


@functools.cache
def render_code_sha256(material: str | None = None) -> str:
    """SHA-256 of the renderer's source (:data:`RENDER_CODE`, and the module of ``material`` when it
    is a plugin's; :func:`floorvo.io.code_sha256`): ``sequence.json`` records it (``versions.render_code``),
    so a render resumed or reused by other code is refused (:class:`floorvo.sequence.SequenceWriter`),
    and the bench's sequence cache is keyed by it (:func:`floorsim.bench.bench.scene_cache_key`)."""
    mods = list(RENDER_CODE)
    if material is not None:
        module = get_material(material).sample.__module__
        if module not in mods:
            mods.append(module)
    return code_sha256(*mods)


def package_versions(material: str | None = None) -> dict:
    """Versions of floorsim, floorvo, numpy, Python and the render backend, and the renderer's code
    (``render_code``: :func:`render_code_sha256` with ``material``) (sequence.json, study records)."""
    v = {
        "floorsim": floorsim.__version__,
        "floorvo": floorvo.__version__,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "render_code": render_code_sha256(material),
    }
    try:
        v.update(backend_info())
    except Exception as exc:  # noqa: BLE001 - informational only
        v["backend"] = f"unavailable: {exc}"
    return v


def _load_tile(renderer, scene: Scene, box, spacing: float, cache: TileCache | None | str = "default") -> float:
    """Load the floor under ``box`` = (xmin, xmax, ymin, ymax) (mm) into ``renderer``; returns the
    tile's highest point (mm above the mean floor plane). A relief that rises to the camera is
    refused (:func:`_check_relief_clearance`).

    The height, albedo and normal grids come from the tile cache (:mod:`floorsim.tilecache`)
    when it holds them (``cache``: "default" is the one the environment names, None none),
    and are stored there otherwise.
    """
    xmin, xmax, ymin, ymax = box
    # Snap the grid to multiples of the spacing in world coordinates: every tile samples
    # the same floor points.
    i0, i1 = int(np.floor(xmin / spacing)), int(np.ceil(xmax / spacing))
    j0, j1 = int(np.floor(ymin / spacing)), int(np.ceil(ymax / spacing))
    xs = np.arange(i0, i1 + 1) * spacing
    ys = np.arange(j0, j1 + 1) * spacing
    f = scene.floor
    mat = get_material(f.material)
    tiles = default_cache() if cache == "default" else cache

    def build() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        h, a = sample_material(
            f.material, xs, ys, scene.floor_seed, f.params, f.relief_scale, f.dirt_density, f.dust_density
        )
        return h, a, renderer.load_heightfield(xs[0], ys[0], spacing, h, a)

    if not isinstance(tiles, TileCache):
        h = build()[0]
    else:
        key = TileCache.key(
            {
                "material": f.material,
                "params": to_plain(build_config(mat.Params, f.params, f"floor.{f.material}")),
                "seed": scene.floor_seed,
                "relief_scale": f.relief_scale,
                "dirt_density": f.dirt_density,
                "dust_density": f.dust_density,
                "spacing_mm": spacing,
                "grid": [i0, i1, j0, j1],
            },
            mat.sample.__module__,
        )
        built: list[bool] = []

        def build_once() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            built.append(True)
            return build()

        h, a, n = tiles.load_or_build(key, (len(ys), len(xs)), build_once)
        if not built:
            renderer.load_heightfield(xs[0], ys[0], spacing, h, a, normals=n)
    renderer.specular = mat.specular
    top_mm = float(np.max(h))
    _check_relief_clearance(scene, top_mm)
    return top_mm


def _check_relief_clearance(scene: Scene, top_mm: float) -> None:
    """Refuse a floor whose relief (highest point of a tile, ``top_mm`` above the mean floor plane)
    reaches the camera at its lowest (:meth:`~floorsim.scene.Scene.lowest_mm`): ``floor.relief_scale``
    = 100 and asphalt's ``relief_mm`` = 3 stand stones 300 mm tall. LEDs in the relief are not
    refused: the LED-height studies take them down into it (0.02 mm over vinyl's 0.03 mm bumps),
    where the relief shadows the floor; a first frame that is black then says so."""
    _, cam_mm = scene.lowest_mm(scene.disturbance() or Disturbance())
    if top_mm >= cam_mm:
        f = scene.floor
        raise ConfigFieldError(
            "floor",
            f": the {f.material} relief (relief_scale = {f.relief_scale:g}) rises {top_mm:.3g} mm above the mean "
            f"floor plane, and the camera comes down to {cam_mm:.3g} mm: it must stay above the floor "
            "(a smaller floor.relief_scale or the material's relief parameters)",
        )


def _black_frame_problem(scene: Scene, top_mm: float) -> str:
    """Why the first frame can be black: the lights, or LEDs at or below the relief's top ``top_mm``."""
    led_mm, _ = scene.lowest_mm(scene.disturbance() or Disturbance())
    if top_mm < led_mm:
        return "lights off or power 0"
    f = scene.floor
    return (
        f"lights off, power 0, or the LEDs ({led_mm:.3g} mm up at their lowest) inside the {f.material} relief, "
        f"which rises {top_mm:.3g} mm (relief_scale = {f.relief_scale:g})"
    )


@locks_folder("out_dir", "sequence folder")
def render_sequence(
    scene: Scene,
    out_dir: str | os.PathLike,
    *,
    frames: int | None = None,
    scale: float | None = None,
    spp: int | None = None,
    seed: int | None = None,
    overwrite: bool = False,
    on_frame: Callable[[int, int], None] | None = None,
) -> Path:
    """Render ``scene`` into the sequence folder ``out_dir`` and return its path.

    Frames already on disk from an interrupted render of the same resolved scene are
    kept; only missing frames are rendered. ``on_frame(done, total)`` reports progress.
    The folder is locked for the whole render (:func:`floorvo.locking.lock_folder`): a
    second writer of it is refused in one line naming this process's pid.
    """
    checked_output_path(out_dir)  # before any work: "" and "/" are refused (the writer checks the rest)
    scene = prepare_scene(scene, frames=frames, scale=scale, spp=spp, seed=seed)
    traj = _trajectory_of(scene)
    if frames is not None and frames > traj.frame_count:  # all were rendered, and nothing said so
        log.warning(
            "%s: --frames = %d, but the trajectory has only %d frames; rendering those %d",
            scene.name,
            frames,
            traj.frame_count,
            traj.frame_count,
        )
    cam = scene.camera_model()
    # The environment's settings before anything is written: the tile cache (FLOORSIM_CACHE,
    # FLOORSIM_CACHE_MAX_MB) and the backend (FLOORSIM_VARIANT) are refused here, not after
    # sequence.json and groundtruth.txt were written into a folder that then held no frame.
    tile_cache = default_cache()
    renderer = FloorRenderer(cam)
    T_all = traj.T_world_cam
    ts = traj.timestamps_s
    spacing = scene.floor_spacing_mm()
    T_01 = scene.T_cam0_cam1()
    T_all_cam1 = None if T_01 is None else np.einsum("nij,jk->nik", T_all, T_01)
    meta = {
        "name": scene.name,
        "fps": scene.fps,
        "frame_count": traj.frame_count,
        "bit_depth": scene.sensor.bit_depth,
        "camera": cam.to_dict(),
        "rig": {
            "height_mm": scene.camera.height_mm,
            "gsd_mm_per_px": cam.gsd_mm_per_px(scene.camera.height_mm),
            "led_positions_cam_mm": scene.led_positions_cam()[0].tolist(),
            "led_height_mm": scene.lights.height_mm,
            "T_cam0_cam1": None if T_01 is None else T_01.tolist(),
            # the range sensor's noise, to which the runner holds the steps' height changes
            **({"height_noise_mm": scene.range_sensor.noise_mm} if scene.range_sensor.enabled else {}),
        },
        "stereo": T_01 is not None,
        "cameras": {"cam1": cam.to_dict()} if T_01 is not None else {},
        "depth": {
            "format": scene.render.depth_format,
            "scale_per_mm": 100.0,
            "content": "depth along the optical axis, mm",
        }
        if scene.render.depth
        else None,
        "seeds": {
            "scene": scene.seed,
            "floor": scene.floor_seed,
            "pixel_jitter": scene.seed,
            "sensor_noise": scene.seed,
        },
        "units": {"length": "mm (sequence.json); m (groundtruth.txt)", "angle": "rad", "time": "s", "frames": "DN"},
        "floor_spacing_mm": spacing,
        "events": dict(traj.events),
        "trajectory": traj.to_dict(),
        "scene": scene.to_dict(),
        "calib": {"flatfield": "calib/cam0_flatfield.png", "flatfield_bit_depth": 16}
        if scene.render.flatfield
        else None,
        "versions": package_versions(scene.floor.material),
    }
    sensor_meta = _sensor_meta(scene)
    if sensor_meta is not None:  # written only when the sensor is not a global shutter of fixed exposure
        meta["sensor"] = sensor_meta
    # Deferred: the folder is checked now, but sequence.json and groundtruth.txt are written (and a
    # sequence being overwritten deleted) only once the exposure is chosen, so a render refused for a
    # black first frame leaves the folder as it found it (a folder it created is removed again).
    writer = SequenceWriter(out_dir, meta, overwrite=overwrite, defer=True)
    root = writer.root
    missing = writer.missing_frames()
    need_flat = scene.render.flatfield and not all(
        writer.has_calib(name) for name in ("cam0_flatfield", "cam1_flatfield")[: 2 if T_01 is not None else 1]
    )
    total = traj.frame_count
    if on_frame:
        on_frame(total - len(missing), total)
    if not missing and not need_flat:
        _write_signals(writer, scene, ts, T_all)
        return root

    sensor_path = root / "calib" / "sensor.json"
    gain = scene.sensor.exposure_gain
    if gain <= 0 and writer.resumed and sensor_path.is_file():
        try:
            gain = float(read_json(sensor_path, ConfigError)["gain_e_per_unit"])
        except (ConfigError, KeyError, TypeError, ValueError) as exc:
            # The exposure is a deterministic function of the scene and seed: choose it again.
            log.warning("%s: unusable (%s); choosing the exposure again", sensor_path, exc)
            gain = 0.0
    # The floor's tiles are planned on the whole trajectory, also when only its first frames are
    # rendered (frames=N): a tile's extent sets its shadow rays' lift, and a lift changed by
    # rounding changes the sensor's noise draws from that pixel on, so the first N frames would
    # otherwise differ from the whole render's.
    T_plan = _trajectory_of(scene, whole=True).T_world_cam
    margin = 2.0 + 2 * spacing
    reach_ms = scene.sensor.exposure_ms + scene.sensor.readout_ms
    if reach_ms > 0 and len(T_plan) > 1:
        # Motion blur and a rolling shutter reach poses up to half an exposure plus half a readout away.
        step_mm = float(np.max(np.linalg.norm(np.diff(T_plan[:, :3, 3], axis=0), axis=1)))
        margin += step_mm * reach_ms / 1000.0 * scene.fps
    # The tile must hold what both cameras see: widen the margin by the baseline.
    tiles = [
        ([i for i in idx if i < total], box)
        for idx, box in plan_tiles(
            T_plan, cam, scene.floor.tile_length_mm, margin + (0.0 if T_01 is None else scene.stereo.baseline_mm)
        )
        if idx[0] < total
    ]
    loaded_box = None  # the floor tile the renderer holds
    rad_first = None  # frame 0's radiance when the exposure was chosen from it
    if gain <= 0:
        # Exposure from the first frame's radiance (rendered again here if it is on disk), on the first
        # tile of the plan, which stays loaded for its frames; frame 0's render is kept for frame 0.
        loaded_box = tiles[0][1]
        top_mm = _load_tile(renderer, scene, loaded_box, spacing, tile_cache)
        rad0 = rad_first = _render_frame(renderer, scene, traj, 0, None, scene.seed)
        vig0 = vignetting_factor(cam, scene.camera.vignetting)
        rad0 = rad0 if vig0 is None else rad0 * vig0
        gain = exposure_gain(rad0, scene.sensor.full_well_e, scene.sensor.target_percentile, scene.sensor.target_level)
        if gain <= 0:
            raise ConfigError(
                f"{scene.name}: the first frame is black ({_black_frame_problem(scene, top_mm)}); "
                "set sensor.exposure_gain explicitly"
            )
    elif missing:
        # The first tile a frame is left on, loaded before anything is written: a floor the render
        # refuses (_check_relief_clearance) leaves the folder as it found it, as above.
        left = set(missing)
        loaded_box = next(box for idx, box in tiles if left.intersection(idx))
        _load_tile(renderer, scene, loaded_box, spacing, tile_cache)
    _write_signals(writer, scene, ts, T_all)  # sequence.json first (the writer's begin), then the ground truth
    atomic_write_json(sensor_path, {"gain_e_per_unit": gain, "full_well_e": scene.sensor.full_well_e})
    sensor = sensor_first = scene.sensor.model(gain)
    ae = None
    if scene.sensor.exposure_mode == "auto":
        ss = scene.sensor
        ae = AutoExposure(
            gain, ss.target_level, ss.target_percentile, ss.ae_loop_gain, ss.ae_delay_frames, ss.bit_depth
        )
        ae_gains, ae_levels = read_exposure_log(root / EXPOSURE_FILE, gain)
        # Each frame's exposure depends on the frames before it: render on from the first frame
        # that is missing or has no recorded exposure.
        first = min([len(ae_gains), *missing])
        del ae_gains[first:], ae_levels[first:]
        missing = list(range(first, total))

    done = total - len(missing)
    missing_set = set(missing)
    vig = vignetting_factor(cam, scene.camera.vignetting)
    t0 = time.perf_counter()
    for idx, box in tiles:
        todo = [i for i in idx if i in missing_set]
        if not todo:
            continue
        if box != loaded_box:
            _load_tile(renderer, scene, box, spacing, tile_cache)
            loaded_box = box
        for i in todo:
            if ae is not None:
                sensor = dataclasses.replace(sensor, gain_e_per_unit=ae.next_gain(i, ae_gains, ae_levels))
            rad = (
                rad_first
                if i == 0 and rad_first is not None
                else _render_frame(renderer, scene, traj, i, None, scene.seed)
            )
            if vig is not None:
                rad = rad * vig
            if T_all_cam1 is not None:
                rad1 = _render_frame(renderer, scene, traj, i, T_01, scene.seed + 1)
                if vig is not None:
                    rad1 = rad1 * vig
                writer.write_frame(i, sensor.capture(rad1, scene.seed + 1, i, noise=scene.sensor.noise), "cam1")
            if scene.render.depth:
                T_depth = T_all[i]
                if scene.sensor.readout_ms > 0:
                    T_depth = traj.pose_at(ts[i] + rolling_row_offsets_s(cam.height_px, scene.sensor.readout_ms))
                writer.write_depth(i, apply_depth_noise(renderer.depth(T_depth), scene.depth_noise, scene.seed, i))
            dn = sensor.capture(rad, scene.seed, i, noise=scene.sensor.noise)
            if ae is not None:
                ae_gains.append(sensor.gain_e_per_unit)
                ae_levels.append(image_level(dn, ae.bit_depth, ae.percentile))
                _write_exposure_log(root / EXPOSURE_FILE, ae_gains, ae_levels)
            # cam0 last: its frame on disk marks the whole frame as done for a resume.
            writer.write_frame(i, dn)
            done += 1
            if on_frame:
                on_frame(done, total)
        renderer.scene, loaded_box = None, None
        gc.collect()
    if need_flat:  # at the first frame's exposure (auto exposure changes `sensor` per frame)
        render_flatfield(renderer, scene, T_all[0], sensor_first, writer)
        if T_all_cam1 is not None:
            render_flatfield(
                renderer, scene, T_all[0], sensor_first, writer, cam_pose=T_all_cam1[0], name="cam1_flatfield"
            )
    log.info("rendered %d frames in %.1f s into %s", len(missing), time.perf_counter() - t0, root)
    return root


def _write_signals(writer: SequenceWriter, scene: Scene, ts: np.ndarray, T_all: np.ndarray) -> None:
    """The files of a render known before its first frame: ``sequence.json`` (the writer's
    :meth:`~floorvo.sequence.SequenceWriter.begin`), ``groundtruth.txt`` and the simulated
    ``height.csv`` / ``attitude.csv``."""
    writer.begin()
    writer.write_groundtruth(ts, T_all)
    if scene.range_sensor.enabled:
        writer.write_heights(range_sensor_heights(T_all, scene.range_sensor, scene.seed), "simulated range sensor")
    if scene.attitude_sensor.enabled:
        writer.write_attitude(attitude_sensor_angles(T_all, scene.attitude_sensor, scene.seed), "simulated IMU")


#: Per-frame exposure of an auto-exposure sequence (relative to the sequence folder).
EXPOSURE_FILE = "calib/exposure.csv"
_EXPOSURE_HEADER = ("frame", "gain_e_per_unit", "level")


def _sensor_meta(scene: Scene) -> dict | None:
    """The ``sensor`` block of sequence.json: shutter timing, exposure mode and, for a render with
    motion blur, its exposure time, centred on each row's time (None for an instantaneous
    global shutter with a fixed exposure, so such sequences keep the older metadata)."""
    ss = scene.sensor
    if ss.readout_ms <= 0 and ss.exposure_mode == "fixed" and ss.exposure_ms <= 0:
        return None
    h = scene.camera.height_px
    block = {
        "shutter": "rolling" if ss.readout_ms > 0 else "global",
        "readout_ms": ss.readout_ms,
        "row_time": ROW_TIME_CONVENTION,
        "groundtruth_row": (h - 1) / 2.0,
        "exposure_mode": ss.exposure_mode,
        "exposure_file": EXPOSURE_FILE if ss.exposure_mode == "auto" else None,
    }
    if ss.exposure_ms > 0:  # the renders before this key had none; theirs stay the same sequence
        block["exposure_ms"] = ss.exposure_ms
    return block


def read_exposure_log(path: Path, initial_gain: float | None = None) -> tuple[list[float], list[float]]:
    """Gains and metered levels of frames 0, 1, ... from an auto-exposure log; empty lists when
    the file is absent, unreadable or from another exposure (its frame 0 has not ``initial_gain``,
    when given)."""
    if not path.is_file():
        return [], []
    gains: list[float] = []
    levels: list[float] = []
    try:
        lines = read_text(path, ConfigError).splitlines()
        for k, line in enumerate(lines[1:]):
            frame, g, m = line.split(",")
            if int(frame) != k:
                break
            gains.append(float(g))
            levels.append(float(m))
    except (ConfigError, ValueError) as exc:
        log.warning("%s: unusable (%s); rendering the auto-exposure frames again", path, exc)
        return [], []
    if gains and initial_gain is not None and gains[0] != initial_gain:
        return [], []
    return gains, levels


def _write_exposure_log(path: Path, gains: list[float], levels: list[float]) -> None:
    atomic_write_csv(path, _EXPOSURE_HEADER, ((k, g, m) for k, (g, m) in enumerate(zip(gains, levels))))


def _frame_seed(seed: int, index: int) -> int:
    return int(np.random.SeedSequence([int(seed), int(index)]).generate_state(1)[0])


def render_flatfield(
    renderer,
    scene: Scene,
    T_world_cam: np.ndarray,
    sensor: SensorModel,
    writer: SequenceWriter,
    *,
    cam_pose: np.ndarray | None = None,
    name: str = "cam0_flatfield",
) -> np.ndarray:
    """Render and write ``calib/NAME.png``: the rig over a flat floor of uniform albedo.

    Same exposure as the sequence (the first frame's, with auto exposure), no noise, no
    fixed pattern and a linear response, 16-bit (the full-well scale of a 16-bit sensor), so estimators can divide a frame by it to remove the LED falloff. The LEDs
    are placed for the rig pose ``T_world_cam`` (cam0); ``cam_pose`` is the pose of the
    camera that sees it (cam1 of a stereo rig), cam0 by default.
    """
    cam = renderer.camera
    pose = T_world_cam if cam_pose is None else cam_pose
    box = footprint_bounds_mm(pose[None], cam, 5.0)
    renderer.load_flat(*box, albedo=scene.render.flatfield_albedo)
    specular, renderer.specular = renderer.specular, None  # the calibration target is matte
    rad = renderer.render(
        pose,
        _leds(scene, T_world_cam),
        max(16, scene.render.spp),
        seed=0,
        ambient=ambient_irradiance(scene, T_world_cam),
    )
    renderer.specular = specular
    vig = vignetting_factor(cam, scene.camera.vignetting)
    if vig is not None:
        rad = rad * vig
    renderer.scene = None
    flat16 = SensorModel(sensor.gain_e_per_unit, sensor.full_well_e, 0.0, False, 16).capture(rad, 0, 0, noise=False)
    writer.write_calib(name, flat16)
    return flat16


def range_sensor_heights(T_world_cam: np.ndarray, spec: RangeSensorSpec, seed: int) -> np.ndarray:
    """(N,) heights (mm) a simulated range sensor reads: the camera's height above the floor
    (z of ``T_world_cam`` (N, 4, 4)) plus Gaussian noise of ``spec.noise_mm``, NaN for a
    fraction ``spec.dropout`` of the frames; seeded by ``seed``, the same in every process. The
    noise and the dropout are drawn frame by frame from streams of their own, so the first k
    frames' readings do not depend on N (``floorsim render --frames k`` gives the whole render's
    first k: the dropout drawn after all N frames' noise moved with N)."""
    z = np.asarray(T_world_cam, dtype=float)[:, 2, 3]
    h = z + np.random.default_rng([int(seed), 0x52414E47]).normal(0.0, spec.noise_mm, z.shape)  # "RANG"
    h[np.random.default_rng([int(seed), 0x52414E47, 1]).random(z.shape) < spec.dropout] = np.nan
    return h


def attitude_sensor_angles(T_world_cam: np.ndarray, spec: AttitudeSensorSpec, seed: int) -> np.ndarray:
    """(N, 2) roll and pitch (rad) a simulated IMU's attitude filter reads: the camera's attitude
    against gravity (:func:`floorvo.geometry.attitude_of_T` of ``T_world_cam`` (N, 4, 4)) plus
    Gaussian noise of ``spec.noise_rad`` on each angle, a row of NaN for a fraction
    ``spec.dropout`` of the frames; seeded by ``seed`` (a stream of its own, not the range
    sensor's), the same in every process; the noise and the dropout each from a stream of its own,
    frame by frame, as :func:`range_sensor_heights`'s."""
    a = attitude_of_T(np.asarray(T_world_cam, dtype=float).reshape(-1, 4, 4))
    a = a + np.random.default_rng([int(seed), 0x41545449]).normal(0.0, spec.noise_rad, a.shape)  # "ATTI"
    a[np.random.default_rng([int(seed), 0x41545449, 1]).random(len(a)) < spec.dropout] = np.nan
    return a
