"""The gallery: a labelled contact sheet with one tile per material and lighting variant."""

import numpy as np
import pytest

from floorsim.gallery import LIGHTING_VARIANTS, render_gallery
from floorsim.materials import MATERIALS
from floorsim.scene import load_scene
from floorvo.io import read_png


def test_every_material_has_a_scene_and_is_distinct():
    assert len(MATERIALS) >= 7
    for name in MATERIALS:
        assert load_scene(f"material_{name}").floor.material == name


@pytest.mark.render
def test_gallery_sheet_has_a_tile_per_material_and_variant(tmp_path):
    path = render_gallery(tmp_path, "demo", scale=0.25, columns=4)
    sheet = read_png(path)
    n = len(MATERIALS) + len(LIGHTING_VARIANTS)
    tile_h, tile_w = 62 + 22, 81  # demo at quarter scale plus the label band
    rows = -(-n // 4)
    assert sheet.shape == (rows * (tile_h + 6) + 6, 4 * (tile_w + 6) + 6)
    # Each tile differs from the others (no material or variant renders the same picture).
    tiles = [
        sheet[
            6 + r * (tile_h + 6) : 6 + r * (tile_h + 6) + 62, 6 + c * (tile_w + 6) : 6 + c * (tile_w + 6) + tile_w
        ].astype(float)
        for r in range(rows)
        for c in range(4)
    ][:n]
    # The first variant is the paper rig, identical to the vinyl material tile.
    names = sorted(MATERIALS)
    vinyl = tiles[names.index("vinyl")]
    np.testing.assert_array_equal(vinyl, tiles[len(names)])
    for i in range(n):
        for j in range(i + 1, n):
            if {i, j} == {names.index("vinyl"), len(names)}:
                continue
            assert np.abs(tiles[i] - tiles[j]).mean() > 1.0, (i, j)
