"""Structured backgrounds for the random scene family: streets, facades, foliage, water, sky.

:func:`street_background` draws a static scene in both channels from a random generator:
an upper row of building facades (with windows and edges), trees and sky, a ground of
bands (pavement, kerbs, a road with lane markings, grass or water), poles and fences.
Each material has its own visible colour and its own infrared level, drawn independently,
so the infrared frame is not a blur of the visible one: by day the sun heats walls and
asphalt and the sky is cold; by night the ground has cooled, lit windows are warm and the
sky is colder still.

Coordinates are frame px; the visible image is RGB float32 in [0, 1], the infrared image
float32 grey levels (0..255 scale, before noise and quantisation).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

# material -> (visible RGB in [0, 1] before jitter, IR offset over ambient by day, by night)
_MATERIALS: dict[str, tuple[tuple[float, float, float], float, float]] = {
    "sky": ((0.62, 0.72, 0.86), -45.0, -55.0),
    "window": ((0.30, 0.37, 0.46), -12.0, -8.0),
    "window-lit": ((0.85, 0.78, 0.45), -12.0, 16.0),
    "asphalt": ((0.30, 0.30, 0.32), 22.0, 8.0),
    "marking": ((0.88, 0.86, 0.78), 14.0, 5.0),
    "kerb": ((0.70, 0.69, 0.66), 12.0, 5.0),
    "pavement": ((0.56, 0.55, 0.53), 12.0, 4.0),
    "grass": ((0.30, 0.48, 0.22), -6.0, -10.0),
    "foliage": ((0.16, 0.33, 0.14), -8.0, -11.0),
    "trunk": ((0.30, 0.22, 0.15), -2.0, -6.0),
    "water": ((0.20, 0.33, 0.42), -18.0, -6.0),
    "pole": ((0.22, 0.23, 0.25), -4.0, -9.0),
    "fence": ((0.40, 0.36, 0.30), 2.0, -4.0),
}
FACADE_COLOURS = (
    (0.80, 0.74, 0.62),
    (0.66, 0.34, 0.26),
    (0.62, 0.63, 0.65),
    (0.90, 0.88, 0.84),
    (0.52, 0.46, 0.40),
    (0.75, 0.62, 0.42),
)


@dataclass
class Background:
    """A drawn background: the two images and where its structures are (frame px)."""

    visible: np.ndarray
    infrared: np.ndarray
    horizon_px: int
    ground_bands: list[tuple[str, int, int]] = field(default_factory=list)
    structures: list[dict[str, object]] = field(default_factory=list)
    params: dict[str, object] = field(default_factory=dict)


def _smooth_noise(rng: np.random.Generator, h: int, w: int, sigma: float) -> np.ndarray:
    n = rng.normal(0, 1, (h, w)).astype(np.float32)
    n = cv2.GaussianBlur(n, (0, 0), sigma)
    return n / max(float(n.std()), 1e-6)


class _Painter:
    """Paints materials into both channels, each with its own colour jitter and IR level."""

    def __init__(self, rng: np.random.Generator, w: int, h: int, night: bool, ambient: float):
        self.rng, self.w, self.h = rng, w, h
        self.vis = np.zeros((h, w, 3), np.float32)
        self.ir = np.full((h, w), ambient, np.float32)
        self.ambient = ambient
        self.night = night
        self.levels: dict[str, float] = {}
        self.colours: dict[str, np.ndarray] = {}

    def material(
        self, name: str, rgb: tuple[float, float, float] | None = None
    ) -> tuple[np.ndarray, float]:
        key = name if rgb is None else f"{name}{rgb}"
        if key not in self.colours:
            base, day, night = _MATERIALS.get(name, ((0.5, 0.5, 0.5), 0.0, 0.0))
            col = np.asarray(rgb if rgb is not None else base, np.float32)
            self.colours[key] = np.clip(
                col + self.rng.uniform(-0.06, 0.06, 3).astype(np.float32), 0.02, 0.98
            )
            spread = 6.0 if name in ("asphalt", "pavement") else 4.0
            self.levels[key] = float((night if self.night else day) + self.rng.normal(0, spread))
        return self.colours[key], self.levels[key]

    def rect(self, name: str, x0: float, y0: float, x1: float, y1: float, rgb=None) -> None:
        xa, ya = max(round(x0), 0), max(round(y0), 0)
        xb, yb = min(round(x1), self.w), min(round(y1), self.h)
        if xb <= xa or yb <= ya:
            return
        col, lev = self.material(name, rgb)
        self.vis[ya:yb, xa:xb] = col
        self.ir[ya:yb, xa:xb] = self.ambient + lev

    def mask(self, name: str, m: np.ndarray, rgb=None) -> None:
        """Paint where the float mask ``m`` (H, W, 0..1) is set, blending at its soft edge."""
        col, lev = self.material(name, rgb)
        a = m[..., None]
        self.vis[:] = self.vis * (1 - a) + col * a
        self.ir[:] = self.ir * (1 - m) + (self.ambient + lev) * m


def street_background(
    rng: np.random.Generator,
    w: int,
    h: int,
    night: bool | None = None,
    ambient: float | None = None,
) -> Background:
    """Draw a street scene of ``w`` x ``h`` px (see the module doc).

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness; the same state gives the same background.
    w, h : int
        Frame size in px, at least 32 x 32.
    night : bool, optional
        Night-time infrared levels (drawn when None, probability 0.3).
    ambient : float, optional
        IR grey level of an object at ambient temperature (drawn in [70, 115] when None).
    """
    if w < 32 or h < 32:
        raise ValueError(f"background needs at least 32 x 32 px; got {w} x {h}")
    night = bool(rng.random() < 0.3) if night is None else night
    ambient = float(rng.uniform(70, 115)) if ambient is None else float(ambient)
    p = _Painter(rng, w, h, night, ambient)
    horizon = int(h * rng.uniform(0.22, 0.45))
    structures: list[dict[str, object]] = []

    # upper row: sky, then facades and trees down to the horizon
    sky_to = int(horizon * rng.uniform(0.1, 0.6)) if rng.random() < 0.7 else 0
    if sky_to:  # the sky shows wherever no facade or tree stands in front of it
        p.rect("sky", 0, 0, w, horizon)
        grad = np.linspace(1.05, 0.88, horizon, dtype=np.float32)[:, None, None]
        p.vis[:horizon] *= grad
    else:  # a far wall or hedge closes the view
        p.rect("facade", 0, 0, w, horizon, FACADE_COLOURS[int(rng.integers(len(FACADE_COLOURS)))])
    x = float(rng.uniform(-0.2, 0) * w)
    while x < w:
        kind = rng.choice(["building", "building", "tree", "gap"])
        bw = float(rng.uniform(0.12, 0.45) * w)
        if kind == "building":
            top = float(rng.uniform(0, max(sky_to, 1) + 0.3 * horizon)) if sky_to else 0.0
            colour = FACADE_COLOURS[int(rng.integers(len(FACADE_COLOURS)))]
            p.rect("facade", x, top, x + bw, horizon, colour)
            # a darker side edge so the building reads as a volume
            p.rect(
                "facade",
                x + bw - max(2.0, 0.04 * bw),
                top,
                x + bw,
                horizon,
                tuple(c * 0.75 for c in colour),
            )
            ww = max(3.0, bw * rng.uniform(0.08, 0.16))
            wh = max(3.0, (horizon - top) * rng.uniform(0.10, 0.22))
            gapx, gapy = ww * rng.uniform(0.6, 1.4), wh * rng.uniform(0.5, 1.2)
            lit_p = 0.35 if night else 0.0
            yy = top + gapy
            while yy + wh < horizon - 2:
                xx = x + gapx * 0.7
                while xx + ww < x + bw - 2:
                    p.rect(
                        "window-lit" if rng.random() < lit_p else "window",
                        xx,
                        yy,
                        xx + ww,
                        yy + wh,
                    )
                    xx += ww + gapx
                yy += wh + gapy
            structures.append(
                {"kind": "building", "x": round(x, 1), "w": round(bw, 1), "top": round(top, 1)}
            )
        elif kind == "tree":
            m = np.zeros((h, w), np.float32)
            cx = x + bw / 2
            trunk_w = max(2.0, bw * 0.08)
            p.rect("trunk", cx - trunk_w / 2, horizon * 0.55, cx + trunk_w / 2, horizon + 2)
            for _ in range(int(rng.integers(3, 7))):
                ex, ey = cx + rng.normal(0, bw * 0.18), horizon * rng.uniform(0.15, 0.6)
                cv2.ellipse(
                    m,
                    (int(ex), int(ey)),
                    (int(bw * rng.uniform(0.15, 0.3)), int(horizon * rng.uniform(0.12, 0.25))),
                    0,
                    0,
                    360,
                    1.0,
                    -1,
                    cv2.LINE_AA,
                )
            m = np.clip(m, 0, 1) * np.clip(1.0 + 0.25 * _smooth_noise(rng, h, w, 2.0), 0.5, 1.2)
            p.mask("foliage", np.clip(m, 0, 1))
            structures.append({"kind": "tree", "x": round(cx, 1), "w": round(bw, 1)})
        x += bw

    # ground bands from the horizon down
    bands: list[tuple[str, int, int]] = []
    y = horizon
    order: list[str] = []
    if rng.random() < 0.75:
        order = [
            "pavement",
            "kerb",
            "asphalt",
            "kerb",
            str(rng.choice(["pavement", "grass", "water"])),
        ]
    else:
        order = [
            str(rng.choice(["pavement", "grass"])),
            str(rng.choice(["grass", "water", "pavement"])),
        ]
    weights = np.array([{"kerb": 0.04, "asphalt": 0.5}.get(o, 0.3) for o in order]) * rng.uniform(
        0.7, 1.3, len(order)
    )
    heights = weights / weights.sum() * (h - horizon)
    for name, bh in zip(order, heights, strict=True):
        y1 = h if name == order[-1] else round(y + max(bh, 2))
        p.rect(name, 0, y, w, y1)
        bands.append((name, y, y1))
        if name == "asphalt" and y1 - y > 12:
            my = (y + y1) / 2
            dash, gap = rng.uniform(8, 20), rng.uniform(6, 16)
            xx = float(rng.uniform(-dash, 0))
            while xx < w:
                p.rect("marking", xx, my - 1, xx + dash, my + 1)
                xx += dash + gap
        if name == "pavement":
            step = int(rng.integers(8, 20))
            for xx in range(int(rng.integers(step)), w, step):
                p.vis[y:y1, xx : xx + 1] *= 0.88
            for yy in range(y, y1, step):
                p.vis[yy : yy + 1] *= 0.9
        y = y1

    # poles and a fence standing on the ground in front of the upper row
    for _ in range(int(rng.poisson(1.2))):
        px = float(rng.uniform(0, w))
        pw = float(rng.uniform(1.5, 4.0))
        foot = float(rng.uniform(horizon, horizon + 0.35 * (h - horizon)))
        p.rect("pole", px, max(foot - rng.uniform(0.4, 0.9) * h, 0), px + pw, foot)
        structures.append({"kind": "pole", "x": round(px, 1), "w": round(pw, 1)})
    if rng.random() < 0.35:
        fy1 = float(horizon + rng.uniform(0.02, 0.2) * (h - horizon))
        fy0 = fy1 - rng.uniform(0.06, 0.14) * h
        fx0, fx1 = sorted(rng.uniform(0, w, 2))
        p.rect("fence", fx0, fy0, fx1, fy0 + 2)
        step = rng.uniform(4, 9)
        for xx in np.arange(fx0, fx1, step):
            p.rect("fence", xx, fy0, xx + 1.5, fy1)
        structures.append(
            {"kind": "fence", "x0": round(float(fx0), 1), "x1": round(float(fx1), 1)}
        )
    if rng.random() < 0.4:  # bushes on the ground
        m = np.zeros((h, w), np.float32)
        for _ in range(int(rng.integers(1, 4))):
            bx, by = rng.uniform(0, w), rng.uniform(horizon, h)
            cv2.ellipse(
                m,
                (int(bx), int(by)),
                (int(rng.uniform(0.04, 0.1) * w), int(rng.uniform(0.03, 0.08) * h)),
                0,
                0,
                360,
                1.0,
                -1,
                cv2.LINE_AA,
            )
        p.mask(
            "foliage",
            np.clip(m * np.clip(1 + 0.3 * _smooth_noise(rng, h, w, 1.5), 0.4, 1.3), 0, 1),
        )
        structures.append({"kind": "bushes"})

    # textures: fine grain and large-scale shading, independent per channel
    tex = (
        _smooth_noise(rng, h, w, 1.0)[..., None] * 0.03
        + _smooth_noise(rng, h, w, 10.0)[..., None] * 0.05
    )
    vis = np.clip(p.vis * (1.0 + tex), 0, 1)
    ir = (
        p.ir
        + _smooth_noise(rng, h, w, 6.0) * rng.uniform(2.0, 6.0)
        + _smooth_noise(rng, h, w, 1.0) * 1.0
    )
    # sun patches on the ground: warmer in IR, brighter in visible
    if not night and rng.random() < 0.5:
        m = np.zeros((h, w), np.float32)
        for _ in range(int(rng.integers(1, 4))):
            cv2.ellipse(
                m,
                (int(rng.uniform(0, w)), int(rng.uniform(horizon, h))),
                (int(rng.uniform(0.1, 0.3) * w), int(rng.uniform(0.05, 0.15) * h)),
                0,
                0,
                360,
                1.0,
                -1,
            )
        m = cv2.GaussianBlur(m, (0, 0), 6.0)
        ir += m * rng.uniform(4, 12)
        vis = np.clip(vis * (1 + 0.12 * m[..., None]), 0, 1)
    params = {
        "night": night,
        "ir_ambient": round(ambient, 2),
        "horizon_px": horizon,
        "sky_px": sky_to,
        "ground_bands": [list(b) for b in bands],
    }
    return Background(
        vis.astype(np.float32), ir.astype(np.float32), horizon, bands, structures, params
    )
