"""Reading an .rrd back with pyarrow only (rerun.md §5a), for tests."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc
from rerun.chunk import RrdReader


def open_store(path: str | Path):
    """The recording's store; a recording without footer (a killed run) is read as a stream, as the
    viewer does."""
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="RRD file has no footer")
        reader = RrdReader(str(path))
    rec = reader.recordings()[0]  # the blueprint store is separate
    try:
        return reader.store(store=rec)
    except RuntimeError:  # "Legacy RRD without footer"
        return reader.stream(store=rec).collect()


def rows(store, entity: str, components: list[str], timeline: str = "frame") -> pa.Table:
    parts = []
    for chunk in store.stream().filter(content=entity).to_chunks():
        rb = chunk.to_record_batch()
        have = [c for c in components if c in rb.schema.names]
        if have and not chunk.is_static and timeline in rb.schema.names:
            parts.append(pa.Table.from_batches([rb]).select([timeline, *have]))
    if not parts:
        return pa.table({timeline: pa.array([], pa.int64())})
    return pa.concat_tables(parts, promote_options="default").sort_by(timeline)


def boxes_at(store, entity: str, frame: int) -> dict[str, np.ndarray] | None:
    """Boxes of ``entity`` logged at ``frame``: mins, sizes (x, y, w, h px), class ids, labels."""
    t = rows(
        store,
        entity,
        ["Boxes2D:centers", "Boxes2D:half_sizes", "Boxes2D:class_ids", "Boxes2D:labels"],
    )
    if t.num_rows == 0:
        return None
    sel = t.filter(pc.equal(t["frame"], frame)).to_pylist()
    if not sel:
        return None
    r = sel[-1]
    c = np.asarray(r["Boxes2D:centers"] or [], float).reshape(-1, 2)
    h = np.asarray(r["Boxes2D:half_sizes"] or [], float).reshape(-1, 2)
    return {
        "mins": c - h,
        "sizes": 2 * h,
        "class_ids": list(r.get("Boxes2D:class_ids") or []),
        "labels": list(r.get("Boxes2D:labels") or []),
    }


def blob_at(store, entity: str, frame: int) -> bytes | None:
    t = rows(store, entity, ["EncodedImage:blob"])
    sel = t.filter(pc.equal(t["frame"], frame)).to_pylist()
    if not sel:
        return None
    blob = sel[-1]["EncodedImage:blob"]
    if isinstance(blob, list):
        blob = blob[0]
    return bytes(blob)


def texts(store, entity: str) -> list[tuple[int, str]]:
    t = rows(store, entity, ["TextLog:text"])
    return [
        (
            r["frame"],
            r["TextLog:text"][0] if isinstance(r["TextLog:text"], list) else r["TextLog:text"],
        )
        for r in t.to_pylist()
    ]
