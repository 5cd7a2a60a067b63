"""The dual tracker as a composition of parts, and its frame: every target's cues, the merge
test, then each group and each single target."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.stages import appearance as app_stage
from pipeline.stages import contour as contour_stage
from pipeline.stages import detection as detection_stage
from pipeline.stages import extent as extent_stage
from pipeline.stages import kalman as kalman_stage
from pipeline.stages import meanshift as meanshift_stage
from pipeline.stages import model_update as model_update_stage
from pipeline.stages.contour import ContourResult
from pipeline.stages.detection import DetectionConfig
from pipeline.stages.model_update import UpdateDecision
from pipeline.tracker_config import DualConfig
from pipeline.trackers.dual import single
from pipeline.trackers.dual.appearance import AppearanceCue
from pipeline.trackers.dual.colour import ColourCue, ColourStep, add_time
from pipeline.trackers.dual.contour import ContourCue
from pipeline.trackers.dual.decide import Case, Decider, Rule
from pipeline.trackers.dual.group import GroupBlob, GroupHandler, Roles, live_boxes
from pipeline.trackers.dual.lifecycle import Lifecycle
from pipeline.trackers.dual.motion import Motion
from pipeline.trackers.dual.redetect import Redetector
from pipeline.trackers.dual.size import ExtentCue, SizeModel
from pipeline.trackers.dual.state import BackgroundSource, DualState, DualTarget, GroupMemory
from pipeline.types import (
    BBox,
    DecisionLabel,
    Event,
    FrameResult,
    InitTarget,
    TargetResult,
    TargetStatus,
)

Done = tuple[DualTarget, TargetResult, list[Event]]
"""A target's new state, its result and its events this frame."""


def _rivals(
    i: int, live: dict[int, BBox], steps: dict[int, ColourStep]
) -> tuple[tuple[BBox, np.ndarray], ...]:
    """Every other target's box this frame (``live``) and colour model, as target ``i``'s
    measurement is checked against them."""
    return tuple((b, steps[j].t.q) for j, b in live.items() if j != i)


def _reach(m: single.Measured) -> float:
    """How far a target's measurement lies from its prediction, in its own sizes."""
    b, p, (w, h) = m.decision.box, m.evidence.prior, m.evidence.ref_size
    assert b is not None
    return float(((b.cx - p.cx) / max(w, 1.0)) ** 2 + ((b.cy - p.cy) / max(h, 1.0)) ** 2) ** 0.5


def _measured_boxes(
    alone: dict[int, single.Measured], leave_out: set[int] | None = None
) -> dict[int, BBox]:
    """The measurements of the targets (but ``leave_out``) that have one."""
    out = {}
    for i, m in alone.items():
        if m.decision.box is not None and i not in (leave_out or ()):
            out[i] = m.decision.box
    return out


def mode_of(frames: FramePair) -> str:
    """``dual`` with both channels, else ``ir`` or ``visible``: the cues follow the channels
    present."""
    if frames.visible is not None and frames.infrared is not None:
        return "dual"
    return "ir" if frames.infrared is not None else "visible"


