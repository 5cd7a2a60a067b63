"""One target that is not merged, one frame: its cues, the decision over them (:func:`measure`),
then its size, models, motion, events and result (:func:`update`)."""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from pipeline.io.sequence import FramePair
from pipeline.stages import detection
from pipeline.stages.appearance import AppearanceModel, Detection
from pipeline.stages.contour import ContourResult, LevelSetMemory
from pipeline.stages.detection import to_grey
from pipeline.stages.merge import merge_test
from pipeline.stages.model_update import UpdateDecision
from pipeline.trackers.dual.appearance import FilterCue
from pipeline.trackers.dual.colour import ColourStep, add_time
from pipeline.trackers.dual.decide import (
    Case,
    Decision,
    Evidence,
    Rule,
    corroborated,
    needs_background,
)
from pipeline.trackers.dual.redetect import step_speed
from pipeline.trackers.dual.state import BackgroundSource, DualTarget
from pipeline.trackers.lifecycle import left_frame
from pipeline.types import BBox, Event, EventKind, TargetResult, TargetStatus

if TYPE_CHECKING:
    from pipeline.trackers.dual.tracker import Dual

Size = tuple[float, float]
NAN = math.nan


@dataclass(frozen=True)
class Measured:
    """One target's cues and decision in one frame, before anything is updated."""

    cs: ColourStep
    cue: FilterCue | None
    contour: ContourResult | None
    rho_contour: float
    rho_appearance: float
    evidence: Evidence
    decision: Decision
    start: tuple[float, float] | None = None


# ------------------------------------------------------------------------------- measure


def measure(
    dual: Dual,
    frames: FramePair,
    cs: ColourStep,
    mode: str,
    timing: dict[str, float],
    start: tuple[float, float] | None = None,
    background: BackgroundSource = None,
    others: tuple[tuple[BBox, np.ndarray], ...] = (),
) -> Measured:
    """The cues of one target (filter, IR contour, colour at each) and the decision over them.

    ``start`` forces a cold contour start there (a blob after a split); ``background`` is the
    detector's, for the whole-frame search; ``others`` are the other targets' boxes this frame
    and their colour models (a filter detection on one of their boxes, or that one of their
    models matches better, is not :func:`~pipeline.trackers.dual.decide.corroborated`)."""
    cue = _filter(dual, frames, cs, mode, timing, background, others)
    c = _contour(dual, frames, cs, cue, mode, timing, start)
    usable = c if dual.contour.usable(c) else None
    rho_c = dual.colour.match_at(cs, usable.box if usable is not None else None)
    rho_a = dual.colour.match_at(cs, cue.box if cue is not None else None)
    ev = evidence(dual, frames, cs, cue, usable, c, (rho_c, rho_a), mode, start)
    ev = _against_others(dual, cs, cue, ev, others)
    if cue is not None and needs_background(ev, dual.decider.cfg):
        ev = dataclasses.replace(
            ev, foreground_share=_foreground_share(frames, cue.box, background)
        )
    d = dual.lifecycle.settle(dual.decider.decide(ev), ev)
    if start is not None and not d.measured and c is not None and c.box is not None:
        d = dual.decider.split_blob(c.box)  # the blob a split re-associated it with
    return Measured(cs, cue, c, rho_c, rho_a, ev, d, start)


def _against_others(
    dual: Dual,
    cs: ColourStep,
    cue: FilterCue | None,
    ev: Evidence,
    others: tuple[tuple[BBox, np.ndarray], ...],
) -> Evidence:
    """``ev`` with the filter's detection of a missing target read against the other targets
    (``others``: their boxes this frame and colour models): whether it overlaps one's box, and
    the best of their colour matches there. Only a detection that could be
    :func:`~pipeline.trackers.dual.decide.corroborated` is read (nothing else asks)."""
    if cue is None or not others or not corroborated(ev, dual.decider.cfg):
        return ev
    rival = max(dual.colour.match_at(cs, cue.box, q) for _, q in others)
    on_another = any(cue.box.iou(b) > 0 for b, _ in others)
    return dataclasses.replace(ev, on_another=on_another, rho_rival=rival)


