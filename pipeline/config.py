"""The resolved configuration: one frozen dataclass per stage, gathered in :class:`PipelineConfig`.

Every parameter lives once, in the config dataclass of its stage, with its unit in its
name and its documentation in the class docstring. Users override them with a TOML file
(``--config FILE.toml``, one table per section) and with ``--set section.param=value``
(applied after the file)::

    [meanshift]
    max_iterations = 30

    dualtrack track SEQ --set levelset.area_weight=2.0
"""

from __future__ import annotations

import dataclasses
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipeline.errors import ConfigError
from pipeline.sinks.settings import RerunConfig
from pipeline.stages.appearance import AppearanceConfig
from pipeline.stages.association import AssociationConfig
from pipeline.stages.contour import ContourConfig
from pipeline.stages.detection import DetectionConfig
from pipeline.stages.extent import ExtentConfig
from pipeline.stages.histogram import HistogramConfig
from pipeline.stages.kalman import KalmanConfig
from pipeline.stages.levelset import LevelSetConfig
from pipeline.stages.meanshift import MeanShiftConfig
from pipeline.stages.model_update import ModelUpdateConfig
from pipeline.stages.occlusion import OcclusionConfig
from pipeline.stages.roi_match import RoiMatchConfig
from pipeline.tracker_config import CamShiftConfig, DualConfig, OpenCVTrackerConfig


@dataclass(frozen=True)
class PipelineConfig:
    """All sections. Field names are the section names used by ``--set`` and TOML tables.

    Parameters
    ----------
    histogram : HistogramConfig
        Appearance histogram binning.
    meanshift : MeanShiftConfig
        Mean-shift iteration and scale search.
    levelset : LevelSetConfig
        DRLSE level-set evolution.
    contour : ContourConfig
        The IR contour stage around the level set (region, starts, failure tests).
    model_update : ModelUpdateConfig
        Selective sub-model update (eq. 8-9).
    dual : DualConfig
        The dual-channel tracker.
    appearance : AppearanceConfig
        The dual tracker's correlation filter.
    extent : ExtentConfig
        The dual tracker's colour extent (the box's width and height from the target's colours).
    camshift : CamShiftConfig
        OpenCV CamShift peer.
    opencv : OpenCVTrackerConfig
        OpenCV MIL/CSRT/KCF peers.
    kalman : KalmanConfig
        Kalman motion stage (all trackers that predict).
    occlusion : OcclusionConfig
        Kalman-CAMShift occlusion grading.
    detection : DetectionConfig
        STDM detection and ROI discrimination.
    roi_match : RoiMatchConfig
        Affine-invariant ROI correlation (the image term).
    association : AssociationConfig
        Global association, track birth and death (the detection-driven tracker).
    rerun : RerunConfig
        The .rrd recording.
    """

    histogram: HistogramConfig = field(default_factory=HistogramConfig)
    meanshift: MeanShiftConfig = field(default_factory=MeanShiftConfig)
    levelset: LevelSetConfig = field(default_factory=LevelSetConfig)
    contour: ContourConfig = field(default_factory=ContourConfig)
    model_update: ModelUpdateConfig = field(default_factory=ModelUpdateConfig)
    dual: DualConfig = field(default_factory=DualConfig)
    appearance: AppearanceConfig = field(default_factory=AppearanceConfig)
    extent: ExtentConfig = field(default_factory=ExtentConfig)
    camshift: CamShiftConfig = field(default_factory=CamShiftConfig)
    opencv: OpenCVTrackerConfig = field(default_factory=OpenCVTrackerConfig)
    kalman: KalmanConfig = field(default_factory=KalmanConfig)
    occlusion: OcclusionConfig = field(default_factory=OcclusionConfig)
    detection: DetectionConfig = field(default_factory=DetectionConfig)
    roi_match: RoiMatchConfig = field(default_factory=RoiMatchConfig)
    association: AssociationConfig = field(default_factory=AssociationConfig)
    rerun: RerunConfig = field(default_factory=RerunConfig)


def section_names() -> list[str]:
    return [f.name for f in dataclasses.fields(PipelineConfig)]


