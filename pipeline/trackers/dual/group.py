"""Targets in mutual occlusion: the merged group's blob, its members' places, and the split.

The paper's multi-target steps 4-9: one level set over the merged blob, started from the
members' positions. If it shows a separate blob for every member, the group splits: blobs
are re-associated globally (colour, plus distance to each prediction) and every member
continues on its own (:func:`pipeline.trackers.dual.single.finish_single`, started on its
blob). Else the group stays merged: the foreground (best colour match) keeps its mean-shift
position, an occluded member is placed by eq. 11 or by its motion state
(``dual.merge_position``), and no model learns while merged.
"""

from __future__ import annotations

import dataclasses
import time

import cv2
import numpy as np

from pipeline.config import PipelineConfig
from pipeline.io.sequence import FramePair
from pipeline.stages import kalman
from pipeline.stages.contour import extract_contour
from pipeline.stages.merge import (
    associate,
    association_cost,
    choose_foreground_stable,
    eq11,
    inside_blob,
    kmeans_shares,
    lookalike_sets,
)
from pipeline.stages.model_update import UpdateDecision
from pipeline.stages.motion import stop
from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual.cues import ColourStep, add_time, match_at
from pipeline.trackers.dual.single import finish_single
from pipeline.trackers.dual.state import DualTarget, GroupMemory
from pipeline.types import BBox, Event, EventKind, TargetResult, TargetStatus


def union(boxes: list[BBox]) -> BBox:
    """The smallest box holding every box of ``boxes``."""
    x0 = min(b.x for b in boxes)
    y0 = min(b.y for b in boxes)
    return BBox(x0, y0, max(b.x2 for b in boxes) - x0, max(b.y2 for b in boxes) - y0)


def main_blob(phi: np.ndarray, box: BBox, origin: tuple[int, int]) -> np.ndarray | None:
    """Mask of the component of ``phi < 0`` with most pixels inside ``box`` (frame px; ``phi``
    starts at ``origin``)."""
    mask = (phi < 0).astype(np.uint8)
    n, labels = cv2.connectedComponents(mask, connectivity=8)
    if n <= 1:
        return None
    u = box.shifted(-origin[0], -origin[1])
    inside = labels[
        max(int(u.y), 0) : max(int(np.ceil(u.y2)), 0),
        max(int(u.x), 0) : max(int(np.ceil(u.x2)), 0),
    ]
    counts = np.bincount(inside.ravel(), minlength=n)
    counts[0] = 0
    best = int(np.argmax(counts))
    return labels == best if counts[best] > 0 else None


def _split(
    frames: FramePair,
    css: list[ColourStep],
    blobs: list[BBox],
    cfg: PipelineConfig,
    mode: str,
    timing: dict[str, float],
) -> dict[int, tuple[DualTarget, TargetResult, list[Event]]]:
    """Every member re-associated with a blob (Hungarian on colour and distance) and continued on
    its own."""
    dcfg: DualConfig = cfg.dual
    mmf = cfg.meanshift.min_mass_fraction
    ids = tuple(cs.t.id for cs in css)
    rho = np.full((len(css), len(blobs)), np.nan)
    dist = np.zeros((len(css), len(blobs)))
    scale = np.array([np.hypot(*cs.t.size) for cs in css])
    for i, cs in enumerate(css):
        for j, b in enumerate(blobs):
            if cs.informative and cs.bins is not None:
                rho[i, j] = match_at(cs.bins, cs.t.q, b, cs.roi0, mmf)
            dist[i, j] = np.hypot(b.cx - cs.y0[0], b.cy - cs.y0[1])
    pairs = associate(association_cost(rho, dist, scale, dcfg.association_motion_weight))
    text = ", ".join(
        f"T{css[i].t.id}->blob at ({blobs[j].cx:.0f},{blobs[j].cy:.0f})" for i, j in pairs
    )
    out = {}
    for i, j in pairs:
        cs = css[i]
        ev = (
            [
                Event(
                    EventKind.SPLIT,
                    f"T{cs.t.id} split from {'+'.join(f'T{k}' for k in ids)}; re-associated: {text}",
                    (cs.t.id,),
                )
            ]
            if i == pairs[0][0]
            else []
        )
        t = dataclasses.replace(cs.t, memory=None, status=TargetStatus.OCCLUDED_PARTIAL)
        out[cs.t.id] = finish_single(
            frames,
            dataclasses.replace(cs, t=t),
            cfg,
            mode,
            timing,
            start=blobs[j].center,
            events_in=ev,
            neighbours=tuple(blobs[k] for _, k in pairs if k != j),
        )
    return out