def _filter(
    dual: Dual,
    frames: FramePair,
    cs: ColourStep,
    mode: str,
    timing: dict[str, float],
    background: BackgroundSource,
    others: tuple[tuple[BBox, np.ndarray], ...] = (),
) -> FilterCue | None:
    """The filter's detection at the prediction (and at the colour's position when that is
    elsewhere: a turn; and, unsure there, where a stop or a reversal would have taken the
    target: :meth:`Decider.turns`); a missing target is also looked for by the re-detector.
    Its size is checked against the target's first filter (``appearance.anchor_every_frames``)
    only where no other target (``others``, their boxes this frame) lies within half a box: a
    larger size's peak could hold the neighbour."""
    t, a = cs.t, dual.appearance
    if a is None or t.appearance is None:
        return None
    clock = time.perf_counter()
    size = t.app_size
    # the places are compared by their translation peaks; the size is estimated at the chosen
    # one only
    best = a.detect(t.appearance, frames, mode, cs.y0, size, with_scale=False)
    if dual.decider.colour_moved(cs.informative, cs.rho1, cs.y1, cs.y0, size, best.psr):
        d = a.detect(t.appearance, frames, mode, cs.y1, size, with_scale=False)
        if d.psr > best.psr:
            best = d
    predicted = (float(cs.prior.x[0]), float(cs.prior.x[1]))
    seen = _seen(t, frames.index)["seen"]
    for c in dual.decider.turns(best.psr, seen, predicted, cs.y0, size):
        d = a.detect(t.appearance, frames, mode, c, size, with_scale=False)
        if d.psr > best.psr:
            best = d
    occupied = tuple(b for b, _ in others)
    best, redetected = _redetect(dual, frames, cs, mode, best, background, occupied)
    if not redetected and a.with_scale(frames.index):
        best = a.rescale(t.appearance, best, frames, mode)
        best = _anchored(dual, t, best, frames, mode, others)
    add_time(timing, "appearance", clock)
    return a.cue(best, frames, redetected)


def _anchored(
    dual: Dual,
    t: DualTarget,
    d: Detection,
    frames: FramePair,
    mode: str,
    others: tuple[tuple[BBox, np.ndarray], ...],
) -> Detection:
    """``d`` with its size checked against the target's first filter when it is confident and
    no other target lies within half a box of it
    (:meth:`~pipeline.trackers.dual.appearance.AppearanceCue.anchored`)."""
    a = dual.appearance
    assert a is not None
    if not a.anchor_due(t.first_model, frames, mode) or not dual.decider.filter_confident(d.psr):
        return d
    if _near_another(a.cue(d, frames, False).box, tuple(b for b, _ in others)):
        return d
    return a.anchored(t.first_model, d, frames, mode)


def _redetect(
    dual: Dual,
    frames: FramePair,
    cs: ColourStep,
    mode: str,
    best: Detection,
    background: BackgroundSource,
    occupied: tuple[BBox, ...] = (),
) -> tuple[Detection, bool]:
    """A missing target is searched for at the re-detector's candidates, unless the filter
    finds it where rule 7 takes it back (a confident peak elsewhere in the window, on something
    the filter learned while the target was hidden, does not stop the search); with
    ``redetect.first_model``, by its first frame's filter too; ``occupied`` are the other
    targets' boxes this frame (the detector's regions inside them are not tried near the
    target). Returns the best detection and whether the search found it."""
    t, a = cs.t, dual.appearance
    if t.missing == 0 or dual.redetector is None or a is None or t.appearance is None:
        return best, False
    predicted = (float(cs.prior.x[0]), float(cs.prior.x[1]))
    if dual.decider.takes_back(best.psr, best.center, predicted, t.reference_size, t.missing):
        return best, False
    size, redetected = t.app_size, False
    models, found = _search_models(dual, t), t.appearance
    for c in dual.redetector.candidates(frames, cs, size, background, occupied):
        for model in models:
            d = a.detect(model, frames, mode, c, size, with_scale=False)
            if d.psr > best.psr:
                best, redetected, found = d, True, model
    if redetected:  # the size at the place found
        best = a.detect(found, frames, mode, best.center, size)
    return best, redetected


