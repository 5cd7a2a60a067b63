"""``dualtrack bench``: accuracy and speed of trackers on the same sequences, in one run, on one
core.

For every sequence the frames are first decoded once to warm the file cache, then the
decode-only rate is measured (read + decode every frame pair, nothing else), and for image
files the rate at which OpenCV alone (``cv2.imread``, one thread) decodes them
(``fps_decode_opencv``; ``end_to_end_vs_opencv_decode`` is the end-to-end rate against it). Each
tracker then runs the full ``track`` pipeline (decode + track + CSV + .rrd) into a run
folder; its ``fps_tracking`` (frames / seconds inside the tracker), ``fps_tracking_cpu``
(frames / CPU seconds of the tracker's thread inside it) and ``fps_end_to_end`` come from
that run, P@20 and AUC from its evaluation. The decode-only rates are of the whole frames;
a run that reads them smaller (its ``decode_scale``, ``--decode-scale auto`` on large JPEG
footage) decodes faster than that. The reader and writer threads run beside the
tracker on the run's other core; what they take from it (the GIL held by the writer's
Python, the machine's other threads) lowers ``fps_tracking`` more for a fast tracker than
for a slow one, and not ``fps_tracking_cpu``, which counts only the tracker's own work
(one thread: the benchmark sets OpenCV and BLAS to one). Speeds are
meant to be read as ratios measured in the same run (against the decode-only rate and
against the peers), never as absolute promises. With several targets the table also
has identity purity, ID switches, MOTA and IDF1.

``repeat`` (``--repeat N``) times every measurement N times and keeps the fastest, as ``timeit``
does: on a shared or virtual machine other work only ever adds time. The trackers' runs on a
sequence go in rounds (every tracker once, then every tracker again), so that a slow spell of the
machine, which can last a whole run, lowers one run of each tracker rather than every run of one
and the ratios between them. Accuracy comes from the last run (the run folder kept); the trackers
are deterministic apart from MIL.

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
    """Frame pairs per second of reading + decoding the whole sequence: the fastest of ``repeat``
    warm passes."""
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


def opencv_decode_rate(seq_path: Path, repeat: int = 1, **open_kw: object) -> float | None:
    """Frame pairs per second at which OpenCV alone reads and decodes the sequence's image
    files on one thread (``cv2.imread``; an infrared channel straight to grey, as the reader
    does): the reference for the end-to-end rate on large frames, the fastest of ``repeat``
    passes after a warm one. None for a video, which OpenCV decodes in both cases.

    On large frames the rate depends on the state of the process's memory allocator (page
    faults on fresh buffers): it is measured as ``dualtrack bench`` finds the process, after
    the reader's own passes, and is best compared within one run."""
    from pipeline.io.frames import ImageListSource

    seq = open_sequence(seq_path, **open_kw)  # type: ignore[arg-type]
    sources = list(seq.sources.values())
    if not all(isinstance(s, ImageListSource) for s in sources):
        return None
    files = [
        (str(p), cv2.IMREAD_GRAYSCALE if s.grey else cv2.IMREAD_UNCHANGED)
        for s in sources
        for p in s.paths
    ]
    best = float("inf")
    for _ in range(repeat + 1):  # the first pass warms the file cache, as decode_rate's
        t0 = time.perf_counter()
        for path, flag in files:
            cv2.imread(path, flag)
        best = min(best, time.perf_counter() - t0)
    return len(sources[0].paths) / best if best > 0 else None


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
    """Run every tracker on every sequence (``repeat`` times, keeping the fastest rates); one row
    per (sequence, tracker)."""
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
            seq_name = Path(sd).name
            try:
                dec_fps, n_frames = decode_rate(sd, repeat, **open_kw)
                cv_fps = opencv_decode_rate(sd, repeat, **open_kw)
            except InputError as exc:  # an unreadable sequence: reported, the others still run
                rows.append({"sequence": seq_name, "tracker": "-", "failed": str(exc)})
                continue
            runs: dict[str, list] = {n: [] for n in names if n in runnable}
            stopped: dict[str, str] = {}
            for _ in range(repeat):  # round by round: a slow spell of the machine falls on every
                for name in runs:  # tracker's runs alike, not on all of one tracker's
                    if name in stopped:
                        continue
                    res = run_track(
                        sd,
                        RunOptions(
                            tracker=name,
                            out_dir=out / name / seq_name,
                            force=True,
                            plots=False,
                            progress=None,
                            sets=list(sets or []),
                            config_path=config_path,
                            **open_kw,  # type: ignore[arg-type]
                        ),
                    )
                    if res.interrupted:
                        raise KeyboardInterrupt
                    if res.error:
                        stopped[name] = res.error
                        continue
                    runs[name].append(res.summary)
            for name in names:
                row: dict[str, object] = {
                    "sequence": seq_name,
                    "tracker": name,
                    "frames": n_frames,
                    "fps_decode": round(dec_fps, 1),
                    "fps_decode_opencv": round(cv_fps, 1) if cv_fps else None,
                    "repeat": repeat,
                }
                if name not in runnable:
                    row["skipped"] = "needs opencv-contrib (not installed here)"
                elif name in stopped:
                    row["failed"] = stopped[name]
                else:
                    row.update(_timed_row(runs[name], dec_fps, cv_fps))
                rows.append(row)
        _add_peer_ratios(rows)
        if json_path is not None:
            Path(json_path).write_text(json.dumps({"rows": rows}, indent=2) + "\n")
    finally:
        if tmp is not None:
            tmp.cleanup()
    return rows


