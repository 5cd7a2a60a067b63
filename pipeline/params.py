"""Declared ranges on configuration fields, and the one validator that checks them.

Every configuration section is a frozen dataclass that derives from :class:`Section` and
declares the range of each numeric or categorical field beside the field itself::

    @dataclass(frozen=True)
    class MeanShiftConfig(Section):
        section = "meanshift"
        max_iterations: int = param(20, ge=1)
        epsilon_px: float = param(0.5, gt=0, le=5)

Construction validates every declared range (:func:`validate`); a section with a rule that
joins several fields (``stop_window >= check_every``) adds it in :meth:`Section.check`.
The range text (:meth:`Range.text`, ``in (0, 5]``) is the one its docstring states, which
the suite checks.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass, field
from typing import Any, ClassVar

__all__ = ["INT_MAX", "Range", "Section", "declared_range", "param", "validate"]

INT_MAX = 2**31 - 1
"""The largest integer parameter: OpenCV and NumPy kernels take 32-bit counts and sizes."""


@dataclass(frozen=True)
class Range:
    """The values a field accepts.

    Parameters
    ----------
    ge, gt, le, lt : float or None
        Lower bound (inclusive ``ge`` or exclusive ``gt``) and upper bound (``le`` or
        ``lt``); None is unbounded.
    odd : bool
        The value must be an odd integer.
    choices : tuple or None
        The value must be one of these (for strings).
    """

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    odd: bool = False
    choices: tuple[Any, ...] | None = None

    def accepts(self, value: Any, integer: bool) -> bool:
        """True when ``value`` lies in the range (an int, not a bool, when ``integer``)."""
        if self.choices is not None:
            return value in self.choices
        if isinstance(value, bool) or not isinstance(value, int | float):
            return False
        if integer and not isinstance(value, int):
            return False
        if isinstance(value, float) and not math.isfinite(value):
            return False
        if integer and abs(value) > INT_MAX:
            return False
        if self.ge is not None and not value >= self.ge:
            return False
        if self.gt is not None and not value > self.gt:
            return False
        if self.le is not None and not value <= self.le:
            return False
        if self.lt is not None and not value < self.lt:
            return False
        return not (self.odd and value % 2 != 1)

    def text(self) -> str:
        """The range as the docstrings write it: ``in [0, 1)``, ``>= 1``, ``one of 'a', 'b'``."""
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        lo = self.ge if self.ge is not None else self.gt
        hi = self.le if self.le is not None else self.lt
        if lo is not None and hi is not None:
            lb = "[" if self.ge is not None else "("
            rb = "]" if self.le is not None else ")"
            return f"in {lb}{_num(lo)}, {_num(hi)}{rb}"
        if lo is not None:
            return f"{'>=' if self.ge is not None else '>'} {_num(lo)}"
        if hi is not None:
            return f"{'<=' if self.le is not None else '<'} {_num(hi)}"
        return "any value"


def _num(v: float) -> str:
    return f"{v:g}"


def param(
    default: Any,
    *,
    ge: float | None = None,
    gt: float | None = None,
    le: float | None = None,
    lt: float | None = None,
    odd: bool = False,
    choices: tuple[Any, ...] | None = None,
) -> Any:
    """A dataclass field with ``default`` and a declared :class:`Range`.

    Examples
    --------
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Demo(Section):
    ...     section = "demo"
    ...     rate: float = param(0.5, ge=0, le=1)
    >>> Demo(rate=2.0)
    Traceback (most recent call last):
    ...
    ValueError: demo.rate must be in [0, 1]; got 2.0
    """
    return field(default=default, metadata={"range": Range(ge, gt, le, lt, odd, choices)})


def declared_range(cls: type, name: str) -> Range | None:
    """The :class:`Range` declared on field ``name`` of the config class ``cls``, or None."""
    for f in dataclasses.fields(cls):
        if f.name == name:
            return f.metadata.get("range")
    raise KeyError(name)


_CHECKS: dict[type, tuple[tuple[str, Range, bool], ...]] = {}


def _checks(cls: type) -> tuple[tuple[str, Range, bool], ...]:
    """``(field, range, integer)`` of every field of ``cls`` that declares a range (computed once
    per class)."""
    out = _CHECKS.get(cls)
    if out is None:
        hints = typing.get_type_hints(cls)
        out = _CHECKS[cls] = tuple(
            (f.name, f.metadata["range"], hints.get(f.name) is int)
            for f in dataclasses.fields(cls)
            if "range" in f.metadata
        )
    return out


def validate(obj: Any) -> None:
    """Check every declared range of the config dataclass instance ``obj``.

    Raises
    ------
    ValueError
        ``"<section>.<field> must be <range>; got <value>"`` for the first field outside
        its range (an integer field also refuses floats, bools and values beyond
        :data:`INT_MAX`; a number field refuses NaN and infinities).
    """
    cls = type(obj)
    for name, r, integer in _checks(cls):
        value = getattr(obj, name)
        if not r.accepts(value, integer):
            kind = "an odd integer " if r.odd else "an integer " if integer else ""
            section = getattr(cls, "section", cls.__name__)
            if _beyond(value):
                need = f"an integer of at most {INT_MAX}" if integer else "a finite number"
                raise ValueError(f"{section}.{name} must be {need}; got {value!r}")
            raise ValueError(f"{section}.{name} must be {kind}{r.text()}; got {value!r}")


def _beyond(value: Any) -> bool:
    """True for a number no field takes, whatever its range: NaN, infinities, integers beyond
    :data:`INT_MAX`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return False
    return not math.isfinite(value) or abs(value) > INT_MAX


class Section:
    """Base of the configuration sections: validation on construction.

    A subclass is a frozen dataclass, sets the class attribute ``section`` to its name in
    ``--set section.param=value`` and TOML tables, declares ranges with :func:`param` and
    may override :meth:`check` for rules that join several fields.
    """

    section: ClassVar[str] = ""

    def __post_init__(self) -> None:
        validate(self)
        self.check()

    def check(self) -> None:
        """Rules over several fields; raise ValueError naming ``section.field``. None by
        default."""
