"""The per-material scale calibration of the motion suite (issue 14): a straight run, and a spin in place for the yaw.

Each estimator's calibration is fitted per floor material on the material's straight run
(``scenes/material_MATERIAL.toml``: x and y, :func:`floorvo.calibration.calibrate_run`) and,
for the yaw's scale, on that run together with a spin in place over the same floor
(:func:`floorvo.calibration.calibrate_runs`). :func:`render_spin` renders the spin (the
suite's ``motion_turn_spin_concrete`` scene with ``floor.material`` set: 2 rad at 5.7 degrees
a frame, 21 frames) at the frame size of the straight run; :func:`fit_material_calibration`
fits both calibrations and says, in one short line, why one of them is missing: the straight
run lost (a featureless floor) or its scale out of range (no calibration at all), or the spin
lost, turned too little in the steps it kept, or its yaw scale out of range (the straight
run's calibration alone: x and y, the yaw's scale 1).

On a grained floor the scales depend on the grain's angle to the rig's lights
(:mod:`floorvo.calibration`, the texture-orientation terms). :func:`render_turned_straight`
renders the material's straight run at other headings over the floor
(:data:`TURNED_HEADINGS_DEG`: 60 and 120 degrees, the camera turned with its direction of travel),
:func:`render_spin` a spin over more than half a turn (:data:`FULL_SPIN_RAD`), and with them
:func:`fit_material_calibration` fits a third calibration on the straight runs and that spin
together with those terms (``with_orientation``), kept only where the runs observe them (the
floor's texture has a direction that turns with it, and the terms are significant): on the
shipped floors, wood.

Every calibration run is rendered over another floor than the scenes it is applied to
(``floor.seed`` = :func:`calibration_floor_seed`: one above the scored scenes' highest, 1 for the
motion suite): "measure on more than what you tune on". At the scenes' own seed the straight run
was the first 25 steps of the suite's vibration scenes (the same floor, path and sensor noise, the
pose 0.05 mm RMS apart) and the 2-rad spin over concrete was the suite's ``motion_turn_spin_concrete``
itself; :func:`same_floor_problem` refuses a calibration run on a scored scene's floor.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable
from collections.abc import Sequence as Sequence_
from dataclasses import dataclass, replace
from pathlib import Path

from floorsim import simulate
from floorsim.scene import Scene, load_scene, scenes_dir
from floorsim.simulate import render_sequence
from floorvo.calibration import (
    ORIENTATION_MIN_COHERENCE,
    ScaleCalibration,
    calibrate_run,
    calibrate_runs,
    scale_range_problem,
)
from floorvo.errors import FloorbenchError
from floorvo.sequence import Sequence

__all__ = [
    "SPIN_SCENE",
    "TURNED_HEADINGS_DEG",
    "FULL_SPIN_RAD",
    "MaterialCalibration",
    "fit_material_calibration",
    "calibration_floor_seed",
    "calibration_render_dir",
    "floor_of",
    "render_spin",
    "render_turned_straight",
    "same_floor_problem",
    "spin_scene",
    "straight_scene",
    "turned_straight_scene",
]

#: The shipped scene a spin over another material is rendered from (``floor.material`` set).
SPIN_SCENE = "motion/motion_turn_spin_concrete.toml"
#: The headings (degrees, from the floor's x axis) of the straight runs that observe the
#: translation's texture-orientation terms, besides the material's own run at 0.
TURNED_HEADINGS_DEG = (60.0, 120.0)
#: The turn (rad) of the spin that observes the yaw's texture-orientation terms: more than half a
#: turn, the grain's period, so that the fit sees every orientation (the 2-rad spin of the constant
#: yaw scale sees 115 degrees of the 180, and a fit on it read the other 65 0.1-0.2 % of the turn wrong).
FULL_SPIN_RAD = 3.5

RunPair = tuple[str | os.PathLike, str | os.PathLike]  # (run folder, sequence folder)


def calibration_floor_seed(scored: Iterable[Scene]) -> int:
    """The floor seed of the calibration runs for the ``scored`` scenes: one above their highest
    (:attr:`floorsim.scene.Scene.floor_seed`), so that no calibration run is over a scored scene's floor."""
    return max((sc.floor_seed for sc in scored), default=0) + 1


def _keys(floor_seed: int, **more: float) -> dict[str, str]:
    return {"floor.seed": json.dumps(int(floor_seed)), **{k: json.dumps(float(v)) for k, v in more.items()}}


def straight_scene(material: str, *, floor_seed: int) -> Scene:
    """The material's straight run (``scenes/material_MATERIAL.toml``) over the floor of ``floor_seed``."""
    return load_scene(scenes_dir() / f"material_{material}.toml", _keys(floor_seed))


def spin_scene(material: str, *, floor_seed: int, angle_rad: float | None = None) -> Scene:
    """The spin in place over ``material`` (:data:`SPIN_SCENE` with ``floor.material`` set) over the
    floor of ``floor_seed``; ``angle_rad``: its turn (None: the scene's, 2 rad)."""
    keys = {"floor.material": json.dumps(material), **_keys(floor_seed)}
    if angle_rad is not None:
        keys["trajectory.angle_rad"] = json.dumps(float(angle_rad))
    return load_scene(scenes_dir() / SPIN_SCENE, keys)