def _timed_row(
    summaries: list[dict[str, object]], dec_fps: float, cv_fps: float | None
) -> dict[str, object]:
    """A tracker's figures on one sequence from the summaries of its runs (in order): each rate
    the best of the runs, the stages of the fastest tracking run, accuracy from the last run."""

    def rates(key: str) -> list[float]:
        return [float(s[key]) for s in summaries if s.get(key)]  # type: ignore[arg-type]

    fps_trk, fps_cpu, fps_e2e = (
        rates("fps_tracking"),
        rates("fps_tracking_cpu"),
        rates("fps_end_to_end"),
    )
    fastest = max(summaries, key=lambda s: float(s.get("fps_tracking") or 0))  # type: ignore[arg-type]
    last = summaries[-1]
    m = last.get("metrics") or {}
    row: dict[str, object] = {
        "p20": m.get("p20") if isinstance(m, dict) else None,
        "auc": m.get("auc") if isinstance(m, dict) else None,
        **_multi_metrics(m),
        "fps_tracking": max(fps_trk) if fps_trk else None,
        "fps_tracking_cpu": max(fps_cpu) if fps_cpu else None,
        "fps_end_to_end": max(fps_e2e) if fps_e2e else None,
        "fps_tracking_runs": fps_trk,
        "stage_seconds": fastest.get("stage_seconds"),
        "decode_scale": last.get("decode_scale"),
        "complete": last.get("complete"),
    }
    fe = max(fps_e2e) if fps_e2e else None  # the kept (fastest) end-to-end rate
    ft = max(fps_trk) if fps_trk else None
    row["end_to_end_vs_decode"] = round(fe / dec_fps, 3) if fe and dec_fps else None
    row["end_to_end_vs_opencv_decode"] = round(fe / cv_fps, 3) if fe and cv_fps else None
    # the overlap of decoding, tracking and writing: 1.0 when end to end runs at the slower of
    # the two
    bound = min(ft, dec_fps) if ft and dec_fps else None
    row["end_to_end_vs_bound"] = round(fe / bound, 3) if fe and bound else None
    return row


def _multi_metrics(m: object) -> dict[str, object]:
    """Purity, ID switches, MOTA and IDF1 of a many-target evaluation, and purity and IDF1 on the
    frames where each target is visible enough where the truth says (empty for one target)."""
    if not isinstance(m, dict) or "purity" not in m:
        return {}
    pur = m["purity"]
    out = {
        "purity": pur.get("overall") if isinstance(pur, dict) else None,
        "id_switches": m.get("id_switches"),
        "mota": m.get("mota"),
        "idf1": m.get("idf1"),
    }
    for k in ("purity_visible", "idf1_visible"):
        if k in m:
            out[k] = m[k]
    return out


