"""The gallery: a labelled contact sheet with one tile per material and lighting variant."""

import numpy as np
import pytest

from floorsim.gallery import AE_FRAMES, LIGHTING_VARIANTS, render_gallery
from floorsim.materials import MATERIALS
from floorsim.scene import load_scene
from floorvo.io import read_png


def test_every_material_has_a_scene_and_is_distinct():
    assert len(MATERIALS) >= 7
    for name in MATERIALS:
        assert load_scene(f"material_{name}").floor.material == name


@pytest.mark.parametrize(
    "out, words", [("", "output folder '': the path is empty"), ("/", "is the root of a file system")]
)
def test_gallery_refuses_the_empty_path_and_the_root_in_one_line(tmp_path, monkeypatch, capsys, out, words):
    """-o "" rendered the gallery into the current folder and -o / into the file-system root."""
    import floorsim.gallery
    from floorsim.cli import main

    def no_writing(path):
        raise AssertionError(f"the gallery was about to write into {path!r}")

    monkeypatch.setattr(floorsim.gallery, "ensure_writable_dir", no_writing)
    monkeypatch.chdir(tmp_path)
    assert main(["gallery", "-o", out, "--scale", "0.05"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == []


@pytest.fixture(scope="module")
def gallery(tmp_path_factory):
    """The demo gallery at quarter scale, rendered once for the tests of this module: (folder, sheet path)."""
    out = tmp_path_factory.mktemp("gallery")
    return out, render_gallery(out, "demo", scale=0.25, columns=4)


@pytest.mark.render
def test_gallery_sheet_has_a_tile_per_material_and_variant(gallery):
    _, path = gallery
    sheet = read_png(path)
    n = len(MATERIALS) + len(LIGHTING_VARIANTS) + 1  # + the auto-exposure strip
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


@pytest.mark.render
def test_gallery_auto_exposure_tile_spans_frames_of_changing_exposure(gallery):
    """The auto-exposure tile comes from a run of AE_FRAMES frames whose gain the loop changed frame to frame,
    and each slice of the strip is its own frame's picture."""
    from floorsim.simulate import read_exposure_log
    from floorvo.sequence import Sequence

    out, path = gallery
    (seq_dir,) = [p for p in (out / "frames").iterdir() if "auto_exposure" in p.name]
    seq = Sequence.open(seq_dir)
    gains, levels = read_exposure_log(seq_dir / "calib" / "exposure.csv")
    assert len(gains) == AE_FRAMES and len(levels) == AE_FRAMES
    assert max(gains) / min(gains) > 1.02  # the loop reacted to the flicker
    n = len(MATERIALS) + len(LIGHTING_VARIANTS)  # the AE tile is the last
    r, c = divmod(n, 4)
    tile = read_png(path)[6 + r * (62 + 22 + 6) :][:62, 6 + c * (81 + 6) :][:, :81]
    edges = np.linspace(0, 81, AE_FRAMES + 1).astype(int)
    k = AE_FRAMES - 1  # the last slice, below the exposure line (drawn in the top third)
    np.testing.assert_array_equal(tile[40:, edges[k] : edges[k + 1]], seq.image(k)[40:, edges[k] : edges[k + 1]])