def turned_straight_scene(material: str, heading_deg: float, *, floor_seed: int) -> Scene:
    """The material's straight run with the camera turned to ``heading_deg`` over the floor and
    travelling along its own x axis, as its run at 0 does, over the floor of ``floor_seed``."""
    heading = math.radians(heading_deg)
    keys = _keys(floor_seed, **{"trajectory.yaw_rad": heading, "trajectory.direction_rad": heading})
    return load_scene(scenes_dir() / f"material_{material}.toml", keys)


def calibration_render_dir(root: str | os.PathLike, name: str, material: str) -> Path:
    """The sequence folder under ``root`` that the calibration render ``name`` (a spin, a turned
    straight run) over ``material`` goes into: ``root/NAME-CODE``, CODE the first 12 hex digits
    of the renderer's code (:func:`floorsim.simulate.render_code_sha256`, with ``material``'s
    plugin module where it has one). A renderer edited since the last run so renders anew beside
    the old render, as the bench's sequence cache does, where the old render's
    ``versions.render_code`` would refuse it to be reused or resumed by other code."""
    return Path(root) / f"{name}-{simulate.render_code_sha256(material)[:12]}"


def render_spin(
    material: str,
    out: str | os.PathLike,
    like: str | os.PathLike,
    angle_rad: float | None = None,
    *,
    floor_seed: int,
) -> Path:
    """The spin in place over ``material`` (:func:`spin_scene`) in the sequence folder ``out``, at
    the frame size of the sequence ``like`` (the material's straight run); ``angle_rad``: its turn
    (None: the scene's, 2 rad; :data:`FULL_SPIN_RAD` for the texture-orientation terms). A finished
    render of the same scene there is reused and an interrupted one resumed
    (:func:`floorsim.simulate.render_sequence`); one of another scene or size is refused in one line."""
    return _render_like(spin_scene(material, floor_seed=floor_seed, angle_rad=angle_rad), out, like)


def render_turned_straight(
    material: str, heading_deg: float, out: str | os.PathLike, like: str | os.PathLike, *, floor_seed: int
) -> Path:
    """:func:`turned_straight_scene` in the sequence folder ``out``, at the frame size of ``like``;
    reused and resumed as :func:`render_spin`."""
    return _render_like(turned_straight_scene(material, heading_deg, floor_seed=floor_seed), out, like)


