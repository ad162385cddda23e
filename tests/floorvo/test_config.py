"""The one configuration mechanism (floorvo.config): building, refusals, --set text, listings."""

from __future__ import annotations

import dataclasses
import pickle
import subprocess
import sys
from dataclasses import dataclass

import pytest

from floorvo.cli import main
from floorvo.config import (
    Config,
    SetText,
    apply_overrides,
    build,
    describe_fields,
    from_overrides,
    param,
    parse_set_args,
    parse_text,
)
from floorvo.errors import ConfigError, ConfigFieldError
from floorvo.estimators import BUILTIN_ESTIMATORS, get_estimator, list_estimators, make_config
from floorvo.mapping.fused import MapFusedConfig
from floorvo.mapping.keyframes import KeyframeConfig
from floorvo.mapping.localize import LocalizeConfig
from floorvo.mapping.localize_run import localize_config
from floorvo.mapping.map import MapConfig
from floorvo.mapping.similarity import SimilarityConfig


@dataclass(frozen=True)
class Inner(Config):
    depth_mm: float = param(1.0, unit="mm", min=0, max=5.0, doc="a bounded depth")


@dataclass(frozen=True)
class Probe(Config):
    """A config with one field of each kind the mechanism handles."""

    config_name = "probe"

    count: int = param(3, min=1, max=10, doc="an int in [1, 10]")
    size_mm: float = param(2.0, unit="mm", gt=0, lt=100, doc="open interval (0, 100)")
    flag: bool = param(False, doc="a bool")
    mode: str = param("a", choices=("a", "b"), doc="a choice")
    seed: int | None = param(None, doc="optional")
    band_hz: tuple[float, ...] = param((1.0, 2.0), unit="Hz", doc="a list")
    table: dict = param(default_factory=dict, doc="free-form")
    inner: Inner = param(default_factory=Inner)

    def validate(self) -> None:
        if self.count > 5 and self.mode == "b":
            raise ConfigFieldError("count", f" = {self.count}: must be <= 5 when mode is 'b'")


def _all_config_classes() -> dict[str, type]:
    from floorsim.materials import MATERIALS
    from floorsim.scene import Scene
    from floorsim.trajectories import TRAJECTORIES, Disturbance

    out = {name: get_estimator(name).Config for name in list_estimators()}
    out |= {"map": MapConfig, "localize": MapFusedConfig, "scene": Scene, "disturbance": Disturbance}
    out |= {f"trajectory {k}": t.Params for k, t in TRAJECTORIES.items()}
    out |= {f"material {k}": m.Params for k, m in MATERIALS.items()}
    return out


# ----------------------------------------------------------------------------- building
def test_build_reads_types_and_nested_tables():
    p = build(Probe, {"count": 4, "size_mm": 5, "band_hz": [3, 4], "inner": {"depth_mm": 2}, "table": {"x": 1}})
    assert p.count == 4 and p.size_mm == 5.0 and isinstance(p.size_mm, float)
    assert p.band_hz == (3.0, 4.0) and p.inner == Inner(2.0) and p.table == {"x": 1}
    assert build(Probe, {"count": 8.0}).count == 8  # a whole float is an int (TOML writes 8.0)
    assert build(Probe, {}) == Probe()


@dataclass(frozen=True)
class WithOptional(Config):
    inner: Inner | None = param(None, doc="an optional table")


def test_an_optional_nested_table_is_built_checked_and_listed():
    assert build(WithOptional, {}).inner is None
    assert build(WithOptional, {"inner": {"depth_mm": 2}}).inner == Inner(2.0)
    with pytest.raises(ConfigError, match=r"^w\.inner\.depth_mm = 6\.0 mm: must be <= 5\.0 mm$"):
        build(WithOptional, {"inner": {"depth_mm": 6.0}}, "w")
    with pytest.raises(ConfigError, match=r"^w\.inner = 3: must be a table$"):
        build(WithOptional, {"inner": 3}, "w")
    assert [f.key for f in describe_fields(WithOptional)] == ["inner.depth_mm"]


def test_a_set_table_is_read_as_an_inline_toml_table():
    """``--set inner={depth_mm=2}`` is the table a TOML file would give, checked as one; a value
    that is no table says how a table is set (``--set inner={}`` read "inner = '{}': must be a
    table", though it was one)."""
    over = parse_set_args(["inner={depth_mm = 2}"])
    assert from_overrides(WithOptional, over).inner == Inner(2.0)
    assert from_overrides(WithOptional, parse_set_args(["inner={}"])).inner == Inner()
    with pytest.raises(ConfigError, match=r"^w\.inner\.depth_mm = 6\.0 mm: must be <= 5\.0 mm$"):
        from_overrides(WithOptional, parse_set_args(["inner={depth_mm=6}"]), "w")
    with pytest.raises(ConfigError) as exc:
        from_overrides(WithOptional, parse_set_args(["inner=3"]), "w")
    assert str(exc.value) == (
        "w.inner = 3: must be a table (an inline TOML table, or set one of its keys: --set w.inner.KEY=VALUE)"
    )


