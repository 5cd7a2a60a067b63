"""The lifecycle every engine shares: each move's event, the moves it refuses, and the engines'
event logs read against their own statuses."""

from __future__ import annotations

import pytest

from pipeline.config import load_config
from pipeline.run import track
from pipeline.trackers.lifecycle import allowed, born, transition
from pipeline.types import EventKind, TargetStatus

S = TargetStatus
K = EventKind

MOVES = [
    (S.TRACKING, S.LOST, K.LOST, "T4 lost (why)"),
    (S.OCCLUDED_SEVERE, S.LOST, K.LOST, "T4 lost (why)"),
    (S.MERGED, S.LOST, K.LOST, "T4 lost (why)"),
    (S.LOST, S.TRACKING, K.REACQUIRED, "T4 re-acquired (why)"),
    (S.LOST, S.OCCLUDED_PARTIAL, K.REACQUIRED, "T4 re-acquired (why)"),
    (S.TENTATIVE, S.TRACKING, K.CONFIRMED, "T4 confirmed (why)"),
    (S.TRACKING, S.MERGED, K.MERGE, "T4 merged (why)"),
    (S.OCCLUDED_PARTIAL, S.MERGED, K.MERGE, "T4 merged (why)"),
    (S.MERGED, S.TRACKING, K.SPLIT, "T4 separated (why)"),
    (S.MERGED, S.OCCLUDED_SEVERE, K.SPLIT, "T4 separated (why)"),
    (S.TRACKING, S.OCCLUDED_PARTIAL, K.OCCLUSION_START, "T4 occluded-partial (why)"),
    (S.TRACKING, S.OCCLUDED_SEVERE, K.OCCLUSION_START, "T4 occluded-severe (why)"),
    (S.OCCLUDED_PARTIAL, S.OCCLUDED_SEVERE, K.OCCLUSION_START, "T4 occluded-severe (why)"),
    (S.OCCLUDED_PARTIAL, S.TRACKING, K.OCCLUSION_END, "T4 visible again (why)"),
    (S.OCCLUDED_SEVERE, S.TRACKING, K.OCCLUSION_END, "T4 visible again (why)"),
]
SILENT = [(s, s) for s in S] + [(S.OCCLUDED_SEVERE, S.OCCLUDED_PARTIAL)]
REFUSED = [(s, S.TENTATIVE) for s in S if s != S.TENTATIVE] + [
    (S.TENTATIVE, s) for s in S if s not in (S.TENTATIVE, S.TRACKING)
]


@pytest.mark.parametrize(("old", "new", "kind", "text"), MOVES)
def test_each_move_names_its_event(old, new, kind, text):
    (e,) = transition(4, old, new, "why")
    assert (e.kind, e.text, e.target_ids) == (kind, text, (4,))


@pytest.mark.parametrize(("old", "new"), SILENT)
def test_moves_without_an_event(old, new):
    assert allowed(old, new)
    assert transition(4, old, new, "why") == ()


@pytest.mark.parametrize(("old", "new"), REFUSED)
def test_moves_the_lifecycle_does_not_have_are_refused(old, new):
    assert not allowed(old, new)
    with pytest.raises(ValueError, match=f"no move from {old} to {new}"):
        transition(4, old, new, "why")


def test_every_pair_of_statuses_is_decided():
    """The tables above cover every ordered pair of statuses once."""
    pairs = [(o, n) for o, n, *_ in MOVES] + SILENT + REFUSED
    assert len(pairs) == len(set(pairs))
    # the rest are allowed moves whose kind the module's table also gives: check they are named
    for old in S:
        for new in S:
            if (old, new) in pairs:
                continue
            assert allowed(old, new)
            assert transition(4, old, new, "x"), (old, new)


def test_born():
    (e,) = born(7, "detected at (10,20)")
    assert (e.kind, e.text, e.target_ids) == (K.BIRTH, "T7 born (detected at (10,20))", (7,))


STATUS_KINDS = {K.LOST, K.REACQUIRED, K.CONFIRMED, K.MERGE, K.SPLIT}
STATUS_KINDS |= {K.OCCLUSION_START, K.OCCLUSION_END}