def _search_models(dual: Dual, t: DualTarget) -> list[AppearanceModel]:
    """The filters the search for a missing target tries at each place: its current one, and
    with ``redetect.first_model`` its first frame's once it has learned since."""
    first = (
        t.first_model if dual.redetector is not None and dual.redetector.cfg.first_model else None
    )
    if first is None or first is t.appearance:
        return [t.appearance]
    return [t.appearance, first]


def _contour(
    dual: Dual,
    frames: FramePair,
    cs: ColourStep,
    cue: FilterCue | None,
    mode: str,
    timing: dict[str, float],
    start: tuple[float, float] | None,
) -> ContourResult | None:
    """The IR contour, started where the other cues put the target (or at ``start``, cold),
    or :meth:`~pipeline.trackers.dual.contour.ContourCue.not_run` where its cold starts keep
    finding nothing and the filter is confident."""
    if mode not in ("dual", "ir") or frames.infrared is None:
        return None
    clock = time.perf_counter()
    cold = start is not None
    confident = cue is not None and dual.decider.filter_confident(cue.psr)
    if start is None:
        if not dual.contour.due(cs.t, frames.index, confident):
            return dual.contour.not_run()
        start = dual.contour.start(
            cue.box if confident and cue is not None else None,
            cs.y1,
            cs.y0,
            dual.decider.colour_good(cs.informative, cs.rho1),
        )
    c = dual.contour.extract(frames.infrared, cs.t, start, cold)
    add_time(timing, "levelset", clock)
    return c


def evidence(
    dual: Dual,
    frames: FramePair,
    cs: ColourStep,
    cue: FilterCue | None,
    usable: ContourResult | None,
    c: ContourResult | None,
    rhos: tuple[float, float],
    mode: str,
    start: tuple[float, float] | None,
) -> Evidence:
    """What the cues found, for the decider: ``usable`` is the contour where the contour cue
    lets it measure, ``rhos`` the colour matches at the contour and at the filter's box."""
    t, prior = cs.t, cs.prior
    ref = t.reference_size
    colour_seen = not math.isnan(cs.rho1)
    return Evidence(
        measured_last=t.missing == 0 or start is not None,
        missing=t.missing,
        prior=BBox.from_center(float(prior.x[0]), float(prior.x[1]), ref[0], ref[1]),
        ref_size=ref,
        colour_informative=(cs.informative and mode != "ir") or (mode == "ir" and colour_seen),
        rho_meanshift=cs.rho1,
        meanshift_box=cs.box1 if colour_seen else None,
        contour_box=usable.box if usable is not None else None,
        contour_ok=c is not None and c.ok,
        contour_reason=c.reason if c is not None else "no-contour",
        rho_contour=rhos[0],
        rho_appearance=rhos[1],
        last=t.box,
        outside=left_frame(prior.box, frames.shape),
        prior_std_px=(math.sqrt(float(prior.P[0, 0])), math.sqrt(float(prior.P[1, 1]))),
        contour_checked=dual.contour.cfg.checks,
        contour_part=c is not None and c.part,
        speed_px=t.speed,
        **_seen(t, frames.index),
        **_filter_evidence(cue),
    )


def _seen(t: DualTarget, frame: int) -> dict:
    """The evidence's fields of the target's last clean measurement: its centre and age."""
    if not t.history:
        return {"seen": None, "seen_frames": 0}
    last = t.history[-1]
    return {"seen": (last[1], last[2]), "seen_frames": int(frame - last[0])}