@pytest.mark.parametrize(
    "data, message",
    [
        ({"bogus": 1}, "probe.bogus: unknown key (known: band_hz, count, flag, inner, mode, seed, size_mm, table)"),
        ({"inner": {"bogus": 1}}, "probe.inner.bogus: unknown key (known: depth_mm)"),
        ({"count": "three"}, "probe.count = 'three': must be integer"),
        ({"count": 2.5}, "probe.count = 2.5: must be integer"),
        ({"size_mm": "big"}, "probe.size_mm = 'big': must be a number"),
        ({"flag": 1}, "probe.flag = 1: must be true or false"),
        ({"band_hz": 3.0}, "probe.band_hz = 3.0: must be a list"),
        ({"seed": "x"}, "probe.seed = 'x': must be integer or none"),
        ({"inner": 3}, "probe.inner = 3: must be a table"),
        ({"count": 0}, "probe.count = 0: must be >= 1"),
        ({"count": 11}, "probe.count = 11: must be <= 10"),
        ({"size_mm": 0.0}, "probe.size_mm = 0.0 mm: must be > 0 mm"),
        ({"size_mm": 100.0}, "probe.size_mm = 100.0 mm: must be < 100 mm"),
        ({"size_mm": float("inf")}, "probe.size_mm = inf mm: must be a finite number"),
        ({"inner": {"depth_mm": 6.0}}, "probe.inner.depth_mm = 6.0 mm: must be <= 5.0 mm"),
        ({"mode": "c"}, "probe.mode = 'c': must be one of 'a', 'b'"),
        ({"count": 6, "mode": "b"}, "probe.count = 6: must be <= 5 when mode is 'b'"),
    ],
)
def test_build_refuses_by_name_with_one_line(data, message):
    with pytest.raises(ConfigError) as exc:
        build(Probe, data, "probe")
    assert str(exc.value) == message
    assert "\n" not in str(exc.value) and "None" not in str(exc.value)


@dataclass(frozen=True)
class Needs(Config):
    name: str = param(doc="required")
    inner: Inner = param(default_factory=Inner)


@dataclass(frozen=True)
class Outer(Config):
    needs: Needs = param(doc="a nested table with a required key")


def test_a_missing_required_key_is_refused_by_name():
    """A field without a default that the table lacks was a TypeError from the constructor."""
    with pytest.raises(ConfigError, match=r"^outer.needs.name: missing \(a required key\)$"):
        build(Outer, {"needs": {"inner": {"depth_mm": 1.0}}}, "outer")
    with pytest.raises(ConfigError, match=r"^needs: missing"):
        build(Outer, {})
    assert build(Outer, {"needs": {"name": "a"}}).needs.name == "a"


def test_direct_construction_checks_the_same_rules():
    with pytest.raises(ConfigError, match=r"^probe.count = 0: must be >= 1$"):
        Probe(count=0)
    with pytest.raises(ConfigError, match=r"^similarity.ratio = 1.5: must be <= 1$"):
        SimilarityConfig(ratio=1.5)
    with pytest.raises(ConfigError, match=r"^keyframes.ratio = 1.0: must be < 1$"):
        KeyframeConfig(ratio=1.0)
    # The cross-field rule of the localiser, under each name it is read by.
    with pytest.raises(ConfigError, match=r"^localize.n_verify = 9: must be <= n_candidates \(4\)$"):
        LocalizeConfig(n_candidates=4, n_verify=9)
    with pytest.raises(ConfigError, match=r"^map-fused.n_verify = 9: must be <= n_candidates \(4\)$"):
        make_config("map-fused", {"n_candidates": "4", "n_verify": "9"})


def test_field_errors_survive_pickling():
    """Sweeps run jobs in worker processes; their errors come back pickled."""
    with pytest.raises(ConfigFieldError) as exc:
        build(Probe, {"count": 0}, "probe")
    back = pickle.loads(pickle.dumps(exc.value))
    assert str(back) == str(exc.value) and isinstance(back, ConfigError)


