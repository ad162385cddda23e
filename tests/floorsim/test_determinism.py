"""The same scene and seed give the same bytes, in any process; the samples recorded are the samples rendered."""

from __future__ import annotations

import hashlib
import json
import logging
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from _tiny import tiny_scene

from floorsim.render import FloorRenderer, heightfield_vertex_normals, stratified_spp
from floorsim.simulate import prepare_scene, render_sequence
from floorvo.sequence import Sequence

#: Renders the tiny scene (3 frames, LEDs 10 mm up, sensor noise on) into argv[2] in a fresh
#: interpreter and prints the SHA-256 of every file of the sequence, and of frame 0's float32
#: radiance (more sensitive than 8-bit frames: a last-bit change of one pixel shows).
_RENDER_PROBE = r"""
import hashlib, json, pathlib, sys
sys.path.insert(0, sys.argv[1])
from _tiny import tiny_scene
from floorsim.render import FloorRenderer
from floorsim.simulate import _leds, _load_tile, _trajectory_of, plan_tiles, render_sequence

scene = tiny_scene(**{"lights.height_mm": 10.0, "sensor.noise": True, "trajectory.distance_mm": 8.0})
root = render_sequence(scene, sys.argv[2])
digests = {str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
           for p in sorted(root.rglob("*")) if p.is_file()}
traj, cam = _trajectory_of(scene), scene.camera_model()
renderer = FloorRenderer(cam)
_load_tile(renderer, scene, plan_tiles(traj.T_world_cam, cam, 240.0, 2.0)[0][1], scene.floor_spacing_mm())
T = traj.T_world_cam[0]
digests["radiance"] = hashlib.sha256(renderer.render(T, _leds(scene, T), 4, seed=1).tobytes()).hexdigest()
print(json.dumps(digests))
"""


@pytest.mark.render
def test_same_scene_same_bytes_in_fresh_processes(tmp_path):
    """Three fresh interpreters render the same scene: every file and the radiance are the same bytes.

    Before the vertex normals were computed in numpy, Mitsuba's atomic scatter-add gave them
    other last bits in every process: the radiance hash differed in 6 of 6 runs, frames and
    the exposure in calib/sensor.json now and then (issue 16, item 2).
    """
    runs = []
    for k in range(3):
        out = subprocess.run(
            [sys.executable, "-c", _RENDER_PROBE, str(pathlib.Path(__file__).parent), str(tmp_path / f"seq{k}")],
            capture_output=True,
            text=True,
            check=True,
            timeout=300,
        )
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    assert {"cam0/000000.png", "cam0/000002.png", "calib/sensor.json", "calib/cam0_flatfield.png"} <= set(runs[0])
    for other in runs[1:]:
        assert other == runs[0]


def test_heightfield_normals_of_a_plane_are_its_normal():
    """On a tilted plane z = a x + b y every vertex normal is (-a, -b, 1) / |.| (hand computation)."""
    xs = np.arange(7) * 0.25 - 0.5
    ys = np.arange(5) * 0.4 + 3.0
    a, b = 0.3, -0.2
    z = a * xs[None, :] + b * ys[:, None]
    n = heightfield_vertex_normals(xs, ys, z)
    expected = np.array([-a, -b, 1.0]) / np.linalg.norm([-a, -b, 1.0])
    assert n.shape == (5, 7, 3) and n.dtype == np.float32
    np.testing.assert_allclose(n.reshape(-1, 3), np.broadcast_to(expected, (35, 3)), atol=1e-6)


def test_heightfield_normals_weight_triangles_by_corner_angle():
    """A single raised corner of a 2x2 grid: each vertex's normal is the angle-weighted mean
    of its triangles' normals, computed here by hand from the two triangles."""
    xs, ys = np.array([0.0, 1.0]), np.array([0.0, 1.0])
    z = np.array([[0.0, 0.0], [0.0, 1.0]])  # z11 = 1
    n = heightfield_vertex_normals(xs, ys, z).astype(np.float64)
    # Lower triangle (0,0,0), (1,0,0), (1,1,1): normal (0, -1, 1)/sqrt2; upper (0,0,0), (1,1,1), (0,1,0): (-1, 0, 1)/sqrt2.
    lower, upper = np.array([0.0, -1.0, 1.0]) / np.sqrt(2), np.array([-1.0, 0.0, 1.0]) / np.sqrt(2)
    # At (0,0) the lower triangle's angle is between (1,0,0) and (1,1,1): arccos(1/sqrt3); the upper's the same.
    v00 = lower + upper
    np.testing.assert_allclose(n[0, 0], v00 / np.linalg.norm(v00), atol=1e-6)
    np.testing.assert_allclose(n[0, 1], lower, atol=1e-6)  # (1,0) belongs to the lower triangle only
    np.testing.assert_allclose(n[1, 0], upper, atol=1e-6)


