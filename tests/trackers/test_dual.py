"""The dual tracker: sequence-level accuracy on the named scenes, the single-channel modes, eq. 7,
observability."""

from __future__ import annotations

import csv
import itertools
import math

import numpy as np
import pytest

from pipeline.config import load_config
from pipeline.errors import ConfigError
from pipeline.run import RunOptions, run_track, track
from pipeline.synthetic import ONE_TARGET_SCENES
from pipeline.trackers.dual import Case, DualConfig, Rule, scale_update
from tests.rrd_helpers import open_store, rows


def test_scale_update_eq7():
    assert scale_update((20.0, 40.0), (30.0, 50.0), 0.2) == pytest.approx((22.0, 42.0))
    assert scale_update((20.0, 40.0), (30.0, 50.0), 0.0) == (20.0, 40.0)
    assert scale_update((20.0, 40.0), (30.0, 50.0), 1.0) == (30.0, 50.0)


def test_the_colour_extent_widens_the_box_and_never_shrinks_it_below_the_filter():
    """The size part: a wider extent moves the width at eq. 7's rate past the filter's 1.25 bound
    (up to ``extent.max_ratio``); a narrower one pulls only down to the filter's size; without
    the extent part the size stays within ``scale_agree_ratio`` of the filter's."""
    from pipeline.tracker_config import SizeConfig
    from pipeline.trackers.dual.appearance import FilterCue
    from pipeline.trackers.dual.decide import decision
    from pipeline.trackers.dual.size import SizeModel
    from pipeline.types import BBox

    model = SizeModel(SizeConfig())
    dec = decision(Case.APPEARANCE, Rule.APPEARANCE_OVER_CONTOUR, BBox.from_center(50, 50, 10, 30))
    cue = FilterCue(BBox.from_center(50, 50, 10, 30), 20.0, 1.0, False)

    def update(size, extent, ratio):
        return model.update(size, (10.0, 30.0), dec, None, cue, True, extent, ratio)

    wide = BBox.from_center(50, 50, 20, 30)
    size, app_size = update((10.0, 30.0), wide, 1.8)
    assert size == pytest.approx((12.0, 30.0)) and app_size == (10.0, 30.0)
    for _ in range(30):
        size, _ = update(size, wide, 1.8)
    assert size == pytest.approx((18.0, 30.0))  # held at 1.8 x the filter's width
    size, _ = update((12.0, 30.0), BBox.from_center(50, 50, 6, 20), 1.8)
    assert size == pytest.approx((11.6, 30.0))  # towards the filter's 10, not the extent's 6
    # without the extent part (no extent, a ratio of 1) the size is held within scale_agree_ratio
    assert update((15.0, 30.0), None, 1.0)[0] == pytest.approx((12.5, 30.0))
    assert update((15.0, 30.0), None, 1.8)[0] == pytest.approx((15.0, 30.0))