def floor_of(seq_dir: str | os.PathLike) -> tuple[str, int] | None:
    """``(material, floor seed)`` of a rendered sequence (its ``sequence.json``), or None where it
    does not say (a recording, an imported sequence)."""
    path = Path(seq_dir) / "sequence.json"
    try:
        meta = json.loads(path.read_text())
        material = meta["scene"]["floor"]["material"]
        seed = meta["seeds"]["floor"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return (str(material), int(seed)) if isinstance(seed, int) else None


def same_floor_problem(calibration: Iterable[str | os.PathLike], scored: Iterable[str | os.PathLike]) -> str:
    """Why a calibration fitted on the sequences ``calibration`` must not be scored on the
    sequences ``scored`` ("" where it may): one of them is a scored sequence itself, or is rendered
    over the same floor (material and floor seed) as a scored one. Sequences that do not say
    their floor (:func:`floor_of`) are compared by folder only."""
    given = [Path(s) for s in scored]
    floors = {floor_of(s): s for s in given}
    floors.pop(None, None)
    resolved = {s.resolve(): s for s in given}
    for c in map(Path, calibration):
        if c.resolve() in resolved:
            return f"calibration run {c} is a scored sequence: a scene is never scored with a calibration fitted on it"
        floor = floor_of(c)
        if floor is not None and floor in floors:
            return (
                f"calibration run {c} is over the floor of the scored sequence {floors[floor]} ({floor[0]}, floor seed "
                f"{floor[1]}): fit on another floor (floor.seed), not on the frames it is scored on"
            )
    return ""


def _render_like(scene: Scene, out: str | os.PathLike, like: str | os.PathLike) -> Path:
    """``scene`` rendered into the sequence folder ``out`` at the frame size of the sequence ``like``."""
    width = Sequence.open(like).camera.width_px
    full = scene.camera_model().width_px
    return render_sequence(scene, out, scale=None if width == full else width / full)


@dataclass(frozen=True)
class MaterialCalibration:
    """One estimator's calibrations on one material.

    ``straight``: fitted on the straight run alone (x and y; None where that run is lost or its
    scale out of range); ``with_yaw``: on the straight run and the spin together (None where the
    spin cannot give the yaw); ``why``: why the first missing one is missing ("" when neither is).
    """

    straight: ScaleCalibration | None
    with_yaw: ScaleCalibration | None
    why: str = ""
    with_orientation: ScaleCalibration | None = None
    orientation_why: str = ""

    def orientation_cell(self) -> str:
        """The texture-orientation calibration's yaw scale at its extremes, or why there is none."""
        c = self.with_orientation
        if c is None:
            return f"none ({self.orientation_why})" if self.orientation_why else "-"
        amp = math.hypot(c.yaw_cos2, c.yaw_sin2)
        amp_x = math.hypot(c.x_cos2, c.x_sin2)
        return f"yaw {c.scale_yaw:.4f} +/- {amp:.4f}, x {c.scale_x:.4f} +/- {amp_x:.4f}"

    def scale_x_cell(self) -> str:
        return f"{self.straight.scale_x:.4f}" if self.straight is not None else f"none ({self.why})"

    def scale_yaw_cell(self) -> str:
        if self.with_yaw is not None:
            return f"{self.with_yaw.scale_yaw:.4f}"
        if self.straight is None:
            return "-"
        return f"x, y only ({self.why})"


def _out_of_range(cal: ScaleCalibration, axes: tuple[str, ...]) -> str:
    """The table cell's words where a scale of ``axes`` leaves the range
    (:func:`floorvo.calibration.scale_range_problem`), else ''."""
    for axis in axes:
        if scale_range_problem(cal, (axis,)):
            v = getattr(cal, f"scale_{axis}")
            amp = math.hypot(getattr(cal, f"{axis}_cos2"), getattr(cal, f"{axis}_sin2"))
            return f"scale {axis} {v:.3f}" + (f" +/- {amp:.3f}" if amp else "") + " fitted: a broken run"
    return ""


def fit_material_calibration(
    straight: RunPair,
    spin: RunPair | None,
    min_turn_deg: float = 10.0,
    turned: Sequence_[RunPair] = (),
    full_spin: RunPair | None = None,
) -> MaterialCalibration:
    """Fit ``straight`` alone and, with ``spin`` (None: no spin over this floor), both together.

    The straight run's calibration is kept either way (the x, y column of the suite); the one
    with the yaw only where the spin's steps reported ok turned ``min_turn_deg`` or more and the
    yaw's scale is in :data:`floorvo.calibration.SCALE_RANGE`, else the straight run's stands
    (x and y, the yaw's scale 1) and ``why`` says why. Both with constant scales. With the
    ``turned`` straight runs (:func:`render_turned_straight`), a ``full_spin`` (over more than half
    a turn, :data:`FULL_SPIN_RAD`) and a calibration with the yaw, ``with_orientation`` is fitted
    on the straight runs and the full spin with the texture-orientation terms, and kept where it
    has some (else ``orientation_why`` says why not).
    """
    fit = _fit_constant(straight, spin, min_turn_deg)
    if not turned or full_spin is None or fit.with_yaw is None:
        return fit
    try:
        cal = calibrate_runs(
            [straight, *turned, full_spin], min_turn_deg=min_turn_deg, orientation=True, check_range=False
        )
    except FloorbenchError as exc:
        return replace(fit, orientation_why=f"a turned straight run lost: {exc}")
    if not cal.uses_orientation:
        if cal.orientation_coherence == 0.0:
            why = "no frames to measure the texture orientation in"
        elif cal.orientation_coherence < ORIENTATION_MIN_COHERENCE:
            why = f"texture without a direction (coherence {cal.orientation_coherence:.2f})"
        else:
            why = "no significant texture-orientation term"
        return replace(fit, orientation_why=why)
    bad = _out_of_range(cal, ("x", "y", "yaw"))
    if bad:
        return replace(fit, orientation_why=bad)
    return replace(fit, with_orientation=cal)


def _fit_constant(straight: RunPair, spin: RunPair | None, min_turn_deg: float) -> MaterialCalibration:
    """:func:`fit_material_calibration`'s two calibrations with constant scales."""
    try:
        cal = calibrate_run(*straight, orientation=False, check_range=False)
    except FloorbenchError:  # the run tracked too little (a featureless floor)
        return MaterialCalibration(None, None, "calibration run lost")
    bad = _out_of_range(cal, ("x", "y"))
    if bad:  # floorvo refuses such a file: a scale that far from 1 is a broken run, not a rig's scale
        return MaterialCalibration(None, None, bad)
    if spin is None:
        return MaterialCalibration(cal, None, "no spin over this floor")
    try:
        both = calibrate_runs([straight, spin], min_turn_deg=min_turn_deg, orientation=False, check_range=False)
    except FloorbenchError as exc:
        # The message names the run and sequence folders: the cell needs the reason only.
        text = str(exc).replace(f"{Path(spin[0])}/", "").replace(str(Path(spin[0])), "the run")
        text = text.replace(str(Path(spin[1])), "the spin")
        return MaterialCalibration(cal, None, f"spin lost: {text}")
    if not both.observed_yaw:
        return MaterialCalibration(
            cal, None, f"the spin's ok steps turned {both.turn_deg:.1f} deg, under {min_turn_deg:g}"
        )
    bad = _out_of_range(both, ("yaw",))
    if bad:
        return MaterialCalibration(cal, None, f"spin: {bad}")
    return MaterialCalibration(cal, both)