@pytest.mark.render
def test_heightfield_normals_agree_with_mitsuba():
    """Our normals are Mitsuba's recompute_vertex_normals up to float32 rounding."""
    rng = np.random.default_rng(1)
    h = rng.normal(0.0, 0.02, (60, 80)).astype(np.float32)
    r = FloorRenderer(tiny_scene().camera_model())
    r.load_heightfield(0.0, 0.0, 0.06, h, np.full_like(h, 0.5))
    mesh = r.scene.shapes()[0]
    ours = np.array(r.mi.traverse(mesh)["vertex_normals"])
    mesh.recompute_vertex_normals()
    theirs = np.array(r.mi.traverse(mesh)["vertex_normals"])
    np.testing.assert_allclose(ours, theirs, atol=1e-6)


@pytest.mark.render
def test_stratified_spp_is_what_the_sampler_takes():
    """The rule matches Mitsuba's samplers for every count up to 70; 1 really is 1 sample."""
    r = FloorRenderer(tiny_scene().camera_model())
    assert [stratified_spp(n) for n in range(1, 71)] == [r.effective_spp(n) for n in range(1, 71)]
    assert r.effective_spp(1) == 1 and stratified_spp(5) == 6 and stratified_spp(16) == 16


def test_sequence_records_the_samples_rendered(caplog):
    """--spp 1 stays 1; --spp 5 is rendered and recorded as 6, with a warning naming both."""
    assert prepare_scene(tiny_scene(), spp=1).render.spp == 1
    with caplog.at_level(logging.WARNING, logger="floorsim.simulate"):
        assert prepare_scene(tiny_scene(), spp=5).render.spp == 6
    assert "render.spp = 5" in caplog.text and "6 samples per pixel" in caplog.text


@pytest.mark.render
def test_spp_1_renders_one_sample(tmp_path):
    """One sample per pixel: sequence.json says 1, and the frame is noisier than the 4-spp one
    (a pixel's one primary ray lands anywhere in it: no averaging of the relief's shading)."""
    scene = tiny_scene()
    one = Sequence.open(render_sequence(scene, tmp_path / "one", frames=1, spp=1))
    four = Sequence.open(render_sequence(scene, tmp_path / "four", frames=1, spp=4))
    assert one.meta["scene"]["render"]["spp"] == 1 and four.meta["scene"]["render"]["spp"] == 4
    ref = Sequence.open(render_sequence(scene, tmp_path / "ref", frames=1, spp=64)).image(0).astype(np.float64)

    def err(seq):
        return float(np.sqrt(np.mean((seq.image(0).astype(np.float64) - ref) ** 2)))

    assert err(one) > 2.0 * err(four)  # measured 11.0 against 3.7 DN
    assert hashlib.sha256(one.image(0).tobytes()).digest() != hashlib.sha256(four.image(0).tobytes()).digest()


@pytest.mark.render
def test_the_first_frames_alone_are_the_whole_renders_first_frames(tmp_path):
    """``frames=N`` renders the first N frames of the whole render, to the bit: the floor is tiled
    for the whole trajectory either way. Tiled for the first frames alone, the tile's extent (and
    with it the shadow rays' lift) changed by rounding, and with sensor noise on that moved the
    noise of every pixel after the first one it touched (38-70 % of the pixels of a full-size
    frame by a DN or more)."""
    scene = tiny_scene(**{"sensor.noise": True, "trajectory.distance_mm": 24.0, "floor.tile_length_mm": 100.0})
    whole = Sequence.open(render_sequence(scene, tmp_path / "whole"))
    first = Sequence.open(render_sequence(scene, tmp_path / "first", frames=3))
    assert first.frame_count == 3 < whole.frame_count
    for i in range(3):
        np.testing.assert_array_equal(first.image(i), whole.image(i))