def test_the_box_follows_a_walking_persons_stride(tmp_path):
    """Random development seed 14: a person given standing (10 x 38 px) walks with its legs spread
    (truth 15-19 px wide). With the colour extent the width follows; the filter's one scale factor
    alone keeps it at 10."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 14, targets=1, progress=False)
    gt = np.loadtxt(d / "visible.txt", delimiter=",")
    ratio = {}
    for on in (True, False):
        res = run_track(
            d,
            RunOptions(
                tracker="dual",
                out_dir=tmp_path / str(on),
                rrd=False,
                plots=False,
                sets=[] if on else ["dual.extent=none"],
            ),
        )
        table = list(csv.DictReader((res.out_dir / "targets.csv").read_text().splitlines()))
        ratio[on] = float(
            np.median([float(r["w_px"]) / gt[int(r["frame"]) - 1, 2] for r in table[20:]])
        )
    assert ratio[True] >= 0.85 and ratio[False] <= 0.7, ratio


TURN_PARTS_OFF = [
    "dual.decider.turn_search=false",
    "dual.decider.reach_missing=false",
    "dual.decider.jump_speed=0",
    "dual.motion.rewind_tolerance=0",
    "dual.decider.corroborate_psr=0",
]
GRID = ["dual.redetect.regions_in_radius=false"]
"""The widening search on its grid of places alone (the detector's regions in it left out), as the
tests of the turn parts measured it: with the regions, a target lost at a turn is also found
where it stands out against the background, which the ablations below do not isolate."""
"""The parts that look where a turn takes a target, or take it back where the filter and the
colour agree on it, off: the motion prediction alone."""


def _p20(d, out, sets, target=None):
    res = run_track(d, RunOptions(tracker="dual", out_dir=out, rrd=False, plots=False, sets=sets))
    m = res.summary["metrics"]
    return m["targets"][target]["p20"] if target else m["p20"]


def _targets_table(d, out, sets) -> tuple[list[dict], dict]:
    """The dual tracker's ``targets.csv`` rows and summary metrics on ``d`` with ``sets``."""
    res = run_track(d, RunOptions(tracker="dual", out_dir=out, rrd=False, plots=False, sets=sets))
    rows = list(csv.DictReader((res.out_dir / "targets.csv").read_text().splitlines()))
    return rows, res.summary["metrics"]


def test_a_fast_target_is_taken_back_where_the_filter_and_the_colour_both_find_it(tmp_path):
    """Random development seed 52: a person 9 x 21 px running at 11 px a frame with 8 turns,
    whose colour a building's shadow dims (a match of 0.2-0.35 where it is). After a turn it
    coasts the wrong way; the filter finds it again at PSR 14-40, confident in both channels,
    where the mean shift converged too, but too far from the prediction and with too little
    colour for the other rules. Taken back there (``APPEARANCE_AND_COLOUR``), every such
    frame's box is within 5 px of the truth, and P@20 rises from 0.55 (the rule off) to 0.70
    (bounds with a margin of 0.05)."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 52, targets=1, progress=False)
    gt = np.loadtxt(d / "visible.txt", delimiter=",")
    rows, on = _targets_table(d, tmp_path / "on", [])
    _, off = _targets_table(d, tmp_path / "off", ["dual.decider.corroborate_psr=0"])
    taken = [r for r in rows if r["decision"] == "re-acquired:appearance-and-colour"]
    assert len(taken) >= 4, len(taken)
    for r in taken:
        g = gt[int(r["frame"]) - 1]
        cx, cy = float(r["x_px"]) + float(r["w_px"]) / 2, float(r["y_px"]) + float(r["h_px"]) / 2
        assert math.hypot(cx - g[0] - g[2] / 2, cy - g[1] - g[3] / 2) <= 5.0, r["frame"]
    assert on["p20"] >= 0.65 and off["p20"] <= 0.6, (on["p20"], off["p20"])


def test_a_target_the_ir_does_not_show_is_not_refused_as_background(tmp_path):
    """Random development seed 54: a person 10 px tall walking at 0.3 px a frame, then
    standing still, through a fall of the light to 0.29. The IR barely shows it (its filter's
    IR peak under 9) and its box differs from the IR background in under 5 % of its pixels,
    while the visible channel carries the filter at PSR 12-25. Refused as background (the
    rule off) it coasts and is lost for 113 frames, P@20 0.25; taken while the visible
    channel carries it without a break, P@20 0.745 (bounds with a margin of 0.05). The first
    filter's size check is off on both sides (with it, 0.71 against 0.675: the check alone
    keeps the tiny walker's box closer and the refusals fewer)."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 54, targets=1, progress=False)
    anchor_off = "dual.appearance.anchor_every_frames=0"
    rows, on = _targets_table(d, tmp_path / "on", [anchor_off])
    _, off = _targets_table(
        d, tmp_path / "off", [anchor_off, "dual.decider.visible_carries_psr=0"]
    )
    assert on["p20"] >= 0.69 and off["p20"] <= 0.3, (on["p20"], off["p20"])
    assert sum(r["status"] == "lost" for r in rows) <= 60


def test_an_approaching_target_s_box_grows_with_it(tmp_path):
    """Random development seed 76: a person 32 px tall walking towards the camera, 58 px by
    frame 160 (0.5 % a frame, under a tenth of the scale filter's step). The scale filter,
    learning each frame at the size it estimated, stays at 33-34 px (0.61 of the truth's
    height over the last third of the run, the first filter's check off); checked against the
    first frame's filter every 5 frames the box grows with the target (0.90 on an AMD EPYC). The
    compiled kernels round differently on an Intel Xeon and the run goes another way there (0.65
    against 0.58): the check's gain is what is asserted, with the processors' figures as bounds
    where they agree."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 76, targets=1, progress=False)
    gt = np.loadtxt(d / "visible.txt", delimiter=",")

    def height_ratio(sets):
        rows, _ = _targets_table(d, tmp_path / str(len(sets)), sets)
        h = [float(r["h_px"]) / g[3] for r, g in zip(rows, gt, strict=True)]
        return float(np.median(h[len(h) * 2 // 3 :]))

    on, off = height_ratio([]), height_ratio(["dual.appearance.anchor_every_frames=0"])
    assert on >= off + 0.05 and off <= 0.7, (on, off)


def test_a_target_that_turns_while_hidden_is_searched_for_where_it_was_seen(tmp_path):
    """Random development seed 1 (two targets), frame 28: target 1 turns back at 7 px per frame as
    it is lost; its coast runs on the other way. On the prediction's line alone (the turn parts
    off), the widened search around where it was last seen (at its own speed) takes it back at
    frame 31; around the prediction alone it is found only by the whole-frame search, 12 frames
    later. With the turn parts it is followed through its turns whichever way. The bounds hold
    with a margin of 0.04 over the spread of level-set step moves of +-1e-7 and +-2e-7 relative
    (seen 0.745-0.83, without it 0.50-0.56, default 0.71-0.875; 0.93 with the first filter's size
    check, which the two ablations leave off: with it and the turn parts off, target 1 is taken
    back elsewhere, 0.555)."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 1, targets=(2, 3), progress=False)
    off = [*TURN_PARTS_OFF, "dual.appearance.anchor_every_frames=0", *GRID]
    seen = _p20(d, tmp_path / "a", off, "1")
    unseen = _p20(d, tmp_path / "b", [*off, "dual.redetect.last_seen=false"], "1")
    default = _p20(d, tmp_path / "c", [], "1")
    assert seen >= 0.7 and unseen <= 0.6 and default >= 0.65, (seen, unseen, default)


def _runner(speed_px: float, height_px: float, xs=(60, 260, 120, 250, 80, 200)):
    """A person running to and fro across a plain street at ``speed_px`` a frame from its first
    frame, turning at each of ``xs`` (px): no distractor, no occluder."""
    from pipeline.synthetic.scenarios import PURPLE, keyframes
    from pipeline.synthetic.scene import Actor, Scene

    points, t = [(1.0, 60.0, 130.0, 1.0)], 1.0
    for a, b in itertools.pairwise(xs):
        t += abs(b - a) / speed_px
        points.append((t, float(b), 130.0, 1.0))
    runner = Actor(
        "person", height_px, keyframes(points), target_id=1, palette=PURPLE, facing_auto=True
    )
    return Scene("runner", "a runner turning to and fro", 320, 240, int(t), (runner,))


