"""Config sections: documented fields, TOML and --set overrides, bad values rejected."""

import dataclasses

import pytest

from pipeline.config import PipelineConfig, apply_overrides, load_config, parse_set
from pipeline.errors import ConfigError


def _sections():
    cfg = PipelineConfig()
    return [getattr(cfg, f.name) for f in dataclasses.fields(cfg)]


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
        ["meanshift.max_iterations=30", "meanshift.epsilon_px=0.25", "opencv.channel=infrared"],
    )
    assert cfg.meanshift.max_iterations == 30 and cfg.meanshift.epsilon_px == 0.25
    assert cfg.opencv.channel == "infrared"
    assert PipelineConfig().meanshift.max_iterations == 20  # defaults untouched (frozen)


def test_toml_then_set(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text("[meanshift]\nmax_iterations = 7\nscale_step = 0.05\n")
    cfg = load_config(f, ["meanshift.max_iterations=9"])
    assert (cfg.meanshift.max_iterations, cfg.meanshift.scale_step) == (9, 0.05)


@pytest.mark.parametrize(
    "item, match",
    [
        ("meanshift.max_iterations=0", "max_iterations"),
        ("meanshift.max_iterations=2.5", "integer"),
        ("meanshift.nope=1", "unknown parameter meanshift.nope"),
        ("nosuch.x=1", "unknown config section"),
        ("meanshift=3", "section.param=value"),
        ("opencv.channel=thermal", "opencv.channel"),
        ("histogram.hue_bins=1", "hue_bins"),
    ],
)
def test_bad_values_rejected(item, match):
    with pytest.raises(ConfigError, match=match):
        load_config(None, [item])


def test_bad_toml(tmp_path):
    f = tmp_path / "c.toml"
    f.write_text("[meanshift\n")
    with pytest.raises(ConfigError, match="not valid TOML"):
        load_config(f)
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "missing.toml")


def test_apply_overrides_returns_new_object():
    cfg = PipelineConfig()
    new = apply_overrides(cfg, parse_set(["rerun.batch_frames=4"]))
    assert new.rerun.batch_frames == 4 and cfg.rerun.batch_frames == 16
