"""Error plots against ground truth (PNG via matplotlib's Agg backend).

Made after the run from the per-target curves of :func:`pipeline.eval.curves`:
``center_error.png`` (centre error per frame per target), ``precision.png`` (precision
plot, 0-50 px) and ``success.png`` (success plot, IoU thresholds 0-1), each with the
P@20 / AUC of every curve in its legend. ``comparison_plots`` draws one curve per
tracker for ``bench`` and ``batch``.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from pipeline.eval.single import PRECISION_THRESHOLDS_PX, SUCCESS_THRESHOLDS


def _color(i: int) -> tuple[float, float, float]:
    from pipeline.sinks.rerun_sink import PALETTE

    r, g, b = PALETTE[i % len(PALETTE)]
    return (r / 255, g / 255, b / 255)


def write_plots(out_dir: Path, curves: dict[int, dict[str, np.ndarray]], title: str) -> list[Path]:
    """Write the three plots for one run; returns the files written."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    fig, ax = plt.subplots(figsize=(8, 3.5), dpi=100)
    for k, (tid, c) in enumerate(curves.items()):
        # the frames with truth only, joined: sparse truth (VTUAV: every 10th frame) is a line
        # through its frames with a marker on each, not points lost between gaps
        e = c["errors"]
        frames = np.arange(1, e.size + 1)
        has = ~np.isnan(e)
        sparse = has.sum() < 0.5 * max(e.size, 1)
        color = _color(tid - 1 if tid >= 1 else k)
        shown = np.where(np.isinf(e[has]), np.nan, e[has])  # no output: a gap in the line
        ax.plot(
            frames[has],
            shown,
            color=color,
            lw=1.2,
            marker="o" if sparse else None,
            ms=3,
            label=f"T{tid}",
        )
    ax.axhline(20, color="0.6", lw=0.8, ls="--")
    ax.set_xlabel("frame")
    ax.set_ylabel("centre error [px]")
    ax.set_title(f"{title}: centre error")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    written.append(out_dir / "center_error.png")
    fig.savefig(written[-1])
    plt.close(fig)

    series = {f"T{tid}": c for tid, c in curves.items()}
    written += comparison_plots(out_dir, series, title)
    return written


def comparison_plots(
    out_dir: Path, series: dict[str, dict[str, np.ndarray]], title: str, prefix: str = ""
) -> list[Path]:
    """Precision and success plots with one curve per entry of ``series``."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    fig, ax = plt.subplots(figsize=(5, 4), dpi=100)
    order = sorted(series, key=lambda k: -np.nan_to_num(series[k]["precision"][20], nan=-1))
    for k, name in enumerate(order):
        p = series[name]["precision"]
        ax.plot(
            PRECISION_THRESHOLDS_PX,
            p,
            color=_color(k),
            lw=1.5,
            label=f"{name} [{np.nan_to_num(p[20]):.3f}]",
        )
    ax.set_xlim(0, 50)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("location error threshold [px]")
    ax.set_ylabel("precision")
    ax.set_title(f"{title}: precision")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    written.append(out_dir / f"{prefix}precision.png")
    fig.savefig(written[-1])
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(5, 4), dpi=100)
    order = sorted(series, key=lambda k: -np.nan_to_num(np.mean(series[k]["success"]), nan=-1))
    for k, name in enumerate(order):
        s = series[name]["success"]
        ax.plot(
            SUCCESS_THRESHOLDS,
            s,
            color=_color(k),
            lw=1.5,
            label=f"{name} [{np.nan_to_num(np.mean(s)):.3f}]",
        )
    ax.set_xlim(0, 1)
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("overlap threshold")
    ax.set_ylabel("success rate")
    ax.set_title(f"{title}: success")
    ax.grid(alpha=0.3)
    ax.legend(loc="lower left", fontsize=8)
    fig.tight_layout()
    written.append(out_dir / f"{prefix}success.png")
    fig.savefig(written[-1])
    plt.close(fig)
    return written