def test_a_fast_target_of_unknown_motion_is_measured_within_the_predictions_uncertainty(tmp_path):
    """A person 12 px wide runs at 12 px a frame from its first frame. The prediction for frame
    2 (no velocity known yet) is where it started, and the measurement lies farther than
    ``jump_fraction`` of its width from it: without ``jump_sigma`` (and the turn parts off) it is
    not taken and the target coasts where it started (P@20 about 0.2); with the prediction's
    uncertain velocity reached by ``jump_sigma`` deviations it is followed, turns included
    (about 0.9), and with the turn parts too on every frame. The outcome holds under
    rounding-level moves of the level set's step (``tools/rounding_spread.py``)."""
    from pipeline.synthetic import synthesize

    d = synthesize(_runner(12.0, 28.0), tmp_path / "s", seed=0, progress=False)
    sigma = _p20(d, tmp_path / "a", TURN_PARTS_OFF)
    neither = _p20(d, tmp_path / "b", [*TURN_PARTS_OFF, "dual.decider.jump_sigma=0"])
    default = _p20(d, tmp_path / "c", [])
    assert sigma >= 0.8 and neither <= 0.4 and default >= 0.95, (sigma, neither, default)


def test_a_target_walking_to_and_fro_is_followed_through_its_turns(tmp_path):
    """A person 26 px tall (11 px wide) walks to and fro at 10 px a frame, turning after 110 to
    180 px (every 11 to 18 frames), for 119 frames. It is followed with few coasting frames
    (P@20 0.983-1.000 and 0-2 coasting frames under level-set step moves of +-1e-7 and +-2e-7
    relative); without the filter's search behind the last measurement (``turn_search``) it
    coasts through the turns (P@20 0.563, 53 coasting frames), and likewise with a reach that
    does not grow with its speed (0.664, 40), each without the filter and colour's agreement
    (``corroborate_psr``), which takes it back after such a turn (the reach not growing: 0.849).
    The reach kept while missing and the coast not restarted on the line before a turn have
    their own tests (``reach_missing`` in ``test_dual_decide.py``, ``rewind_tolerance``
    below)."""
    from pipeline.synthetic import synthesize

    xs = (60, 200, 90, 260, 110, 230, 70, 250, 100)
    d = synthesize(_runner(10.0, 26.0, xs), tmp_path / "s", seed=0, progress=False)
    variants = {
        "all": [],
        "turns": ["dual.decider.turn_search=false", "dual.decider.corroborate_psr=0", *GRID],
        "reach-speed": ["dual.decider.jump_speed=0", "dual.decider.corroborate_psr=0", *GRID],
        "agreement": ["dual.decider.jump_speed=0"],
    }
    p20, coast = {}, {}
    for name, sets in variants.items():
        p20[name] = _p20(d, tmp_path / name, sets)
        rows = csv.DictReader((tmp_path / name / "targets.csv").read_text().splitlines())
        coast[name] = sum(r["decision"].startswith(("coast", "lost")) for r in rows)
    assert p20["all"] >= 0.95 and coast["all"] <= 5, (p20, coast)
    assert p20["turns"] <= 0.7 and p20["reach-speed"] <= 0.75, p20
    assert p20["agreement"] >= p20["reach-speed"] + 0.05, p20


def test_a_confident_peak_on_what_hid_the_target_does_not_stop_its_search(tmp_path):
    """Random development seed 83: a person walks behind a pillar; the filter, which learned the
    pillar's edge while the person passed it, keeps a confident peak there, away from the
    prediction. The search for the hidden target runs all the same and takes it back where it comes
    out (P@20 0.75 when that peak stopped the search)."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 83, targets=1, progress=False)
    res = run_track(d, RunOptions(tracker="dual", out_dir=tmp_path / "r", rrd=False, plots=False))
    assert res.summary["metrics"]["p20"] >= 0.9


def test_a_cold_cyclist_whose_contour_collapses_is_not_called_occluded(tmp_path):
    """Random development seed 39: a cyclist at nearly the ground's temperature, fully in view;
    its contour collapses from frame 2 while the filter and the colour (match 0.92-0.96) hold it.
    It is reported ``tracking`` on its first ten frames and its models learn there; where every
    collapse counted as a partial occlusion (``whole_colour_rho = 1``) it was ``occluded-partial``
    with frozen models, and its box fitted worse (AUC 0.750 against 0.783). Its first contour
    collapsed too, to its rider: the warm part (``contour.warm_part``, tested below) is left out
    here, so that the colour's rule is what is measured."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 39, targets=1, progress=False)
    tables, auc = {}, {}
    for whole in ("0.9", "1"):
        sets = [f"dual.decider.whole_colour_rho={whole}", "dual.contour.warm_part=false"]
        rows, metrics = _targets_table(d, tmp_path / whole, sets)
        tables[whole] = [r for r in rows if 2 <= int(r["frame"]) <= 10]
        auc[whole] = metrics["auc"]
    assert all("contour-collapse" in r["decision"] for r in tables["0.9"])
    assert all(r["status"] == "tracking" for r in tables["0.9"])
    assert all(r["model_update"].startswith("updated") for r in tables["0.9"])
    assert all(r["status"] == "occluded-partial" for r in tables["1"])
    assert all(r["model_update"].startswith("frozen") for r in tables["1"])
    assert auc["0.9"] >= auc["1"] + 0.02, auc


