"""Shared fixtures: synthetic sequences (generated once per session), real data, tiny layouts."""

from __future__ import annotations

import os
from pathlib import Path

import cv2
import numpy as np
import pytest

REALDATA = Path(__file__).resolve().parents[1].parent / "shared" / "realdata"
REAL_SEQUENCES = ("otb-crossing", "ptbtir-airplane", "vottir-horse")


@pytest.fixture(scope="session")
def realdata() -> Path:
    """``../shared/realdata``; tests using it skip with a reason when it is absent."""
    if not REALDATA.is_dir():
        pytest.skip(f"shared real footage not found at {REALDATA} (CI has it beside the clone)")
    return REALDATA


class SceneCache:
    """Synthetic sequences rendered on first use and reused for the whole session."""

    def __init__(self, root: Path):
        self.root = root
        self._done: dict[tuple[str, int], Path] = {}

    def __call__(self, name: str, seed: int = 0) -> Path:
        key = (name, seed)
        if key not in self._done:
            from pipeline.synthetic import synthesize

            self._done[key] = synthesize(
                name, self.root / f"{name}-{seed}", seed=seed, progress=False
            )
        return self._done[key]


@pytest.fixture(scope="session")
def scene(tmp_path_factory: pytest.TempPathFactory) -> SceneCache:
    """``scene("crossing2")`` -> path of that synthetic sequence (rendered once per session)."""
    return SceneCache(tmp_path_factory.mktemp("synthetic"))


def write_frames(
    folder: Path,
    n: int,
    size: tuple[int, int] = (64, 48),
    color: bool = True,
    ext: str = ".jpg",
    name: str = "{:05d}",
    dtype: type = np.uint8,
    seed: int = 0,
) -> list[Path]:
    """Write ``n`` small frames (a bright square moving right on noise) and return their paths."""
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    w, h = size
    paths = []
    for i in range(n):
        if dtype == np.uint16:
            img = (rng.normal(20000, 200, (h, w))).astype(np.uint16)
            img[10:20, 10 + i : 20 + i] = 40000
        else:
            img = rng.integers(40, 80, (h, w, 3) if color else (h, w), dtype=np.uint8)
            if color:
                img[10:20, 10 + i : 20 + i] = (30, 60, 220)
            else:
                img[10:20, 10 + i : 20 + i] = 220
        p = folder / (name.format(i + 1) + ext)
        cv2.imwrite(str(p), img)
        paths.append(p)
    return paths


def write_boxes(
    path: Path, n: int, sep: str = ",", corners: bool = False, base: float = 0.0
) -> None:
    """Truth of the moving square of :func:`write_frames` (x, y, w, h = 10+i, 10, 10, 10 in 0-based
    px)."""
    lines = []
    for i in range(n):
        x, y, w, h = 10 + i + base, 10 + base, 10, 10
        vals = (x, y, x + w, y + h) if corners else (x, y, w, h)
        lines.append(sep.join(f"{v:g}" for v in vals))
    path.write_text("\n".join(lines) + "\n")


def write_pair(root: Path, n: int = 6) -> Path:
    """A two-channel RGBT234-layout folder of :func:`write_frames` with per-channel truth; returns
    ``root``."""
    write_frames(root / "visible", n)
    write_frames(root / "infrared", n, color=False)
    write_boxes(root / "visible.txt", n)
    write_boxes(root / "infrared.txt", n)
    return root


@pytest.fixture(autouse=True)
def _no_rerun_off(monkeypatch: pytest.MonkeyPatch) -> None:
    """RERUN=off would silently disable recordings (rerun.md §6); tests always record."""
    if os.environ.get("RERUN", "").lower() in ("off", "0", "false"):
        monkeypatch.delenv("RERUN")
