"""How far a tracker's scores move when only the rounding of its arithmetic changes.

Usage::

    python tools/rounding_spread.py SEQ_DIR... [--tracker dual] [--param dual.levelset.timestep]
        [--steps 2] [--json FILE]

Runs ``dualtrack bench`` on the sequences once as configured and once for each of ``2 *
--steps`` values of one parameter moved by a relative 1e-7 (``value * (1 + k * 1e-7)``, k =
+-1 .. +-steps): a change of the last bits of float32 arithmetic, nothing a tracker's behaviour
should depend on. Prints per sequence the configured P@20 / AUC, the spread over the moved runs
(min, max, standard deviation) and the configured run's distance from their mean.

A tracker whose decisions switch on thresholds amplifies such a change: a contour that touches
the window's edge in one run and not in the other takes a different branch, and the runs part
from there. This is the floor under any comparison of two versions whose outputs differ at the
rounding level (a compiled kernel rewritten, a library's new release, another CPU's vector
width): a difference within this spread is not a difference of the code's quality.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from pipeline.config import PipelineConfig  # noqa: E402

RELATIVE_STEP = 1e-7


def _value(param: str) -> float:
    """The configured default of ``section.sub.param`` (``dual.levelset.timestep``)."""
    obj: object = PipelineConfig()
    for part in param.split("."):
        obj = getattr(obj, part)
    if not isinstance(obj, float):
        raise SystemExit(f"rounding_spread: {param} is not a float parameter ({obj!r})")
    return obj


def moved_values(v0: float, steps: int) -> list[float]:
    """``v0 * (1 + k * RELATIVE_STEP)`` for k = -steps .. -1, 1 .. steps.

    Examples
    --------
    >>> [round(v, 9) for v in moved_values(5.0, 1)]
    [4.9999995, 5.0000005]
    """
    return [v0 * (1 + k * RELATIVE_STEP) for k in range(-steps, steps + 1) if k != 0]


def _bench(seqs: list[str], tracker: str, sets: list[str]) -> dict[str, tuple[float, float]]:
    """``{sequence: (P@20, AUC)}`` of one ``dualtrack bench`` run."""
    with tempfile.TemporaryDirectory(prefix="dualtrack-spread-") as tmp:
        out = Path(tmp) / "bench.json"
        cmd = [sys.executable, "-m", "pipeline", "bench", *seqs, "--trackers", tracker]
        cmd += ["--json", str(out)]
        for s in sets:
            cmd += ["--set", s]
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        rows = json.loads(out.read_text())["rows"]
    return {r["sequence"]: (float(r["p20"]), float(r["auc"])) for r in rows}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seqs", nargs="+", help="sequence folders")
    ap.add_argument("--tracker", default="dual")
    ap.add_argument("--param", default="dual.levelset.timestep")
    ap.add_argument("--steps", type=int, default=2)
    ap.add_argument("--json", type=Path, default=None, help="also write the scores here")
    a = ap.parse_args()
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    v0 = _value(a.param)
    base = _bench(a.seqs, a.tracker, [])
    moved: dict[str, list[tuple[float, float]]] = {k: [] for k in base}
    values = moved_values(v0, a.steps)
    for v in values:
        for seq, score in _bench(a.seqs, a.tracker, [f"{a.param}={v!r}"]).items():
            moved[seq].append(score)
    print(f"{a.tracker}: {a.param} = {v0}, moved to {', '.join(repr(v) for v in values)}")
    print(
        "| sequence | P@20 | AUC | P@20 moved: min / max | AUC moved: min / max / sd "
        "| AUC configured - mean(moved) |"
    )
    print("|---|---|---|---|---|---|")
    for seq, (p, auc) in base.items():
        p20s, aucs = [m[0] for m in moved[seq]], [m[1] for m in moved[seq]]
        sd, off = statistics.pstdev(aucs), auc - statistics.fmean(aucs)
        print(
            f"| {seq} | {p:.3f} | {auc:.3f} | {min(p20s):.3f} / {max(p20s):.3f} "
            f"| {min(aucs):.3f} / {max(aucs):.3f} / {sd:.3f} | {off:+.3f} |"
        )
    if a.json is not None:
        a.json.write_text(json.dumps({"param": a.param, "base": base, "moved": moved}, indent=1))


if __name__ == "__main__":
    main()