def run_scaling(
    counts: list[int],
    trackers: list[str] | None = None,
    out: Path | None = None,
    seed: int = 0,
    sets: list[str] | None = None,
    config_path: Path | None = None,
    repeat: int = 1,
) -> list[dict[str, object]]:
    """fps of each tracker on the ``walkers<n>`` scene for every n in ``counts`` (fastest of
    ``repeat`` runs)."""
    from pipeline.synthetic import SCENARIOS, synthesize

    for n in counts:
        if f"walkers{n}" not in SCENARIOS:
            have = sorted(int(k[7:]) for k in SCENARIOS if k.startswith("walkers"))
            raise InputError(
                f"no scene with {n} targets; --targets takes some of {','.join(map(str, have))}"
            )
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
        rows = run_bench(
            dirs,
            trackers or ["dual"],
            out=out / "runs",
            sets=sets,
            config_path=config_path,
            repeat=repeat,
        )
    finally:
        if tmp is not None:
            tmp.cleanup()
    base: dict[str, float] = {}
    for r, n in zip(rows, [n for n in counts for _ in (trackers or ["dual"])], strict=True):
        r["targets"] = n
        fps = r.get("fps_tracking")
        if isinstance(fps, int | float) and fps > 0:
            r["ms_per_target"] = round(1000.0 / (fps * n), 3)
            base.setdefault(
                str(r["tracker"]), float(r["ms_per_target"]) if n == counts[0] else float("nan")
            )
            b = base[str(r["tracker"])]
            r["per_target_cost_vs_first"] = (
                round(float(r["ms_per_target"]) / b, 2) if b == b else None
            )
    return rows


