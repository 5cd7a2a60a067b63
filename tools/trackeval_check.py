"""Check ``dualtrack evaluate``'s HOTA, CLEAR and Identity scores against TrackEval itself.

TrackEval (``trackeval`` on PyPI) declares a dependency on the non-headless ``opencv-python``,
which conflicts with the headless wheel dualtrack uses; none of the code this check runs
imports OpenCV, so install it without its dependencies next to dualtrack::

    pip install --no-deps trackeval && pip install tabulate pycocotools
    python tools/trackeval_check.py runs/crossing2 runs/group3 [--perturb 6] [--json check.json]

Each run folder's ``tracks.csv`` is scored by TrackEval's ``MotChallenge2DBox`` dataset
(its default preprocessing, as for MOTChallenge) against the sequence's own ``gt.txt``
(for a single-target sequence, a ``gt.txt`` written from its truth; distractor rows, class 8,
included), exactly as a user would
score the folder, and by :func:`pipeline.eval.evaluate`. ``--perturb N`` adds N
results made from the truth itself with seeded id swaps, gaps, false positives, misses and
jitter, to widen the cases. The table lists every metric of both and the largest
difference; the exit status is 1 when any differs by more than ``--tol`` (default 1e-9).
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

KEYS = (
    ("hota", "HOTA", "HOTA"),
    ("deta", "HOTA", "DetA"),
    ("assa", "HOTA", "AssA"),
    ("loca", "HOTA", "LocA"),
    ("mota", "CLEAR", "MOTA"),
    ("motp", "CLEAR", "MOTP"),
    ("id_switches", "CLEAR", "IDSW"),
    ("false_positives", "CLEAR", "CLR_FP"),
    ("misses", "CLEAR", "CLR_FN"),
    ("idf1", "Identity", "IDF1"),
    ("idp", "Identity", "IDP"),
    ("idr", "Identity", "IDR"),
)


def _row(b) -> str:
    """``x,y,w,h`` of a 0-based box as a 1-based MOTChallenge row's text."""
    return f"{_n(b[0] + 1)},{_n(b[1] + 1)},{_n(b[2])},{_n(b[3])}"


def _n(v: float) -> str:
    return repr(float(v))


def _gt_rows(seq) -> list[str]:
    """MOTChallenge gt rows (1-based) of a sequence's scored truth, as ``batch --export mot``
    writes them (distractors as class 8: TrackEval drops the tracks matched to them)."""
    from pipeline.sinks.export import mot_gt_rows

    return mot_gt_rows(seq.truth, seq.n_frames)


