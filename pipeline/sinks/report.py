"""The report of a batch: ``report.json``, ``report.md`` and ``plots/`` under DIR.

``report.json``::

    {"protocol": ..., "trackers": [...], "wall_seconds": ..., "interrupted": bool,
     "sequences": {name: {"status": "done|failed|skipped", "error": ..., "tracker": ...,
                          "sequence": ..., "run_dir": ..., "attributes": [...],
                          "metrics": ..., "fps_tracking": ..., "frames": ...}},
     "overall": {tracker: {scores (pipeline.eval.aggregate), "done", "failed", "skipped",
                           "attributes": {attr: scores over the sequences that have it}}}}

``name`` is the sequence's path under ROOT, prefixed with ``<tracker>/`` when the batch
ran several trackers. ``skipped`` sequences were complete from an earlier run; their
results count in the report as if run now. ``plots/precision.png`` and
``plots/success.png`` draw one curve per tracker over all finished sequences, the plots
tracking papers print, and ``plots/attributes/<A>_*.png`` the same per attribute.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import numpy as np

from pipeline.eval import json_safe
from pipeline.eval.aggregate import SCORE_KEYS, aggregate, sequence_curves
from pipeline.io.attributes import read_root_table, sequence_attributes

HEADLINE = {
    "default": ("p20", "auc"),
    "rgbt234": ("mpr", "msr"),
    "vtuav": ("mpr", "msr"),
    "gtot": ("mpr", "msr"),
    "lasher": ("pr", "npr", "sr"),
}
LABEL = {
    "p5": "P@5",
    "p20": "P@20",
    "auc": "AUC",
    "mpr": "MPR",
    "msr": "MSR",
    "npr": "NPR",
    "pr": "PR",
    "sr": "SR",
    "mota": "MOTA",
    "idf1": "IDF1",
    "hota": "HOTA",
    "purity": "purity",
    "purity_visible": "purity (visible)",
    "idf1_visible": "IDF1 (visible)",
    "id_switches": "ID sw.",
}


def _f(v: object, nd: int = 3) -> str:
    if isinstance(v, bool) or v is None:
        return "" if v is None else str(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "" if math.isnan(v) else f"{v:.{nd}f}"
    return str(v)


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def write_progress_report(out: Path, results: list, opts, total: int, wall_seconds: float) -> None:
    """A running batch's report: every finished sequence's status, scores and error, rewritten
    after each one (atomically), so a batch that is killed leaves a report of what finished. The
    final report replaces it."""
    out = Path(out)
    sequences = {}
    for r in results:
        t = r.task
        sequences[t.key] = {
            "status": r.status,
            "error": r.error,
            "tracker": t.tracker,
            "sequence": t.sequence,
            "run_dir": _rel(t.run_dir, out),
            "metrics": r.summary.get("metrics"),
            "fps_tracking": r.summary.get("fps_tracking"),
            "frames": r.summary.get("frames"),
        }
    report = json_safe(
        {
            "protocol": opts.protocol,
            "trackers": list(opts.trackers),
            "partial": True,
            "finished": len(results),
            "tasks": total,
            "wall_seconds": round(wall_seconds, 3),
            "sequences": sequences,
        }
    )
    _write_atomic(out / "report.json", json.dumps(report, indent=1) + "\n")
    keys = list(HEADLINE[opts.protocol])[:2]
    lines = [
        "# dualtrack batch report (in progress)",
        "",
        f"{len(results)} of {total} runs finished after {wall_seconds:.1f} s; the full report is "
        "written when the "
        "batch ends.",
        "",
        "| run | status | " + " / ".join(LABEL[k] for k in keys) + " | error |",
        "|---|---|---|---|",
    ]
    for k, rec in sequences.items():
        m = rec.get("metrics") or {}
        lines.append(
            f"| {k} | {rec['status']} | "
            + " / ".join(_f(m.get(x)) for x in keys)  # type: ignore[union-attr]
            + f" | {rec.get('error') or ''} |"
        )
    _write_atomic(out / "report.md", "\n".join(lines) + "\n")


def write_report(
    out: Path, results: list, opts, wall_seconds: float, interrupted: bool
) -> dict[str, object]:
    """Write report.json, report.md and the plots; returns the report object."""
    from pipeline.sinks.plots import comparison_plots

    out = Path(out)
    protocol = opts.protocol
    trackers = list(opts.trackers)
    roots = {r.task.seq_dir.parent for r in results}
    tables: dict[Path, dict[str, tuple[str, ...]]] = {d: read_root_table(d) for d in roots}
    sequences: dict[str, dict[str, object]] = {}
    entries: dict[str, list[dict[str, object]]] = {t: [] for t in trackers}
    for r in results:
        t = r.task
        attrs = list(sequence_attributes(t.seq_dir, tables.get(t.seq_dir.parent)))
        rec: dict[str, object] = {
            "status": r.status,
            "error": r.error,
            "tracker": t.tracker,
            "sequence": t.sequence,
            "run_dir": _rel(t.run_dir, out),
            "attributes": attrs,
        }
        if r.status in ("done", "skipped"):
            s = r.summary
            rec.update(
                {
                    "metrics": s.get("metrics"),
                    "fps_tracking": s.get("fps_tracking"),
                    "frames": s.get("frames"),
                }
            )
            entry = dict(rec)
            if isinstance(s.get("metrics"), dict):
                try:
                    rule = (
                        "assign" if s.get("ids") == "detected" or not s.get("targets") else "truth"
                    )
                    entry["curves"] = sequence_curves(
                        t.seq_dir, t.run_dir / "tracks.csv", protocol, rule
                    )
                except Exception as e:
                    rec["report_warning"] = f"no curves: {e}"
            entries[t.tracker].append(entry)
        else:
            rec.update({"metrics": None, "fps_tracking": None, "frames": r.summary.get("frames")})
        sequences[t.key] = rec

    overall: dict[str, dict[str, object]] = {}
    for trk in trackers:
        scored = [e for e in entries[trk] if isinstance(e.get("metrics"), dict)]
        o = aggregate(scored, protocol)
        mine = [r for r in results if r.task.tracker == trk]
        o.update({st: sum(r.status == st for r in mine) for st in ("done", "failed", "skipped")})
        by_attr: dict[str, dict[str, object]] = {}
        for a in sorted({a for e in scored for a in e["attributes"]}):  # type: ignore[union-attr]
            # type: ignore[operator]
            by_attr[a] = aggregate([e for e in scored if a in e["attributes"]], protocol)
        o["attributes"] = by_attr
        overall[trk] = o

    report = json_safe(
        {
            "protocol": protocol,
            "trackers": trackers,
            "wall_seconds": round(wall_seconds, 3),
            "interrupted": interrupted,
            "sequences": sequences,
            "overall": overall,
        }
    )
    _write_atomic(out / "report.json", json.dumps(report, indent=1) + "\n")

    plots: list[Path] = []
    series = {
        t: {
            "precision": np.asarray(o["precision_curve"]),
            "success": np.asarray(o["success_curve"]),
        }
        for t, o in overall.items()
        if o.get("precision_curve") is not None
    }
    if series:
        plots += comparison_plots(out / "plots", series, f"all sequences ({protocol})")
        # type: ignore[union-attr]
        attrs = sorted({a for o in overall.values() for a in o["attributes"]})
        for a in attrs:
            s = {
                t: {
                    # type: ignore[index]
                    "precision": np.asarray(o["attributes"][a]["precision_curve"]),
                    "success": np.asarray(o["attributes"][a]["success_curve"]),
                }  # type: ignore[index]
                for t, o in overall.items()
                if a in o["attributes"]  # type: ignore[operator]
                and o["attributes"][a].get("precision_curve") is not None
            }  # type: ignore[index]
            if s:
                n = max(
                    int(o["attributes"][a]["sequences"])
                    for o in overall.values()
                    if a in o["attributes"]
                )  # type: ignore[index, operator]
                plots += comparison_plots(
                    out / "plots" / "attributes", s, f"{a} ({n} sequences)", prefix=f"{a}_"
                )
    _write_atomic(out / "report.md", _markdown(report, protocol, trackers, plots, out))
    return report  # type: ignore[return-value]


def _rel(p: Path, base: Path) -> str:
    try:
        return Path(p).relative_to(base).as_posix()
    except ValueError:
        return str(p)


def _markdown(
    report: dict, protocol: str, trackers: list[str], plots: list[Path], out: Path
) -> str:
    overall = report["overall"]
    keys = list(HEADLINE[protocol])
    many = ("purity", "purity_visible", "id_switches", "mota", "idf1", "idf1_visible", "hota")
    extra = [k for k in many if any(k in o for o in overall.values())]
    seqs = report["sequences"]
    n_seq = len({s["sequence"] for s in seqs.values()})
    pooling = "frames pooled over all sequences" if protocol == "gtot" else "mean over sequences"
    lines = [
        "# dualtrack batch report",
        "",
        f"{n_seq} sequences, trackers: {', '.join(trackers)}; protocol `{protocol}` "
        f"({pooling}); "
        f"wall time {report['wall_seconds']:.1f} s"
        + (" (interrupted)" if report["interrupted"] else "")
        + ".",
        "",
        "## Overall",
        "",
        "| tracker | done | skipped (earlier run) | failed | "
        + " | ".join(LABEL[k] for k in keys + extra)
        + " | fps (mean) | fps (pooled) |",
        "|---|---|---|---|" + "---|" * (len(keys) + len(extra)) + "---|---|",
    ]
    for t in trackers:
        o = overall[t]
        lines.append(
            f"| {t} | {o.get('done', 0)} | {o.get('skipped', 0)} | {o.get('failed', 0)} | "
            + " | ".join(_f(o.get(k)) for k in keys + extra)
            + f" | {_f(o.get('fps_tracking_mean'), 1)} | {_f(o.get('fps_tracking_pooled'), 1)} |"
        )
    attrs = sorted({a for o in overall.values() for a in o.get("attributes", {})})
    if attrs:
        k0 = keys[0]
        lines += [
            "",
            f"## Per attribute ({LABEL[k0]}"
            + (f" / {LABEL[keys[1]]}" if len(keys) > 1 else "")
            + ")",
            "",
            "| attribute | sequences | " + " | ".join(trackers) + " |",
            "|---|---|" + "---|" * len(trackers),
        ]
        for a in attrs:
            n = max(
                int(o["attributes"][a]["sequences"])
                for o in overall.values()
                if a in o.get("attributes", {})
            )
            cells = []
            for t in trackers:
                s = overall[t].get("attributes", {}).get(a)
                cells.append("" if not s else " / ".join(_f(s.get(k)) for k in keys[:2]))
            lines.append(f"| {a} | {n} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "## Sequences",
        "",
        "| sequence | "
        + " | ".join(f"{t}: " + " / ".join(LABEL[k] for k in keys[:2]) + ", fps" for t in trackers)
        + " |",
        "|---|" + "---|" * len(trackers),
    ]
    by_seq: dict[str, dict[str, dict]] = {}
    for rec in seqs.values():
        by_seq.setdefault(rec["sequence"], {})[rec["tracker"]] = rec
    for name in sorted(by_seq):
        cells = []
        for t in trackers:
            rec = by_seq[name].get(t)
            if rec is None:
                cells.append("")
            elif rec["status"] == "failed":
                cells.append("failed")
            else:
                m = rec.get("metrics") or {}
                cells.append(
                    " / ".join(_f(m.get(k)) for k in keys[:2])
                    + f", {_f(rec.get('fps_tracking'), 1)}"
                )
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    failed = [(k, r) for k, r in seqs.items() if r["status"] == "failed"]
    if failed:
        lines += ["", "## Failed", ""] + [f"- `{k}`: {r['error']}" for k, r in failed]
    if plots:
        lines += ["", "## Plots", ""] + [
            f"![{p.stem}]({_rel(p, out)})" for p in plots if p.parent == out / "plots"
        ]
        if any(p.parent != out / "plots" for p in plots):
            lines += ["", "Per attribute: `plots/attributes/`."]
    lines.append("")
    return "\n".join(lines)


__all__ = ["SCORE_KEYS", "write_report"]