def _foreground_share(frames: FramePair, box: BBox, background: BackgroundSource) -> float:
    """The share of ``box`` that differs from the sequence's still IR background; NaN without an
    IR frame (a visible target at dusk differs little from its background; the test was made
    for heat), without a background or where it does not hold (a moving camera)."""
    if frames.infrared is None:
        return NAN
    bg = background() if callable(background) else background
    if bg is None or not bg.static or not bg.holds:
        return NAN
    return detection.foreground_share(to_grey(frames.infrared), bg, box.as_tuple())


def _filter_evidence(cue: FilterCue | None) -> dict:
    """The filter's fields of the evidence (absent: no box, NaN PSR)."""
    if cue is None:
        return {"appearance_box": None, "psr": NAN, "support": (NAN, NAN), "redetected": False}
    return {
        "appearance_box": cue.box,
        "psr": cue.psr,
        "support": cue.support,
        "redetected": cue.redetected,
    }


# -------------------------------------------------------------------------------- update


def update(
    dual: Dual,
    frames: FramePair,
    m: Measured,
    mode: str,
    timing: dict[str, float],
    events_in: list[Event] | None = None,
    neighbours: tuple[BBox, ...] = (),
    was: TargetStatus | None = None,
) -> tuple[DualTarget, TargetResult, list[Event]]:
    """Size, models, motion, events and the reported result of one target after its decision:
    (new state, result, events). ``neighbours`` are the other targets' boxes this frame (the
    colour extent is not measured where one is near, a measurement over a collapsed contour
    teaches the models nothing beside one, :func:`_near_another`, nor one overlapping another,
    :func:`_overlaps_another`, with ``decider.overlap_freezes``). ``was`` is the status the
    target had before this frame where the caller measured it under another (a group's member
    after the split); the status event is the move from it (default: the target's own)."""
    cs, c = m.cs, m.contour
    t = cs.t
    clock = time.perf_counter()
    if m.decision.learn and _beside_another(dual, m.decision, neighbours):
        m = dataclasses.replace(m, decision=dataclasses.replace(m.decision, learn=False))
    size, app_size, d, entering = _size(dual, m, neighbours)
    out = _output_box(cs, d, size)
    q, colour, rho2 = dual.colour.learn(cs, out, d.learn, d.measured)
    model, app_size = _learn_filter(dual, frames, m, mode, d, out, (size, app_size), colour)
    events = [*(events_in or []), *_frozen(t, colour)]
    clock = add_time(timing, "model_update", clock)
    kf, history, out = dual.motion.update(t, cs.prior, d, out, frames.index)
    add_time(timing, "kalman", clock)
    old = t.status if was is None else was
    events += dual.lifecycle.events(t.id, old, d, c.reason if c is not None else None)
    memory, memory_center = _contour_memory(t, d, c)
    empty_starts, empty_start_frame = dual.contour.empty_starts(t, c, frames.index)
    nt = dataclasses.replace(
        t,
        box=out,
        size=size,
        app_size=app_size,
        entering=entering,
        q=q,
        status=d.status,
        kf=kf,
        memory=memory,
        memory_center=memory_center,
        history=history,
        missing=0 if d.measured else t.missing + 1,
        last_update=str(colour),
        split_frame=frames.index if m.start is not None else t.split_frame,
        appearance=model,
        # a target that walked in is first seen whole now: its filter, trained afresh, is its first
        first_model=model if d.rule == Rule.WALKED_IN else t.first_model,
        case=d.case.value,
        speed=step_speed(history) if len(history) >= 2 else t.speed,
        partial=d.partial,
        empty_starts=empty_starts,
        empty_start_frame=empty_start_frame,
    )
    return nt, result(dual, m, d, out, nt.missing, colour, rho2), events


def _output_box(cs: ColourStep, d: Decision, size: Size) -> BBox:
    """The reported box: the measurement at the new size, or the prediction at the usual
    size."""
    if d.box is not None:
        return BBox.from_center(d.box.cx, d.box.cy, size[0], size[1])
    ref = cs.t.reference_size
    return BBox.from_center(float(cs.prior.x[0]), float(cs.prior.x[1]), ref[0], ref[1])


