"""Generate ``docs/benchmarks.md`` (and the README's headline table) from one benchmark run.

Usage::

    tools/peer_venv.sh .venv-peers                  # once: a second environment with CSRT and KCF
    .venv-peers/bin/python tools/benchmarks.py      # about 1.5 hours on 2 cores

Runs, in one process of the current environment (every tracker and peer in the same run, so that
speeds are ratios measured together):

* the random family's test range: a sample of one-target scenes and a sample of 2-3-target
  scenes spread over seeds 1000-1999 (``--single``, ``--multi``), and the same on the
  development range (``--dev-single``, ``--dev-multi``; 0 skips);
* the real footage of ``--realdata`` (default ``../shared/realdata`` beside the project), when
  the folder is there;
* the eight named single-target scenes (seed 0, ``--repeat 2``) for speed: each tracker's
  tracking rate in its own CPU time, and the dual tracker's ratios to CSRT and KCF;
* the ``walkers<n>`` scenes (n = 1, 2, 4, 8) for the cost per target.

Writes ``docs/benchmarks.md`` (the commit, the machine, the command and the date at the top),
replaces the table between ``<!-- benchmarks:readme-table -->`` markers in ``README.md`` with the
one in the page, and keeps every row as JSON in ``--out`` (default ``runs/benchmarks``).
``--quick`` runs a few scenes of each kind, to check the script itself (its page says so).
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
MARK_START = "<!-- benchmarks:readme-table -->"
MARK_END = "<!-- /benchmarks:readme-table -->"
SINGLE_TRACKERS = ("dual", "meanshift", "kalman-camshift", "camshift", "mil", "csrt", "kcf")
MULTI_TRACKERS = ("dual", "csrt", "detect")
REAL_TRACKERS = ("dual", "meanshift", "mil", "csrt", "kcf")
SPEED_TRACKERS = ("dual", "csrt", "kcf")


def spread(lo: int, hi: int, n: int) -> list[int]:
    """``n`` seeds spread evenly over ``[lo, hi)`` (the first is ``lo``)."""
    step = (hi - lo) / n
    return [lo + int(k * step) for k in range(n)]


def machine() -> str:
    """The CPU model and count, and the versions that matter."""
    import cv2
    import numpy

    model = platform.processor() or "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    contrib = (
        "with contrib"
        if hasattr(cv2, "TrackerCSRT_create")
        or hasattr(getattr(cv2, "legacy", None), "TrackerCSRT_create")
        else "headless, no contrib"
    )
    return (
        f"{model}, {os.cpu_count()} cores; Python {platform.python_version()}, "
        f"OpenCV {cv2.__version__} ({contrib}), NumPy {numpy.__version__}"
    )


def commit() -> str:
    """The commit the figures are for (``+changes`` when the work tree differs from it)."""

    def git(*args: str) -> str:
        r = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
        return r.stdout.strip()

    sha = git("rev-parse", "--short", "HEAD") or "unknown"
    dirty = git("status", "--porcelain", "--untracked-files=no", "--", "pipeline", "tools")
    return sha + (" +changes" if dirty else "")


def f3(v: object) -> str:
    return f"{v:.3f}" if isinstance(v, float) else "-"


def random_section(title: str, result: dict, seeds: list[int], what: str) -> list[str]:
    """A random-family sample's distribution table and per-attribute table."""
    from pipeline.bench import format_distribution

    lo, hi = min(seeds), max(seeds)
    return [
        f"## {title}",
        "",
        f"{len(seeds)} scenes ({what}), seeds {lo} to {hi} spread evenly "
        f"({', '.join(map(str, seeds[:4]))}, ...). Every tracker but `detect` is started from "
        "the truth of frame 1; P@20 and AUC are means over each scene's targets, then their "
        "mean, 10th percentile and worst over the scenes.",
        "",
        format_distribution(result),
        "",
    ]


