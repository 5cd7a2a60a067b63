"""The lifecycle every engine's targets share: the statuses a target moves between, which moves
exist, and the event each move emits.

The engines decide *when* a target's status changes (a detector's hit count, the dual tracker's
decision over its cues, CamShift's back-projection); :func:`transition` is the one place that says
whether the move exists and what it is called, so that ``lost``, ``merged`` and an occlusion's end
read the same in every engine's event log. A group's own events (two targets merging into one
blob, its split and the re-association of its members) are the group's, not a status move, and
stay with the code that handles groups.

The moves (old -> new), the first line that applies:

===========================================  ==================  ==============================
move                                         event kind          text
===========================================  ==================  ==============================
any -> the same status                       none
``tentative`` -> anything but ``tracking``   refused (ValueError)
anything -> ``tentative``                    refused (ValueError)
any -> ``lost``                              ``lost``            ``T3 lost (why)``
``lost`` -> any                              ``re-acquired``     ``T3 re-acquired (why)``
``tentative`` -> ``tracking``                ``confirmed``       ``T3 confirmed (why)``
any -> ``merged``                            ``merge``           ``T3 merged (why)``
``merged`` -> any                            ``split``           ``T3 separated (why)``
visible -> an occlusion                      ``occlusion-start`` ``T3 occluded-partial (why)``
``occluded-partial`` -> ``occluded-severe``  ``occlusion-start`` ``T3 occluded-severe (why)``
an occlusion -> ``tracking``                 ``occlusion-end``   ``T3 visible again (why)``
``occluded-severe`` -> ``occluded-partial``  none
===========================================  ==================  ==============================

A coast ends in ``lost`` by one rule in every engine (:func:`coast_ends`): the prediction left the
frame, or too many frames went without a measurement. A target that is dropped before it was ever
confirmed (a detector's tentative track failing M of
N) leaves without a move: it was never reported. A new target enters with :func:`born`.
"""

from __future__ import annotations

from pipeline.types import BBox, Event, EventKind, TargetStatus

S = TargetStatus


def allowed(old: TargetStatus, new: TargetStatus) -> bool:
    """Whether the lifecycle has the move ``old -> new``.

    Examples
    --------
    >>> allowed(TargetStatus.TENTATIVE, TargetStatus.TRACKING)
    True
    >>> allowed(TargetStatus.TRACKING, TargetStatus.TENTATIVE)
    False
    """
    if new == old:
        return True
    if new == S.TENTATIVE:
        return False
    return old != S.TENTATIVE or new == S.TRACKING


def transition(tid: int, old: TargetStatus, new: TargetStatus, why: str) -> tuple[Event, ...]:
    """The event of target ``tid``'s status moving from ``old`` to ``new`` (none for a move
    without one), ``why`` saying what the engine saw (the text in brackets).

    Raises
    ------
    ValueError
        For a move the lifecycle does not have (see the module's table).

    Examples
    --------
    >>> [e.text for e in transition(3, TargetStatus.TRACKING, TargetStatus.LOST, "left the frame")]
    ['T3 lost (left the frame)']
    >>> e, = transition(3, TargetStatus.OCCLUDED_SEVERE, TargetStatus.TRACKING, "contour")
    >>> e.kind.value, e.text
    ('occlusion-end', 'T3 visible again (contour)')
    >>> transition(3, TargetStatus.TRACKING, TargetStatus.TRACKING, "same")
    ()
    """
    if not allowed(old, new):
        raise ValueError(f"T{tid}: no move from {old} to {new} in the lifecycle")
    kind, text = _named(old, new)
    if kind is None:
        return ()
    return (Event(kind, f"T{tid} {text} ({why})", (tid,)),)


def _named(old: TargetStatus, new: TargetStatus) -> tuple[EventKind | None, str]:
    """The kind and the verb of an allowed move (the table's first line that applies)."""
    if new == old:
        return None, ""
    if new == S.LOST:
        return EventKind.LOST, "lost"
    if old == S.LOST:
        return EventKind.REACQUIRED, "re-acquired"
    if old == S.TENTATIVE:
        return EventKind.CONFIRMED, "confirmed"
    if new == S.MERGED:
        return EventKind.MERGE, "merged"
    if old == S.MERGED:
        return EventKind.SPLIT, "separated"
    if new.is_occluded and (not old.is_occluded or new == S.OCCLUDED_SEVERE):
        return EventKind.OCCLUSION_START, str(new)
    if new == S.TRACKING:
        return EventKind.OCCLUSION_END, "visible again"
    return None, ""


def born(tid: int, why: str) -> tuple[Event, ...]:
    """The event of a new target ``tid`` (a detector's new track): ``T3 born (why)``."""
    return (Event(EventKind.BIRTH, f"T{tid} born ({why})", (tid,)),)


def left_frame(box: BBox, shape: tuple[int, ...]) -> bool:
    """Less than a quarter of ``box`` lies inside a frame of ``shape`` (H, W, ...): a coasting
    target whose prediction this is has left the frame.

    Examples
    --------
    >>> left_frame(BBox(-31, 0, 40, 10), (100, 100)), left_frame(BBox(-30, 0, 40, 10), (100, 100))
    (True, False)
    """
    return box.clip(shape[1], shape[0]).area < 0.25 * box.area


def coast_ends(prediction: BBox, shape: tuple[int, ...], missing: int, limit: int) -> str | None:
    """Why a target coasting on ``prediction`` for ``missing`` frames without a measurement is
    lost, or None while it may coast on: its prediction left the frame (:func:`left_frame`), or it
    has gone more than ``limit`` frames without a measurement. Every engine's coast ends by this
    rule (with its own ``limit``).

    Examples
    --------
    >>> coast_ends(BBox(10, 10, 20, 20), (100, 100), 31, 30)
    '31 frames without a measurement'
    >>> coast_ends(BBox(96, 10, 20, 20), (100, 100), 1, 30)
    'left the frame'
    >>> coast_ends(BBox(10, 10, 20, 20), (100, 100), 30, 30) is None
    True
    """
    if left_frame(prediction, shape):
        return "left the frame"
    if missing > limit:
        return f"{missing} frames without a measurement"
    return None
