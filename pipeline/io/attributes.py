"""Challenge attributes of sequences (occlusion, low illumination, ...) for per-attribute reports.

Where a sequence's attributes come from, first that applies:

* ``scene.json`` with an ``attributes`` list (our synthetic scenes, named and random alike, in
  RGBT234's codes; LasHeR's ``OV`` for out of view);
* per-frame tag files ``<seq>/*.tag`` (VOT style, one 0/1 or label per frame line): the
  file's stem is the attribute, which the sequence has if any frame carries it;
* a table at the archive root, ``sequencesAttr.txt`` (GTOT toolkit) or ``attributes.txt``
  / ``attributes.csv``: one row per sequence, its name first, then 0/1 flags, separated by
  spaces, tabs or commas. A header row (``name A B C ...``) names the columns; without one,
  8 flags are read in GTOT's order (OCC LSV FM LI HI TC SO DEF), 12 in RGBT234's (NO PO HO LI
  LR TC DEF FM SV MB CM BC) and 19 in LasHeR's.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

GTOT_ATTRIBUTES = ("OCC", "LSV", "FM", "LI", "HI", "TC", "SO", "DEF")
RGBT234_ATTRIBUTES = ("NO", "PO", "HO", "LI", "LR", "TC", "DEF", "FM", "SV", "MB", "CM", "BC")
LASHER_ATTRIBUTES = (
    "NO",
    "PO",
    "TO",
    "HO",
    "MB",
    "LI",
    "HI",
    "AIV",
    "LR",
    "DEF",
    "BC",
    "SA",
    "CM",
    "TC",
    "FL",
    "OV",
    "FM",
    "SV",
    "ARC",
)
ROOT_TABLES = ("sequencesAttr.txt", "attributes.txt", "attributes.csv")
_SPLIT = re.compile(r"[,\s]+")


def read_root_table(root: Path) -> dict[str, tuple[str, ...]]:
    """Attributes per sequence name from an archive-root table (empty when there is none)."""
    for fname in ROOT_TABLES:
        f = root / fname
        if f.is_file():
            break
    else:
        return {}
    out: dict[str, tuple[str, ...]] = {}
    names: tuple[str, ...] | None = None
    for line in f.read_text(errors="replace").splitlines():
        parts = [p for p in _SPLIT.split(line.strip()) if p]
        if len(parts) < 2:
            continue
        flags = parts[1:]
        if not all(re.fullmatch(r"[01](\.0*)?", v) for v in flags):
            if names is None:  # a header row
                names = tuple(flags)
            continue
        cols = names or {8: GTOT_ATTRIBUTES, 12: RGBT234_ATTRIBUTES, 19: LASHER_ATTRIBUTES}.get(
            len(flags)
        )
        if cols is None or len(cols) != len(flags):
            continue
        out[parts[0]] = tuple(c for c, v in zip(cols, flags, strict=True) if float(v) > 0)
    return out


def sequence_attributes(
    seq_dir: Path, root_table: dict[str, tuple[str, ...]] | None = None
) -> tuple[str, ...]:
    """The attributes of one sequence folder (see the module doc); () when nothing says."""
    meta = seq_dir / "scene.json"
    if meta.is_file():
        try:
            attrs = json.loads(meta.read_text()).get("attributes")
        except (ValueError, OSError):
            attrs = None
        if isinstance(attrs, list):
            return tuple(str(a) for a in attrs)
    tags = []
    for f in sorted(seq_dir.glob("*.tag")):
        lines = [ln.strip() for ln in f.read_text(errors="replace").splitlines()]
        if any(ln and ln not in ("0", "0.0") for ln in lines):
            tags.append(f.stem)
    if tags:
        return tuple(tags)
    if root_table:
        return root_table.get(seq_dir.name, ())
    return ()