def test_a_missing_target_is_searched_for_with_its_first_filter_too():
    """A target's filter trained on its first frame (a patch of texture on a textured scene) and
    a filter that has since learned something else there (another texture): searched for at the
    place where the first look now is, far from its prediction, the missing target is found
    there with ``redetect.first_model`` (a confident peak within 1 px of its centre) and not by
    the current filter alone (no confident peak: nothing it learned is in the frame)."""
    import dataclasses

    import numpy as np

    from pipeline.io.sequence import FramePair
    from pipeline.stages import kalman
    from pipeline.trackers.dual import DualConfig
    from pipeline.trackers.dual.single import _redetect
    from pipeline.trackers.dual.state import DualTarget
    from pipeline.trackers.dual.tracker import Dual
    from pipeline.types import BBox, TargetStatus

    rng = np.random.default_rng(3)
    H, W, w, h = 160, 240, 20, 40

    def frame(patches):  # a fresh textured scene: only the planted patch repeats
        vis = rng.integers(0, 256, (H, W, 3), dtype=np.uint8)
        for (x, y), tex in patches:
            vis[y : y + h, x : x + w] = tex
        return FramePair(1, vis, vis[..., 0].copy())

    look = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)  # the target
    other = rng.integers(0, 256, (h, w, 3), dtype=np.uint8)  # what its filter learned later
    first = frame([((40, 60), look)])
    later = frame([((40, 60), other)])
    now = dataclasses.replace(frame([((170, 60), look)]), index=5)
    results = {}
    for on in (True, False):
        cfg = DualConfig()
        cfg = dataclasses.replace(cfg, redetect=dataclasses.replace(cfg.redetect, first_model=on))
        dual = Dual.from_config(cfg)
        box = BBox(40, 60, w, h)
        t = DualTarget(
            1,
            box,
            (w, h),
            np.ones(1),
            TargetStatus.OCCLUDED_SEVERE,
            dual.motion.start(box),
            appearance=dual.appearance.train(later, "dual", box),
            first_model=dual.appearance.train(first, "dual", box),
            app_size=(w, h),
            missing=3,
        )

        class Place:  # the search's candidates: the place where the target now is
            cfg = dual.redetector.cfg

            def candidates(self, frames, cs, size, background=None, occupied=()):
                return [(180.0, 80.0)]

        dual = dataclasses.replace(dual, redetector=Place())
        prior = kalman.GaussianState(np.array([50.0, 80.0, 0, 0, 0, 0]), np.eye(6))
        cs = type("CS", (), {"t": t, "prior": prior})()
        at_prior = dual.appearance.detect(t.appearance, now, "dual", (50.0, 80.0), (w, h))
        results[on] = _redetect(dual, now, cs, "dual", at_prior, None)
    (found, redetected), (alone, _) = results[True], results[False]
    assert redetected
    assert abs(found.center[0] - 180.0) <= 1 and abs(found.center[1] - 80.0) <= 1
    assert found.psr >= 9.0  # psr_reacquire
    assert alone.psr < 7.0  # psr_confident


def test_a_cyclist_whose_ir_shows_its_rider_is_not_called_occluded(tmp_path):
    """Random development seed 18: a cyclist (36 x 36 px) whose IR shows the rider (a warm 12 x
    18 px part) and not the bicycle, fully in view, its colour not matching the whole box. Its
    first contour collapses to the rider, and so does every later one. Taken as the target's
    warm part (``contour.warm_part``), those contours leave it ``tracking`` (96 of frames 2-100);
    without, every collapse is a partial occlusion (96 of 99 frames ``occluded-partial``), its
    models freeze, its box shrinks to 29 px against the truth's 41 and it is lost at frame 104.
    Over frames 1-130, before an occluder the filter can stick to comes in, the box overlaps the
    truth at IoU 0.5 on every frame with the warm part, on 0.80 of them without (bound 0.9)."""
    from pipeline.synthetic import synthesize_random
    from pipeline.types import BBox

    d = synthesize_random(tmp_path / "s", 18, targets=1, progress=False)
    gt = np.loadtxt(d / "visible.txt", delimiter=",")
    status, overlap = {}, {}
    for part in ("true", "false"):
        sets = [f"dual.contour.warm_part={part}"]
        rows, _ = _targets_table(d, tmp_path / part, sets)
        status[part] = [r["status"] for r in rows if 2 <= int(r["frame"]) <= 100]
        boxes = [BBox(*(float(r[k]) for k in ("x_px", "y_px", "w_px", "h_px"))) for r in rows]
        ious = [b.iou(BBox(*g[:4])) for b, g in zip(boxes[:130], gt[:130], strict=True)]
        overlap[part] = float(np.mean(np.array(ious) >= 0.5))
    assert status["true"].count("tracking") >= 85, status["true"]
    assert status["false"].count("occluded-partial") >= 85, status["false"]
    assert overlap["true"] >= 0.99 and overlap["false"] <= 0.9, overlap


def test_a_target_walking_in_through_the_border_grows_its_box(tmp_path):
    """Random development seed 34: a person given cut by the left border (9 x 33 px) walks in to
    its full width (18-19 px by frame 10). Its first clean contour inside the frame gives the box
    the width the border hid (``walked-in``): the width against the truth's goes from under 0.7
    before that frame to at least 0.75 after it."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 34, targets=1, progress=False)
    gt = np.loadtxt(d / "visible.txt", delimiter=",")
    res = run_track(d, RunOptions(tracker="dual", out_dir=tmp_path / "r", rrd=False, plots=False))
    table = list(csv.DictReader((res.out_dir / "targets.csv").read_text().splitlines()))
    walked = [int(r["frame"]) for r in table if r["decision"].endswith("walked-in")]
    assert walked and walked[0] <= 20, walked
    ratio = {int(r["frame"]): float(r["w_px"]) / gt[int(r["frame"]) - 1, 2] for r in table}
    before = float(np.median([ratio[f] for f in range(walked[0] - 4, walked[0])]))
    after = float(np.median([ratio[f] for f in range(walked[0], walked[0] + 9)]))
    assert before < 0.7 and after >= 0.75, (before, after)


def test_a_target_that_walked_in_is_searched_for_with_its_whole_first_filter(tmp_path):
    """Random development seed 34 again: the filter trained afresh on the frame the person has
    walked in whole by (``walked-in``) replaces the one trained on its cut first box as the
    filter the search for it tries besides its current one (``redetect.first_model``); before
    that frame it is the first frame's."""
    import cv2

    from pipeline.api import DualTracker
    from pipeline.synthetic import synthesize_random
    from pipeline.types import BBox

    d = synthesize_random(tmp_path / "s", 34, targets=1, progress=False)
    x, y, w, h = np.loadtxt(d / "visible.txt", delimiter=",")[0, :4]

    def frame(t):
        vis = cv2.imread(str(d / "visible" / f"{t:05d}v.jpg"))
        return vis, cv2.imread(str(d / "infrared" / f"{t:05d}i.jpg"), 0)

    tr = DualTracker()
    tr.start(frame(1), [BBox(x, y, w, h)])
    first = tr._engine.state.targets[0].first_model
    walked = None
    for t in range(2, 21):
        result = tr.step(frame(t))
        target = tr._engine.state.targets[0]
        if result.targets[0].decision.rule == Rule.WALKED_IN:
            walked = t
            assert target.first_model is target.appearance
            break
        assert target.first_model is first
    assert walked is not None


