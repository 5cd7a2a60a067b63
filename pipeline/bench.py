"""``dualtrack bench``: accuracy and speed of trackers on the same sequences, in one run, on one core.

For every sequence the frames are first decoded once to warm the file cache, then the
decode-only rate is measured (read + decode every frame pair, nothing else). Each
tracker then runs the full ``track`` pipeline (decode + track + CSV + .rrd) into a run
folder; its ``fps_tracking`` (frames / seconds inside the tracker) and
``fps_end_to_end`` come from that run, P@20 and AUC from its evaluation. Speeds are
meant to be read as ratios measured in the same run (against the decode-only rate and
against the peers), never as absolute promises. With several targets the table also
has identity purity, ID switches, MOTA and IDF1.

``repeat`` (``--repeat N``) times every measurement N times and keeps the fastest, as
``timeit`` does: on a shared or virtual machine other work only ever adds time, and the
rates measured here drift by 30-50 % from one minute to the next. Accuracy comes from the
last run (the run folder kept); the trackers are deterministic apart from MIL.

``run_scaling`` (``dualtrack bench --targets 1,2,4,8``) measures how the cost grows with
the number of targets: it renders the ``walkers<n>`` scenes (n people, each in its own
lane, the same work per target) and reports fps and the tracker's time per target.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

import cv2

from pipeline.errors import InputError
from pipeline.io.sequence import open_sequence
from pipeline.run import RunOptions, run_track
from pipeline.trackers import PEERS, available_trackers, tracker_names

DEFAULT_BENCH_TRACKERS = ("meanshift", "camshift", "mil")


def decode_rate(seq_path: Path, repeat: int = 1, **open_kw: object) -> tuple[float, int]:
    """Frame pairs per second of reading + decoding the whole sequence: the fastest of ``repeat`` warm passes."""
    seq = open_sequence(seq_path, **open_kw)  # type: ignore[arg-type]
    for _ in seq.frames():  # warm the cache
        pass
    best, n = float("inf"), 0
    for _ in range(repeat):
        t0 = time.perf_counter()
        n = 0
        for _ in seq.frames():
            n += 1
        best = min(best, time.perf_counter() - t0)
    return (n / best if best > 0 else float("inf")), n


def run_bench(
    seq_dirs: list[Path],
    trackers: list[str] | None = None,
    out: Path | None = None,
    json_path: Path | None = None,
    sets: list[str] | None = None,
    config_path: Path | None = None,
    repeat: int = 1,
    **open_kw: object,
) -> list[dict[str, object]]:
    """Run every tracker on every sequence (``repeat`` times, keeping the fastest rates); one row per
    (sequence, tracker)."""
    if not (isinstance(repeat, int) and repeat >= 1):
        raise InputError(f"--repeat must be an integer >= 1; got {repeat!r}")
    cv2.setNumThreads(1)
    names = list(trackers) if trackers else list(DEFAULT_BENCH_TRACKERS)
    known = tracker_names()
    for n in names:
        if n not in known:
            raise InputError(f"unknown tracker {n!r}; available: {', '.join(known)}")
    runnable = set(available_trackers())
    tmp = None
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="dualtrack-bench-")
        out = Path(tmp.name)
    rows: list[dict[str, object]] = []
    try:
        for sd in seq_dirs:
            dec_fps, n_frames = decode_rate(sd, repeat, **open_kw)
            seq_name = Path(sd).name
            for name in names:
                row: dict[str, object] = {"sequence": seq_name, "tracker": name, "frames": n_frames,
                                          "fps_decode": round(dec_fps, 1), "repeat": repeat}
                if name not in runnable:
                    row["skipped"] = "needs opencv-contrib (not installed here)"
                    rows.append(row)
                    continue
                fps_trk: list[float] = []
                fps_e2e: list[float] = []
                fastest: dict[str, object] | None = None  # the summary of the run with the best fps_tracking
                for _ in range(repeat):
                    res = run_track(sd, RunOptions(
                        tracker=name, out_dir=out / name / seq_name, force=True, plots=False, progress=None,
                        sets=list(sets or []), config_path=config_path, **open_kw,  # type: ignore[arg-type]
                    ))
                    s = res.summary
                    fps_trk += [float(s["fps_tracking"])] if s.get("fps_tracking") else []
                    fps_e2e += [float(s["fps_end_to_end"])] if s.get("fps_end_to_end") else []
                    if fastest is None or float(s.get("fps_tracking") or 0) > float(fastest.get("fps_tracking") or 0):
                        fastest = s
                m = s.get("metrics") or {}
                row.update({
                    "p20": m.get("p20") if isinstance(m, dict) else None,
                    "auc": m.get("auc") if isinstance(m, dict) else None,
                    **_multi_metrics(m),
                    "fps_tracking": max(fps_trk) if fps_trk else None,
                    "fps_end_to_end": max(fps_e2e) if fps_e2e else None,
                    "fps_tracking_runs": fps_trk,
                    "stage_seconds": (fastest or s).get("stage_seconds"),
                    "complete": s.get("complete"),
                })
                fe = row["fps_end_to_end"]  # the kept (fastest) end-to-end rate, as printed beside it
                row["end_to_end_vs_decode"] = round(float(fe) / dec_fps, 3) if fe and dec_fps else None  # type: ignore[arg-type]
                rows.append(row)
        _add_peer_ratios(rows)
        if json_path is not None:
            Path(json_path).write_text(json.dumps({"rows": rows}, indent=2) + "\n")
    finally:
        if tmp is not None:
            tmp.cleanup()
    return rows


def _multi_metrics(m: object) -> dict[str, object]:
    """Purity, ID switches, MOTA and IDF1 of a many-target evaluation (empty for one target)."""
    if not isinstance(m, dict) or "purity" not in m:
        return {}
    pur = m["purity"]
    return {"purity": pur.get("overall") if isinstance(pur, dict) else None, "id_switches": m.get("id_switches"),
            "mota": m.get("mota"), "idf1": m.get("idf1")}


def run_scaling(counts: list[int], trackers: list[str] | None = None, out: Path | None = None, seed: int = 0,
                sets: list[str] | None = None, config_path: Path | None = None, repeat: int = 1) -> list[dict[str, object]]:
    """fps of each tracker on the ``walkers<n>`` scene for every n in ``counts`` (fastest of ``repeat`` runs)."""
    from pipeline.synthetic import SCENARIOS, synthesize

    for n in counts:
        if f"walkers{n}" not in SCENARIOS:
            have = sorted(int(k[7:]) for k in SCENARIOS if k.startswith("walkers"))
            raise InputError(f"no scene with {n} targets; --targets takes some of {','.join(map(str, have))}")
    tmp = None
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="dualtrack-scaling-")
        out = Path(tmp.name)
    try:
        dirs = []
        for n in counts:
            d = out / "scenes" / f"walkers{n}"
            if not (d / "scene.json").exists():
                synthesize(f"walkers{n}", d, seed=seed, progress=False)
            dirs.append(d)
        rows = run_bench(dirs, trackers or ["dual"], out=out / "runs", sets=sets, config_path=config_path, repeat=repeat)
    finally:
        if tmp is not None:
            tmp.cleanup()
    base: dict[str, float] = {}
    for r, n in zip(rows, [n for n in counts for _ in (trackers or ["dual"])], strict=True):
        r["targets"] = n
        fps = r.get("fps_tracking")
        if isinstance(fps, int | float) and fps > 0:
            r["ms_per_target"] = round(1000.0 / (fps * n), 3)
            base.setdefault(str(r["tracker"]), float(r["ms_per_target"]) if n == counts[0] else float("nan"))
            b = base[str(r["tracker"])]
            r["per_target_cost_vs_first"] = round(float(r["ms_per_target"]) / b, 2) if b == b else None
    return rows


def format_scaling(rows: list[dict[str, object]]) -> str:
    """The fps-vs-targets table."""
    lines = ["| tracker | targets | fps_tracking | ms per target | per-target cost vs fewest | P@20 | purity | ID sw. |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['tracker']} | {r['targets']} | skipped: {r['skipped']} |  |  |  |  |  |")
            continue

        def f(v: object, nd: int) -> str:
            return f"{v:.{nd}f}" if isinstance(v, float) else ("" if v is None else str(v))

        lines.append(f"| {r['tracker']} | {r['targets']} | {f(r.get('fps_tracking'), 1)} | {f(r.get('ms_per_target'), 2)} | "
                     f"{f(r.get('per_target_cost_vs_first'), 2)} | {f(r.get('p20'), 3)} | {f(r.get('purity'), 3)} | "
                     f"{f(r.get('id_switches'), 0)} |")
    return "\n".join(lines)


def _add_peer_ratios(rows: list[dict[str, object]]) -> None:
    """Speed of each of our trackers relative to each OpenCV peer on the same sequence."""
    by_seq: dict[str, dict[str, dict[str, object]]] = {}
    for r in rows:
        by_seq.setdefault(str(r["sequence"]), {})[str(r["tracker"])] = r
    for trk in by_seq.values():
        for name, r in trk.items():
            if name in PEERS or not r.get("fps_tracking"):
                continue
            ratios = {}
            for peer in PEERS:
                p = trk.get(peer)
                if p and p.get("fps_tracking"):
                    ratios[peer] = round(float(r["fps_tracking"]) / float(p["fps_tracking"]), 2)  # type: ignore[arg-type]
            if ratios:
                r["speed_vs_peers"] = ratios


def format_table(rows: list[dict[str, object]]) -> str:
    """The bench table as aligned text (Markdown-compatible)."""
    multi = any("purity" in r for r in rows)
    head = ["sequence", "tracker", "P@20", "AUC", "fps_tracking", "fps_end_to_end", "fps_decode", "e2e/decode"]
    if multi:
        head += ["purity", "ID sw.", "MOTA", "IDF1"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def f(v: object, nd: int = 3) -> str:
        return f"{v:.{nd}f}" if isinstance(v, float) else ("" if v is None else str(v))

    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['sequence']} | {r['tracker']} | skipped: {r['skipped']} |" + "  |" * (len(head) - 3))
            continue
        cells = [
            str(r["sequence"]), str(r["tracker"]), f(r.get("p20")), f(r.get("auc")), f(r.get("fps_tracking"), 1),
            f(r.get("fps_end_to_end"), 1), f(r.get("fps_decode"), 1), f(r.get("end_to_end_vs_decode"), 2),
        ]
        if multi:
            cells += [f(r.get("purity")), f(r.get("id_switches")), f(r.get("mota")), f(r.get("idf1"))]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)
