"""The dual tracker's group handling: targets in mutual occlusion (the paper's multi-target steps
4-9, eq. 10-11).

The eq. 10 merge test on the mean-shift positions joins targets into groups
(:meth:`GroupHandler.groups`). One level set runs over a group's blob, started from its
members' positions (:meth:`GroupHandler.blob`). If it shows a separate component for every
member, the group splits: the components are re-associated globally (colour, plus distance to
each prediction; :meth:`GroupHandler.split`) and every member continues on its own, started on
its component. Else the group stays merged: the foreground (best colour match) keeps its
mean-shift position, an occluded member is placed by eq. 11 or by its motion
(:meth:`GroupHandler.place`, a rule of :class:`~pipeline.trackers.dual.decide.Rule` each), and
no model learns while merged.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.stages.contour import ContourResult
from pipeline.stages.merge import (
    associate,
    association_cost,
    choose_foreground_stable,
    eq11,
    inside_blob,
    kmeans_shares,
    lookalike_sets,
    merge_groups,
)
from pipeline.tracker_config import GroupConfig
from pipeline.trackers.dual.colour import ColourCue, ColourStep
from pipeline.trackers.dual.contour import ContourCue
from pipeline.trackers.dual.decide import Rule
from pipeline.trackers.dual.state import GroupMemory
from pipeline.types import BBox, Event, EventKind, TargetStatus

Placement = tuple[tuple[float, float], Rule]


def union(boxes: list[BBox]) -> BBox:
    """The smallest box holding every box of ``boxes``.

    Examples
    --------
    >>> union([BBox(0, 0, 10, 10), BBox(5, 8, 10, 10)])
    BBox(x=0, y=0, w=15, h=18)
    """
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
    rows = slice(max(int(u.y), 0), max(int(np.ceil(u.y2)), 0))
    cols = slice(max(int(u.x), 0), max(int(np.ceil(u.x2)), 0))
    counts = np.bincount(labels[rows, cols].ravel(), minlength=n)
    counts[0] = 0
    best = int(np.argmax(counts))
    return labels == best if counts[best] > 0 else None


def live_boxes(steps: dict[int, ColourStep]) -> dict[int, BBox]:
    """Each target's box this frame as the others see it (the merge test, the neighbours of the
    colour extent): its mean-shift position, or its prediction for a member of a merge (its mean
    shift may sit on whoever hides it, a look-alike above all, and would hold the group
    together); lost targets take no part."""
    return {
        i: cs.box_prior if cs.t.status == TargetStatus.MERGED else cs.box1
        for i, cs in steps.items()
        if cs.t.status != TargetStatus.LOST
    }


@dataclass(frozen=True)
class GroupBlob:
    """One frame of a merged group: its members' colour steps, the union of their boxes, the
    level set over it, and the group's memory from the previous frame."""

    css: tuple[ColourStep, ...]
    box: BBox
    contour: ContourResult
    prev: GroupMemory | None

    @property
    def ids(self) -> tuple[int, ...]:
        return tuple(cs.t.id for cs in self.css)

    @property
    def center(self) -> tuple[float, float]:
        """The blob's centre (eq. 11's y2), or the union's without a contour."""
        c = self.contour
        return c.box.center if c.box is not None else self.box.center


@dataclass(frozen=True)
class Roles:
    """Who is in front in a merged group this frame, and what the blob shows."""

    foreground: int
    group_ok: bool  # the group's contour has contrast: it may place members
    blob_wider: bool  # the blob is wider than the foreground (eq. 11 places the other)
    blob_ratio: float  # the blob's area over the members' usual areas