def test_a_measurement_over_a_collapsed_contour_teaches_nothing_beside_another_target():
    """Another target's box within half a box of the measurement (either side, either axis):
    the colour match cannot tell that target from this one, so the models do not learn there."""
    from pipeline.trackers.dual.single import _near_another
    from pipeline.types import BBox

    box = BBox(100, 100, 20, 40)
    assert not _near_another(box, ())
    assert not _near_another(None, (box,))
    assert _near_another(box, (BBox(129, 100, 20, 40),))  # 9 px to the right: within 10
    assert not _near_another(box, (BBox(131, 100, 20, 40),))
    assert _near_another(box, (BBox(100, 45, 20, 40),))  # 15 px above: within 20
    assert not _near_another(box, (BBox(100, 39, 20, 40),))


def test_a_target_found_again_restarts_its_motion_at_rest():
    """The motion part: a lost target re-acquired 100 px from where it was believed to be, or
    one found there by the re-detection search or by two cues that agree, gets the measured
    position and zero velocity (the jump is not its motion); re-acquired near its prediction
    after an occlusion, the Kalman correction keeps its velocity."""
    from pipeline.stages import kalman
    from pipeline.trackers.dual.decide import decision
    from pipeline.trackers.dual.motion import Motion
    from pipeline.trackers.dual.state import DualTarget
    from pipeline.types import BBox, TargetStatus

    cfg = DualConfig()
    motion = Motion(cfg.motion, cfg.kalman)
    kf = kalman.init_state(BBox.from_center(300, 100, 12, 30), cfg.kalman)
    kf = kalman.GaussianState(np.r_[kf.x[:4], 8.0, 0.0, kf.x[6:]], kf.P * 50)
    found = BBox.from_center(200, 100, 12, 30)
    for status, rule, moving in (
        (TargetStatus.LOST, Rule.APPEARANCE_NEAR_PREDICTION, False),
        (TargetStatus.OCCLUDED_PARTIAL, Rule.REDETECTED, False),
        (TargetStatus.OCCLUDED_PARTIAL, Rule.APPEARANCE_AND_COLOUR, False),
        (TargetStatus.OCCLUDED_PARTIAL, Rule.APPEARANCE_NEAR_PREDICTION, True),
    ):
        t = DualTarget(1, found, (12.0, 30.0), np.ones(4) / 4, status, kf, missing=5)
        dec = decision(Case.REACQUIRED, rule, found, 1.5, stage="appearance")
        new, history, _ = motion.update(t, kf, dec, found, 50)
        if moving:
            assert abs(new.x[4]) > 1.0, rule
        else:
            assert tuple(new.x[:2]) == (200.0, 100.0) and not new.x[4:].any(), (status, rule)
            assert history == ((50.0, 200.0, 100.0, 12.0, 30.0),)


def test_recent_speed_and_last_seen():
    from pipeline.tracker_config import RedetectConfig
    from pipeline.trackers.dual.redetect import Redetector, recent_speed
    from pipeline.trackers.dual.state import DualTarget

    t = DualTarget.__new__(DualTarget)
    object.__setattr__(
        t, "history", ((10.0, 100.0, 50.0, 10.0, 20.0), (14.0, 112.0, 66.0, 10.0, 20.0))
    )
    assert recent_speed(t) == pytest.approx(5.0)
    assert Redetector(RedetectConfig()).last_seen(t) == (112.0, 66.0)
    assert Redetector(RedetectConfig(last_seen=False)).last_seen(t) is None
    object.__setattr__(t, "history", ())
    assert recent_speed(t) == 0.0 and Redetector(RedetectConfig()).last_seen(t) is None


def test_acceptance_on_the_synthetic_scenes(scene, tmp_path):
    p20, auc = {}, {}
    for name in ONE_TARGET_SCENES:
        res = run_track(
            scene(name),
            RunOptions(tracker="dual", out_dir=tmp_path / name, rrd=False, plots=False),
        )
        m = res.summary["metrics"]
        p20[name], auc[name] = m["p20"], m["auc"]
    assert min(p20.values()) >= 0.9, p20
    assert np.mean(list(p20.values())) >= 0.95, p20
    assert np.mean(list(auc.values())) >= 0.75, auc


def test_beats_the_colour_only_tracker_where_colour_fails(scene):
    """Shadows and a pillar defeat visible mean shift (measured P@20 0.44 and 0.50), darkness ruins
    its box (AUC 0.38); the IR contour and the motion prior keep the target."""
    from pipeline.eval.single import center_errors, ious, success_curve
    from pipeline.io.sequence import open_sequence

    def score(d, trk):
        gt = open_sequence(d).truth.primary()[1]
        boxes = np.array([r.targets[0].box.as_tuple() for r in track(d, tracker=trk)])
        e = center_errors(boxes, gt)
        return float(np.mean(e[~np.isnan(e)] <= 20)), float(
            np.mean(success_curve(ious(boxes, gt)))
        )

    for name in ("shadows", "occluder"):
        dual, ms = score(scene(name), "dual"), score(scene(name), "meanshift")
        assert dual[0] >= 0.95 and ms[0] < 0.7, (name, dual, ms)
    dual, ms = score(scene("dusk"), "dual"), score(scene("dusk"), "meanshift")
    assert dual[1] >= ms[1] + 0.3, (dual, ms)