def _size(
    dual: Dual, m: Measured, neighbours: tuple[BBox, ...]
) -> tuple[Size, Size, Decision, tuple[bool, bool]]:
    """The size after this frame, the filter's own size, the decision (a target that walked in
    takes its first clean contour) and the axes along which it is still walking in."""
    t, d = m.cs.t, m.decision
    confident = m.cue is not None and dual.decider.filter_confident(m.cue.psr)
    ratio = dual.extent.cfg.max_ratio if dual.extent is not None else 1.0
    size, app_size = dual.size.update(
        t.size,
        t.app_size,
        d,
        _contour_size(dual, d, m.contour),
        m.cue,
        confident,
        _extent(dual, m, neighbours),
        ratio,
    )
    size, d, entering = _walked_in(dual, m, size, d)
    return size, app_size, d, entering


def _beside_another(dual: Dual, d: Decision, neighbours: tuple[BBox, ...]) -> bool:
    """Whether another target is too close for the models to learn from this decision: a
    measurement over a cut or collapsed contour within half a box of one
    (:func:`_near_another`), or any measurement overlapping one (:func:`_overlaps_another`,
    with ``decider.overlap_freezes``)."""
    if d.partial and _near_another(d.box, neighbours):
        return True
    return dual.decider.cfg.overlap_freezes and _overlaps_another(d.box, neighbours)


def _overlaps_another(box: BBox | None, neighbours: tuple[BBox, ...]) -> bool:
    """Another target's box overlaps ``box`` (eq. 10: the centres closer than half the summed
    sizes on both axes).

    Examples
    --------
    >>> _overlaps_another(BBox(0, 0, 10, 20), (BBox(9, 5, 10, 20),))
    True
    >>> _overlaps_another(BBox(0, 0, 10, 20), (BBox(10, 5, 10, 20), BBox(0, 20, 10, 20)))
    False
    """
    if box is None:
        return False
    return any(merge_test(box, b) for b in neighbours)


def _near_another(box: BBox | None, neighbours: tuple[BBox, ...]) -> bool:
    """Another target's box overlaps ``box`` grown by half its size on every side."""
    if box is None:
        return False
    grown = BBox(box.x - 0.5 * box.w, box.y - 0.5 * box.h, 2 * box.w, 2 * box.h)
    return any(grown.iou(b) > 0 for b in neighbours)


def _extent(dual: Dual, m: Measured, neighbours: tuple[BBox, ...]) -> BBox | None:
    """The colour extent at the measurement, when the decision lets the models learn (a hidden
    target's colours are someone else's) and the colour is seen."""
    d = m.decision
    if dual.extent is None or d.box is None or not d.learn or d.partial or not m.cs.informative:
        return None
    return dual.extent.measure(m.cs, d.box.center, neighbours)


def _contour_size(dual: Dual, d: Decision, c: ContourResult | None) -> Size | None:
    """The contour's box size, where the decision lets it enter the size and it is clearly
    contrasted."""
    if not d.contour_scale or c is None or c.box is None:
        return None
    if not dual.contour.contrasted(c, dual.size.cfg.contour_contrast_ratio):
        return None
    return (c.box.w, c.box.h)


def _walked_in(
    dual: Dual, m: Measured, size: Size, d: Decision
) -> tuple[Size, Decision, tuple[bool, bool]]:
    """A target given cut by the frame's border takes the size of its first clean contour once
    it has walked in (``WALKED_IN``); it walks in no more once its contour is clean."""
    c, entering = m.contour, m.cs.t.entering
    if not any(entering):
        return size, d, entering
    contradicts = dual.decider.colour_contradicts(m.rho_contour)
    walked = dual.size.walked_in(size, c, contradicts, entering)
    if walked is not None and c is not None and c.box is not None:
        # its first clean contour shows what the frame's border hid
        size, d = walked, dual.decider.walked_in(c.box)
    if c is not None and c.ok:
        entering = (False, False)
    return size, d, entering