def _placements(
    css: list[ColourStep], c, box: BBox, fg_id: int, group_ok: bool, dcfg: DualConfig
) -> dict[int, tuple[tuple[float, float], str]]:
    """``auto``: look-alikes located by k-means on the blob; any other member whose own colour is
    clearly seen (and not where a better-matching member already is) at its mean shift."""
    placed: dict[int, tuple[tuple[float, float], str]] = {}
    alike = {
        i
        for g in lookalike_sets(
            {cs.t.id: cs.t.q for cs in css if cs.informative}, dcfg.lookalike_rho
        )
        for i in g
    }
    if alike and group_ok and c.box is not None and c.memory is not None:
        mask = main_blob(c.memory.phi, box, c.memory.origin)
        members = [cs for cs in css if cs.t.id in alike]
        if mask is not None:
            cents = kmeans_shares(
                mask,
                c.memory.origin,
                [(float(cs.prior.x[0]), float(cs.prior.x[1])) for cs in members],
                [cs.t.reference_size for cs in members],
                dcfg.kmeans_iterations,
            )
            for cs, cen in zip(members, cents, strict=True):
                if cen is not None:
                    placed[cs.t.id] = (cen, "merge-kmeans")
    near = 0.5 * min(cs.t.size[0] for cs in css)
    for cs in sorted(css, key=lambda cs: -cs.rho1 if cs.informative else 1.0):
        if (
            cs.t.id in placed
            or not cs.informative
            or (cs.t.id != fg_id and cs.rho1 < dcfg.merge_visible_rho)
        ):
            continue
        if all(np.hypot(cs.y1[0] - p[0], cs.y1[1] - p[1]) > near for p, _ in placed.values()):
            placed[cs.t.id] = (cs.y1, "merge-foreground" if cs.t.id == fg_id else "merge-visible")
    return placed