# ----------------------------------------------------------------------------- --set text
def test_parse_set_args_splits_once_and_refuses_by_name():
    assert parse_set_args(["a=1", " b = x=y ", "c="]) == {"a": "1", "b": "x=y", "c": ""}
    assert all(isinstance(v, SetText) for v in parse_set_args(["a=1"]).values())
    with pytest.raises(ConfigError, match=r"--set 'a': expected KEY=VALUE"):
        parse_set_args(["a"])
    with pytest.raises(ConfigError, match=r"--set '=1': empty key"):
        parse_set_args(["=1"])
    # a key given twice: --set grid=3 --set grid=4 ran with 4, the last, silently
    with pytest.raises(ConfigError, match=r"--set 'a = 2': 'a' is given twice \(also = '1'\); give it once"):
        parse_set_args(["a=1", "a = 2"])
    with pytest.raises(ConfigError, match=r"^--est-set 'e.k=2': 'e.k' is given twice"):
        parse_set_args(["e.k=1", "e.k=2"], "--est-set")


@pytest.mark.parametrize(
    "text, tp, value",
    [
        ("yes", bool, True),
        ("on", bool, True),
        ("1", bool, True),
        ("False", bool, False),
        ("0", bool, False),
        ("8", int, 8),
        ("8.0", int, 8),
        ("1e3", float, 1000.0),
        ("none", int | None, None),
        ("7", int | None, 7),
        ("left", str, "left"),
        ('"left"', str, "left"),
        ("123", str, "123"),
        ("[0.1, 2]", tuple[float, ...], [0.1, 2]),
        ("2", dict, 2),
        ("word", dict, "word"),
    ],
)
def test_parse_text_reads_by_the_field_type(text, tp, value):
    assert parse_text(text, tp) == value


@pytest.mark.parametrize("text, tp", [("maybe", bool), ("2.5", int), ("many", int), ("x", float)])
def test_parse_text_refuses_text_of_another_type(text, tp):
    with pytest.raises(ValueError):
        parse_text(text, tp)


def test_overrides_reach_nested_fields_and_keep_file_values_strict():
    p = from_overrides(Probe, {"inner.depth_mm": "3", "flag": "yes", "seed": "none", "band_hz": "[5, 6]"})
    assert p.inner.depth_mm == 3.0 and p.flag is True and p.seed is None and p.band_hz == (5.0, 6.0)
    # The same text read from a file (not --set) is not converted: a file says what type it means.
    with pytest.raises(ConfigError, match=r"probe.flag = 'yes': must be true or false"):
        build(Probe, {"flag": "yes"}, "probe")
    with pytest.raises(ConfigError, match=r"--set inner.depth_mm.x: 'depth_mm' is not a table"):
        apply_overrides({"inner": {"depth_mm": 1.0}}, {"inner.depth_mm.x": "1"})


def test_every_default_read_back_from_its_listing_is_the_default():
    """What a listing prints as a field's default, given back as --set text, builds the default."""
    for name, cls in _all_config_classes().items():
        rows = describe_fields(cls)
        required = {r.key for r in rows if r.default == "(required)"}
        base = {k: "x" for k in required}
        texts = {r.key: r.default for r in rows if r.key not in required and r.type != "table"}
        built = from_overrides(cls, {**base, **texts}, name)
        assert built == from_overrides(cls, base, name), name


def test_every_field_declares_a_doc_and_its_rule_reads_without_none():
    for name, cls in _all_config_classes().items():
        for row in describe_fields(cls):
            assert row.doc, f"{name}: {row.key} has no doc"
            assert row.rule and "None" not in row.rule, f"{name}: {row.key}: {row.rule!r}"


def test_every_bound_refusal_names_the_bound_it_broke_and_a_long_value_is_cut():
    """Issue 16 item 10: no "must be within [None, 200.0] mm"; a 100,000-character value is not echoed."""
    import typing

    from floorvo.config import rule_of

    checked = 0
    for name, cls in _all_config_classes().items():
        hints = typing.get_type_hints(cls)
        base = {r.key: "x" for r in describe_fields(cls) if r.default == "(required)"}
        for f in dataclasses.fields(cls):
            r = rule_of(f)
            if hints[f.name] not in (float, int, float | None, int | None) or r.choices is not None:
                continue
            for bound, beyond in ((r.max, 1), (r.lt, 0), (r.min, -1), (r.gt, 0)):
                if bound is None:
                    continue
                with pytest.raises(ConfigError) as info:
                    from_overrides(cls, {**base, f.name: str(bound + beyond)}, name)
                msg = str(info.value)
                assert "None" not in msg and "\n" not in msg and f"{bound}" in msg, msg
                checked += 1
            with pytest.raises(ConfigError) as info:
                from_overrides(cls, {**base, f.name: "9x" * 50_000}, name)
            assert len(str(info.value)) < 300 and "..." in str(info.value)
    assert checked > 50
    with pytest.raises(ConfigError) as info:
        build(Probe, {"mode": "x" * 100_000})
    assert len(str(info.value)) < 300 and str(info.value).startswith("mode = 'xxx")