def test_strong_colour_carries_a_target_whose_contour_fails(scene, tmp_path):
    """Fast curved motion, seed 1, without the correlation filter: the contour loses the legs
    (shape change) while colour matches at rho 0.9. Trusting that colour keeps the target; so does
    coasting on the prediction, as long as the coast is not restarted on the line of the frames
    before a turn (``motion.rewind_tolerance``); coasting on that line loses it."""
    d = scene("fast", seed=1)
    alone = ["dual.appearance=none"]
    coast = [*alone, "dual.decider.colour_trust_rho=1"]
    assert _p20(d, tmp_path / "a", alone) >= 0.95
    assert _p20(d, tmp_path / "b", coast) >= 0.95  # the coast does not rewind past a turn
    assert _p20(d, tmp_path / "c", [*coast, "dual.motion.rewind_tolerance=0"]) < 0.7
    table = list(csv.DictReader((tmp_path / "a" / "targets.csv").read_text().splitlines()))
    assert any(r["source"] == "meanshift" and r["status"] == "tracking" for r in table)


def test_contours_statuses_and_reasons_are_recorded(scene, tmp_path):
    out = run_track(scene("crossover"), RunOptions(tracker="dual", out_dir=tmp_path / "r")).out_dir
    table = list(csv.DictReader((out / "targets.csv").read_text().splitlines()))
    sources = {r["source"] for r in table}
    assert {
        "levelset",
        "appearance",
    } <= sources  # the IR fades: the filter carries the target for a while
    cases = {r["decision"].split(":")[0] for r in table}
    assert {"init", "contour", "appearance"} <= cases <= {c.value for c in Case} | {"init"}
    assert all(":" in r["decision"] and r["decision"].split(":")[1] for r in table)
    assert any("contour-low-contrast" in r["model_update"] for r in table)
    assert all(
        "levelset=" in r["iterations"] and "meanshift=" in r["iterations"] for r in table[1:]
    )
    assert any(r["model_update"].startswith("updated:") for r in table)
    store = open_store(out / "run.rrd")
    strips = rows(store, "/infrared/contours", ["LineStrips2D:strips"])
    assert strips.num_rows == 240
    paths = {str(p) for p in store.schema().entity_paths()}
    assert {"/targets/1/status", "/targets/1/decision"} <= paths
    decisions = rows(store, "/targets/1/decision", ["StateChange:state"])
    assert decisions.num_rows >= 3  # written when the case or its reason changes


def test_ir_only_mode_on_real_thermal_footage(realdata, tmp_path):
    res = run_track(
        realdata / "vottir-horse", RunOptions(tracker="dual", out_dir=tmp_path / "h", plots=False)
    )
    assert res.summary["channels"] == ["infrared"] and res.complete
    table = list(csv.DictReader((res.out_dir / "targets.csv").read_text().splitlines()))
    assert "levelset" in {r["source"] for r in table}
    assert res.summary["metrics"]["p20"] >= 0.5


def test_visible_only_mode_is_the_same_tracker_with_the_visible_cues(realdata, tmp_path):
    """No hand-off to another engine: colour and the filter's visible features measure the target,
    and the box keeps its size (the meanshift engine's +-10 % scale search inflated it 3.9x on
    footage like this)."""
    res = run_track(
        realdata / "otb-crossing",
        RunOptions(tracker="dual", out_dir=tmp_path / "d", rrd=False, plots=False),
    )
    assert res.summary["channels"] == ["visible"]
    table = list(csv.DictReader((res.out_dir / "targets.csv").read_text().splitlines()))
    assert {r["source"] for r in table[1:]} <= {"appearance", "meanshift", "kalman"}
    assert "levelset=0" in table[5]["iterations"]
    area = np.array([float(r["w_px"]) * float(r["h_px"]) for r in table])
    assert 0.6 <= np.median(area) / area[0] <= 1.6
    assert res.summary["metrics"]["p20"] >= 0.95


@pytest.mark.parametrize(
    "item",
    [
        "dual.size.scale_rate=1.5",
        "dual.lifecycle.max_missing_frames=0",
        "dual.levelset.timestep=9",
        "dual.contour.cold_start_scale=0.5",
        "dual.model_update.rank_rule=best",
        "dual.contour.start_at=nowhere",
        "dual.motion.search_from=nowhere",
    ],
)
def test_bad_configs_rejected(item):
    with pytest.raises(ConfigError, match=item.split("=")[0].replace(".", "\\.")):
        load_config(None, [item])
    assert DualConfig().size.scale_rate == 0.2


def _walking_scene(seed: int, rows: slice, cols: tuple[int, int], warmth: float, *more):
    """A textured ground (25 frames, noise 2 grey levels) where a patch ``warmth`` grey levels
    warmer (``rows``, and columns ``cols`` from a 22 px wide walker's left edge at ``20 + 10 k``)
    walks right at 10 px a frame (and each of ``more``, ``(rows, cols, warmth)`` patches walking
    with it): the sequence's background and frame 13 (the walker's left edge at 140)."""
    import cv2

    from pipeline.io.sequence import FramePair
    from pipeline.stages.detection import DetectionConfig, quantile_background

    rng = np.random.default_rng(seed)
    ground = cv2.GaussianBlur(rng.normal(90, 25, (240, 320)), (0, 0), 3)
    frames = []
    for k in range(25):
        img = ground + rng.normal(0, 2, ground.shape)
        x = 20 + 10 * k
        for r, c, warm in ((rows, cols, warmth), *more):
            img[r, x + c[0] : x + c[1]] += warm
        frames.append(np.clip(img, 0, 255).astype(np.uint8))
    return quantile_background(frames, DetectionConfig()), FramePair(13, None, frames[12])


def _missing_step(missing: int, speed: float, history: tuple, y0: tuple[float, float]):
    """The colour step of a target missing for ``missing`` frames, predicted at ``y0`` (its mean
    shift there too, without colour), with its speed and clean-measurement history."""
    from pipeline.stages import kalman
    from pipeline.trackers.dual.colour import ColourStep
    from pipeline.trackers.dual.state import DualTarget

    t = DualTarget.__new__(DualTarget)
    for k, v in {"missing": missing, "speed": speed, "history": history}.items():
        object.__setattr__(t, k, v)
    prior = kalman.GaussianState(np.zeros(8), np.eye(8))
    return ColourStep(t, prior, y0, y0, float("nan"), False, 0.0, None, (0, 0), 0)


