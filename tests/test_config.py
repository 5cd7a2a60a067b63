"""Config sections: documented fields, TOML and --set overrides along the tree, parts left out
and put back, bad values rejected."""

import dataclasses
import json
from pathlib import Path

import pytest

from pipeline.config import (
    PipelineConfig,
    apply_overrides,
    config_to_dict,
    load_config,
    parse_set,
    walk_sections,
)
from pipeline.errors import ConfigError
from pipeline.tracker_config import DualConfig, GroupConfig

ROOT = Path(__file__).resolve().parents[1]


def _sections():
    full = load_config(None, ["dual.groups=default"])
    return [s for _, s in walk_sections(full)]


@pytest.mark.parametrize("section", _sections(), ids=lambda s: type(s).__name__)
def test_every_field_documented(section):
    doc = type(section).__doc__ or ""
    for f in dataclasses.fields(section):
        assert f"{f.name} :" in doc, (
            f"{type(section).__name__}.{f.name} is not documented in its docstring"
        )


def test_pipeline_sections_documented():
    doc = PipelineConfig.__doc__
    for f in dataclasses.fields(PipelineConfig):
        assert f"{f.name} :" in doc


def test_set_overrides_coerce_types():
    cfg = load_config(
        None,
        [
            "dual.meanshift.max_iterations=30",
            "dual.meanshift.epsilon_px=0.25",
            "opencv.channel=infrared",
            "meanshift.search.max_iterations=7",
        ],
    )
    assert cfg.dual.meanshift.max_iterations == 30 and cfg.dual.meanshift.epsilon_px == 0.25
    assert cfg.opencv.channel == "infrared" and cfg.meanshift.search.max_iterations == 7
    assert PipelineConfig().dual.meanshift.max_iterations == 20  # defaults untouched (frozen)


def test_toml_then_set(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text("[dual.meanshift]\nmax_iterations = 7\nscale_step = 0.05\n")
    cfg = load_config(f, ["dual.meanshift.max_iterations=9"])
    assert (cfg.dual.meanshift.max_iterations, cfg.dual.meanshift.scale_step) == (9, 0.05)


def test_a_part_is_left_out_and_put_back():
    cfg = load_config(None, ["dual.appearance=none", "dual.groups.merge_position=eq11"])
    assert cfg.dual.appearance is None and cfg.dual.groups == GroupConfig(merge_position="eq11")
    back = load_config(None, ["dual.appearance=none", "dual.appearance=default"])
    assert back.dual.appearance == PipelineConfig().dual.appearance
    # a later item wins, and setting a key of a part left out puts it back with its defaults
    again = load_config(None, ["dual.groups=default", "dual.groups=off"])
    assert again.dual.groups is None
    assert load_config(None, ["dual.extent=none", "dual.extent.max_ratio=1.5"]).dual.extent


def test_the_paper_file_is_the_paper_composition():
    """``data/dual-paper.toml`` and :meth:`DualConfig.paper` are one configuration."""
    cfg = load_config(ROOT / "data" / "dual-paper.toml")
    assert cfg.dual == DualConfig.paper()
    assert cfg.dual.appearance is None and cfg.dual.redetect is None and cfg.dual.extent is None
    assert cfg.dual.groups is not None and cfg.dual.groups.merge_position == "eq11"


def test_the_summary_holds_the_tracker_s_own_sections():
    cfg = load_config(None, ["dual.appearance=none"])
    d = config_to_dict(cfg, "dual")
    assert sorted(d) == ["dual", "rerun"] and d["dual"]["appearance"] is None
    assert d["dual"]["decider"]["psr_confident"] == 7.0
    json.dumps(config_to_dict(cfg))  # every section, plain JSON


@pytest.mark.parametrize(
    "item, match",
    [
        ("dual.meanshift.max_iterations=0", "dual.meanshift.max_iterations"),
        ("dual.meanshift.max_iterations=2.5", "integer"),
        ("dual.meanshift.nope=1", "unknown parameter dual.meanshift.nope"),
        ("nosuch.x=1", "unknown config section"),
        ("meanshift=3", "section.param=value"),
        ("dual.decider=3", "dual.decider is a section"),
        ("dual.decider=none", "dual.decider is a section"),
        ("dual.size.scale_rate.x=1", "dual.size.scale_rate is a parameter"),
        ("opencv.channel=thermal", "opencv.channel"),
        ("dual.histogram.hue_bins=1", "dual.histogram.hue_bins"),
        ("kalman-camshift.kalman.dt_frames=0", "kalman_camshift.kalman.dt_frames"),
    ],
)
def test_bad_values_rejected(item, match):
    with pytest.raises(ConfigError, match=match):
        load_config(None, [item])


def test_bad_toml(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text("[dual.meanshift\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(f)
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "missing.toml")


def test_apply_overrides_returns_new_object():
    cfg = PipelineConfig()
    new = apply_overrides(cfg, parse_set(["rerun.batch_frames=4"]))
    assert new.rerun.batch_frames == 4 and cfg.rerun.batch_frames == 16