@dataclass(frozen=True)
class Dual:
    """The dual-channel tracker, composed of its parts (each with its own config section).

    A part left out (None) is absent from every frame: without ``appearance`` no filter
    detection enters the decision, without ``extent`` the size follows the filter and the
    contour only, without ``redetector`` a missing target is looked for near its prediction
    only, without ``groups`` targets in mutual occlusion each keep themselves. The tracker is
    pure: :meth:`init` and :meth:`step` return a new :class:`DualState`.

    Parameters
    ----------
    motion : Motion
        The Kalman prior of every search, and coasting.
    colour : ColourCue
        Mean shift on the colour histogram (the paper's step 2) and its model update.
    contour : ContourCue
        The IR level-set contour (step 3) and its checks.
    decider : Decider
        The rule table that picks the measurement.
    size : SizeModel
        Eq. 7 over the cues' sizes.
    lifecycle : Lifecycle
        Lost targets, status events, confidences.
    appearance : AppearanceCue, optional
        The correlation filter over both channels.
    extent : ExtentCue, optional
        The box's width and height from the target's colours.
    redetector : Redetector, optional
        The search for a missing target.
    groups : GroupHandler, optional
        Eq. 10-11: merged groups, the split and re-association.

    Examples
    --------
    >>> from pipeline.trackers.dual import Dual
    >>> default, paper = Dual.from_config(DualConfig()), Dual.paper()
    >>> default.appearance is not None, default.groups is None
    (True, True)
    >>> paper.appearance is None, paper.groups is not None
    (True, True)
    """

    motion: Motion
    colour: ColourCue
    contour: ContourCue
    decider: Decider
    size: SizeModel
    lifecycle: Lifecycle
    appearance: AppearanceCue | None = None
    extent: ExtentCue | None = None
    redetector: Redetector | None = None
    groups: GroupHandler | None = None

    @classmethod
    def from_config(cls, cfg: DualConfig) -> Dual:
        """The composition ``cfg`` describes (``dual`` section; a part None there is absent)."""
        return cls(
            motion=Motion(cfg.motion, cfg.kalman),
            colour=ColourCue(cfg.colour, cfg.histogram, cfg.meanshift, cfg.model_update),
            contour=ContourCue(cfg.contour, cfg.levelset),
            decider=Decider(cfg.decider),
            size=SizeModel(cfg.size),
            lifecycle=Lifecycle(cfg.lifecycle),
            appearance=AppearanceCue(cfg.appearance) if cfg.appearance is not None else None,
            extent=ExtentCue(cfg.extent) if cfg.extent is not None else None,
            redetector=Redetector(cfg.redetect) if cfg.redetect is not None else None,
            groups=GroupHandler(cfg.groups) if cfg.groups is not None else None,
        )

    @classmethod
    def paper(cls) -> Dual:
        """The paper's tracker (:meth:`DualConfig.paper`)."""
        return cls.from_config(DualConfig.paper())

    def warm_up(self) -> None:
        """Compile or load the parts' numba kernels once per process, so that the first timed
        frame does not pay for them."""
        meanshift_stage.warm_up()  # and the histogram loops
        detection_stage.warm_up()  # the whole-frame search
        contour_stage.warm_up()
        extent_stage.warm_up()
        model_update_stage.warm_up()
        kalman_stage.warm_up()
        if self.appearance is not None:
            app_stage.warm_up()

    lazy_background: ClassVar[bool] = True  # the whole-frame search seldom runs

    @staticmethod
    def detector_channel(channels: tuple[str, ...]) -> str:
        """The whole-frame search detects in the IR frame, in the visible one without IR."""
        return "infrared" if "infrared" in channels else "visible"

    @property
    def detection(self) -> DetectionConfig | None:
        """The detector settings of the whole-frame search (None without a re-detector): what
        the sequence's background is estimated for."""
        return self.redetector.detection if self.redetector is not None else None

    # ------------------------------------------------------------------------------ frame 1
    def init(
        self, frames: FramePair, targets: Sequence[InitTarget], background: BackgroundSource = None
    ) -> tuple[DualState, FrameResult]:
        """Start on the first frame: every target's colour model, filter and level set;
        ``background`` is the detector's for this frame (:attr:`DualState.background`)."""
        mode = mode_of(frames)
        qs = self.colour.models(frames, mode, [t.box for t in targets])
        ir = frames.infrared if mode in ("dual", "ir") else None
        states, results = [], []
        for t, q in zip(targets, qs, strict=True):
            c = self.contour.first(ir, t.box) if ir is not None else None
            states.append(self._first(frames, mode, t, q, c))
            results.append(
                TargetResult(
                    t.id,
                    t.box,
                    TargetStatus.TRACKING,
                    "init",
                    {"levelset": c.iterations if c is not None else 0},
                    1.0,
                    "none:init",
                    1.0,
                    c.contour if c is not None else (),
                    decision=DecisionLabel(Case.INIT, Rule.GIVEN, Rule.GIVEN.value),
                )
            )
        return DualState(tuple(states), mode, background=background), FrameResult(
            frames.index, tuple(results)
        )

    def _first(self, frames: FramePair, mode: str, t: InitTarget, q, c: ContourResult | None):
        """The state of target ``t`` on its first frame (its contour ``c``)."""
        b = t.box
        H, W = frames.shape
        # walking in: the given box and the target's IR blob are both cut by the frame's border
        cut = c.at_border if c is not None and c.box is not None else (False, False)
        entering = (
            cut[0] and (b.x <= 1.0 or b.x2 >= W - 1.0),
            cut[1] and (b.y <= 1.0 or b.y2 >= H - 1.0),
        )
        model = self.appearance.train(frames, mode, b) if self.appearance is not None else None
        return DualTarget(
            t.id,
            b,
            (b.w, b.h),
            q,
            TargetStatus.TRACKING,
            self.motion.start(b),
            c.memory if c is not None and c.box is not None else None,
            b.center,
            ((1.0, b.cx, b.cy, b.w, b.h),),
            appearance=model,
            first_model=model,
            app_size=(b.w, b.h),
            entering=entering,
            part=self.contour.part(b, c, entering),
        )

    # ------------------------------------------------------------------------- every frame
    def step(self, state: DualState, frames: FramePair) -> tuple[DualState, FrameResult]:
        """One frame: the colour step of every target, the merge test (eq. 10), then each
        group and each single target."""
        t0 = time.perf_counter()
        timing: dict[str, float] = {}
        steps = {t.id: self._colour_step(frames, t, state.mode, timing) for t in state.targets}
        live = live_boxes(steps)
        groups = []
        if self.groups is not None and state.mode != "visible":
            groups = self.groups.groups(steps, live, frames.index)
        done, memories = self._groups(frames, groups, steps, state, timing)
        alone = {
            i: self._measure_alone(frames, cs, state, timing, _rivals(i, live, steps))
            for i, cs in steps.items()
            if i not in done
        }
        for i, m in self._one_object_one_target(alone).items():
            others = tuple(b for j, b in live.items() if j != i)
            done[i] = single.update(self, frames, m, state.mode, timing, None, others)
        new, results, events = [], [], []
        for t in state.targets:
            nt, r, ev = done[t.id]
            new.append(nt)
            results.append(r)
            events += ev
        timing["dual"] = time.perf_counter() - t0
        return (
            dataclasses.replace(state, targets=tuple(new), groups=tuple(memories)),
            FrameResult(frames.index, tuple(results), tuple(events), timing),
        )

    def _groups(
        self,
        frames: FramePair,
        groups: list[tuple[int, ...]],
        steps: dict[int, ColourStep],
        state: DualState,
        timing: dict[str, float],
    ) -> tuple[dict[int, Done], list[GroupMemory]]:
        """Every merged group's members this frame, and the groups' level sets."""
        done: dict[int, Done] = {}
        memories = []
        for g in groups:
            out, mem = self._group(frames, [steps[i] for i in g], state, timing)
            done.update(out)
            if mem is not None:
                memories.append(mem)
        return done, memories

    def _colour_step(
        self, frames: FramePair, t: DualTarget, mode: str, timing: dict[str, float]
    ) -> ColourStep:
        """The motion prior and the mean shift of ``t`` (the paper's step 2)."""
        clock = time.perf_counter()
        prior = self.motion.predict(t)
        y0 = self.motion.search_start(t, prior)
        add_time(timing, "kalman", clock)
        return self.colour.step(frames, t, prior, y0, mode, timing)

    def _measure_alone(
        self,
        frames: FramePair,
        cs: ColourStep,
        state: DualState,
        timing: dict[str, float],
        others: tuple[tuple[BBox, np.ndarray], ...] = (),
    ) -> single.Measured:
        """The cues and decision of a target in no group this frame (``others``: the other
        targets' boxes, :func:`~pipeline.trackers.dual.group.live_boxes`, and colour models);
        one whose group dissolved without a visible split starts again from its prediction (its
        move out of ``merged`` is the lifecycle's ``split`` event, with the decision that took
        it)."""
        start = None
        if cs.t.status == TargetStatus.MERGED and cs.t.case == Case.MERGED.value:
            start = cs.box_prior.center
        return single.measure(
            self, frames, cs, state.mode, timing, start, state.background, others
        )

    def _one_object_one_target(
        self, alone: dict[int, single.Measured]
    ) -> dict[int, single.Measured]:
        """The frame-level step after every target's own decision: where two targets'
        measurements land on one object (:meth:`Decider.shared`), one keeps it
        (:meth:`Decider.owner_of`) and the other learns nothing, merged with it or coasting
        hidden (:meth:`Decider.yields`). Pairs are settled from the most overlapping down; a
        target that yielded takes part in no later pair. Then a target whose measurement lies
        on another target and whose colour says it is not its own (:meth:`Decider.on_other`)
        yields to that one, the worst colour match first."""
        out = dict(alone)
        yielded: set[int] = set()
        for i, j in self._shared_pairs(alone):
            if i in yielded or j in yielded:
                continue
            owner, other = self._settle(i, j, out[i], out[j])
            out[other] = self._yield(out[other], owner)
            yielded.add(other)
        for i, j in self._inside_pairs(out, yielded):
            if i not in yielded and j not in yielded:
                other_box = out[j].decision.box
                assert other_box is not None
                on = self.decider.lies_in(out[i].evidence.prior, other_box)
                out[i] = self._yield(out[i], j, on)
                yielded.add(i)
        return out

    def _yield(self, m: single.Measured, owner: int, on: bool | None = None) -> single.Measured:
        """A target whose measurement target ``owner`` takes: merged where its own prediction
        lies on the object too (``on``; by default :meth:`Decider.yields` tests the overlap),
        else coasting; it learns nothing."""
        box = m.decision.box
        assert box is not None
        d = self.decider.yields(owner, box, m.evidence.prior, on)
        return dataclasses.replace(m, decision=self.lifecycle.settle(d, m.evidence))

    def _inside_pairs(
        self, alone: dict[int, single.Measured], yielded: set[int]
    ) -> list[tuple[int, int]]:
        """``(i, j)``: target ``i``'s measurement lies on target ``j`` and its colour says it is
        not ``i`` (:meth:`Decider.on_other`); the worst colour match first."""
        if self.decider.cfg.colour_deny_rho <= 0:
            return []
        boxes = _measured_boxes(alone, yielded)
        if len(boxes) < 2:
            return []
        rho = {i: self._match(alone[i]) for i in boxes}
        pairs = sorted(
            (rho[i], i, j)
            for i, a in boxes.items()
            for j, b in boxes.items()
            if i != j and self.decider.on_other(a, b, rho[i])
        )
        return [(i, j) for _, i, j in pairs]

    def _shared_pairs(self, alone: dict[int, single.Measured]) -> list[tuple[int, int]]:
        """The pairs of measured targets whose boxes are one object, most overlapping first: the
        measurements' own boxes, or the boxes they will be reported as (each measurement's
        centre at its target's size; a contour's or filter's box is often smaller or larger than
        the box the target reports)."""
        if self.decider.cfg.shared_iou <= 0:
            return []  # the rule is off (the default): no boxes to build
        boxes = _measured_boxes(alone)
        sized = {i: BBox.from_center(b.cx, b.cy, *alone[i].cs.t.size) for i, b in boxes.items()}
        pairs = sorted(
            (
                (max(a.iou(boxes[j]), sized[i].iou(sized[j])), i, j)
                for i, a in boxes.items()
                for j in boxes
                if i < j
                and (self.decider.shared(a, boxes[j]) or self.decider.shared(sized[i], sized[j]))
            ),
            reverse=True,
        )
        return [(i, j) for _, i, j in pairs]

    def _settle(self, i: int, j: int, mi: single.Measured, mj: single.Measured) -> tuple[int, int]:
        """Which of targets ``i`` and ``j`` owns their shared object: ``(owner, other)``."""
        rho = (self._match(mi), self._match(mj))
        reach = (_reach(mi), _reach(mj))
        held = (mi.evidence.measured_last, mj.evidence.measured_last)
        return (i, j) if self.decider.owner_of(rho, reach, held) == 0 else (j, i)

    def _match(self, m: single.Measured) -> float:
        """The colour match of a target's own model at its measurement (NaN without colour)."""
        if not m.evidence.colour_informative:
            return float("nan")
        return self.colour.match_at(m.cs, m.decision.box)

    # ---------------------------------------------------------------------- merged groups
    def _group(
        self,
        frames: FramePair,
        css: list[ColourStep],
        state: DualState,
        timing: dict[str, float],
    ) -> tuple[dict[int, Done], GroupMemory | None]:
        """One merged group this frame: its members split onto their blobs, or placed in the
        group's blob. Returns every member's outcome and the group's level set (None after a
        split or without a contour)."""
        gh = self.groups
        assert gh is not None and frames.infrared is not None
        clock = time.perf_counter()
        g = gh.blob(self.contour, frames.infrared, css, state.groups)
        clock = add_time(timing, "levelset", clock)
        blobs = gh.parts(g)
        if len(blobs) >= len(css):  # split: every member has its own blob again
            out = {}
            for cs, blob, others, ev in gh.split(self.colour, g, blobs):
                # a member continues on its own from the blob, not from the group's level set
                t = dataclasses.replace(cs.t, memory=None, status=TargetStatus.OCCLUDED_PARTIAL)
                alone = dataclasses.replace(cs, t=t)
                m = single.measure(self, frames, alone, state.mode, timing, blob.center)
                out[t.id] = single.update(
                    self, frames, m, state.mode, timing, ev, others, was=cs.t.status
                )
            return out, None
        c = g.contour
        roles = gh.roles(g, c.box is not None and self.contour.contrasted(c))
        events = gh.merge_events(g, roles)
        placed = gh.placements(g, roles)
        out = {}
        for cs in css:
            nt, res, moved = self._merged(cs, g, roles, gh.place(cs, g, roles, placed))
            shared = events if cs.t.id == roles.foreground else []
            out[cs.t.id] = (nt, res, [*moved, *shared])
        add_time(timing, "merge", clock)
        mem = None
        if c.box is not None:
            mem = GroupMemory(g.ids, c.memory, g.box.center, roles.foreground)
        return out, mem

    def _merged(
        self,
        cs: ColourStep,
        g: GroupBlob,
        roles: Roles,
        placement: tuple[tuple[float, float], Rule],
    ) -> tuple[DualTarget, TargetResult, list[Event]]:
        """A member of a merged group at its placement: corrected there (or coasting, placed by
        its motion), no model learning; lost once hidden too long. Returns its state, result and
        the event of its status move (joining the group, or lost in it)."""
        gh = self.groups
        assert gh is not None
        t, c = cs.t, g.contour
        (y, rule), ref = placement, t.reference_size
        out = BBox.from_center(y[0], y[1], ref[0], ref[1])
        missing, kf = 0, None
        if rule == Rule.MERGE_MOTION:
            kf, missing = cs.prior, t.missing + 1
        else:
            kf = self.motion.correct(cs.prior, out)
        status = self.lifecycle.merged_status(missing)
        fg = t.id == roles.foreground
        if status == TargetStatus.LOST:
            kf = self.motion.stop(kf)
            moved = self.lifecycle.lost_in_group(t.id, t.status, missing)
        else:
            where = "in front" if fg else "hidden"
            moved = self.lifecycle.joined(t.id, t.status, "+".join(f"T{k}" for k in g.ids), where)
        update = UpdateDecision(False, "merged")
        nt = dataclasses.replace(
            t,
            box=out,
            status=status,
            kf=kf,
            memory=None,
            missing=missing,
            last_update=str(update),
            case=Case.MERGED.value,
        )
        res = TargetResult(
            t.id,
            out,
            status,
            f"merge-{rule.value}",
            {"meanshift": cs.ms_iters, "levelset": c.iterations},
            cs.rho1,
            str(update),
            gh.confidence(fg),
            c.contour if fg else (),
            gh.diagnostics(cs, g, roles, missing),
            {"prediction": cs.prior.box, "meanshift": cs.box1},
            decision=DecisionLabel(Case.MERGED, rule, rule.value),
        )
        return nt, res, moved