def test_the_whole_frame_search_finds_a_faint_target_against_the_sequence_background():
    """Candidates for a target lost anywhere: against the frame's own spatial background a faint
    person on a textured ground is missed or misplaced (the texture raises the threshold); against
    the sequence's he is the one candidate, at his centre."""
    from pipeline.tracker_config import RedetectConfig
    from pipeline.trackers.dual.redetect import Redetector

    bg, fp = _walking_scene(11, slice(80, 136), (0, 22), 12)  # a faint person, textured ground
    search = Redetector(RedetectConfig(candidates=4))
    truth = (20 + 120 + 11, 108)
    with_bg = search.frame_candidates(fp, (22, 56), bg)
    assert len(with_bg) == 1 and with_bg[0] == pytest.approx(truth, abs=2.0)
    own = search.frame_candidates(fp, (22, 56))  # missed, or a piece of him joined to the texture
    assert not any(abs(c[0] - truth[0]) < 4 and abs(c[1] - truth[1]) < 4 for c in own), own


def test_the_whole_frame_search_tries_a_fragment_of_the_target():
    """A target whose IR shows only a warm part (a torso above legs and a frame at the ground's
    temperature) gives the detector a region of a tenth of its box: the search tries it (the
    filter's window around it holds the whole target); taking only regions of about the
    target's size, it tried nothing."""
    from pipeline.tracker_config import RedetectConfig
    from pipeline.trackers.dual.redetect import Redetector

    bg, fp = _walking_scene(5, slice(90, 102), (7, 15), 40)  # an 8 x 12 px torso of 22 x 56
    torso = (20 + 120 + 11, 96)
    found = Redetector(RedetectConfig()).frame_candidates(fp, (22, 56), bg)
    assert len(found) == 1 and found[0] == pytest.approx(torso, abs=2.0)
    whole_only = Redetector(RedetectConfig(min_region_area_ratio=0.25))
    assert whole_only.frame_candidates(fp, (22, 56), bg) == []


def test_the_widening_search_tries_the_regions_within_its_radius_first():
    """A target missing for 4 frames, last seen walking at 10 px a frame: a person standing out
    against the sequence background 50 px behind its prediction (it turned) is the first place
    tried, before the grid's; not where that place lies inside another target's box, and not
    at all with ``regions_in_radius`` off (the grid alone passes 6 px from it)."""
    from pipeline.tracker_config import RedetectConfig
    from pipeline.trackers.dual.redetect import Redetector
    from pipeline.types import BBox

    bg, fp = _walking_scene(3, slice(80, 136), (0, 22), 40)
    person = (20 + 120 + 11, 108)
    history = ((8.0, 161.0, 108.0, 22.0, 56.0), (9.0, 171.0, 108.0, 22.0, 56.0))
    cs = _missing_step(4, 10.0, history, (person[0] + 50.0, 108.0))  # predicted 50 px past him
    search = Redetector(RedetectConfig())
    found = search.candidates(fp, cs, (22, 56), bg)
    assert found[0] == pytest.approx(person, abs=2.0)
    assert len(found) == RedetectConfig().candidates  # the grid fills the rest
    other = BBox(person[0] - 15, 70, 30, 80)  # another target's box holds him
    held = search.candidates(fp, cs, (22, 56), bg, (other,))
    grid_only = Redetector(RedetectConfig(regions_in_radius=False)).candidates(
        fp, cs, (22, 56), bg
    )
    for cands in (held, grid_only):
        assert not any(abs(c[0] - person[0]) < 2 and abs(c[1] - person[1]) < 2 for c in cands)
    assert held == grid_only


def test_a_target_lost_before_its_speed_is_known_is_searched_at_the_prior_speed():
    """A target given at frame 5 and lost on its next frame (one clean measurement, no speed),
    missing for 8 frames at its given place while it walked on at 10 px a frame: the region
    widens at ``unknown_speed_px_per_frame`` and takes in the person 80 px on; at 3 px a frame
    (the rule off) it does not. A target known to stand still widens at 3 px a frame."""
    import math

    from pipeline.tracker_config import RedetectConfig
    from pipeline.trackers.dual.redetect import Redetector

    bg, fp = _walking_scene(3, slice(80, 136), (0, 22), 40)
    person, given = (20 + 120 + 11, 108), (20 + 40 + 11.0, 108.0)
    cs = _missing_step(8, 0.0, ((5.0, *given, 22.0, 56.0),), given)
    half = 0.5 * math.hypot(22, 56)
    search = Redetector(RedetectConfig())
    assert search._region(cs, (22, 56))[1] == pytest.approx(half + 10 * 8)
    found = search.candidates(fp, cs, (22, 56), bg)
    assert found[0] == pytest.approx(person, abs=2.0)
    off = Redetector(RedetectConfig(unknown_speed_px_per_frame=0))
    assert off._region(cs, (22, 56))[1] == pytest.approx(half + 3 * 8)
    cands = off.candidates(fp, cs, (22, 56), bg)
    assert not any(abs(c[0] - person[0]) < 2 and abs(c[1] - person[1]) < 2 for c in cands)
    still = _missing_step(8, 0.0, ((4.0, *given, 22.0, 56.0), (5.0, *given, 22.0, 56.0)), given)
    assert search._region(still, (22, 56))[1] == pytest.approx(half + 3 * 8)


