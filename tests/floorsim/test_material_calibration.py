"""floorsim.bench.material_calibration: the motion suite's straight-run calibration and the one
with the yaw from a spin, and the fall-back to the first where the spin gives no yaw."""

from __future__ import annotations

import json

import numpy as np
import pytest
from tests.floorvo._synth import chain_scaled, hand_run

from floorsim import simulate
from floorsim.bench.material_calibration import (
    FULL_SPIN_RAD,
    SPIN_SCENE,
    calibration_floor_seed,
    calibration_render_dir,
    fit_material_calibration,
    floor_of,
    render_spin,
    same_floor_problem,
    spin_scene,
    straight_scene,
    turned_straight_scene,
)
from floorsim.bench.suites import suite_scenes
from floorsim.scene import load_scene
from floorsim.simulate import render_sequence
from floorvo.errors import SequenceError
from floorvo.geometry import T_world_cam_down
from floorvo.sequence import Sequence

STRAIGHT = np.stack([T_world_cam_down(4.0 * i, 0.0, 100.0) for i in range(26)])  # 100 mm along x
SPIN = np.stack([T_world_cam_down(0.0, 0.0, 100.0, 0.1 * i) for i in range(21)])  # 115 degrees in place


def test_the_yaw_comes_from_the_spin_and_the_straight_calibration_stays(tmp_path):
    straight = hand_run(tmp_path / "a", STRAIGHT, chain_scaled(STRAIGHT, 1.003))
    spin = hand_run(tmp_path / "b", SPIN, chain_scaled(SPIN, 1.0, s_yaw=1.0035))
    fit = fit_material_calibration(straight, spin)
    assert fit.straight is not None and fit.with_yaw is not None and fit.why == ""
    assert fit.straight.scale_x == pytest.approx(1.003) and fit.straight.scale_yaw == 1.0
    assert not fit.straight.observed_yaw
    assert fit.with_yaw.scale_x == pytest.approx(1.003) and fit.with_yaw.scale_yaw == pytest.approx(1.0035)
    assert fit.scale_x_cell() == "1.0030" and fit.scale_yaw_cell() == "1.0035"


@pytest.mark.parametrize(
    "spin_poses, lost_after, why",
    [
        # every step after the first frame lost: nothing to fit the yaw on
        (SPIN, 1, "spin lost: "),
        # 4 ok steps of 5.7 degrees, then lost: 23 degrees is enough
        (SPIN, 5, None),
        # a spin of 0.3 degrees a frame: 5.7 degrees in all, under the 10 the yaw needs
        (np.stack([T_world_cam_down(0.0, 0.0, 100.0, 0.005 * i) for i in range(21)]), None, "turned 5.7 deg, under 10"),
    ],
)
def test_a_spin_that_cannot_give_the_yaw_leaves_the_straight_calibration(tmp_path, spin_poses, lost_after, why):
    straight = hand_run(tmp_path / "a", STRAIGHT, chain_scaled(STRAIGHT, 1.003))
    spin = hand_run(tmp_path / "b", spin_poses, chain_scaled(spin_poses, 1.0, s_yaw=1.0035), lost_after=lost_after)
    fit = fit_material_calibration(straight, spin)
    assert fit.straight is not None and fit.straight.scale_x == pytest.approx(1.003)
    if why is None:
        assert fit.with_yaw is not None and fit.with_yaw.scale_yaw == pytest.approx(1.0035)
        return
    assert fit.with_yaw is None and why in fit.why
    assert fit.scale_yaw_cell().startswith("x, y only (") and fit.scale_x_cell() == "1.0030"
    assert str(tmp_path) not in fit.why  # the cell gives the reason, not the folders


def test_a_yaw_scale_out_of_range_or_no_spin_leaves_the_straight_calibration(tmp_path):
    straight = hand_run(tmp_path / "a", STRAIGHT, chain_scaled(STRAIGHT, 1.003))
    spin = hand_run(tmp_path / "b", SPIN, chain_scaled(SPIN, 1.0, s_yaw=1.2))
    fit = fit_material_calibration(straight, spin)
    assert fit.with_yaw is None and fit.why == "spin: scale yaw 1.200 fitted: a broken run"
    fit = fit_material_calibration(straight, None)
    assert fit.straight is not None and fit.with_yaw is None and fit.why == "no spin over this floor"


def test_a_lost_or_broken_straight_run_gives_no_calibration(tmp_path):
    spin = hand_run(tmp_path / "b", SPIN, chain_scaled(SPIN, 1.0, s_yaw=1.0035))
    lost = hand_run(tmp_path / "a", STRAIGHT, STRAIGHT, lost_after=1)
    fit = fit_material_calibration(lost, spin)
    assert fit.straight is None and fit.with_yaw is None and fit.why == "calibration run lost"
    assert fit.scale_x_cell() == "none (calibration run lost)" and fit.scale_yaw_cell() == "-"
    broken = hand_run(tmp_path / "c", STRAIGHT, chain_scaled(STRAIGHT, 1.5))
    fit = fit_material_calibration(broken, spin)
    assert fit.straight is None and fit.scale_x_cell() == "none (scale x 1.500 fitted: a broken run)"