def _learn_filter(
    dual: Dual,
    frames: FramePair,
    m: Measured,
    mode: str,
    d: Decision,
    out: BBox,
    sizes: tuple[Size, Size],
    colour: UpdateDecision,
) -> tuple[AppearanceModel | None, Size]:
    """The filter and its size after this frame (``sizes``: the size and the filter's own):
    learned afresh on a target that walked in (at its whole size), else blended with this frame
    when the decision and the colour model allow."""
    size, app_size = sizes
    walked = d.rule == Rule.WALKED_IN
    model = m.cs.t.appearance
    if walked:
        app_size = size
    if dual.appearance is None or model is None:
        return model, app_size
    if walked:
        return dual.appearance.train(frames, mode, out), app_size
    at = BBox.from_center(out.cx, out.cy, *app_size)
    seen = m.cs.informative
    reuse = m.cue.scale_samples if m.cue is not None else None
    window = m.cue.window_samples if m.cue is not None else None
    support = m.cue.support if m.cue is not None else None
    learned = dual.appearance.learn(
        model, frames, mode, at, d, colour, seen, frames.index, reuse, window, support
    )
    return learned, app_size


def _frozen(t: DualTarget, colour: UpdateDecision) -> list[Event]:
    """The event of the colour model freezing after it was updating."""
    if colour.update or not t.last_update.startswith("updated"):
        return []
    if colour.reason == "colour-uninformative":
        return []
    return [Event(EventKind.MODEL_FROZEN, f"T{t.id} model frozen ({colour.reason})", (t.id,))]


def _contour_memory(
    t: DualTarget, d: Decision, c: ContourResult | None
) -> tuple[LevelSetMemory | None, tuple[float, float]]:
    """The level set kept for the next warm start: this frame's when the contour measured the
    target, else the last good one."""
    if d.case == Case.CONTOUR and c is not None and c.box is not None:
        return c.memory, c.box.center
    return t.memory, t.memory_center


def result(
    dual: Dual,
    m: Measured,
    d: Decision,
    out: BBox,
    missing: int,
    colour: UpdateDecision,
    rho2: float,
) -> TargetResult:
    """What ``targets.csv`` and the recording show of one target this frame."""
    cs, cue, c = m.cs, m.cue, m.contour
    overlays = {"prediction": cs.prior.box, "meanshift": cs.box1}
    if cue is not None:
        overlays["appearance"] = cue.box
    contour_note = "" if c is None or c.ok else f";contour-{c.reason}"
    shown = c is not None and c.box is not None
    return TargetResult(
        cs.t.id,
        out,
        d.status,
        d.stage,
        {"meanshift": cs.ms_iters, "levelset": c.iterations if c is not None else 0},
        rho2 if not math.isnan(rho2) else cs.rho1,
        f"{colour}{contour_note}",
        dual.lifecycle.confidence(d.status),
        c.contour if shown and c is not None else (),
        diagnostics(m, missing, rho2),
        overlays,
        decision=d.label,
    )


def diagnostics(m: Measured, missing: int, rho2: float) -> dict[str, float]:
    """A target's ``targets.csv`` diagnostics (NaN for a cue that did not run)."""
    cs, cue, c = m.cs, m.cue, m.contour
    diag = {
        "rho_y1": cs.rho1,
        "rho_y2": rho2,
        "rho_contour": m.rho_contour,
        "contrast": c.contrast if c is not None else NAN,
        "bright_fraction": cs.bright,
        "missing": float(missing),
        "components": float(len(c.components)) if c is not None else 0.0,
    }
    diag.update(_filter_diagnostics(cue))
    diag["rho_appearance"] = m.rho_appearance
    return diag


def _filter_diagnostics(cue: FilterCue | None) -> dict[str, float]:
    if cue is None:
        return {"psr": NAN, "scale_factor": NAN, "psr_visible": NAN, "psr_ir": NAN}
    return {
        "psr": cue.psr,
        "scale_factor": cue.scale_factor,
        "psr_visible": cue.support[0],
        "psr_ir": cue.support[1],
    }
