"""The declared ranges of the configuration sections and the one validator over them."""

from __future__ import annotations

import dataclasses
import re
import typing

import pytest

from pipeline.config import load_config, sub_sections, walk_sections
from pipeline.errors import ConfigError
from pipeline.params import Range, Section, param

_TREE = walk_sections(load_config(None, ["dual.groups=default"]))
SECTIONS = sorted({(type(s).section, type(s)) for _, s in _TREE}, key=lambda x: x[1].__name__)
"""Every section class of the configuration tree, with its own name."""


def _doc_entries(doc: str) -> dict[str, str]:
    """numpydoc ``name : type`` entries of a class docstring, their text on one line."""
    out: dict[str, str] = {}
    cur = None
    for line in doc.splitlines():
        m = re.match(r"^    ([a-z_0-9]+) : ", line)
        if m:
            cur = m.group(1)
            out[cur] = ""
        elif cur and line.startswith("        "):
            out[cur] += " " + line.strip()
        elif line.strip():
            cur = None
    return out


def test_range_accepts_and_text_on_small_cases():
    r = Range(ge=0, lt=1)
    assert r.text() == "in [0, 1)"
    assert r.accepts(0, integer=False) and r.accepts(0.999, integer=False)
    assert not r.accepts(1.0, integer=False) and not r.accepts(-1e-9, integer=False)
    assert not r.accepts(float("nan"), integer=False) and not r.accepts(True, integer=False)
    assert Range(gt=1).text() == "> 1" and Range(le=5).text() == "<= 5"
    odd = Range(ge=3, le=31, odd=True)
    assert (
        odd.accepts(7, integer=True)
        and not odd.accepts(8, integer=True)
        and not odd.accepts(7.0, integer=True)
    )
    assert Range(choices=("a", "b")).text() == "one of 'a', 'b'"
    assert not Range(choices=("a", "b")).accepts("c", integer=False)


def test_a_section_reports_the_field_and_its_range():
    @dataclasses.dataclass(frozen=True)
    class Demo(Section):
        section = "demo"
        count: int = param(3, ge=1)
        rate: float = param(0.5, gt=0, le=1)

    assert Demo().count == 3
    with pytest.raises(ValueError, match=r"^demo\.count must be an integer >= 1; got 0$"):
        Demo(count=0)
    with pytest.raises(ValueError, match=r"^demo\.count must be an integer >= 1; got 2\.0$"):
        Demo(count=2.0)
    with pytest.raises(ValueError, match=r"^demo\.rate must be in \(0, 1\]; got 0$"):
        Demo(rate=0)


@pytest.mark.parametrize("name, cls", SECTIONS)
def test_every_field_is_documented_and_its_range_is_the_documented_one(name, cls):
    assert issubclass(cls, Section) and cls.section == name
    entries = _doc_entries(cls.__doc__)
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if f.name in sub_sections(cls):
            assert f.name in entries, f"{name}.{f.name} is not in the {cls.__name__} docstring"
            continue
        assert f.name in entries, f"{name}.{f.name} is not in the {cls.__name__} docstring"
        r = f.metadata.get("range")
        if hints[f.name] in (int, float):
            assert r is not None, f"{name}.{f.name} declares no range"
        if r is None:
            continue
        text = re.sub(r"\s+", " ", entries[f.name])
        if r.choices is not None:
            for c in r.choices:
                assert f"``{c}``" in text, f"{name}.{f.name}: choice {c!r} not documented"
        elif r.text() != "any value":
            assert r.text() in text, f"{name}.{f.name}: the docstring does not say {r.text()!r}"


def _outside(r: Range, default):
    """Values just outside each declared bound of ``r``."""
    if r.choices is not None:
        return ["not-a-choice"]
    out = []
    if r.ge is not None:
        out.append(type(default)(r.ge) - 1 if isinstance(default, int) else r.ge - 1e-6)
    if r.gt is not None:
        out.append(type(default)(r.gt) if isinstance(default, int) else r.gt)
    if r.le is not None:
        out.append(type(default)(r.le) + 1 if isinstance(default, int) else r.le + 1e-6)
    if r.lt is not None:
        out.append(type(default)(r.lt) if isinstance(default, int) else r.lt)
    if r.odd:
        out.append(default + 1)
    return out


@pytest.mark.parametrize("name, cls", SECTIONS)
def test_defaults_pass_and_each_bound_refuses_the_value_beyond_it(name, cls):
    cls()  # the defaults lie in range
    for f in dataclasses.fields(cls):
        r = f.metadata.get("range")
        if r is None:
            continue
        for bad in _outside(r, f.default):
            with pytest.raises(ValueError, match=rf"^{name}\.{f.name} must be "):
                cls(**{f.name: bad})


def test_the_cli_path_names_the_parameter_and_the_range():
    with pytest.raises(
        ConfigError,
        match=r"^dual\.histogram\.hue_bins must be an integer in \[2, 180\]; got 1$",
    ):
        load_config(sets=["dual.histogram.hue_bins=1"])
    with pytest.raises(
        ConfigError,
        match=r"^dual\.appearance\.scale_count must be an odd integer in \[3, 33\]; got 4$",
    ):
        load_config(sets=["dual.appearance.scale_count=4"])
    with pytest.raises(
        ConfigError,
        match=r"^dual\.groups\.merge_position must be one of 'auto', 'eq11', 'motion'",
    ):
        load_config(sets=["dual.groups.merge_position=x"])


@pytest.mark.parametrize("path", [p for p, s in _TREE if dataclasses.fields(s)])
def test_every_path_of_the_tree_names_itself_in_its_errors(path):
    """Each section, wherever it sits in the tree, reports a bad value with its full path."""
    sec = dict(_TREE)[path]
    hints = typing.get_type_hints(type(sec))
    for f in dataclasses.fields(sec):
        r = f.metadata.get("range")
        if r is None or hints[f.name] not in (int, float):
            continue
        bad = _outside(r, f.default)[0]
        with pytest.raises(ConfigError, match=rf"^{path.replace('.', chr(92) + '.')}\.{f.name} "):
            load_config(sets=[f"{path}.{f.name}={bad}"])
        return
    pytest.skip(f"{path} has no numeric field with a range")


def test_rules_over_several_fields_still_hold():
    with pytest.raises(ConfigError, match=r"must be < 0\.25 for stability"):
        load_config(sets=["dual.levelset.timestep=9"])
    with pytest.raises(ConfigError, match=r"detect\.association\.confirm_hits"):
        load_config(sets=["detect.association.confirm_hits=9"])
    with pytest.raises(ConfigError, match=r"detect\.detection\.perimeter_px"):
        load_config(sets=["detect.detection.perimeter_px=50,40"])