def _check_log(results) -> dict[EventKind, int]:
    """Every status change a run reports carries the lifecycle's event for it, in that frame, and
    every per-target status event belongs to a change; returns the kinds seen."""
    last: dict[int, TargetStatus] = {}
    seen: dict[EventKind, int] = {}
    for r in results:
        events: dict[int, list[EventKind]] = {}
        for e in r.events:
            if e.kind in STATUS_KINDS | {K.BIRTH} and len(e.target_ids) == 1:
                events.setdefault(e.target_ids[0], []).append(e.kind)
                seen[e.kind] = seen.get(e.kind, 0) + 1
        for t in r.targets:
            old = last.get(t.id)
            got = events.pop(t.id, [])
            if old is None:  # a target's first frame: born, or given at the start
                assert got in ([], [K.BIRTH], [K.REACQUIRED]), (r.frame, t.id, got)
            else:
                want = [e.kind for e in transition(t.id, old, t.status, "")]
                # one frame may hold two moves (merged into a blob, then lost in it)
                assert got == want or (got[-1:] == want and t.status == S.LOST), (
                    r.frame,
                    t.id,
                    old,
                    t.status,
                    got,
                )
            last[t.id] = t.status
        assert not events, (r.frame, events)  # no event for a target the frame does not report
    return seen


def test_dual_log_follows_its_statuses(scene):
    # three walkers crossing: targets that meet yield to each other (merged) and part (split)
    seen = _check_log(track(scene("crossing3"), tracker="dual"))
    assert seen.get(K.MERGE, 0) >= 1 and seen.get(K.SPLIT, 0) >= 1
    # a walker behind an occluder: hidden and seen again
    seen = _check_log(track(scene("occluded-moving"), tracker="dual"))
    assert seen.get(K.OCCLUSION_START, 0) >= 1 and seen.get(K.OCCLUSION_END, 0) >= 1


def test_dual_with_groups_log_follows_its_statuses(scene):
    cfg = load_config(None, ["dual.groups=default"])
    _check_log(track(scene("meet-part"), tracker="dual", config=cfg))


def test_detect_log_follows_its_statuses(scene):
    seen = _check_log(track(scene("crossing2"), tracker="detect"))
    assert seen.get(K.BIRTH, 0) >= 2 and seen.get(K.CONFIRMED, 0) >= 2


def test_kalman_camshift_log_follows_its_statuses(scene):
    cfg = load_config(
        None,
        [
            "kalman_camshift.occlusion.max_severe_frames=3",
            "kalman_camshift.occlusion.distance_threshold=0.4",
        ],
    )
    seen = _check_log(track(scene("occluded-moving"), tracker="kalman-camshift", config=cfg))
    assert seen.get(K.OCCLUSION_START, 0) >= 1


def test_meanshift_log_follows_its_statuses(scene):
    _check_log(track(scene("occluded-moving"), tracker="meanshift"))


@pytest.mark.parametrize(
    ("x", "missing", "why"),
    [
        (10.0, 30, None),  # in view, at the limit
        (10.0, 31, "31 frames without a measurement"),
        (-30.0, 1, None),  # a quarter of it still in view
        (-31.0, 1, "left the frame"),
        (-31.0, 99, "left the frame"),  # the frame's edge is named first
    ],
)
def test_coast_ends_by_one_rule(x, missing, why):
    from pipeline.trackers.lifecycle import coast_ends
    from pipeline.types import BBox

    assert coast_ends(BBox(x, 0.0, 40.0, 10.0), (100, 100), missing, 30) == why


def test_engines_lose_a_target_for_the_same_reasons(scene):
    """On the meet-and-part scene the detector loses a track for its misses and Kalman-CAMShift
    loses both walkers at the frame's edge; every loss is worded by the one rule."""
    import re

    d = scene("meet-part")
    words = re.compile(r"^T\d+ lost \((left the frame|\d+ frames without a measurement)\)$")
    reasons = set()
    for tracker in ("detect", "kalman-camshift"):
        texts = [e.text for r in track(d, tracker=tracker) for e in r.events if e.kind == K.LOST]
        assert texts and all(words.match(t) for t in texts), (tracker, texts)
        reasons |= {words.match(t)[1].split()[-1] for t in texts}
    assert reasons == {"frame", "measurement"}


def test_decisions_reach_the_sinks_as_enums(scene, tmp_path):
    """Every dual result carries its decision's case and rule as the decider's enums, and
    ``targets.csv`` writes ``case:why`` from them."""
    import csv

    from pipeline.run import RunOptions, run_track
    from pipeline.trackers.dual.decide import Case, Rule

    d = scene("crossing2")
    res = track(d, tracker="dual")
    labels = [t.decision for r in res for t in r.targets]
    assert all(isinstance(x.case, Case) and isinstance(x.rule, Rule) for x in labels)
    assert {x.case for x in labels} >= {Case.INIT, Case.CONTOUR}
    out = run_track(d, RunOptions(tracker="dual", out_dir=tmp_path / "r")).out_dir
    rows = list(csv.DictReader((out / "targets.csv").read_text().splitlines()))
    assert [r["decision"] for r in rows] == [str(x) for x in labels]
