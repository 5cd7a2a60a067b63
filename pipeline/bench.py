"""``dualtrack bench``: accuracy and speed of trackers on the same sequences, in one run, on one core.

For every sequence the frames are first decoded once to warm the file cache, then the
decode-only rate is measured (read + decode every frame pair, nothing else). Each
tracker then runs the full ``track`` pipeline (decode + track + CSV + .rrd) into a run
folder; its ``fps_tracking`` (frames / seconds inside the tracker) and
``fps_end_to_end`` come from that run, P@20 and AUC from its evaluation. Speeds are
meant to be read as ratios measured in the same run (against the decode-only rate and
against the peers), never as absolute promises.
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


def decode_rate(seq_path: Path, **open_kw: object) -> tuple[float, int]:
    """Frame pairs per second of reading + decoding the whole sequence (second, warm pass)."""
    seq = open_sequence(seq_path, **open_kw)  # type: ignore[arg-type]
    for _ in seq.frames():  # warm the cache
        pass
    t0 = time.perf_counter()
    n = 0
    for _ in seq.frames():
        n += 1
    dt = time.perf_counter() - t0
    return (n / dt if dt > 0 else float("inf")), n


def run_bench(
    seq_dirs: list[Path],
    trackers: list[str] | None = None,
    out: Path | None = None,
    json_path: Path | None = None,
    sets: list[str] | None = None,
    config_path: Path | None = None,
    **open_kw: object,
) -> list[dict[str, object]]:
    """Run every tracker on every sequence; return one row per (sequence, tracker)."""
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
            dec_fps, n_frames = decode_rate(sd, **open_kw)
            seq_name = Path(sd).name
            for name in names:
                row: dict[str, object] = {"sequence": seq_name, "tracker": name, "frames": n_frames,
                                          "fps_decode": round(dec_fps, 1)}
                if name not in runnable:
                    row["skipped"] = "needs opencv-contrib (not installed here)"
                    rows.append(row)
                    continue
                res = run_track(sd, RunOptions(
                    tracker=name, out_dir=out / name / seq_name, force=True, plots=False, progress=None,
                    sets=list(sets or []), config_path=config_path, **open_kw,  # type: ignore[arg-type]
                ))
                s = res.summary
                m = s.get("metrics") or {}
                row.update({
                    "p20": m.get("p20") if isinstance(m, dict) else None,
                    "auc": m.get("auc") if isinstance(m, dict) else None,
                    "fps_tracking": s.get("fps_tracking"),
                    "fps_end_to_end": s.get("fps_end_to_end"),
                    "stage_seconds": s.get("stage_seconds"),
                    "complete": s.get("complete"),
                })
                fe = s.get("fps_end_to_end")
                row["end_to_end_vs_decode"] = round(float(fe) / dec_fps, 3) if fe and dec_fps else None
                rows.append(row)
        _add_peer_ratios(rows)
        if json_path is not None:
            Path(json_path).write_text(json.dumps({"rows": rows}, indent=2) + "\n")
    finally:
        if tmp is not None:
            tmp.cleanup()
    return rows


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
    head = ["sequence", "tracker", "P@20", "AUC", "fps_tracking", "fps_end_to_end", "fps_decode", "e2e/decode"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def f(v: object, nd: int = 3) -> str:
        return f"{v:.{nd}f}" if isinstance(v, float) else ("" if v is None else str(v))

    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['sequence']} | {r['tracker']} | skipped: {r['skipped']} |  |  |  |  |  |")
            continue
        lines.append("| " + " | ".join([
            str(r["sequence"]), str(r["tracker"]), f(r.get("p20")), f(r.get("auc")), f(r.get("fps_tracking"), 1),
            f(r.get("fps_end_to_end"), 1), f(r.get("fps_decode"), 1), f(r.get("end_to_end_vs_decode"), 2),
        ]) + " |")
    return "\n".join(lines)
