"""Figures of the reproduction studies in ``tools/`` (matplotlib, Agg)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def purity_figure(
    path: Path, matrices: dict[str, np.ndarray], routes: np.ndarray, paper: dict[str, list[float]]
) -> Path:
    """The purity matrices (one panel per association mode) and the routes of one run."""
    fig, axes = plt.subplots(1, len(matrices) + 1, figsize=(4.2 * (len(matrices) + 1), 4), dpi=100)
    for ax, (mode, m) in zip(axes, matrices.items(), strict=False):
        ax.imshow(m, vmin=0, vmax=1, cmap="viridis")
        for i in range(m.shape[0]):
            for j in range(m.shape[1]):
                ax.text(
                    j,
                    i,
                    f"{m[i, j]:.2f}",
                    ha="center",
                    va="center",
                    color="w" if m[i, j] < 0.6 else "k",
                    fontsize=9,
                )
        ax.set_xticks(range(m.shape[1]), [f"track {j + 1}" for j in range(m.shape[1])], fontsize=8)
        ax.set_yticks(
            range(m.shape[0]), [f"target {i + 1}" for i in range(m.shape[0])], fontsize=8
        )
        ref = paper.get(mode)
        ax.set_title(
            f"{mode}: mean diagonal {np.trace(m) / m.shape[0]:.3f}"
            + (f"\n(paper {np.mean(ref):.3f})" if ref else "\n"),
            fontsize=10,
        )
    ax = axes[-1]
    for i, r in enumerate(routes):
        ax.plot(r[:, 0], r[:, 1], lw=1.5, label=f"target {i + 1}")
        ax.plot(r[0, 0], r[0, 1], "o", color=ax.lines[-1].get_color(), ms=4)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("routes of one run (o = start)", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def radar_figures(
    out_dir: Path, series: dict[str, dict[str, np.ndarray]], title: str
) -> list[Path]:
    """RMS position and velocity error over time, one curve per algorithm (the CHNN study)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for key, unit in (("pos", "m"), ("vel", "m/s")):
        fig, ax = plt.subplots(figsize=(6, 3.5), dpi=100)
        for name, s in series.items():
            ax.plot(s["t"], s[key], lw=1.3, label=name)
        ax.set_xlabel("time [s]")
        ax.set_ylabel(f"RMS {'position' if key == 'pos' else 'velocity'} error [{unit}]")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
        fig.tight_layout()
        p = out_dir / f"{title.replace(' ', '_')}_rms_{key}.png"
        fig.savefig(p)
        plt.close(fig)
        written.append(p)
    return written


def radar_trajectories(path: Path, truth: np.ndarray) -> Path:
    """True trajectories (N, steps, 4: x, x', y, y') of one run of the CHNN study."""
    fig, ax = plt.subplots(figsize=(5, 4), dpi=100)
    for i, tr in enumerate(truth):
        ax.plot(tr[:, 0] / 1e3, tr[:, 2] / 1e3, lw=1.5, label=f"target {i + 1}")
        ax.plot(tr[0, 0] / 1e3, tr[0, 2] / 1e3, "o", color=ax.lines[-1].get_color(), ms=4)
    ax.set_xlabel("x [km]")
    ax.set_ylabel("y [km]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("true trajectories (o = start)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def radar_sensitivity_figure(path: Path, rows: list[dict], paper: dict) -> Path:
    """Single-target RMS position error of algorithms 1-3 against the sampling period (CHNN study).

    One panel per filter Q (``acc_std``); solid lines the 2-D distance RMS, dashed the RMS of
    one coordinate (alg. 1); dotted horizontal lines the paper's figures; both axes logarithmic.
    """
    accs = sorted({r["acc_std"] for r in rows}, reverse=True)
    fig, axes = plt.subplots(1, len(accs), figsize=(5.2 * len(accs), 3.8), dpi=100, sharey=True)
    axes = np.atleast_1d(axes)
    for ax, acc in zip(axes, accs, strict=True):
        sel = sorted((r for r in rows if r["acc_std"] == acc), key=lambda r: r["dt_s"])
        dts = [r["dt_s"] for r in sel]
        for alg in ("alg1", "alg2", "alg3"):
            (line,) = ax.plot(
                dts, [r["single"][alg]["pos"] for r in sel], "o-", lw=1.3, label=f"{alg} 2-D"
            )
            ax.axhline(
                paper["single"][alg]["pos"],
                color=line.get_color(),
                ls=":",
                lw=1,
                label=f"paper {alg} {paper['single'][alg]['pos']:.0f} m",
            )
        ax.plot(
            dts,
            [r["single"]["alg1"]["pos_per_axis"] for r in sel],
            "s--",
            lw=1.1,
            color="k",
            label="alg1 per axis",
        )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("sampling period [s]")
        ax.set_title(
            "paper's Q (20 m position noise)"
            if acc == 0
            else f"Q + white acceleration {acc:g} m/s²",
            fontsize=10,
        )
        ax.grid(alpha=0.3, which="both")
    axes[0].set_ylabel("RMS position error, single target [m]")
    axes[-1].legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