def format_scaling(rows: list[dict[str, object]]) -> str:
    """The fps-vs-targets table."""
    lines = [
        "| tracker | targets | fps_tracking | ms per target | per-target cost vs fewest | P@20 "
        "| purity | ID sw. |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "skipped" in r:
            lines.append(
                f"| {r['tracker']} | {r['targets']} | skipped: {r['skipped']} |  |  |  |  |  |"
            )
            continue

        def f(v: object, nd: int) -> str:
            return f"{v:.{nd}f}" if isinstance(v, float) else ("" if v is None else str(v))

        lines.append(
            f"| {r['tracker']} | {r['targets']} | {f(r.get('fps_tracking'), 1)} | "
            f"{f(r.get('ms_per_target'), 2)} | "
            f"{f(r.get('per_target_cost_vs_first'), 2)} | {f(r.get('p20'), 3)} | "
            f"{f(r.get('purity'), 3)} | "
            f"{f(r.get('id_switches'), 0)} |"
        )
    return "\n".join(lines)


def _add_peer_ratios(rows: list[dict[str, object]]) -> None:
    """Speed of each of our trackers relative to each OpenCV peer on the same sequence:
    ``speed_vs_peers`` from the tracking rates, ``speed_vs_peers_cpu`` from the rates in CPU time.
    """
    by_seq: dict[str, dict[str, dict[str, object]]] = {}
    for r in rows:
        by_seq.setdefault(str(r["sequence"]), {})[str(r["tracker"])] = r
    for trk in by_seq.values():
        for name, r in trk.items():
            if name in PEERS:
                continue
            for key, out in (
                ("fps_tracking", "speed_vs_peers"),
                ("fps_tracking_cpu", "speed_vs_peers_cpu"),
            ):
                if not r.get(key):
                    continue
                ratios = {}
                for peer in PEERS:
                    p = trk.get(peer)
                    if p and p.get(key):
                        # type: ignore[arg-type]
                        ratios[peer] = round(float(r[key]) / float(p[key]), 2)
                if ratios:
                    r[out] = ratios


def format_table(rows: list[dict[str, object]]) -> str:
    """The bench table as aligned text (Markdown-compatible)."""
    multi = any("purity" in r for r in rows)
    head = [
        "sequence",
        "tracker",
        "P@20",
        "AUC",
        "tracking fps",
        "tracking fps (CPU)",
        "end-to-end fps",
        "decode fps",
    ]
    visible = any("purity_visible" in r for r in rows)
    if multi:
        head += ["purity", "ID switches", "MOTA", "IDF1"]
    if visible:
        head += ["purity (visible)", "IDF1 (visible)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def f(v: object, nd: int = 3) -> str:
        if isinstance(v, float):
            return f"{v:.{nd}f}" if v == v else "-"
        return "" if v is None else str(v)

    failed = [r for r in rows if "failed" in r]
    for r in rows:
        if "failed" in r:
            continue
        if "skipped" in r:
            lines.append(
                f"| {r['sequence']} | {r['tracker']} | skipped: {r['skipped']} |"
                + "  |" * (len(head) - 3)
            )
            continue
        cells = [
            str(r["sequence"]),
            str(r["tracker"]),
            f(r.get("p20")),
            f(r.get("auc")),
            f(r.get("fps_tracking"), 1),
            f(r.get("fps_tracking_cpu"), 1),
            f(r.get("fps_end_to_end"), 1),
            f(r.get("fps_decode"), 1),
        ]
        if multi:
            cells += [
                f(r.get("purity")),
                f(r.get("id_switches")),
                f(r.get("mota")),
                f(r.get("idf1")),
            ]
        if visible:
            cells += [f(r.get("purity_visible")), f(r.get("idf1_visible"))]
        lines.append("| " + " | ".join(cells) + " |")
    if failed:
        lines += ["", f"{len(failed)} failed:"] + [
            f"- {r['sequence']}"
            + (f" / {r['tracker']}" if r["tracker"] != "-" else "")
            + f": {r['failed']}"
            for r in failed
        ]
    lines += ["", *TABLE_LEGEND]
    if visible:
        lines.append(VISIBLE_LEGEND)
    return "\n".join(lines)


TABLE_LEGEND = (
    "P@20: share of frames whose box centre is within 20 px of the truth's; AUC: mean share of "
    "frames above each IoU threshold 0-1.",
    "tracking fps: frames per second of wall time inside the tracker; (CPU): in the tracker "
    "thread's own CPU time, which other work on the machine does not slow; end-to-end: decode, "
    "track and write the run folder; decode: decoding the frames alone. Compare rates of one run.",
)
"""The lines under ``dualtrack bench``'s table that say what its columns mean."""
VISIBLE_LEGEND = (
    "(visible): on the frames where each target is at least 25 % visible; a less visible truth "
    "box and the track box on it are left out (MOTChallenge's visibility filter)."
)


def random_scene_set(
    count: int | None = None,
    split: str = "test",
    seeds: range | None = None,
    targets: tuple[int, int] | None = None,
    out: Path | None = None,
    size: tuple[int, int] = (320, 240),
    frames: int = 200,
    progress: bool | None = None,
) -> list[Path]:
    """Folders of random scenes (:mod:`pipeline.synthetic.family`), generated into ``out`` unless
    already there.

    ``seeds`` names them outright; otherwise the first ``count`` seeds of the ``split``
    (``dev``: tuning, ``test``: only ever scored). A folder is reused when its
    ``scene.json`` was written with the same generator options: ``random-NNNN-tA-B`` as
    written here, or ``random-NNNN`` as ``dualtrack synth random`` names it.
    """
    from pipeline.progress import Progress
    from pipeline.synthetic import synthesize_random
    from pipeline.synthetic.family import DEV_SEEDS, TEST_SEEDS

    if split not in ("dev", "test"):
        raise InputError(f"--split must be dev or test; got {split!r}")
    if seeds is None:
        if count is None or count < 1:
            raise InputError(f"--random takes a number of scenes >= 1; got {count!r}")
        pool = TEST_SEEDS if split == "test" else DEV_SEEDS
        if count > len(pool):
            raise InputError(f"--random {count}: the {split} range has {len(pool)} seeds")
        seeds = pool[:count]
    if out is None:
        raise InputError("random_scene_set needs an output folder")
    want = {"targets": list(targets) if targets else None, "size": list(size), "frames": frames}
    dirs = []
    with Progress(len(seeds), "random scenes", enabled=progress, unit="scenes") as bar:
        for seed in seeds:
            tag = f"random-{seed:04d}" + (f"-t{targets[0]}-{targets[1]}" if targets else "")
            names = dict.fromkeys((tag, f"random-{seed:04d}"))  # ours, then synth random's
            found = [Path(out) / n for n in names if _written_as(Path(out) / n, seed, want)]
            d = found[0] if found else Path(out) / tag
            if not found:
                synthesize_random(d, seed, targets, size, frames, force=True, progress=False)
            dirs.append(d)
            bar.update(1)
    return dirs


def _written_as(d: Path, seed: int, want: dict) -> bool:
    """Whether ``d`` holds the random scene of ``seed`` written with the generator options
    ``want`` (its ``scene.json``)."""
    import json as _json

    try:
        m = _json.loads((d / "scene.json").read_text())
    except (ValueError, OSError):
        return False
    return m.get("seed") == seed and m.get("generator") == want


def run_random_bench(
    count: int | None = None,
    split: str = "test",
    seeds: range | None = None,
    targets: tuple[int, int] | None = None,
    trackers: list[str] | None = None,
    out: Path | None = None,
    json_path: Path | None = None,
    sets: list[str] | None = None,
    config_path: Path | None = None,
    repeat: int = 1,
    progress: bool | None = None,
    channel: str | None = None,
) -> dict[str, object]:
    """``dualtrack bench --random N``: every tracker on a set of random scenes, and the
    distribution of its scores; ``channel`` (``visible`` or ``infrared``) runs the trackers on
    that channel of the scenes alone.

    Returns ``{"rows": [...], "distribution": {tracker: {...}}, "attributes": {tracker: {attr:
    {...}}}}``: per tracker the mean, 10th percentile and worst seed of P@20 and AUC (and of
    identity purity and IDF1 on many-target scenes), the median tracking rate, and per attribute
    the P@20 and AUC over the frames carrying it (pooled over scenes).
    """
    import json as _json

    from pipeline.eval import Assessment
    from pipeline.eval.frame_attributes import attribute_counts, attribute_masks, pool_counts
    from pipeline.io.results import read_tracks

    tmp = None
    if out is None:
        tmp = tempfile.TemporaryDirectory(prefix="dualtrack-random-")
        out = Path(tmp.name)
    try:
        dirs = random_scene_set(
            count, split, seeds, targets, Path(out) / "scenes", progress=progress
        )
        rows = run_bench(
            dirs,
            trackers,
            out=Path(out) / "runs",
            sets=sets,
            config_path=config_path,
            repeat=repeat,
            channel=channel,
        )
        seed_of = {d.name: int(_json.loads((d / "scene.json").read_text())["seed"]) for d in dirs}
        by_dir = {d.name: d for d in dirs}
        attr_counts: dict[str, list[dict[str, dict[str, object]]]] = {}
        for r in rows:
            r["seed"] = seed_of.get(str(r["sequence"]))
            if "skipped" in r or "failed" in r:
                continue
            d = by_dir[str(r["sequence"])]
            run = Path(out) / "runs" / str(r["tracker"]) / d.name
            seq = open_sequence(d)
            tracks = read_tracks(run / "tracks.csv", seq.n_frames)
            assessment = Assessment(seq.truth, tracks, seq.n_frames, "truth")
            meta = _json.loads((d / "scene.json").read_text())
            attr_counts.setdefault(str(r["tracker"]), []).append(
                attribute_counts(assessment, attribute_masks(meta, seq.n_frames))
            )
        result = {
            "split": split if seeds is None else "seeds",
            "seeds": [seed_of[d.name] for d in dirs],
            "targets": list(targets) if targets else None,
            "rows": rows,
            "distribution": score_distribution(rows),
            "attributes": {t: pool_counts(c) for t, c in attr_counts.items()},
        }
        if json_path is not None:
            Path(json_path).write_text(_json.dumps(_json_clean(result), indent=2) + "\n")
        return result
    finally:
        if tmp is not None:
            tmp.cleanup()


def _json_clean(x: object) -> object:
    from pipeline.eval import json_safe

    return json_safe(x)


def score_distribution(rows: list[dict[str, object]]) -> dict[str, dict[str, object]]:
    """Per tracker over its rows: mean, 10th percentile and worst (with its seed) of each score,
    median fps."""
    import numpy as np

    out: dict[str, dict[str, object]] = {}
    trackers = list(dict.fromkeys(str(r["tracker"]) for r in rows if r["tracker"] != "-"))
    for t in trackers:
        mine = [r for r in rows if r["tracker"] == t and "skipped" not in r and "failed" not in r]
        if not mine:
            why = next(
                (r.get("skipped") or r.get("failed") for r in rows if r["tracker"] == t), "no runs"
            )
            out[t] = {"skipped": why}
            continue
        d: dict[str, object] = {"scenes": len(mine)}
        for key in ("p20", "auc", "purity", "idf1", "mota", "purity_visible", "idf1_visible"):
            vals = [
                (float(r[key]), r.get("seed")) for r in mine if isinstance(r.get(key), int | float)
            ]
            if not vals:
                continue
            v = np.array([x for x, _ in vals])
            worst = min(vals, key=lambda p: p[0])
            d[key] = {
                "mean": float(v.mean()),
                "p10": float(np.percentile(v, 10)),
                "worst": worst[0],
                "worst_seed": worst[1],
                "n": len(vals),
            }
        fps = [
            float(r["fps_tracking"])
            for r in mine
            if isinstance(r.get("fps_tracking"), int | float)
        ]
        d["fps_tracking_median"] = float(np.median(fps)) if fps else None
        out[t] = d
    return out


def format_distribution(result: dict[str, object]) -> str:
    """The tables ``bench --random`` prints: the score distribution per tracker, then per
    attribute."""
    dist = result["distribution"]
    assert isinstance(dist, dict)
    multi = any("purity" in v for v in dist.values() if isinstance(v, dict))
    head = [
        "tracker",
        "scenes",
        "P@20 mean",
        "P@20 p10",
        "P@20 worst (seed)",
        "AUC mean",
        "AUC p10",
        "AUC worst (seed)",
    ]
    visible = any("purity_visible" in v for v in dist.values() if isinstance(v, dict))
    if multi:
        head += ["purity mean", "purity p10", "IDF1 mean", "IDF1 p10"]
    if visible:
        head += ["purity visible", "IDF1 visible"]
    head += ["fps (median)"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]

    def f(v: object, nd: int = 3) -> str:
        return f"{v:.{nd}f}" if isinstance(v, float) else ("" if v is None else str(v))

    for t, d in dist.items():
        if "skipped" in d:
            lines.append(f"| {t} | skipped: {d['skipped']} |" + "  |" * (len(head) - 2))
            continue
        p, a = d.get("p20", {}), d.get("auc", {})
        cells = [
            t,
            str(d["scenes"]),
            f(p.get("mean")),
            f(p.get("p10")),
            f"{f(p.get('worst'))} ({p.get('worst_seed')})",
            f(a.get("mean")),
            f(a.get("p10")),
            f"{f(a.get('worst'))} ({a.get('worst_seed')})",
        ]
        if multi:
            pu, idf = d.get("purity", {}), d.get("idf1", {})
            cells += [f(pu.get("mean")), f(pu.get("p10")), f(idf.get("mean")), f(idf.get("p10"))]
        if visible:
            pv, iv = d.get("purity_visible", {}), d.get("idf1_visible", {})
            cells += [f(pv.get("mean")), f(iv.get("mean"))]
        cells.append(f(d.get("fps_tracking_median"), 0))
        lines.append("| " + " | ".join(cells) + " |")
    if visible:
        lines += ["", VISIBLE_LEGEND]
    attrs = result.get("attributes") or {}
    assert isinstance(attrs, dict)
    names = sorted({a for v in attrs.values() for a in v})
    if names:
        lines += [
            "",
            "P@20 / AUC over the frames with each attribute (frames pooled over the scenes):",
            "",
        ]
        trk = list(attrs)
        lines.append("| attribute | frames | " + " | ".join(trk) + " |")
        lines.append("|" + "---|" * (len(trk) + 2))
        for name in names:
            frames = next((int(v[name]["frames"]) for v in attrs.values() if name in v), 0)
            cells = [
                f"{f(attrs[t].get(name, {}).get('p20'))} / {f(attrs[t].get(name, {}).get('auc'))}"
                for t in trk
            ]
            lines.append(f"| {name} | {frames} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