# ----------------------------------------------------------------------------- estimators and mapping
def test_estimator_and_mapping_configs_go_through_the_mechanism():
    cfg = make_config("akaze-guided", {"hamming_threshold": "180", "use_flatfield": "off"})
    assert cfg.hamming_threshold == 180 and cfg.use_flatfield is False
    with pytest.raises(ConfigError, match=r"^akaze-guided.search_radius_px = 0.0 px: must be > 0.0 px$"):
        make_config("akaze-guided", {"search_radius_px": "0"})
    with pytest.raises(ConfigError, match=r"^map.similarity.block_px = 2 px: must be >= 4 px$"):
        MapConfig.from_overrides({"similarity.block_px": "2"})
    with pytest.raises(ConfigError, match=r"^map.keyframes.nope: unknown key \(known: ratio, window\)$"):
        MapConfig.from_overrides({"keyframes.nope": "1"})
    with pytest.raises(ConfigError, match=r"^map.poses = 'survey': must be one of 'groundtruth', 'chain'$"):
        MapConfig.from_overrides({"poses": "survey"})
    assert MapConfig.from_dict(MapConfig().to_dict()) == MapConfig()
    loc = localize_config("MAP", "none", {"fix_every": "2", "retrieval": "bow"})
    assert (loc.map, loc.odometry, loc.fix_every, loc.retrieval) == ("MAP", "none", 2, "bow")
    with pytest.raises(ConfigError, match=r"^localize.map: set by the --map option, not --set$"):
        localize_config("MAP", "none", {"map": "other"})
    with pytest.raises(ConfigError, match=r"^localize.min_corr = 2.0: must be <= 1.0$"):
        localize_config("MAP", "none", {"min_corr": "2"})


def test_map_fused_uses_the_localizer_config_itself():
    assert issubclass(MapFusedConfig, LocalizeConfig)
    loc_fields = {f.name: f.default for f in dataclasses.fields(LocalizeConfig)}
    fused = {f.name: f.default for f in dataclasses.fields(MapFusedConfig)}
    assert loc_fields.items() <= fused.items()


def test_every_builtin_estimator_loads_under_its_name():
    assert set(BUILTIN_ESTIMATORS) <= set(list_estimators())
    for name in BUILTIN_ESTIMATORS:
        cls = get_estimator(name)
        assert cls.name == name and dataclasses.is_dataclass(cls.Config)
        assert isinstance(make_config(name), cls.Config)


@pytest.mark.parametrize(
    "first", ["floorvo.mapping.fused", "floorvo.mapping.localize", "floorvo.estimators.akaze", "floorvo.run"]
)
def test_no_import_order_breaks_registration(first):
    """No import cycle: whichever module a program imports first, every estimator is found."""
    code = (
        f"import {first}\n"
        "from floorvo.estimators import get_estimator, list_estimators\n"
        "print(sorted(get_estimator(n).name for n in list_estimators()))\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert eval(r.stdout) == sorted(BUILTIN_ESTIMATORS)


# ----------------------------------------------------------------------------- listings
def test_list_config_prints_every_field_with_type_default_and_rule(capsys):
    assert main(["list", "--config", "akaze-guided"]) == 0
    out = capsys.readouterr().out.splitlines()
    cfg = get_estimator("akaze-guided").Config()
    for f in dataclasses.fields(cfg):
        line = next((ln for ln in out if ln.split()[:1] == [f.name]), None)
        assert line is not None, f.name
        value = getattr(cfg, f.name)
        words = line.split()
        assert words[1] == type(value).__name__
        assert words[2] == (str(value).lower() if isinstance(value, bool) else str(value))
    line = next(ln for ln in out if ln.split()[:1] == ["hamming_threshold"])
    assert "[1, 512]" in line
    line = next(ln for ln in out if ln.split()[:1] == ["search_radius_px"])
    assert " px " in line and "> 0.0" in line


def test_list_config_of_mapping_commands_and_unknown_names(capsys):
    assert main(["list", "--config", "map"]) == 0
    out = capsys.readouterr().out
    for key in ("similarity.block_px", "keyframes.window", "vocab_words", "poses"):
        assert f"  {key} " in out
    assert main(["list", "--config", "localize"]) == 0
    out = capsys.readouterr().out
    assert "  fix_every " in out and "  n_verify " in out and "  map " not in out
    assert main(["list", "--config", "nope"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("floorvo: error: --config 'nope': no such configuration") and "\n" not in err
