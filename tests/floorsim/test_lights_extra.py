"""LED aim and colour temperature; memory across floor tiles."""

import json
import pathlib
import subprocess
import sys

import numpy as np
import pytest
from _tiny import tiny_scene

from floorsim.scene import scene_T_world_leds
from floorsim.spectral import mono_response


def test_aim_defaults_to_floor_under_camera_and_offsets_away_from_bar():
    scene = tiny_scene()
    T = scene.build_trajectory().T_world_cam[0]
    pos, aim = scene_T_world_leds(scene, T)
    # Default: every LED aims at the floor point under the camera.
    for p, a in zip(pos, aim):
        t = (T[2, 3] * 0 - p[2]) / a[2] if a[2] != 0 else None
        hit = p + t * a
        np.testing.assert_allclose(hit[:2], T[:2, 3], atol=1e-9)
    off = tiny_scene(**{"lights.aim_offset_mm": 10.0})
    pos2, aim2 = scene_T_world_leds(off, T)
    left = pos2[:, 0] < T[0, 3]
    assert np.all(aim2[left, 0] > 0) and np.all(aim2[~left, 0] < 0)
    hit_left = pos2[left][0] - pos2[left][0][2] / aim2[left][0][2] * aim2[left][0]
    assert hit_left[0] == pytest.approx(T[0, 3] + 10.0)


def test_colour_temperature_weight():
    assert mono_response(5000.0) == pytest.approx(1.0)
    # Silicon sees more of a warm (red-rich) source's power than the eye does, per lumen.
    assert mono_response(2700.0) > mono_response(5000.0) > mono_response(10000.0)
    assert 0.7 < mono_response(10000.0) < 1.0 < mono_response(2700.0) < 2.0


#: Renders a line ten floor tiles long in a fresh interpreter and prints resident memory (MB)
#: after each frame: in the test process other tests' allocations would blur the figure.
#: Memory that is free but kept by an allocator is given back before each reading (Dr.Jit's
#: cache of freed buffers, glibc's free heap): which buffers those caches happen to hold
#: depends on the order in which threads free them, and moved single readings by +-30 MB
#: from run to run (a fresh install once read 61.6 MB of growth without any leak).
_MEMORY_PROBE = r"""
import ctypes, json, pathlib, sys, tempfile
sys.path.insert(0, sys.argv[1])
from _tiny import tiny_scene
from floorsim.simulate import render_sequence

def rss_mb():
    import drjit as dr  # loaded by the renderer by now

    dr.sync_thread()
    dr.flush_malloc_cache()
    ctypes.CDLL("libc.so.6").malloc_trim(0)
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * 4096 / 2**20

# Camera 20 mm above the floor: a 16 x 12 mm footprint, so 30 mm tiles hold two frames.
scene = tiny_scene(**{
    "camera.height_mm": 20.0,
    "trajectory": {"type": "line", "length_mm": 180.0, "speed_mm_s": 300.0},
    "floor.tile_length_mm": 30.0,
    "floor.spacing_mm": 0.04,
})
marks = {}
with tempfile.TemporaryDirectory() as d:
    render_sequence(scene, pathlib.Path(d) / "seq", on_frame=lambda done, total: marks.setdefault(done, rss_mb()))
print(json.dumps(marks))
"""


@pytest.mark.render
def test_memory_flat_across_floor_tiles():
    """A line ten tiles long: resident memory after the last tile is that after the second."""
    out = subprocess.run(
        [sys.executable, "-c", _MEMORY_PROBE, str(pathlib.Path(__file__).parent)],
        capture_output=True,
        text=True,
        check=True,
        timeout=300,
    )
    marks = {int(k): v for k, v in json.loads(out.stdout.strip().splitlines()[-1]).items()}
    n = max(marks)
    assert n == 19
    # A tile (30 x 16 mm at 0.04 mm) holds ~0.3 M vertices, ~30 MB with its BVH; the
    # nine tiles of this line would add hundreds of MB if they were kept.
    assert marks[n] - marks[6] < 40.0, marks