def multi_section(title: str, result: dict, seeds: list[int]) -> list[str]:
    """A many-target sample: identity scores per tracker."""
    dist = result["distribution"]
    lines = [
        f"## {title}",
        "",
        f"{len(seeds)} scenes of 2-3 targets, seeds {min(seeds)} to {max(seeds)} spread evenly. "
        "`dual` and `csrt` (one CSRT per target) start from the truth of frame 1; `detect` "
        "finds its own targets (its ids are matched to the truth by the IDF1 assignment). "
        "(visible): on the frames where each target is at least 25 % visible.",
        "",
        "| tracker | scenes | IDF1 mean | IDF1 p10 | IDF1 worst (seed) | purity mean | purity p10 "
        "| IDF1 (visible) | purity (visible) | MOTA mean | P@20 mean | fps (median) |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for t, d in dist.items():
        if "skipped" in d:
            lines.append(f"| {t} | skipped: {d['skipped']} |||||||||||")
            continue
        keys = ("idf1", "purity", "mota", "p20", "idf1_visible", "purity_visible")
        i, p, m, a, iv, pv = (d.get(k, {}) for k in keys)
        lines.append(
            f"| {t} | {d['scenes']} | {f3(i.get('mean'))} | {f3(i.get('p10'))} | "
            f"{f3(i.get('worst'))} ({i.get('worst_seed')}) | {f3(p.get('mean'))} | "
            f"{f3(p.get('p10'))} | {f3(iv.get('mean'))} | {f3(pv.get('mean'))} | "
            f"{f3(m.get('mean'))} | {f3(a.get('mean'))} | "
            f"{d.get('fps_tracking_median') or 0:.0f} |"
        )
    return [*lines, ""]


def real_section(rows: list[dict]) -> list[str]:
    seqs = list(dict.fromkeys(str(r["sequence"]) for r in rows))
    trk = list(dict.fromkeys(str(r["tracker"]) for r in rows if r["tracker"] != "-"))
    lines = [
        "## Real footage",
        "",
        "The sequences of `../shared/realdata` (otb-crossing visible, ptbtir-airplane and "
        "vottir-horse thermal, vtuav-bus1 both at 1920x1080, truth every 10th frame), started "
        "from the first frame's truth. P@20 / AUC:",
        "",
        "| sequence | " + " | ".join(trk) + " |",
        "|" + "---|" * (len(trk) + 1),
    ]
    for s in seqs:
        cells = []
        for t in trk:
            r = next((r for r in rows if r["sequence"] == s and r["tracker"] == t), {})
            cells.append(
                "skipped" if "skipped" in r else f"{f3(r.get('p20'))} / {f3(r.get('auc'))}"
            )
        lines.append(f"| {s} | " + " | ".join(cells) + " |")
    return [*lines, ""]


def real_means(rows: list[dict]) -> dict[str, tuple[float, float]]:
    out = {}
    for t in dict.fromkeys(str(r["tracker"]) for r in rows):
        mine = [r for r in rows if r["tracker"] == t and isinstance(r.get("p20"), float)]
        if mine:
            out[t] = (
                sum(r["p20"] for r in mine) / len(mine),
                sum(r["auc"] for r in mine) / len(mine),
            )
    return out


def speed_section(rows: list[dict]) -> tuple[list[str], dict[str, float]]:
    """The named scenes' tracking rates in CPU time and the dual tracker's ratios to the peers."""
    import numpy as np

    lines = [
        "## Speed: the eight named scenes",
        "",
        "One target, 320x240, seed 0, `--repeat 2` (the faster of two runs), one core. Rates are "
        "frames per second of the tracker's own CPU time (`fps_tracking_cpu`); the ratios are "
        "of one run, which is what these machines measure reliably.",
        "",
        "| scene | " + " | ".join(SPEED_TRACKERS) + " | dual / CSRT | dual / KCF |",
        "|" + "---|" * (len(SPEED_TRACKERS) + 3),
    ]
    ratios: dict[str, list[float]] = {"csrt": [], "kcf": []}
    for s in dict.fromkeys(str(r["sequence"]) for r in rows):
        rate = {
            str(r["tracker"]): r.get("fps_tracking_cpu")
            for r in rows
            if r["sequence"] == s and isinstance(r.get("fps_tracking_cpu"), float)
        }
        cells = [f"{rate[t]:.0f}" if t in rate else "-" for t in SPEED_TRACKERS]
        for p in ("csrt", "kcf"):
            if "dual" in rate and p in rate:
                ratios[p].append(rate["dual"] / rate[p])
                cells.append(f"{ratios[p][-1]:.2f}")
            else:
                cells.append("-")
        lines.append(f"| {s} | " + " | ".join(cells) + " |")
    med = {p: float(np.median(v)) for p, v in ratios.items() if v}
    low = {p: float(np.min(v)) for p, v in ratios.items() if v}
    if med:
        lines += [
            "",
            "Median dual / CSRT "
            + (f"{med['csrt']:.2f} (lowest {low['csrt']:.2f})" if "csrt" in med else "-")
            + ", dual / KCF "
            + (f"{med['kcf']:.2f} (lowest {low['kcf']:.2f})" if "kcf" in med else "-")
            + ".",
        ]
    return [*lines, ""], med


def scaling_section(rows: list[dict]) -> list[str]:
    lines = [
        "## Cost per target",
        "",
        "The `walkers<n>` scenes (n people in separate lanes, the same work per target), `dual`:",
        "",
        "| targets | fps tracking | ms per target | per-target cost vs one |",
        "|---|---|---|---|",
    ]
    for r in rows:
        if r.get("tracker") != "dual":
            continue
        lines.append(
            f"| {r['targets']} | {r.get('fps_tracking') or 0:.0f} | "
            f"{r.get('ms_per_target') or 0:.2f} | {r.get('per_target_cost_vs_first') or 0:.2f} |"
        )
    return [*lines, ""]


def readme_table(single: dict, multi: dict | None, real: dict[str, tuple[float, float]]) -> str:
    """The README's headline table: one line per tracker."""
    dist = single["distribution"]
    lines = [
        "| tracker | random test range, one target: P@20 / AUC (10th percentile P@20) "
        "| real footage: mean P@20 / AUC | fps tracking (median, random) |",
        "|---|---|---|---|",
    ]
    for t, d in dist.items():
        if "skipped" in d:
            continue
        p, a = d["p20"], d["auc"]
        r = real.get(t)
        lines.append(
            f"| `{t}` | {p['mean']:.3f} / {a['mean']:.3f} ({p['p10']:.3f}) | "
            + (f"{r[0]:.3f} / {r[1]:.3f}" if r else "")
            + f" | {d.get('fps_tracking_median') or 0:.0f} |"
        )
    if multi is not None:
        md = multi["distribution"]
        cells = []
        for t in ("dual", "csrt", "detect"):
            d = md.get(t, {})
            if "idf1" in d:
                cells.append(
                    f"`{t}` IDF1 {d['idf1']['mean']:.3f} (p10 {d['idf1']['p10']:.3f}), "
                    f"purity {d.get('purity', {}).get('mean', float('nan')):.3f}"
                )
        lines += ["", "Many targets (2-3, test range): " + "; ".join(cells) + "."]
    return "\n".join(lines)


def replace_readme_table(readme: Path, table: str) -> None:
    text = readme.read_text()
    a, b = text.find(MARK_START), text.find(MARK_END)
    if a < 0 or b < a:
        raise SystemExit(f"{readme}: no {MARK_START} ... {MARK_END} markers")
    readme.write_text(text[: a + len(MARK_START)] + "\n" + table + "\n" + text[b:])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "benchmarks")
    ap.add_argument("--single", type=int, default=200)
    ap.add_argument("--multi", type=int, default=100)
    ap.add_argument("--dev-single", type=int, default=100)
    ap.add_argument("--dev-multi", type=int, default=50)
    ap.add_argument("--realdata", type=Path, default=ROOT.parent / "shared" / "realdata")
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "benchmarks.md")
    ap.add_argument("--readme", type=Path, default=ROOT / "README.md")
    ap.add_argument("--quick", action="store_true", help="a few scenes of each kind")
    a = ap.parse_args()
    if a.quick:
        a.single, a.multi, a.dev_single, a.dev_multi = 4, 2, 2, 1
    sys.path.insert(0, str(ROOT))
    import cv2

    from pipeline.bench import run_bench, run_random_bench, run_scaling
    from pipeline.synthetic import ONE_TARGET_SCENES, synthesize

    cv2.setNumThreads(1)
    t0 = time.time()
    out = a.out
    out.mkdir(parents=True, exist_ok=True)
    started = dt.datetime.now(dt.UTC).strftime("%Y-%m-%d %H:%M UTC")
    raw: dict[str, object] = {}

    def random(name: str, lo: int, hi: int, n: int, targets: tuple[int, int], trk) -> dict:
        seeds = spread(lo, hi, n)
        res = run_random_bench(
            seeds=seeds, targets=targets, trackers=list(trk), out=out / name, progress=False
        )
        raw[name] = {"seeds": seeds, **res}
        print(f"{name}: {len(seeds)} scenes in {time.time() - t0:.0f} s", flush=True)
        return res

    single = random("test-single", 1000, 2000, a.single, (1, 1), SINGLE_TRACKERS)
    multi = random("test-multi", 1000, 2000, a.multi, (2, 3), MULTI_TRACKERS) if a.multi else None
    dev_single = dev_multi = None
    if a.dev_single:
        dev_single = random("dev-single", 0, 1000, a.dev_single, (1, 1), ("dual", "csrt"))
    if a.dev_multi:
        dev_multi = random("dev-multi", 0, 1000, a.dev_multi, (2, 3), ("dual", "detect"))
    real_rows: list[dict] = []
    if a.realdata.is_dir():
        seqs = sorted(p for p in a.realdata.iterdir() if p.is_dir())
        real_rows = run_bench(seqs, list(REAL_TRACKERS), out=out / "real")
        raw["real"] = real_rows
    named = []
    for s in ONE_TARGET_SCENES:
        d = out / "named" / s
        if not (d / "scene.json").is_file():
            synthesize(s, d, seed=0, force=True)
        named.append(d)
    speed_rows = run_bench(named, list(SPEED_TRACKERS), out=out / "named-runs", repeat=2)
    raw["speed"] = speed_rows
    scaling = run_scaling([1, 2, 4, 8], ["dual"], out=out / "scaling")
    raw["scaling"] = scaling
    (out / "benchmarks.json").write_text(json.dumps(raw, indent=1, default=str) + "\n")

    real = real_means(real_rows)
    table = readme_table(single, multi, real)
    speed_lines, _ = speed_section(speed_rows)
    minutes = (time.time() - t0) / 60
    cmd = " ".join(["python tools/benchmarks.py", *sys.argv[1:]])
    lines = [
        "# Benchmarks",
        "",
        "<!-- generated by tools/benchmarks.py from one run; edit the script, not this page -->",
        "",
        f"- **Commit** `{commit()}`, run {started}, {minutes:.0f} minutes",
        f"- **Machine** {machine()}",
        f"- **Command** `{cmd}` (in the environment of `tools/peer_venv.sh`, which has CSRT "
        "and KCF); the raw rows are in `runs/benchmarks/benchmarks.json`",
        *(
            ["- **A quick run to check the script: a few scenes only, not figures to quote**"]
            if a.quick
            else []
        ),
        "",
        "What each figure means: `docs/formats.md` (the metrics) and `README.md` (the "
        "trackers). Why the defaults are what they are: `docs/decisions.md`; what changed "
        "when: `CHANGELOG.md`.",
        "",
        "## Headline (the README's table)",
        "",
        MARK_START,
        table,
        MARK_END,
        "",
        *random_section(
            "One target: the random family's test range",
            single,
            raw["test-single"]["seeds"],
            "one target each",
        ),
    ]
    if multi is not None:
        lines += multi_section(
            "Many targets: the random family's test range", multi, raw["test-multi"]["seeds"]
        )
    if dev_single is not None:
        lines += random_section(
            "One target: the development range (tuned on)",
            dev_single,
            raw["dev-single"]["seeds"],
            "one target each",
        )
    if dev_multi is not None:
        lines += multi_section(
            "Many targets: the development range (tuned on)", dev_multi, raw["dev-multi"]["seeds"]
        )
    if real_rows:
        lines += real_section(real_rows)
    lines += speed_lines
    lines += scaling_section(scaling)
    a.doc.write_text("\n".join(lines).rstrip() + "\n")
    replace_readme_table(a.readme, table)
    print(f"wrote {a.doc} and the table of {a.readme} ({minutes:.0f} minutes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