def test_the_search_detects_once_a_frame_and_takes_the_regions_near_before_the_cap(monkeypatch):
    """Two missing targets searching one frame run the detector once (a new frame once more);
    with one place a search, the whole-frame search takes the region of the target's size 150 px
    away, and the widening search the part of the target beside its prediction."""
    import dataclasses

    from pipeline.stages import detection
    from pipeline.tracker_config import RedetectConfig
    from pipeline.trackers.dual.redetect import Redetector

    bg, fp = _walking_scene(5, slice(90, 102), (7, 15), 40, (slice(80, 136), (150, 172), 40))
    torso, far = (151, 96), (301, 108)
    calls = []
    real = detection.detect
    monkeypatch.setattr(detection, "detect", lambda *a, **k: calls.append(1) or real(*a, **k))
    search = Redetector(RedetectConfig(candidates=1))
    assert search.frame_candidates(fp, (22, 56), bg)[0] == pytest.approx(far, abs=2.0)
    cs = _missing_step(2, 0.0, (), (torso[0] + 10.0, 108.0))
    assert search.candidates(fp, cs, (22, 56), bg)[0] == pytest.approx(torso, abs=2.0)
    assert len(calls) == 1
    search.frame_candidates(dataclasses.replace(fp, infrared=fp.infrared.copy()), (22, 56), bg)
    assert len(calls) == 2


def test_the_runner_gives_the_dual_tracker_the_sequence_background(scene):
    from pipeline.io.sequence import open_sequence
    from pipeline.trackers import make_tracker
    from pipeline.trackers.base import attach_sequence
    from pipeline.types import BBox, InitTarget

    seq = open_sequence(scene("crossing2"))
    engine = make_tracker("dual", load_config(None, []))
    attach_sequence(engine, seq)
    frames = seq.frames()
    engine.start(next(frames), [InitTarget(1, BBox(*seq.truth.primary()[1][0]))])
    engine.step(next(frames))
    assert (
        callable(engine.state.background) and engine.state.background().static
    )  # read only when asked
    plain = make_tracker(
        "dual", load_config(None, ["dual.redetect.detection.background_init=first-frame"])
    )
    attach_sequence(plain, seq)
    plain.start(seq.frame(1), [InitTarget(1, BBox(*seq.truth.primary()[1][0]))])
    assert plain.state.background is None


def test_the_stages_candidate_boxes_are_apart_from_the_targets_own(scene, tmp_path):
    """In the recording each stage's candidate box is coloured by its stage and named for it,
    not drawn in the target's colour with its label (a target looked like three or four "T1"
    boxes)."""
    from pipeline.sinks.rerun_sink import OVERLAY_COLORS

    out = run_track(scene("crossover"), RunOptions(out_dir=tmp_path / "r", plots=False)).out_dir
    store = open_store(out / "run.rrd")
    for stage in ("prediction", "meanshift", "appearance"):
        t = rows(
            store, f"/visible/{stage}", ["Boxes2D:labels", "Boxes2D:class_ids", "Boxes2D:colors"]
        )
        r = t.to_pylist()[5]
        assert r["Boxes2D:labels"] == [f"T1 {stage}"] and not r.get("Boxes2D:class_ids")
        rgb = tuple(int(r["Boxes2D:colors"][0]) >> s & 255 for s in (24, 16, 8))
        assert rgb == OVERLAY_COLORS[stage]


_NEW_SIGNATURES = """
import sys
import numba.core.registry
from pipeline.config import PipelineConfig
from pipeline.io.init import resolve_init
from pipeline.io.sequence import open_sequence
from pipeline.trackers import make_tracker
from pipeline.trackers.base import attach_sequence

def signatures():
    return {
        (name, k, str(s))
        for name, mod in list(sys.modules.items())
        if name.startswith("pipeline") and mod is not None
        for k, obj in list(vars(mod).items())
        if isinstance(obj, numba.core.registry.CPUDispatcher)
        for s in obj.signatures
    }

seq = open_sequence(sys.argv[2])
for tracker in sys.argv[1].split(","):
    engine = make_tracker(tracker, PipelineConfig())
    attach_sequence(engine, seq)
    before = signatures()
    pairs = seq.frames(1, None)
    engine.start(next(pairs), resolve_init(seq, None))
    for p in pairs:
        engine.step(p)
    for name, k, s in sorted(signatures() - before):
        print(tracker, name, k, s)
"""


def test_no_kernel_is_compiled_or_loaded_after_the_engine_is_built(scene):
    """Every numba kernel an engine calls on a sequence is compiled or loaded when the engine is
    built, not on the first timed frames: a fresh process running dual (an occlusion and its
    whole-frame search included), meanshift, kalman-camshift and detect through the occluder
    scene adds no kernel signature (the mean-shift loop used to load on the first frame, 7 ms
    counted as tracking time)."""
    import subprocess
    import sys

    out = subprocess.run(
        [
            sys.executable,
            "-c",
            _NEW_SIGNATURES,
            "dual,meanshift,kalman-camshift,detect",
            scene("occluder"),
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout == ""


def test_the_whole_frame_search_leaves_out_the_places_other_targets_hold():
    """A target missing for 12 frames is looked for over the whole frame: a person there is
    tried, unless another target's box holds him this frame (a look-alike another target
    follows is that target); a second person, free, is still tried."""
    from pipeline.tracker_config import RedetectConfig
    from pipeline.trackers.dual.redetect import Redetector
    from pipeline.types import BBox

    bg, fp = _walking_scene(5, slice(80, 136), (0, 22), 40, (slice(80, 136), (150, 172), 40))
    held, free = (151, 108), (301, 108)
    search = Redetector(RedetectConfig())
    cs = _missing_step(12, 0.0, (), (60.0, 108.0))

    def near(cands, p):
        return any(abs(c[0] - p[0]) < 2 and abs(c[1] - p[1]) < 2 for c in cands)

    everyone = search.candidates(fp, cs, (22, 56), bg)
    assert near(everyone, held) and near(everyone, free)
    other = BBox(held[0] - 15, 75, 30, 66)  # another target's box over the first person
    left = search.candidates(fp, cs, (22, 56), bg, (other,))
    assert not near(left, held) and near(left, free)
