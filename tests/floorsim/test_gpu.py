"""The CUDA variant (``cuda_ad_mono``): selected by itself on a machine with an NVIDIA device, and it
renders what the LLVM variant renders. Run with ``pytest -m gpu`` on a GPU machine; skipped elsewhere."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = [pytest.mark.gpu, pytest.mark.render]

_RENDER = """
import json, sys
sys.path.insert(0, {tests!r})
from _tiny import tiny_scene
from floorsim.render import backend_info
from floorsim.simulate import render_sequence
root = render_sequence(tiny_scene(**{{"sensor.exposure_gain": 600000.0, **json.loads(sys.argv[2])}}), sys.argv[1])
print(json.dumps(backend_info()))
"""


def _render(tmp_path: Path, variant: str | None, overrides: dict) -> tuple[dict, np.ndarray]:
    from floorvo.sequence import Sequence

    env = {k: v for k, v in os.environ.items() if k != "FLOORSIM_VARIANT"}
    if variant:
        env["FLOORSIM_VARIANT"] = variant
    out = tmp_path / (variant or "auto")
    code = _RENDER.format(tests=str(Path(__file__).parent))
    proc = subprocess.run(
        [sys.executable, "-c", code, str(out), json.dumps(overrides)],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    info = json.loads(proc.stdout.strip().splitlines()[-1])
    return info, Sequence.open(out).image(0).astype(np.float64)


@pytest.mark.skipif(not os.path.exists("/dev/nvidia0"), reason="needs an NVIDIA device")
@pytest.mark.parametrize(
    "overrides",
    [{}, {"lights.led_size_mm": 3.0}, {"lights.emitter": "bar"}],
    ids=["point-leds", "3mm-leds", "bar"],
)
def test_cuda_is_chosen_by_itself_and_renders_what_llvm_renders(tmp_path, overrides):
    """Point LEDs and both extended-emitter kernels (one point per bar and sample, importance-sampled)."""
    info, gpu = _render(tmp_path, None, overrides)
    assert info["variant"] == "cuda_ad_mono"
    info_cpu, cpu = _render(tmp_path, "llvm_ad_mono", overrides)
    assert info_cpu["variant"] == "llvm_ad_mono"
    # Same scene, seed and exposure: the two backends may differ only in float rounding.
    mse = float(np.mean((gpu - cpu) ** 2))
    assert mse == 0.0 or 10 * np.log10(255.0**2 / mse) > 40.0


@pytest.mark.skipif(not os.path.exists("/dev/nvidia0"), reason="needs an NVIDIA device")
def test_cuda_renders_the_same_sequence_to_the_bit_twice(tmp_path):
    """The same scene and seed give the same frames on the same machine, on the GPU too (two processes)."""
    info, first = _render(tmp_path / "first", None, {"lights.led_size_mm": 3.0})
    assert info["variant"] == "cuda_ad_mono"
    _, second = _render(tmp_path / "second", None, {"lights.led_size_mm": 3.0})
    assert np.array_equal(first, second)
