"""The resolved configuration: a tree of frozen sections, gathered in :class:`PipelineConfig`.

Every parameter lives once, in the section of the part that uses it, with its unit in its
name and its documentation in the section's docstring. A tracker's section holds the sections
of the parts it is built from (:mod:`pipeline.tracker_config`); users override any of them
with a TOML file (``--config FILE.toml``, one table per section, dotted as the tree is) and
with ``--set path.param=value`` (applied after the file)::

    [dual.meanshift]
    max_iterations = 30

    dualtrack track SEQ --set dual.levelset.area_weight=2.0 --set dual.groups=default

An optional part (a section that may be None) is left out with ``none`` (``off``, ``false``)
and put back with its defaults with ``default`` (``on``, ``true``) or by setting any of its
parameters.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import re
import tomllib
import types
import typing
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pipeline.errors import ConfigError
from pipeline.params import INT_MAX, Section
from pipeline.sinks.settings import RerunConfig
from pipeline.tracker_config import (
    CamShiftConfig,
    DetectConfig,
    DualConfig,
    KalmanCamShiftConfig,
    MeanShiftTrackerConfig,
    OpenCVTrackerConfig,
)


@dataclass(frozen=True)
class PipelineConfig:
    """Every tracker's configuration tree, the peers' and the recording's.

    Field names are the first part of every ``--set`` key and TOML table
    (``kalman-camshift`` may be written for ``kalman_camshift``).

    Parameters
    ----------
    dual : DualConfig
        The dual-channel tracker and its parts.
    meanshift : MeanShiftTrackerConfig
        The ``meanshift`` tracker.
    kalman_camshift : KalmanCamShiftConfig
        The ``kalman-camshift`` tracker.
    detect : DetectConfig
        The detection-driven ``detect`` tracker; also ``dualtrack detect`` and ``--detect``.
    camshift : CamShiftConfig
        OpenCV's CamShift peer.
    opencv : OpenCVTrackerConfig
        OpenCV's MIL, CSRT and KCF peers (and the channel CamShift runs on).
    rerun : RerunConfig
        The .rrd recording.

    Examples
    --------
    >>> cfg = PipelineConfig()
    >>> cfg.dual.decider.psr_confident, cfg.dual.groups is None, cfg.detect.association.max_misses
    (7.0, True, 1)
    """

    dual: DualConfig = field(default_factory=DualConfig)
    meanshift: MeanShiftTrackerConfig = field(default_factory=MeanShiftTrackerConfig)
    kalman_camshift: KalmanCamShiftConfig = field(default_factory=KalmanCamShiftConfig)
    detect: DetectConfig = field(default_factory=DetectConfig)
    camshift: CamShiftConfig = field(default_factory=CamShiftConfig)
    opencv: OpenCVTrackerConfig = field(default_factory=OpenCVTrackerConfig)
    rerun: RerunConfig = field(default_factory=RerunConfig)


TRACKER_SECTIONS = {
    "dual": "dual",
    "meanshift": "meanshift",
    "kalman-camshift": "kalman_camshift",
    "detect": "detect",
    "camshift": "camshift",
    "mil": "opencv",
    "csrt": "opencv",
    "kcf": "opencv",
}
"""The section of :class:`PipelineConfig` each tracker runs with."""


def section_names() -> list[str]:
    """The top-level sections: the first part of every key."""
    return [f.name for f in dataclasses.fields(PipelineConfig)]


@functools.cache
def sub_sections(cls: type) -> dict[str, tuple[type, bool]]:
    """``{field: (section class, optional)}`` of the fields of ``cls`` that are sections
    themselves (optional: the field may be None, the part left out)."""
    out = {}
    for name, hint in typing.get_type_hints(cls).items():
        if name not in {f.name for f in dataclasses.fields(cls)}:
            continue
        args = (
            typing.get_args(hint)
            if typing.get_origin(hint) in (typing.Union, types.UnionType)
            else (hint,)
        )
        sections = [a for a in args if isinstance(a, type) and issubclass(a, Section)]
        if sections:
            out[name] = (sections[0], type(None) in args)
    return out


def walk_sections(cfg: object, path: str = "") -> list[tuple[str, Section]]:
    """``(path, section)`` of every section in the tree under ``cfg`` (present ones only),
    depth first: ``[("dual", DualConfig(...)), ("dual.motion", MotionConfig(...)), ...]``."""
    out: list[tuple[str, Section]] = []
    for name in sub_sections(type(cfg)):
        sec = getattr(cfg, name)
        if sec is None:
            continue
        p = f"{path}.{name}" if path else name
        out.append((p, sec))
        out += walk_sections(sec, p)
    return out


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
        if isinstance(value, int) and abs(value) <= INT_MAX:
            return value
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where} must be an integer; got {value!r}") from None
        if not math.isfinite(f) or f != int(f):
            raise ConfigError(f"{where} must be an integer; got {value!r}")
        if abs(f) > INT_MAX:
            raise ConfigError(f"{where} must be an integer of at most {INT_MAX}; got {value!r}")
        return int(f)
    if hint is float:
        if isinstance(value, bool):
            raise ConfigError(f"{where} must be a number; got {value!r}")
        try:
            f = float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where} must be a number; got {value!r}") from None
        if not math.isfinite(f):
            raise ConfigError(f"{where} must be a finite number; got {value!r}")
        return f
    if hint is str:
        return str(value)
    return value


_OFF = ("none", "off", "false", "no")
_ON = ("default", "on", "true", "yes")


def _toggle(value: Any) -> bool | None:
    """True / False for a value that puts an optional part in / leaves it out; None otherwise."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str) and value.strip().lower() in _OFF + _ON:
        return value.strip().lower() in _ON
    return None