def finish_group(
    frames: FramePair,
    css: list[ColourStep],
    cfg: PipelineConfig,
    mode: str,
    timing: dict[str, float],
    memories: tuple[GroupMemory, ...],
):
    """One merged group this frame (module doc): ({id: (new state, result, events)}, the group's
    level set or None)."""
    dcfg: DualConfig = cfg.dual
    kcfg = cfg.kalman
    ir = frames.infrared
    assert ir is not None
    clock = time.perf_counter()
    ids = tuple(cs.t.id for cs in css)
    box = union(
        [cs.box1 for cs in css]
        + [cs.box_prior for cs in css if cs.t.status == TargetStatus.MERGED]
    )
    group_cfg = dataclasses.replace(cfg.contour, max_area_ratio=50.0, max_dimension_ratio=50.0)
    prev = next((m for m in memories if m.members == ids), None)
    shift = (box.cx - prev.center[0], box.cy - prev.center[1]) if prev else (0.0, 0.0)
    c = extract_contour(
        ir,
        box,
        group_cfg,
        cfg.levelset,
        prev.memory if prev else None,
        shift,
        cold_init=box.scaled(1.15),
        part_width=min(cs.t.size[0] for cs in css),
    )
    clock = add_time(timing, "levelset", clock)
    min_area = dcfg.split_min_area_fraction * min(cs.t.reference_area for cs in css)
    blobs = [
        b for b in c.components if b.area >= min_area and b.intersect(box.scaled(1.2)).area > 0
    ]
    if len(blobs) >= len(css):  # split: every member has its own blob again
        return _split(frames, css, blobs, cfg, mode, timing), None

    # still merged; a group contour without contrast (leaked into the background) places nobody
    was_merged = all(cs.t.status == TargetStatus.MERGED for cs in css)
    group_ok = c.box is not None and abs(c.contrast) >= cfg.contour.min_contrast
    y2 = c.box.center if c.box is not None else box.center
    fg_id = choose_foreground_stable(
        {cs.t.id: cs.rho1 if cs.informative else float("nan") for cs in css},
        prev.foreground if prev else None,
        dcfg.role_margin,
        {cs.t.id: float(np.hypot(cs.y1[0] - y2[0], cs.y1[1] - y2[1])) for cs in css},
    )
    fg = next(cs for cs in css if cs.t.id == fg_id)
    Hm, Rm = kalman.measurement_model(kcfg)
    blob_wider = group_ok and c.box is not None and c.box.w > 1.2 * fg.t.size[0]
    blob_ratio = (
        c.box.area / sum(cs.t.reference_area for cs in css) if c.box is not None else float("nan")
    )
    events: list[Event] = []
    if not was_merged:
        roles = ", ".join(
            f"T{cs.t.id} {'foreground' if cs.t.id == fg_id else 'occluded'}" for cs in css
        )
        events.append(
            Event(EventKind.MERGE, f"{'+'.join(f'T{k}' for k in ids)} merged ({roles})", ids)
        )
    elif prev is not None and prev.foreground != fg_id:
        events.append(
            Event(
                EventKind.MERGE,
                f"T{fg_id} now in front of {'+'.join(f'T{k}' for k in ids if k != fg_id)}",
                ids,
            )
        )
    placed = (
        _placements(css, c, box, fg_id, group_ok, dcfg) if dcfg.merge_position == "auto" else {}
    )
    out: dict[int, tuple[DualTarget, TargetResult, list[Event]]] = {}
    for cs in css:
        t = cs.t
        ref = t.reference_size
        missing_n = 0
        if t.id in placed:
            y, source = placed[t.id]
        elif t.id == fg_id:
            y, source = cs.y1, "merge-foreground"
        elif len(css) == 2 and (
            dcfg.merge_position == "eq11" or (dcfg.merge_position == "auto" and blob_wider)
        ):
            y, source = eq11(y2, fg.y1), "merge-eq11"
            if c.box is not None:  # the mirrored position stays inside the blob it was mirrored in
                y = inside_blob(y, ref, c.box)
        else:
            y, source = (float(cs.prior.x[0]), float(cs.prior.x[1])), "merge-motion"
            if dcfg.merge_inside_blob and group_ok and c.box is not None:
                y = inside_blob(
                    y, ref, c.box
                )  # reported inside the blob; the motion state is left as it is
        out_box = BBox.from_center(y[0], y[1], ref[0], ref[1])
        if source == "merge-motion":
            kf = cs.prior
            missing_n = t.missing + 1
        else:
            kf = kalman.correct(cs.prior, kalman.box_measurement(out_box), Hm, Rm, kcfg).state
        status = TargetStatus.LOST if missing_n > dcfg.max_missing_frames else TargetStatus.MERGED
        if status == TargetStatus.LOST:
            kf = stop(kf)
            if t.status != TargetStatus.LOST:
                events.append(
                    Event(
                        EventKind.LOST,
                        f"T{t.id} lost (hidden in a merge for {missing_n} frames)",
                        (t.id,),
                    )
                )
        update = UpdateDecision(False, "merged")
        nt = dataclasses.replace(
            t,
            box=out_box,
            status=status,
            kf=kf,
            memory=None,
            missing=missing_n,
            last_update=str(update),
            case="merged",
        )
        diag = {
            "rho_y1": cs.rho1,
            "role": 1.0 if t.id == fg_id else 2.0,
            "group_size": float(len(css)),
            "contrast": c.contrast,
            "blob_area_ratio": blob_ratio,
            "components": float(len(c.components)),
            "missing": float(missing_n),
        }
        res = TargetResult(
            t.id,
            out_box,
            status,
            source,
            {"meanshift": cs.ms_iters, "levelset": c.iterations},
            cs.rho1,
            str(update),
            0.7 if t.id == fg_id else 0.4,
            c.contour if t.id == fg_id else (),
            diag,
            {"prediction": cs.prior.box, "meanshift": cs.box1},
            decision=f"merged:{source.removeprefix('merge-')}",
        )
        out[t.id] = (nt, res, events if t.id == fg_id else [])
    add_time(timing, "merge", clock)
    mem = GroupMemory(ids, c.memory, box.center, fg_id) if c.box is not None else None
    return out, mem
