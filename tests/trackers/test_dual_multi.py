"""Many targets through mutual occlusion: merge, split, re-association, events."""

from __future__ import annotations

import csv
import itertools

import numpy as np
import pyarrow.compute as pc
import pytest

from pipeline.run import RunOptions, run_track
from pipeline.types import BBox
from tests.rrd_helpers import open_store, rows, texts


def metrics(path, tmp_path, name, sets=()):
    res = run_track(
        path,
        RunOptions(
            tracker="dual", out_dir=tmp_path / name, rrd=False, plots=False, sets=list(sets)
        ),
    )
    return res.summary["metrics"]


@pytest.mark.parametrize("name", ["crossing2", "crossing3", "meet-part"])
def test_identities_survive_crossings_and_lookalikes_side_by_side(scene, tmp_path, name):
    m = metrics(scene(name), tmp_path, name)
    assert m["id_switches"] == 0, m["purity"]
    assert m["purity"]["overall"] >= 0.98, m["purity"]
    assert m["p20"] >= 0.95, m["targets"]


def test_overlapping_targets_teach_their_models_nothing(tmp_path):
    """Random development seed 58 (two targets that overlap from frame 3 and again at the end).
    Learning through the overlap, each model takes in the other target's pixels: the colour
    model updates on 30 target-frames of the 34 frames whose boxes overlap by IoU 0.2 and IDF1
    is 0.84-0.87 under rounding-level moves of the level set's step (0.80 before the first
    colour model left out the nearer target's pixels); with ``decider.overlap_freezes`` no
    model learns on any of them and IDF1 is 0.97-0.98 (the boxes keep their own targets'
    sizes; P@20 is 1.000 either way)."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 58, targets=(2, 3), progress=False)
    found = {}
    for on in (True, False):
        out = tmp_path / str(on)
        sets = [] if on else ["dual.decider.overlap_freezes=false"]
        res = run_track(d, RunOptions(out_dir=out, rrd=False, plots=False, sets=sets))
        table = list(csv.DictReader((out / "targets.csv").read_text().splitlines()))
        by_frame: dict[int, dict[str, dict]] = {}
        for r in table:
            by_frame.setdefault(int(r["frame"]), {})[r["id"]] = r

        def box(r):
            return BBox(*(float(r[c]) for c in ("x_px", "y_px", "w_px", "h_px")))

        overlap = [
            f
            for f, pair in by_frame.items()
            if f > 1 and len(pair) == 2 and box(pair["1"]).iou(box(pair["2"])) >= 0.2
        ]
        learned = [
            (f, i)
            for f in overlap
            for i in ("1", "2")
            if by_frame[f][i]["model_update"].startswith("updated")
        ]
        found[on] = (len(overlap), len(learned), res.summary["metrics"]["idf1"])
    assert found[True][0] >= 20 and found[True][1] == 0, found
    assert found[False][1] >= 10, found
    assert found[True][2] >= 0.93 and found[False][2] <= 0.9, found


def test_group_of_three_merging_at_once(scene, tmp_path):
    """The group scene. Measured on seeds 0-2: purity 0.988 / 0.992 / 0.978, no ID
    switch, P@20 0.998 (AMD EPYC; on an Intel Xeon, whose compiled kernels round differently,
    seed 0 gives 0.975); without keeping coasting members inside the merged blob 0.925 / 0.928 /
    0.937 with 2 / 2 / 0 switches; independent tracking without merge handling: P@20 0.79, purity
    0.70, 3 switches."""
    m = metrics(scene("group3"), tmp_path, "group3")
    assert m["p20"] >= 0.97, m["targets"]
    assert m["purity"]["overall"] >= 0.97, m["purity"]
    assert m["id_switches"] == 0
    # what the merge handling itself is worth, without the correlation filter (which keeps most
    # identities alone)
    paper = metrics(
        scene("group3"),
        tmp_path,
        "merge",
        ["dual.appearance=none", "dual.groups=default"],
    )
    coasting = metrics(
        scene("group3"),
        tmp_path,
        "coast",
        ["dual.appearance=none", "dual.groups.inside_blob=false"],
    )
    assert paper["purity"]["overall"] >= coasting["purity"]["overall"] + 0.03, (
        paper["purity"],
        coasting["purity"],
    )
    indep = metrics(
        scene("group3"),
        tmp_path,
        "indep",
        ["dual.appearance=none", "dual.groups=none"],
    )
    assert paper["purity"]["overall"] >= indep["purity"]["overall"] + 0.1, (
        paper["purity"],
        indep["purity"],
    )


def test_lookalikes_need_the_beyond_the_paper_placement(scene, tmp_path):
    """The paper's eq. 11 with mean shift for the foreground lets one twin's mean shift slide onto
    the other."""
    ours = metrics(
        scene("meet-part"),
        tmp_path,
        "auto",
        ["dual.appearance=none", "dual.groups=default"],
    )
    paper = metrics(
        scene("meet-part"),
        tmp_path,
        "eq11",
        ["dual.appearance=none", "dual.groups.merge_position=eq11"],
    )
    assert ours["purity"]["overall"] >= paper["purity"]["overall"] + 0.1, (
        ours["purity"],
        paper["purity"],
    )


def test_merge_and_split_events_roles_and_drawing(scene, tmp_path):
    out = run_track(
        scene("crossing2"),
        RunOptions(
            tracker="dual", out_dir=tmp_path / "r", plots=False, sets=["dual.groups=default"]
        ),
    ).out_dir
    table = list(csv.DictReader((out / "targets.csv").read_text().splitlines()))
    merged = [r for r in table if r["status"] == "merged"]
    assert merged, "the crossing never registered as a merge"
    frames = sorted({int(r["frame"]) for r in merged})
    assert 70 <= frames[0] <= 82 and frames[-1] <= 100  # the people overlap around frame 80
    by_frame = {}
    for r in merged:
        by_frame.setdefault(int(r["frame"]), {})[r["id"]] = r
    both = [f for f, d in by_frame.items() if len(d) == 2]
    assert both
    roles = {d[i]["source"] for f in both for d in [by_frame[f]] for i in d}
    assert "merge-foreground" in roles and roles & {"merge-eq11", "merge-motion", "merge-visible"}
    assert all(
        r["model_update"] == "frozen:merged" for r in merged
    )  # no model update while merged
    # after the merge both are tracked again, each on its own person (P@20 is checked above)
    last = {r["id"]: r["status"] for r in table if int(r["frame"]) == 160}
    assert last == {"1": "tracking", "2": "tracking"}
    # one crossing, one merge episode: no merge / split / merge flicker as they part
    # (dual.split_hold_frames)
    for tid in ("1", "2"):
        st = [r["status"] == "merged" for r in table if r["id"] == tid]
        assert sum(x != y for x, y in itertools.pairwise(st)) == 2, tid

    store = open_store(out / "run.rrd")
    log = [t for _f, t in texts(store, "events")]
    # each member's move into the group is its own event, naming the group and its place in it
    assert any("merged (in T1+T2, in front)" in t for t in log), log
    assert any("merged (in T1+T2, hidden)" in t for t in log), log
    assert any("split" in t or "separated" in t for t in log), log
    # the occluded member is drawn thin, the foreground thick
    f = both[len(both) // 2]
    t = rows(store, "infrared/targets", ["Boxes2D:labels", "Boxes2D:radii"])
    r = t.filter(pc.equal(t["frame"], f)).to_pylist()[-1]
    labels, radii = list(r["Boxes2D:labels"]), np.asarray(r["Boxes2D:radii"], float)
    fg = next(i for i, d in by_frame[f].items() if d["source"] == "merge-foreground")
    thick = {lab.split()[0] for lab, rad in zip(labels, radii, strict=True) if rad < -2}
    assert thick == {f"T{fg}"}, (labels, radii)
    assert all(lab.endswith("merged") for lab in labels)


def test_the_paper_s_tracker_runs_from_its_file_and_merges(scene, tmp_path):
    """``--config data/dual-paper.toml``: the paper's composition (no filter, extent or
    re-detector; eq. 10-11 groups) runs end to end on a crossing, where its targets merge and
    split; the same composition from Python (:meth:`DualTracker.paper`) gives the same boxes."""
    from pathlib import Path

    from pipeline import DualTracker
    from pipeline.io.sequence import open_sequence

    paper = Path(__file__).resolve().parents[2] / "data" / "dual-paper.toml"
    res = run_track(
        scene("crossing2"),
        RunOptions(out_dir=tmp_path / "p", config_path=paper, rrd=False, plots=False),
    )
    assert res.complete and res.summary["config"]["dual"]["appearance"] is None
    table = list(csv.DictReader((tmp_path / "p" / "targets.csv").read_text().splitlines()))
    assert {"merged", "tracking"} <= {r["status"] for r in table}
    assert {r["decision"].split(":")[0] for r in table} <= {
        "init",
        "contour",
        "colour",
        "re-acquired",
        "coast",
        "lost",
        "merged",
    }
    seq = open_sequence(scene("crossing2"))
    frames = [(fp.visible, fp.infrared) for fp in seq.frames()]
    boxes = [b.tolist() for b in seq.truth.primary().values()]
    results = DualTracker.paper().track(frames, [b[0] for b in boxes])
    for r, fr in zip(table[-2:], results[-1].targets, strict=True):
        assert float(r["x_px"]) == pytest.approx(fr.box.x, abs=0.01)


def _frames(out):
    by = {}
    with open(out / "targets.csv") as f:
        for r in csv.DictReader(f):
            by.setdefault(int(r["frame"]), []).append(r)
    return by


def _shared_pairs(by) -> int:
    """Frames x pairs where two targets are both ``tracking`` on boxes of IoU >= 0.5."""
    from pipeline.types import BBox

    n = 0
    for rs in by.values():
        live = [r for r in rs if r["status"] == "tracking"]
        for a, b in itertools.combinations(live, 2):
            keys = ("x_px", "y_px", "w_px", "h_px")
            ba, bb = (BBox(*(float(r[k]) for k in keys)) for r in (a, b))
            n += ba.iou(bb) >= 0.5
    return n


def test_one_object_goes_to_one_target(scene, tmp_path):
    """With ``decider.shared_iou`` set, two targets never both take one object: group3, where
    the default lets two targets track one person (25-72 frame-pairs), has none, and every yield
    names its owner (purity about 0.95 against 0.98-1.0 without: the option is off by default).
    Under level-set step moves of +-1e-7 and +-2e-7 relative (and the configured step) the rule's
    purity spans 0.930-0.997, with two identity switches in two of five runs, the default's
    0.980-1.000."""
    both = metrics(scene("group3"), tmp_path, "both")
    one = metrics(scene("group3"), tmp_path, "one", ["dual.decider.shared_iou=0.5"])
    by_both, by_one = _frames(tmp_path / "both"), _frames(tmp_path / "one")
    assert _shared_pairs(by_both) >= 20 and _shared_pairs(by_one) == 0
    yields = [r for rs in by_one.values() for r in rs if "measurement-taken-by-T" in r["decision"]]
    assert len(yields) >= 30
    for r in yields:
        owner = r["decision"].rsplit("-T", 1)[1]
        frame = by_one[int(r["frame"])]
        assert owner != r["id"] and any(o["id"] == owner for o in frame)
        # merged with the owner's object, or coasting hidden; never learning
        assert (r["status"], r["decision"].split(":")[0]) in (
            ("merged", "shared"),
            ("occluded-partial", "coast"),
        )
        assert not r["model_update"].startswith("updated")
    assert one["purity"]["overall"] >= 0.92 and one["id_switches"] <= 2
    assert both["purity"]["overall"] >= 0.975


def test_one_object_goes_to_one_target_whatever_the_rounding(scene, tmp_path):
    """The rule settles the boxes the targets report (a measurement's centre at its target's
    size), not only the measurements' own boxes: with the level set's step moved by 2e-7
    (rounding only), group3's T2 was re-acquired by a contour of IoU under 0.5 with T3's filter
    box and reported at its size beside T3 at IoU 0.53, both ``tracking`` (frame 124)."""
    for step in ("5.000001", "4.9999995"):
        sets = ["dual.decider.shared_iou=0.5", f"dual.levelset.timestep={step}"]
        metrics(scene("group3"), tmp_path, step, sets)
        assert _shared_pairs(_frames(tmp_path / step)) == 0, step


def test_a_target_on_another_with_the_wrong_colour_yields_to_it(scene, tmp_path):
    """group3: when the three meet, T1's measurement lies inside T2's box while T1's colour no
    longer matches there; by default it yields to T2 (merged, learning nothing) instead of
    following T2's body, which without the rule costs T1 purity where the models learn
    through overlaps (``overlap_freezes`` off: 0.945-0.995 against 0.985-1.0 under level-set
    step moves of +-1e-7 and +-2e-7 relative and the configured step; overall purity 0.98-1.0,
    no identity switch). By default no model learns through an overlap, which alone keeps T1
    (0.99 without the rule; 0.935 with it on an Intel Xeon, whose kernels round differently)."""
    on = metrics(scene("group3"), tmp_path, "on")
    learning = ["dual.decider.overlap_freezes=false"]
    was_on = metrics(scene("group3"), tmp_path, "was-on", learning)
    off = metrics(scene("group3"), tmp_path, "off", [*learning, "dual.decider.colour_deny_rho=0"])
    by_on = _frames(tmp_path / "on")
    yields = [r for rs in by_on.values() for r in rs if "measurement-taken-by-T" in r["decision"]]
    assert len(yields) >= 10 and not _frames(tmp_path / "off").keys() - by_on.keys()
    for r in yields:
        assert (r["status"], r["decision"].split(":")[0]) in (
            ("merged", "shared"),
            ("occluded-partial", "coast"),
        )
        assert not r["model_update"].startswith("updated")
    t1_on, t1_off = (m["purity"]["target_purity"]["1"] for m in (was_on, off))
    assert t1_on >= 0.97 and t1_on > t1_off, (t1_on, t1_off)
    assert on["purity"]["target_purity"]["1"] >= 0.93
    for m in (on, was_on):
        assert m["purity"]["overall"] >= 0.975 and m["id_switches"] == 0


def test_a_target_given_behind_another_does_not_take_its_colours():
    """Two targets given on one frame, the red one's box partly behind the green one's (which
    reaches lower in the frame, so is nearer): the red target's first colour model holds no
    green, the green one's is the whole box's; with ``first_model_excludes_nearer`` off the red
    model takes in the green it overlaps; a target with under ``first_model_min_uncovered``
    (0.05) of its box's kernel weight outside the nearer one's box (0.02 here), or wholly
    inside it, keeps its whole box's model."""
    from pipeline.io.sequence import FramePair
    from pipeline.stages.histogram import HistogramConfig, appearance_bins, kernel_histogram
    from pipeline.stages.meanshift import MeanShiftConfig
    from pipeline.stages.model_update import ModelUpdateConfig
    from pipeline.tracker_config import ColourConfig
    from pipeline.trackers.dual.colour import ColourCue

    vis = np.full((60, 80, 3), 128, np.uint8)
    far, near = BBox(20, 10, 16, 30), BBox(28, 20, 16, 30)
    vis[10:40, 20:36] = (0, 0, 230)  # red (BGR), then the green one in front of it
    vis[20:50, 28:44] = (0, 230, 0)
    frames = FramePair(1, vis, np.zeros((60, 80), np.uint8))
    hcfg = HistogramConfig()
    bins, m = appearance_bins(vis, hcfg)
    green = int(bins[30, 40])
    assert green != int(bins[15, 22])

    def cue(on):
        return ColourCue(
            ColourConfig(first_model_excludes_nearer=on),
            hcfg,
            MeanShiftConfig(),
            ModelUpdateConfig(),
        )

    q_far, q_near = cue(True).models(frames, "dual", [far, near])
    assert q_far[green] == 0.0 and q_far.sum() == pytest.approx(1.0)
    assert np.array_equal(q_near, kernel_histogram(bins, near, m))
    q_off, _ = cue(False).models(frames, "dual", [far, near])
    assert q_off[green] >= 0.1, q_off[green]
    for hidden in (BBox(27, 17, 16, 30), BBox(30, 22, 8, 10)):
        q_hidden, _ = cue(True).models(frames, "dual", [hidden, near])
        assert np.array_equal(q_hidden, kernel_histogram(bins, hidden, m))
        assert q_hidden[green] > 0.5


def test_a_target_given_behind_another_keeps_its_identity(tmp_path):
    """Random development seed 111 (three targets): target 2, a cyclist, is given partly behind
    target 1, a person whose box reaches lower (visibility 0.78 on frame 1). Its first colour
    model taken from the whole box holds the person's colours: the cyclist's track coasts and
    drifts off it, on it 0.17 of its frames (IDF1 0.485-0.49 under rounding-level moves of the
    level set's step); without them (``first_model_excludes_nearer``) it stays on it
    throughout (0.889-0.895)."""
    from pipeline.synthetic import synthesize_random

    d = synthesize_random(tmp_path / "s", 111, targets=(2, 3), progress=False)
    on = metrics(d, tmp_path, "on")
    off = metrics(d, tmp_path, "off", ["dual.colour.first_model_excludes_nearer=false"])
    assert on["idf1"] >= 0.84 and off["idf1"] <= 0.55, (on["idf1"], off["idf1"])
    purity = [m["purity"]["target_purity"]["2"] for m in (on, off)]
    assert purity[0] >= 0.95 and purity[1] <= 0.4, purity