def test_no_orientation_calibration_without_frames_or_turned_runs(tmp_path):
    """The texture-orientation calibration needs the turned straight runs and frames to measure
    the orientation in: hand-made runs of ground truth only get none, and say why; without
    turned runs there is none to fit (the two constant calibrations as before)."""
    straight = hand_run(tmp_path / "a", STRAIGHT, chain_scaled(STRAIGHT, 1.003))
    spin = hand_run(tmp_path / "b", SPIN, chain_scaled(SPIN, 1.0, s_yaw=1.0035))
    turned = [hand_run(tmp_path / f"t{k}", STRAIGHT, chain_scaled(STRAIGHT, 1.003)) for k in range(2)]
    fit = fit_material_calibration(straight, spin, turned=turned, full_spin=spin)
    assert fit.with_yaw is not None and fit.with_orientation is None
    assert fit.orientation_why == "no frames to measure the texture orientation in"
    assert fit.orientation_cell() == "none (no frames to measure the texture orientation in)"
    fit = fit_material_calibration(straight, spin)
    assert fit.with_orientation is None and fit.orientation_cell() == "-"


def _rendered(path, material: str, floor_seed: int):
    """A sequence folder's sequence.json as a render writes it, as far as its floor goes."""
    path.mkdir(parents=True)
    meta = {"scene": {"floor": {"material": material}}, "seeds": {"scene": 0, "floor": floor_seed}}
    (path / "sequence.json").write_text(json.dumps(meta))
    return path


def test_the_calibration_runs_are_over_another_floor_than_the_suite():
    """Measure on more than what you tune on: the motion suite's scenes are all over floor seed 0;
    the calibration's straight run, spins and turned runs were too, so the straight run was the
    first 25 steps of the vibration scenes and the 2-rad spin over concrete the suite's own
    motion_turn_spin_concrete. Now every calibration scene is over the floor of the seed given."""
    suite = [load_scene(p) for p in suite_scenes("motion")]
    seed = calibration_floor_seed(suite)
    assert seed == 1 and all(sc.floor_seed != seed for sc in suite)
    spin = spin_scene("concrete", floor_seed=seed)
    own = next(sc for sc in suite if sc.name == SPIN_SCENE.split("/")[-1].removesuffix(".toml"))
    assert spin.to_dict()["trajectory"] == own.to_dict()["trajectory"] and spin.floor.material == own.floor.material
    assert spin.floor_seed == seed != own.floor_seed
    assert spin_scene("polished", floor_seed=seed, angle_rad=FULL_SPIN_RAD).floor_seed == seed
    assert straight_scene("polished", floor_seed=seed).floor_seed == seed
    assert turned_straight_scene("wood", 60.0, floor_seed=seed).floor_seed == seed
    with pytest.raises(TypeError):  # no default: a caller cannot render one over the suite's floor by leaving it out
        spin_scene("concrete")  # type: ignore[call-arg]


def test_a_calibration_run_on_a_scored_sequence_or_its_floor_is_refused(tmp_path):
    """The suite's own spin (the scored sequence itself) and a spin re-rendered over the scored
    scene's floor are refused; one over another floor, or another material's floor, is not."""
    scored = _rendered(tmp_path / "motion_turn_spin_concrete-abc", "concrete", 0)
    vinyl = _rendered(tmp_path / "motion_turn_s_curve_vinyl-def", "vinyl", 0)
    problem = same_floor_problem([scored], [scored, vinyl])
    assert "is a scored sequence" in problem
    again = _rendered(tmp_path / "spins" / "concrete", "concrete", 0)
    problem = same_floor_problem([again], [scored, vinyl])
    assert "over the floor of the scored sequence" in problem and "floor seed 0" in problem
    assert same_floor_problem([_rendered(tmp_path / "spins" / "concrete-floor1", "concrete", 1)], [scored]) == ""
    assert same_floor_problem([_rendered(tmp_path / "spins" / "wood", "wood", 0)], [scored, vinyl]) == ""
    assert floor_of(tmp_path) is None  # a folder that does not say its floor: compared by folder only
    assert same_floor_problem([tmp_path], [scored]) == ""


@pytest.mark.render
def test_a_renderer_edited_since_renders_the_calibration_spin_beside_the_old_one(tmp_path, monkeypatch):
    """``motion_suite.py --spins DIR`` after a renderer edit: the spin rendered by the old code is
    refused to the new code (its ``versions.render_code``), so the new code's spin goes into a
    folder of its own beside it (:func:`calibration_render_dir` names the code) and renders."""
    like = render_sequence(straight_scene("wood", floor_seed=1), tmp_path / "straight", frames=1, scale=0.25, spp=1)
    spins = tmp_path / "spins"
    old_dir = render_spin("wood", calibration_render_dir(spins, "wood-floor1", "wood"), like, 0.2, floor_seed=1)
    old_code = Sequence.open(old_dir).meta["versions"]["render_code"]
    assert old_dir.name == f"wood-floor1-{old_code[:12]}"

    edited = "0" * 64  # every hash of the renderer's code is another one after an edit
    monkeypatch.setattr(simulate, "render_code_sha256", lambda material=None: edited)
    with pytest.raises(SequenceError, match="render_code"):  # what --spins DIR did before: refused
        render_spin("wood", old_dir, like, 0.2, floor_seed=1)
    new_dir = render_spin("wood", calibration_render_dir(spins, "wood-floor1", "wood"), like, 0.2, floor_seed=1)
    assert new_dir != old_dir and new_dir.parent == spins
    new, old = Sequence.open(new_dir), Sequence.open(old_dir)
    assert new.meta["versions"]["render_code"] == edited and new.frame_count == old.frame_count >= 2
    assert new.camera.width_px == Sequence.open(like).camera.width_px  # at the straight run's size