@dataclass(frozen=True)
class GroupHandler:
    """Merge test, the group's blob, the split and the members' places.

    Parameters
    ----------
    cfg : GroupConfig
        ``dual.groups``.
    """

    cfg: GroupConfig

    def groups(
        self, steps: dict[int, ColourStep], live: dict[int, BBox], frame: int
    ) -> list[tuple[int, ...]]:
        """Eq. 10 over ``live``: the groups of two or more targets (sorted ids); a target split
        from a group in the last ``split_hold_frames`` merges again only on a deep overlap."""
        if len(live) < 2:
            return []
        held = {
            i for i, cs in steps.items() if frame - cs.t.split_frame <= self.cfg.split_hold_frames
        }
        return merge_groups(live, held, self.cfg.remerge_scale)

    def blob(
        self,
        contour: ContourCue,
        ir: np.ndarray,
        css: list[ColourStep],
        memories: tuple[GroupMemory, ...],
    ) -> GroupBlob:
        """One level set over the union of the members' boxes (and the predictions of those
        already merged), warm-started from the group's last one."""
        ids = tuple(cs.t.id for cs in css)
        merged = [cs.box_prior for cs in css if cs.t.status == TargetStatus.MERGED]
        box = union([cs.box1 for cs in css] + merged)
        prev = next((m for m in memories if m.members == ids), None)
        shift = (box.cx - prev.center[0], box.cy - prev.center[1]) if prev else (0.0, 0.0)
        c = contour.group(
            ir,
            box,
            prev.memory if prev else None,
            shift,
            self.cfg.blob_cold_start_scale,
            self.cfg.blob_max_ratio,
            min(cs.t.size[0] for cs in css),
        )
        return GroupBlob(tuple(css), box, c, prev)

    def parts(self, g: GroupBlob) -> list[BBox]:
        """The blob's components large enough to be a member (``split_min_area_fraction`` of the
        smallest usual box) that meet the group: a split when there is one for every member."""
        min_area = self.cfg.split_min_area_fraction * min(cs.t.reference_area for cs in g.css)
        near = g.box.scaled(self.cfg.blob_margin_scale)
        return [
            b for b in g.contour.components if b.area >= min_area and b.intersect(near).area > 0
        ]

    def split(
        self, colour: ColourCue, g: GroupBlob, blobs: list[BBox]
    ) -> list[tuple[ColourStep, BBox, tuple[BBox, ...], list[Event]]]:
        """Every member re-associated with a component (Hungarian on colour and distance):
        ``(member, its component, the other components, events)``; the split's event goes with
        the first member."""
        css = g.css
        rho = np.full((len(css), len(blobs)), np.nan)
        dist = np.zeros((len(css), len(blobs)))
        scale = np.array([np.hypot(*cs.t.size) for cs in css])
        for i, cs in enumerate(css):
            for j, b in enumerate(blobs):
                rho[i, j] = colour.match_at(cs, b)
                dist[i, j] = np.hypot(b.cx - cs.y0[0], b.cy - cs.y0[1])
        pairs = associate(association_cost(rho, dist, scale, self.cfg.association_motion_weight))
        text = ", ".join(
            f"T{css[i].t.id}->blob at ({blobs[j].cx:.0f},{blobs[j].cy:.0f})" for i, j in pairs
        )
        members = "+".join(f"T{k}" for k in g.ids)
        out = []
        for i, j in pairs:
            tid = css[i].t.id
            ev = []
            if i == pairs[0][0]:
                split = f"T{tid} split from {members}; re-associated: {text}"
                ev = [Event(EventKind.SPLIT, split, g.ids)]
            others = tuple(blobs[k] for _, k in pairs if k != j)
            out.append((css[i], blobs[j], others, ev))
        return out

    def roles(self, g: GroupBlob, group_ok: bool) -> Roles:
        """The foreground (best colour match, keeping its role within ``role_margin``) and what
        the blob shows."""
        css, c, y2 = g.css, g.contour, g.center
        rhos = {cs.t.id: cs.rho1 if cs.informative else float("nan") for cs in css}
        dists = {cs.t.id: float(np.hypot(cs.y1[0] - y2[0], cs.y1[1] - y2[1])) for cs in css}
        prev_fg = g.prev.foreground if g.prev else None
        fg_id = choose_foreground_stable(rhos, prev_fg, self.cfg.role_margin, dists)
        fg_width = next(cs.t.size[0] for cs in css if cs.t.id == fg_id)
        if c.box is None:
            return Roles(fg_id, group_ok, False, float("nan"))
        wider = group_ok and c.box.w > self.cfg.wider_ratio * fg_width
        return Roles(fg_id, group_ok, wider, c.box.area / sum(cs.t.reference_area for cs in css))

    def merge_events(self, g: GroupBlob, roles: Roles) -> list[Event]:
        """The group's event of a new foreground (each member's move into the group is its own
        status event, :meth:`Lifecycle.joined`)."""
        ids, fg_id = g.ids, roles.foreground
        if not all(cs.t.status == TargetStatus.MERGED for cs in g.css):
            return []
        if g.prev is not None and g.prev.foreground != fg_id:
            behind = "+".join(f"T{k}" for k in ids if k != fg_id)
            return [Event(EventKind.MERGE, f"T{fg_id} now in front of {behind}", ids)]
        return []

    def placements(self, g: GroupBlob, roles: Roles) -> dict[int, Placement]:
        """With ``merge_position = "auto"``: look-alikes located by k-means on the blob; any
        other member whose own colour is clearly seen (and not where a better-matching member
        already is) at its mean shift."""
        if self.cfg.merge_position != "auto":
            return {}
        placed = self._lookalikes(g, roles)
        near = 0.5 * min(cs.t.size[0] for cs in g.css)
        for cs in sorted(g.css, key=lambda cs: -cs.rho1 if cs.informative else 1.0):
            if cs.t.id in placed or not self._seen(cs, roles):
                continue
            if all(np.hypot(cs.y1[0] - p[0], cs.y1[1] - p[1]) > near for p, _ in placed.values()):
                fg = cs.t.id == roles.foreground
                placed[cs.t.id] = (cs.y1, Rule.MERGE_FOREGROUND if fg else Rule.MERGE_VISIBLE)
        return placed

    def _seen(self, cs: ColourStep, roles: Roles) -> bool:
        """A member whose colour places it: the foreground, or one at ``merge_visible_rho``."""
        if not cs.informative:
            return False
        return cs.t.id == roles.foreground or cs.rho1 >= self.cfg.merge_visible_rho

    def _lookalikes(self, g: GroupBlob, roles: Roles) -> dict[int, Placement]:
        """Members whose colour models are alike, placed by k-means on the blob's pixels."""
        c = g.contour
        members = self._alike(g.css)
        if not (members and roles.group_ok) or c.box is None or c.memory is None:
            return {}
        mask = main_blob(c.memory.phi, g.box, c.memory.origin)
        if mask is None:
            return {}
        priors = [(float(cs.prior.x[0]), float(cs.prior.x[1])) for cs in members]
        sizes = [cs.t.reference_size for cs in members]
        cents = kmeans_shares(mask, c.memory.origin, priors, sizes, self.cfg.kmeans_iterations)
        placed = zip(members, cents, strict=True)
        return {cs.t.id: (cen, Rule.MERGE_KMEANS) for cs, cen in placed if cen is not None}

    def _alike(self, css: tuple[ColourStep, ...]) -> list[ColourStep]:
        """The members whose colour models match another's by ``lookalike_rho``."""
        models = {cs.t.id: cs.t.q for cs in css if cs.informative}
        alike = {i for grp in lookalike_sets(models, self.cfg.lookalike_rho) for i in grp}
        return [cs for cs in css if cs.t.id in alike]

    def place(
        self, cs: ColourStep, g: GroupBlob, roles: Roles, placed: dict[int, Placement]
    ) -> Placement:
        """Where a member of a merged group is this frame, and by which rule: a placement,
        the foreground's mean shift, eq. 11 (a pair, with ``eq11`` or the blob wider than the
        foreground), else its motion (inside the blob with ``inside_blob``)."""
        tid, c, ref = cs.t.id, g.contour, cs.t.reference_size
        if tid in placed:
            return placed[tid]
        if tid == roles.foreground:
            return cs.y1, Rule.MERGE_FOREGROUND
        if self._mirrored(g, roles):
            fg = next(m for m in g.css if m.t.id == roles.foreground)
            y = eq11(g.center, fg.y1)
            # the mirrored position stays inside the blob it was mirrored in
            return (inside_blob(y, ref, c.box) if c.box is not None else y), Rule.MERGE_EQ11
        y = (float(cs.prior.x[0]), float(cs.prior.x[1]))
        if self.cfg.inside_blob and roles.group_ok and c.box is not None:
            # reported inside the blob; the motion state is left as it is
            y = inside_blob(y, ref, c.box)
        return y, Rule.MERGE_MOTION

    def _mirrored(self, g: GroupBlob, roles: Roles) -> bool:
        """Eq. 11 places the hidden member of a pair: always with ``eq11``, while the blob is
        wider than the foreground with ``auto``."""
        pos = self.cfg.merge_position
        return len(g.css) == 2 and (pos == "eq11" or (pos == "auto" and roles.blob_wider))

    def confidence(self, foreground: bool) -> float:
        """``conf`` of a merged member: the foreground's, or a hidden member's."""
        return self.cfg.confidence_foreground if foreground else self.cfg.confidence_hidden

    @staticmethod
    def diagnostics(cs: ColourStep, g: GroupBlob, roles: Roles, missing: int) -> dict[str, float]:
        """A merged member's ``targets.csv`` diagnostics."""
        c = g.contour
        return {
            "rho_y1": cs.rho1,
            "role": 1.0 if cs.t.id == roles.foreground else 2.0,
            "group_size": float(len(g.css)),
            "contrast": c.contrast,
            "blob_area_ratio": roles.blob_ratio,
            "components": float(len(c.components)),
            "missing": float(missing),
        }
