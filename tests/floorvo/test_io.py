"""Numbers in every JSON and CSV output are plain decimals (issue 16 item 9: numpy 2 wrote
``np.float64(100.0)``), read back with ``json`` / ``csv`` + ``float``."""

import csv
import importlib
import json

import numpy as np

from floorvo.camera import CameraModel
from floorvo.io import atomic_write_csv, atomic_write_json, code_sha256, csv_cell, plain
from floorvo.run import run_estimator
from floorvo.synthetic import line_poses, write_synthetic_sequence


def test_numpy_scalars_become_plain_numbers():
    assert csv_cell(np.float64(100.0)) == "100.0"
    assert csv_cell(np.float32(0.5)) == "0.5"
    assert csv_cell(np.int64(3)) == "3"
    assert csv_cell(np.float64("nan")) == "nan" and csv_cell(float("-inf")) == "-inf"
    assert csv_cell(None) == "" and csv_cell("ok") == "ok"
    assert float(csv_cell(np.float64(0.1) + np.float64(0.2))) == 0.1 + 0.2  # exact round trip
    p = plain({"a": np.float64(1.5), "b": (np.int64(2), np.arange(2)), "c": [np.bool_(True)]})
    assert p == {"a": 1.5, "b": [2, [0, 1]], "c": [True]}
    assert type(p["a"]) is float and type(p["b"][0]) is int and type(p["c"][0]) is bool


def test_writers_read_back_with_csv_and_float(tmp_path):
    atomic_write_csv(tmp_path / "t.csv", ["x", "n", "label"], [[np.float64(100.0), np.int64(7), "a"]])
    with (tmp_path / "t.csv").open(newline="") as fh:
        (row,) = list(csv.DictReader(fh))
    assert float(row["x"]) == 100.0 and float(row["n"]) == 7 and row["label"] == "a"
    atomic_write_json(tmp_path / "t.json", {"x": np.float64(100.0), "n": np.int64(7)})  # np.int64 was a TypeError
    assert (tmp_path / "t.json").read_text() == '{\n  "x": 100.0,\n  "n": 7\n}\n'


def _leaves(obj):
    if isinstance(obj, dict):
        for v in obj.values():
            yield from _leaves(v)
    elif isinstance(obj, list):
        for v in obj:
            yield from _leaves(v)
    else:
        yield obj


def assert_plain_json(path):
    """Every leaf of the JSON file is a plain JSON value; no string holds a Python repr of a number."""
    for v in _leaves(json.loads(path.read_text())):
        assert v is None or isinstance(v, (bool, int, float, str)), (path, v)
        assert not (isinstance(v, str) and v.startswith("np.")), (path, v)


def assert_csv_numbers(path, text_columns=()):
    """Every cell of ``path`` outside ``text_columns`` is empty or a number that ``float`` reads."""
    with path.open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert rows, path
    for r in rows:
        for k, v in r.items():
            if k not in text_columns and v != "":
                float(v)  # a ValueError names the cell, e.g. 'np.float64(100.0)'
    return rows


def test_a_run_folder_has_plain_numbers(tmp_path):
    cam = CameraModel.from_sensor().scaled(0.25)
    seq = write_synthetic_sequence(tmp_path / "seq", cam, line_poses(12.0, 4.0), seed=0)
    run_estimator(seq, "phase-corr", tmp_path / "run")
    assert_csv_numbers(tmp_path / "run" / "timing.csv", text_columns=("status", "reason"))
    assert_plain_json(tmp_path / "run" / "result.json")
    assert_plain_json(tmp_path / "seq" / "sequence.json")


def test_a_byte_order_mark_is_not_part_of_the_text(tmp_path):
    """A scene file a Windows editor saved with a BOM was 'not valid TOML (Invalid statement (at
    line 1, column 1))', a TUM file 'not a number in TUM line', a JSON file 'not valid JSON'."""
    from floorvo.io import read_json, read_text, read_toml
    from floorvo.tum import read_tum

    bom = b"\xef\xbb\xbf"
    (tmp_path / "s.toml").write_bytes(bom + b'name = "x"\n')
    (tmp_path / "t.txt").write_bytes(bom + b"0.0 0 0 0.1 0 0 0 1\n")
    (tmp_path / "j.json").write_bytes(bom + b'{"a": 1}')
    assert read_toml(tmp_path / "s.toml") == {"name": "x"}
    assert read_tum(tmp_path / "t.txt")[0].tolist() == [0.0]
    assert read_json(tmp_path / "j.json") == {"a": 1}
    assert read_text(tmp_path / "s.toml").startswith("name")


def test_code_sha256_follows_every_edit_of_a_module_or_a_package(tmp_path, monkeypatch):
    """The fingerprint the caches key code by: an estimator's step made 1 % longer is another fingerprint."""
    pkg = tmp_path / "fingerprinted_pkg"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "est.py").write_text("STEP = 1.00\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    mod = importlib.import_module("fingerprinted_pkg.est")
    before = code_sha256("fingerprinted_pkg"), code_sha256(mod), code_sha256("fingerprinted_pkg.est")
    assert before[1] == before[2] != before[0]
    assert code_sha256("fingerprinted_pkg") == before[0]  # the same code, the same fingerprint
    (pkg / "est.py").write_text("STEP = 1.01\n")
    after = code_sha256("fingerprinted_pkg"), code_sha256(mod)
    assert after[0] != before[0] and after[1] != before[1]
    (pkg / "util.py").write_text("")  # a file added to the package
    assert code_sha256("fingerprinted_pkg") != after[0]