def _coerce(value: Any, hint: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if origin is typing.Literal:
        allowed = typing.get_args(hint)
        if value not in allowed:
            raise ConfigError(
                f"{where} must be one of {', '.join(map(repr, allowed))}; got {value!r}"
            )
        return value
    if origin in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(hint) if a is not type(None)]
        if value is None or (isinstance(value, str) and value.lower() == "none"):
            return None
        return _coerce(value, args[0], where)
    if origin is tuple:
        args = typing.get_args(hint)
        if isinstance(value, str):
            value = [v for v in value.replace(",", " ").split() if v]
        if not isinstance(value, list | tuple):
            raise ConfigError(f"{where} must be a list; got {value!r}")
        elem = args[0] if args else str
        return tuple(_coerce(v, elem, where) for v in value)
    if hint is bool:
        if isinstance(value, bool):
            return value
        if isinstance(value, str) and value.lower() in (
            "true",
            "1",
            "yes",
            "on",
            "false",
            "0",
            "no",
            "off",
        ):
            return value.lower() in ("true", "1", "yes", "on")
        raise ConfigError(f"{where} must be true or false; got {value!r}")
    if hint is int:
        if isinstance(value, bool):
            raise ConfigError(f"{where} must be an integer; got {value!r}")
        if isinstance(value, int):
            return value
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where} must be an integer; got {value!r}") from None
        if f != int(f):
            raise ConfigError(f"{where} must be an integer; got {value!r}")
        return int(f)
    if hint is float:
        if isinstance(value, bool):
            raise ConfigError(f"{where} must be a number; got {value!r}")
        try:
            return float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where} must be a number; got {value!r}") from None
    if hint is str:
        return str(value)
    return value


def _replace_section(section: Any, name: str, values: dict[str, Any]) -> Any:
    hints = typing.get_type_hints(type(section))
    known = {f.name for f in dataclasses.fields(section)}
    changes = {}
    for key, raw in values.items():
        if key not in known:
            raise ConfigError(
                f"unknown parameter {name}.{key}; {name} has: {', '.join(sorted(known))}"
            )
        changes[key] = _coerce(raw, hints[key], f"{name}.{key}")
    try:
        return dataclasses.replace(section, **changes)
    except ValueError as exc:
        raise ConfigError(str(exc)) from None


def apply_overrides(cfg: PipelineConfig, overrides: dict[str, dict[str, Any]]) -> PipelineConfig:
    """Return ``cfg`` with ``{section: {param: value}}`` applied (values coerced and validated)."""
    sections = section_names()
    changes = {}
    for name, values in overrides.items():
        if name not in sections:
            raise ConfigError(f"unknown config section {name!r}; sections: {', '.join(sections)}")
        if not isinstance(values, dict):
            raise ConfigError(f"config section {name!r} must be a table of parameters")
        changes[name] = _replace_section(getattr(cfg, name), name, values)
    return dataclasses.replace(cfg, **changes)


def parse_set(items: list[str]) -> dict[str, dict[str, Any]]:
    """Parse ``["section.param=value", ...]`` into ``{section: {param: value}}``."""
    out: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        section, dot, param = key.strip().partition(".")
        if not sep or not dot or not section or not param:
            raise ConfigError(f"--set {item!r}: expected section.param=value")
        out.setdefault(section, {})[param] = value.strip()
    return out


def load_config(path: str | Path | None = None, sets: list[str] | None = None) -> PipelineConfig:
    """Defaults, then the TOML file ``path``, then the ``--set`` items."""
    cfg = PipelineConfig()
    if path is not None:
        p = Path(path)
        try:
            data = tomllib.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise ConfigError(f"config file not found: {p}") from None
        except IsADirectoryError:
            raise ConfigError(f"--config {p} is a folder, not a TOML file") from None
        except UnicodeDecodeError:
            raise ConfigError(f"{p}: not a TOML file (not UTF-8 text)") from None
        except OSError as exc:
            raise ConfigError(f"cannot read the config file {p}: {exc.strerror}") from None
        except tomllib.TOMLDecodeError as exc:
            raise ConfigError(f"{p}: not valid TOML ({exc})") from None
        cfg = apply_overrides(cfg, data)
    if sets:
        cfg = apply_overrides(cfg, parse_set(sets))
    return cfg


def config_to_dict(cfg: PipelineConfig) -> dict[str, dict[str, Any]]:
    """Plain dict of the resolved config (for summary.json and the .rrd)."""
    out = {}
    for f in dataclasses.fields(cfg):
        out[f.name] = {
            k: (list(v) if isinstance(v, tuple) else v)
            for k, v in dataclasses.asdict(getattr(cfg, f.name)).items()
        }
    return out