def _sub(current: Any, cls: type, optional: bool, path: str, value: Any) -> Any:
    """The section at ``path`` (``current``, possibly None) after ``value``: a table of
    overrides, or (for an optional part) ``none`` / ``default``."""
    switch = _toggle(value)
    if switch is not None and not isinstance(value, dict):
        if not optional:
            raise ConfigError(f"{path} is a section; set its parameters ({path}.name=value)")
        if not switch:
            return None
        return current if current is not None else cls()
    if not isinstance(value, dict):
        raise ConfigError(f"{path} is a section; set its parameters ({path}.name=value)")
    return _replace_section(current if current is not None else cls(), path, value)


def _replace_section(section: Any, path: str, values: dict[str, Any]) -> Any:
    """``section`` (the one at ``path``) with ``values`` applied, sub-sections recursively."""
    cls = type(section)
    hints = typing.get_type_hints(cls)
    subs = sub_sections(cls)
    known = {f.name for f in dataclasses.fields(section)}
    changes = {}
    for key, raw in values.items():
        key = key.replace("-", "_")
        where = f"{path}.{key}" if path else key
        if key not in known:
            has = ", ".join(sorted(known))
            if not path:
                raise ConfigError(f"unknown config section {key!r}; sections: {has}")
            raise ConfigError(f"unknown parameter {where}; {path} has: {has}")
        if key in subs:
            changes[key] = _sub(getattr(section, key), *subs[key], where, raw)
        elif isinstance(raw, dict):
            raise ConfigError(f"{where} is a parameter, not a section; got a table")
        else:
            changes[key] = _coerce(raw, hints[key], where)
    try:
        return dataclasses.replace(section, **changes)
    except ValueError as exc:
        raise ConfigError(_full_path(str(exc), cls, path)) from None


def _full_path(message: str, cls: type, path: str) -> str:
    """A section's validation message (``"<section>.<field> must ..."``) with the section's
    name replaced by its path in the tree."""
    short = getattr(cls, "section", "")
    if not (short and path):
        return message
    return re.sub(rf"(?<![\w.]){re.escape(short)}\.", path + ".", message)


def apply_overrides(cfg: PipelineConfig, overrides: dict[str, Any]) -> PipelineConfig:
    """Return ``cfg`` with ``{section: {param or sub-section: value or table}}`` applied (values
    coerced and validated)."""
    if not isinstance(overrides, dict):
        raise ConfigError("a configuration must be a table of sections")
    for name, values in overrides.items():
        if name.replace("-", "_") in section_names() and not isinstance(values, dict):
            raise ConfigError(
                f"config section {name!r} must be a table of parameters ({name}.param=value)"
            )
    return _replace_section(cfg, "", overrides)


def parse_set(items: list[str]) -> dict[str, Any]:
    """Parse ``["path.param=value", ...]`` into a nested ``{section: {...: value}}`` table; a
    later item wins over an earlier one on the same key."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, value = item.partition("=")
        parts = [p.strip() for p in key.strip().split(".")]
        if not sep or len(parts) < 2 or not all(parts):
            raise ConfigError(f"--set {item!r}: expected section.param=value")
        node = out
        for p in parts[:-1]:
            if not isinstance(node.get(p), dict):
                node[p] = {}
            node = node[p]
        node[parts[-1]] = value.strip()
    return out


def load_config(path: str | Path | None = None, sets: list[str] | None = None) -> PipelineConfig:
    """The configuration: the defaults, then the TOML file ``path``, then the ``--set`` items.

    Parameters
    ----------
    path : str or Path, optional
        A TOML file whose tables follow the tree (``[dual.decider]``, ``[detect.association]``;
        ``appearance = "none"`` in ``[dual]`` leaves a part out).
    sets : list of str, optional
        ``path.param=value`` items, applied after the file, a later one winning.

    Returns
    -------
    PipelineConfig
        Every value coerced to its field's type and checked against its declared range.

    Raises
    ------
    ConfigError
        An unreadable or invalid file, an unknown section or parameter, a value of the wrong
        type or out of range (the message names its full path: ``dual.decider.psr_confident must
        be >= 0; got -1``).

    Examples
    --------
    >>> cfg = load_config(None, ["dual.decider.psr_confident=8", "dual.groups=default"])
    >>> cfg.dual.decider.psr_confident, cfg.dual.groups is not None
    (8.0, True)
    >>> load_config(None, ["dual.appearance=none"]).dual.appearance is None
    True
    """
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
        try:
            cfg = apply_overrides(cfg, data)
        except ConfigError as exc:
            raise ConfigError(f"{p}: {exc}") from None
    if sets:
        cfg = apply_overrides(cfg, parse_set(sets))
    return cfg


def section_to_dict(section: Any) -> Any:
    """Plain nested dict of a section (None for a part left out), for JSON."""
    if section is None:
        return None
    out: dict[str, Any] = {}
    subs = sub_sections(type(section))
    for f in dataclasses.fields(section):
        v = getattr(section, f.name)
        out[f.name] = (
            section_to_dict(v) if f.name in subs else (list(v) if isinstance(v, tuple) else v)
        )
    return out


def config_to_dict(cfg: PipelineConfig, tracker: str | None = None) -> dict[str, Any]:
    """Plain dict of the resolved configuration (for summary.json and the .rrd): every section,
    or with ``tracker`` only the ones that tracker runs with and the recording's."""
    names = (
        section_names() if tracker is None else [TRACKER_SECTIONS.get(tracker, tracker), "rerun"]
    )
    if tracker == "camshift":
        names.insert(1, "opencv")
    return {n: section_to_dict(getattr(cfg, n)) for n in names if hasattr(cfg, n)}