def _perturbed(seq, rng: np.random.Generator) -> dict[int, np.ndarray]:
    """A result made from the truth with an id swap, a gap, a false positive, a miss and jitter."""
    ch = seq.truth.primary_channel()
    gt = {k: v.copy() for k, v in seq.truth.boxes[ch].items()}
    n = seq.n_frames
    out = {}
    for k, (_, b) in enumerate(sorted(gt.items())):
        b = b + rng.normal(0, rng.uniform(0.5, 4.0), b.shape) * [1, 1, 0.3, 0.3]
        a0 = int(rng.integers(0, max(n - 10, 1)))
        b[a0 : a0 + int(rng.integers(1, 8))] = np.nan
        out[100 + k] = b
    ids = sorted(out)
    if len(ids) >= 2 and rng.random() < 0.7:
        s = int(rng.integers(n // 4, 3 * n // 4))
        i, j = ids[0], ids[1]
        out[i][s:], out[j][s:] = out[j][s:].copy(), out[i][s:].copy()
    fp = np.full((n, 4), np.nan)
    s = int(rng.integers(0, n - 5))
    fp[s : s + int(rng.integers(3, 30))] = [
        rng.uniform(0, seq.width - 30),
        rng.uniform(0, seq.height - 30),
        25.0,
        40.0,
    ]
    out[999] = fp
    for k, b in enumerate(
        seq.truth.distractors.values()
    ):  # a track on each object that is not a target
        out[900 + k] = b + rng.normal(0, 1.0, b.shape) * [1, 1, 0.3, 0.3]
    if len(ids) >= 2 and rng.random() < 0.4:
        out.pop(ids[-1])
    return out


def _write_tracks(path: Path, boxes: dict[int, np.ndarray]) -> None:
    rows = []
    for f in range(next(iter(boxes.values())).shape[0]):
        for tid, b in sorted(boxes.items()):
            if not np.isnan(b[f]).any():
                rows.append(f"{f + 1},{tid},{_row(b[f])},1,-1,-1,-1")
    path.write_text("\n".join(rows) + "\n")


def trackeval_scores(
    gt_rows: list[str], tracks_csv: Path, n_frames: int, work: Path
) -> dict[str, float]:
    """TrackEval's HOTA, CLEAR and Identity for one sequence (MOTChallenge layout written under
    ``work``)."""
    import trackeval

    seq = "seq"
    gt_dir = work / "gt" / seq / "gt"
    gt_dir.mkdir(parents=True, exist_ok=True)
    (gt_dir / "gt.txt").write_text("\n".join(gt_rows) + "\n")
    (work / "gt" / seq / "seqinfo.ini").write_text(
        f"[Sequence]\nname={seq}\nseqLength={n_frames}\n"
    )
    data = work / "trackers" / "ours" / "data"
    data.mkdir(parents=True, exist_ok=True)
    shutil.copy(tracks_csv, data / f"{seq}.txt")
    evaluator = trackeval.Evaluator(
        {
            "USE_PARALLEL": False,
            "PRINT_RESULTS": False,
            "PRINT_CONFIG": False,
            "TIME_PROGRESS": False,
            "OUTPUT_SUMMARY": False,
            "OUTPUT_DETAILED": False,
            "PLOT_CURVES": False,
            "DISPLAY_LESS_PROGRESS": True,
            "OUTPUT_EMPTY_CLASSES": False,
        }
    )
    dataset = trackeval.datasets.MotChallenge2DBox(
        {
            "GT_FOLDER": str(work / "gt"),
            "TRACKERS_FOLDER": str(work / "trackers"),
            "SKIP_SPLIT_FOL": True,
            "TRACKERS_TO_EVAL": ["ours"],
            "SEQ_INFO": {seq: n_frames},
            "BENCHMARK": "DT",
            "PRINT_CONFIG": False,
        }
    )
    metrics = [
        trackeval.metrics.HOTA(),
        trackeval.metrics.CLEAR({"PRINT_CONFIG": False}),
        trackeval.metrics.Identity({"PRINT_CONFIG": False}),
    ]
    res, _ = evaluator.evaluate([dataset], metrics)
    r = res["MotChallenge2DBox"]["ours"][seq]["pedestrian"]
    out = {}
    for ours, family, key in KEYS:
        v = r[family][key]
        out[ours] = float(np.mean(v)) if np.ndim(v) else float(v)
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", type=Path, help="run folders (tracks.csv + summary.json)")
    ap.add_argument(
        "--perturb", type=int, default=0, help="also N results made from each sequence's truth"
    )
    ap.add_argument("--tol", type=float, default=1e-9)
    ap.add_argument("--json", type=Path)
    a = ap.parse_args(argv)
    try:
        import trackeval  # noqa: F401
    except ImportError:
        print(
            "trackeval is not installed: pip install --no-deps trackeval && pip install "
            "tabulate pycocotools",
            file=sys.stderr,
        )
        return 1
    from pipeline.eval import evaluate
    from pipeline.io.results import read_tracks
    from pipeline.io.sequence import open_sequence

    rng = np.random.default_rng(0)
    rows = []
    with tempfile.TemporaryDirectory(prefix="trackeval-check-") as tmp:
        for k, run in enumerate(a.runs):
            summary = json.loads((run / "summary.json").read_text())
            seq = open_sequence(summary["sequence_path"])
            gt_rows = _gt_rows(seq)
            cases = [(f"{run.name}", run / "tracks.csv")]
            for p in range(a.perturb):
                f = Path(tmp) / f"perturbed-{k}-{p}.csv"
                _write_tracks(f, _perturbed(seq, rng))
                cases.append((f"{run.name} perturbed {p + 1}", f))
            for name, csv in cases:
                work = Path(tmp) / f"w{len(rows)}"
                ref = trackeval_scores(gt_rows, csv, seq.n_frames, work)
                ours = evaluate(
                    seq.truth,
                    read_tracks(csv, seq.n_frames),
                    seq.n_frames,
                    id_rule="assign",
                    multi=True,
                )
                diffs = {key: abs(float(ours[key]) - ref[key]) for key, _, _ in KEYS}
                rows.append(
                    {
                        "case": name,
                        "trackeval": ref,
                        "dualtrack": {key: ours[key] for key, _, _ in KEYS},
                        "max_diff": max(diffs.values()),
                        "worst": max(diffs, key=diffs.get),
                    }
                )
    print("| case | HOTA | DetA | AssA | MOTA | MOTP | IDSW | IDF1 | max |diff| (metric) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        t = r["trackeval"]
        print(
            f"| {r['case']} | {t['hota']:.6f} | {t['deta']:.6f} | {t['assa']:.6f} | "
            f"{t['mota']:.6f} | {t['motp']:.6f} | "
            f"{int(t['id_switches'])} | {t['idf1']:.6f} | {r['max_diff']:.2e} ({r['worst']}) |"
        )
    worst = max(r["max_diff"] for r in rows)
    print(f"\n{len(rows)} cases; largest difference {worst:.2e} (tolerance {a.tol:g})")
    if a.json:
        a.json.write_text(json.dumps(rows, indent=1) + "\n")
    return 0 if worst <= a.tol else 1


if __name__ == "__main__":
    raise SystemExit(main())
