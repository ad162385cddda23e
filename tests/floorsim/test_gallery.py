"""The gallery: a labelled contact sheet with one tile per material and lighting variant."""

import numpy as np
import pytest

from floorsim.gallery import AE_FRAMES, LIGHTING_VARIANTS, render_gallery
from floorsim.materials import MATERIALS
from floorsim.scene import list_scenes, load_scene
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
    rows = -(-n // 4)
    tile_h, tile_w = (sheet.shape[0] - 6) // rows - 6, 81  # demo at quarter scale plus the label band
    assert tile_h > 62 + 12  # a band of at least one line of text
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
    sheet = read_png(path)
    rows = -(-(len(MATERIALS) + len(LIGHTING_VARIANTS) + 1) // 4)
    tile_h = (sheet.shape[0] - 6) // rows - 6
    (seq_dir,) = [p for p in (out / "frames").iterdir() if "auto_exposure" in p.name]
    seq = Sequence.open(seq_dir)
    gains, levels = read_exposure_log(seq_dir / "calib" / "exposure.csv")
    assert len(gains) == AE_FRAMES and len(levels) == AE_FRAMES
    assert max(gains) / min(gains) > 1.02  # the loop reacted to the flicker
    n = len(MATERIALS) + len(LIGHTING_VARIANTS)  # the AE tile is the last
    r, c = divmod(n, 4)
    tile = sheet[6 + r * (tile_h + 6) :][:62, 6 + c * (81 + 6) :][:, :81]
    edges = np.linspace(0, 81, AE_FRAMES + 1).astype(int)
    k = AE_FRAMES - 1  # the last slice, below the exposure line (drawn in the top third)
    np.testing.assert_array_equal(tile[40:, edges[k] : edges[k + 1]], seq.image(k)[40:, edges[k] : edges[k + 1]])


@pytest.mark.render
def test_gallery_labels_tell_every_tile_apart(gallery):
    """Labels were cut to max(8, width // 7) characters: at quarter scale two tiles read
    'material: c' and three 'vinyl, LEDs'. Each label band now differs from every other."""
    _, path = gallery
    sheet = read_png(path)
    n = len(MATERIALS) + len(LIGHTING_VARIANTS) + 1
    rows = -(-n // 4)
    tile_h = (sheet.shape[0] - 6) // rows - 6
    bands = [
        sheet[6 + r * (tile_h + 6) + 62 : 6 + r * (tile_h + 6) + tile_h, 6 + c * 87 : 6 + c * 87 + 81].astype(int)
        for r in range(rows)
        for c in range(4)
    ][:n]
    for i in range(n):
        for j in range(i + 1, n):
            assert np.abs(bands[i] - bands[j]).sum() > 0, (i, j)


def _base(tmp_path, name, replace):
    """The demo scene with ``replace`` (old line -> new line) applied, written to tmp_path/NAME.toml."""
    text = load_scene_text("demo")
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new, 1)
    path = tmp_path / f"{name}.toml"
    path.write_text(text)
    return path


def load_scene_text(name):
    from floorsim.scene import resolve_scene_path

    return resolve_scene_path(name).read_text()


@pytest.mark.parametrize("name", [p.stem for p in list_scenes()])
def test_every_shipped_scene_can_be_the_gallery_base(name):
    """7 of the 17 shipped scenes failed as --base: the gallery set trajectory.type = "uniform" and
    kept the base's other trajectory keys ("paper001_line.toml: trajectory.length_mm: unknown key")."""
    from floorsim.gallery import gallery_scenes

    tiles = gallery_scenes(name, scale=0.25)
    assert len(tiles) == len(MATERIALS) + len(LIGHTING_VARIANTS) + 1
    for _, scene, frames in tiles:
        assert scene.trajectory["type"] == "uniform" and scene.build_trajectory().frame_count >= frames


def test_the_base_lighting_tile_is_labelled_with_the_base_scenes_lights(tmp_path):
    """The first lighting tile is the base's own lighting: it was labelled "paper rig: both bars,
    LEDs 3 mm" over a base with one bar lit 5 mm up. Its label now says what it shows."""
    from floorsim.gallery import gallery_scenes

    labels = [label for label, _, _ in gallery_scenes("demo", scale=0.25)]
    assert "vinyl, base lighting: both bars, LEDs 3 mm" in labels
    base = _base(tmp_path, "left5", {"[lights]\nheight_mm = 3.0": '[lights]\nside = "left"\nheight_mm = 5.0'})
    tiles = {label: scene for label, scene, _ in gallery_scenes(base, scale=0.25)}
    scene = tiles["vinyl, base lighting: left bar only, LEDs 5 mm"]
    assert scene.lights.side == "left" and scene.lights.height_mm == 5.0
    assert not any("paper rig" in label for label in tiles)


@pytest.mark.render
def test_gallery_fits_its_variants_to_the_base(tmp_path, capsys):
    """A 60 fps base failed after 16 renders on its own 30 ms rolling shutter, and a camera 25 mm
    up after 10 on its own 30 mm LEDs, leaving the tiles rendered so far. The readout now stays within
    the base's frame period and the raised LEDs below its camera, and the labels say the values used."""
    from floorsim.cli import main
    from floorsim.gallery import gallery_scenes

    base = _base(tmp_path, "fast_low", {"fps = 30.0": "fps = 60.0", "height_mm = 100.0": "height_mm = 25.0"})
    tiles = {label: scene for label, scene, _ in gallery_scenes(base, scale=0.25)}
    shutter = [s for label, s in tiles.items() if "rolling shutter" in label]
    assert len(shutter) == 1 and 0 < shutter[0].sensor.readout_ms <= 1000.0 / 60
    assert all(s.lights.height_mm < 25.0 for s in tiles.values())
    assert "vinyl, rolling shutter 16.6 ms" in tiles and "vinyl, LEDs 15 mm" in tiles
    out = tmp_path / "g"
    assert main(["gallery", "-o", str(out), "--base", str(base), "--scale", "0.25"]) == 0, capsys.readouterr().err
    assert (out / "gallery.png").is_file()
    assert len(list((out / "frames").iterdir())) == len(tiles)


def test_gallery_refuses_a_base_a_tile_cannot_use_before_writing(tmp_path, capsys):
    """A tile the base cannot take (LEDs 0.5 mm up under LEDs 2 mm tall) is refused in one line naming
    the base, the tile and the rule, before any tile is rendered or the output folder made."""
    from floorsim.cli import main

    base = _base(tmp_path, "big_leds", {"[lights]\n": "[lights]\nled_size_mm = 2.0\nled_size_z_mm = 2.0\n"})
    out = tmp_path / "g"
    assert main(["gallery", "-o", str(out), "--base", str(base), "--scale", "0.25"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert "big_leds.toml: gallery tile 'vinyl, LEDs 0.5 mm': lights.height_mm = 0.5 mm" in err, err
    assert not out.exists()


@pytest.mark.render
def test_gallery_overwrite_replaces_tiles_of_other_settings(tmp_path, capsys):
    """Re-running with another --scale said "... pass --overwrite", which gallery did not take
    (unrecognized arguments). The same settings still reuse the tiles; --overwrite replaces them."""
    from floorsim.cli import main

    out = tmp_path / "g"
    assert main(["gallery", "-o", str(out), "--scale", "0.2"]) == 0
    sheet = (out / "gallery.png").read_bytes()
    capsys.readouterr()
    assert main(["gallery", "-o", str(out), "--scale", "0.2"]) == 0  # re-running reuses them
    assert (out / "gallery.png").read_bytes() == sheet
    capsys.readouterr()
    assert main(["gallery", "-o", str(out), "--scale", "0.25"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds a different sequence" in err and "--overwrite" in err, err
    assert read_png(out / "gallery.png").shape == read_png_bytes_shape(sheet)  # the old sheet is kept
    assert main(["gallery", "-o", str(out), "--scale", "0.25", "--overwrite"]) == 0, capsys.readouterr().err
    assert read_png(out / "gallery.png").shape[1] == 4 * (81 + 6) + 6  # the quarter-scale demo's tiles


def read_png_bytes_shape(data):
    import cv2

    return cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED).shape
