"""Procedural actors (people, cars, occluders) drawn once at high resolution.

A sprite is an RGB layer (0..1), an alpha layer (0..1, anti-aliased) and a *heat* layer
(0..1, relative temperature of each part: a person's head is warmer than the clothes, a
car's engine and wheels warmer than its glass). The renderer scales and places sprites
with a sub-pixel affine warp; the tight box of each sprite's alpha (> 0.5), measured
here at high resolution, gives the exact ground truth after the same warp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

SS = 4  # sub-pixel precision of drawing: coordinates in 1/4 canvas px (cv2 shift bits = 2)


@dataclass(frozen=True)
class Sprite:
    """One pose of an actor: layers of shape (H, W[, 3]) float32 and the alpha's tight box."""

    rgb: np.ndarray
    alpha: np.ndarray
    heat: np.ndarray
    box: tuple[float, float, float, float]  # x0, y0, x1, y1 of alpha > 0.5, continuous sprite px

    @property
    def height(self) -> int:
        return self.alpha.shape[0]


@dataclass(frozen=True)
class Palette:
    """Colours (RGB 0..255) of an actor's parts."""

    top: tuple[int, int, int] = (200, 40, 40)
    bottom: tuple[int, int, int] = (40, 50, 110)
    skin: tuple[int, int, int] = (224, 172, 140)
    hair: tuple[int, int, int] = (50, 35, 25)
    shoes: tuple[int, int, int] = (30, 30, 30)
    pattern: str = "stripes"  # texture of the top: stripes, checks, plain


def _pts(points: list[tuple[float, float]]) -> np.ndarray:
    return (np.asarray(points, np.float64) * SS).round().astype(np.int32).reshape(-1, 1, 2)


class _Canvas:
    def __init__(self, w: int, h: int):
        self.w, self.h = w, h
        self.rgb = np.zeros((h, w, 3), np.float32)
        self.alpha = np.zeros((h, w), np.float32)
        self.heat = np.zeros((h, w), np.float32)

    def _mask(self, draw) -> np.ndarray:
        m = np.zeros((self.h, self.w), np.uint8)
        draw(m)
        return m.astype(np.float32) / 255.0

    def poly(self, points, color, heat: float, texture: np.ndarray | None = None) -> None:
        m = self._mask(lambda img: cv2.fillPoly(img, [_pts(points)], 255, cv2.LINE_AA, shift=2))
        self._paint(m, color, heat, texture)

    def ellipse(
        self,
        center,
        axes,
        color,
        heat: float,
        angle: float = 0.0,
        texture: np.ndarray | None = None,
    ) -> None:
        c = (round(center[0] * SS), round(center[1] * SS))
        a = (max(round(axes[0] * SS), 1), max(round(axes[1] * SS), 1))
        m = self._mask(
            lambda img: cv2.ellipse(img, c, a, angle, 0, 360, 255, -1, cv2.LINE_AA, shift=2)
        )
        self._paint(m, color, heat, texture)

    def ring(self, center, radius: float, width: float, color, heat: float) -> None:
        """A circle outline ``width`` thick (a tyre): only the ring is opaque."""
        c = (round(center[0] * SS), round(center[1] * SS))
        r = max(round((radius - width / 2) * SS), 1)
        t = max(round(width), 1)
        m = self._mask(lambda img: cv2.circle(img, c, r, 255, t, cv2.LINE_AA, shift=2))
        self._paint(m, color, heat, None)

    def _paint(self, m: np.ndarray, color, heat: float, texture: np.ndarray | None) -> None:
        col = np.asarray(color, np.float32) / 255.0
        layer = np.broadcast_to(col, self.rgb.shape)
        if texture is not None:
            layer = layer * texture[..., None]
        a = m[..., None]
        self.rgb = self.rgb * (1 - a) + layer * a
        self.heat = self.heat * (1 - m) + heat * m
        self.alpha = np.maximum(self.alpha, m)

    def done(self) -> Sprite:
        ys, xs = np.nonzero(self.alpha > 0.5)
        box = (float(xs.min()), float(ys.min()), float(xs.max() + 1), float(ys.max() + 1))
        return Sprite(np.clip(self.rgb, 0, 1), self.alpha, self.heat, box)


def _texture(h: int, w: int, kind: str, period: float, rng: np.random.Generator) -> np.ndarray:
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    if kind == "stripes":
        t = 1.0 + 0.22 * np.sign(np.sin(2 * np.pi * yy / period))
    elif kind == "checks":
        t = 1.0 + 0.2 * np.sign(np.sin(2 * np.pi * yy / period) * np.sin(2 * np.pi * xx / period))
    else:
        t = np.ones((h, w), np.float32)
    noise = cv2.GaussianBlur(rng.normal(0, 1, (h, w)).astype(np.float32), (0, 0), 1.5)
    return (t * (1.0 + 0.06 * noise)).astype(np.float32)


def person(height_px: float, palette: Palette, phase: float, rng: np.random.Generator) -> Sprite:
    """A walking person, ``height_px`` tall in sprite pixels, at walk ``phase`` in [0, 1).

    Heat: head 1.0, hands/arms 0.85, torso 0.75, legs 0.7, shoes 0.4.
    """
    H = height_px
    W = 0.62 * H
    cw, ch = math.ceil(W) + 1, math.ceil(H) + 2
    cv = _Canvas(cw, ch)
    cx = W / 2
    tex = _texture(ch, cw, palette.pattern, 0.035 * H, rng)
    plain = _texture(ch, cw, "plain", 1, rng)
    swing = math.sin(2 * math.pi * phase)
    hip_y, leg_len, leg_w = 0.50 * H, 0.46 * H, 0.095 * H
    for side, sgn in ((-1, 1), (1, -1)):  # back leg first
        ang = math.radians(17) * swing * sgn
        hx = cx + side * 0.055 * H
        dx, dy = math.sin(ang), math.cos(ang)
        px, py = -dy * leg_w / 2, dx * leg_w / 2
        foot = (hx + dx * leg_len, hip_y + dy * leg_len)
        cv.poly(
            [
                (hx + px, hip_y + py),
                (hx - px, hip_y - py),
                (foot[0] - px, foot[1] - py),
                (foot[0] + px, foot[1] + py),
            ],
            palette.bottom,
            0.70,
            plain,
        )
        shoe_dir = 1 if side > 0 else -1
        cv.poly(
            [
                (foot[0] - leg_w * 0.55, foot[1] - 0.02 * H),
                (foot[0] + leg_w * 0.55 + shoe_dir * 0.02 * H, foot[1] - 0.02 * H),
                (foot[0] + leg_w * 0.55 + shoe_dir * 0.02 * H, foot[1] + 0.035 * H),
                (foot[0] - leg_w * 0.55, foot[1] + 0.035 * H),
            ],
            palette.shoes,
            0.40,
        )
    # arms swing opposite to the legs
    for side, sgn in ((-1, -1), (1, 1)):
        ang = math.radians(14) * swing * sgn
        sx, sy = cx + side * 0.165 * H, 0.19 * H
        alen, aw = 0.30 * H, 0.065 * H
        dx, dy = math.sin(ang), math.cos(ang)
        px, py = -dy * aw / 2, dx * aw / 2
        hand = (sx + dx * alen, sy + dy * alen)
        cv.poly(
            [
                (sx + px, sy + py),
                (sx - px, sy - py),
                (hand[0] - px, hand[1] - py),
                (hand[0] + px, hand[1] + py),
            ],
            palette.top,
            0.80,
            tex,
        )
        cv.ellipse(hand, (aw * 0.55, aw * 0.6), palette.skin, 0.9)
    # torso with a slightly narrower waist
    cv.poly(
        [
            (cx - 0.15 * H, 0.17 * H),
            (cx + 0.15 * H, 0.17 * H),
            (cx + 0.135 * H, 0.53 * H),
            (cx - 0.135 * H, 0.53 * H),
        ],
        palette.top,
        0.75,
        tex,
    )
    cv.ellipse((cx, 0.175 * H), (0.15 * H, 0.035 * H), palette.top, 0.75, texture=tex)  # shoulders
    # neck, head, hair
    cv.poly(
        [
            (cx - 0.03 * H, 0.12 * H),
            (cx + 0.03 * H, 0.12 * H),
            (cx + 0.03 * H, 0.17 * H),
            (cx - 0.03 * H, 0.17 * H),
        ],
        palette.skin,
        0.95,
    )
    cv.ellipse((cx, 0.075 * H), (0.058 * H, 0.072 * H), palette.skin, 1.0)
    cv.ellipse((cx, 0.045 * H), (0.06 * H, 0.045 * H), palette.hair, 0.85)
    return cv.done()


def car(
    length_px: float, body: tuple[int, int, int], rng: np.random.Generator, facing: int = 1
) -> Sprite:
    """A car seen from the side, ``length_px`` long, nose to the right if ``facing`` > 0.

    Heat: engine/bonnet 1.0, wheels 0.85, exhaust 0.9, body 0.45, glass 0.15.
    """
    L = length_px
    H = 0.45 * L
    cw, ch = math.ceil(L) + 2, math.ceil(H) + 2
    cv = _Canvas(cw, ch)
    tex = _texture(ch, cw, "plain", 1, rng)

    def X(u: float) -> float:
        return (u if facing > 0 else 1 - u) * L

    cv.poly(
        [(X(0.0), 0.40 * H), (X(1.0), 0.45 * H), (X(1.0), 0.80 * H), (X(0.0), 0.80 * H)],
        body,
        0.45,
        tex,
    )
    cv.poly(
        [(X(0.22), 0.42 * H), (X(0.30), 0.05 * H), (X(0.68), 0.05 * H), (X(0.80), 0.43 * H)],
        body,
        0.45,
        tex,
    )
    glass = (70, 85, 105)
    cv.poly(
        [(X(0.27), 0.40 * H), (X(0.33), 0.12 * H), (X(0.47), 0.12 * H), (X(0.47), 0.40 * H)],
        glass,
        0.15,
    )
    cv.poly(
        [(X(0.50), 0.40 * H), (X(0.50), 0.12 * H), (X(0.66), 0.12 * H), (X(0.75), 0.41 * H)],
        glass,
        0.15,
    )
    cv.poly(
        [(X(0.80), 0.45 * H), (X(1.0), 0.48 * H), (X(1.0), 0.70 * H), (X(0.80), 0.70 * H)],
        body,
        1.0,
        tex,
    )  # bonnet/engine
    cv.ellipse((X(0.985), 0.56 * H), (0.02 * L, 0.05 * H), (250, 240, 200), 0.7)  # headlight
    cv.ellipse((X(0.01), 0.55 * H), (0.012 * L, 0.05 * H), (200, 20, 20), 0.5)  # tail light
    cv.ellipse((X(0.05), 0.78 * H), (0.03 * L, 0.03 * H), (60, 60, 60), 0.9)  # exhaust
    for u in (0.2, 0.8):
        cv.ellipse((X(u), 0.80 * H), (0.11 * L, 0.2 * H), (20, 20, 20), 0.85)
        cv.ellipse((X(u), 0.80 * H), (0.05 * L, 0.09 * H), (150, 150, 150), 0.6)
    return cv.done()


def truck(
    length_px: float, body: tuple[int, int, int], rng: np.random.Generator, facing: int = 1
) -> Sprite:
    """A box truck seen from the side: an opaque cargo box, a cab, wheels.

    Heat: cab/engine 1.0, wheels 0.85, cargo box 0.25, glass 0.15.
    """
    L = length_px
    H = 0.55 * L
    cw, ch = math.ceil(L) + 2, math.ceil(H) + 2
    cv = _Canvas(cw, ch)
    tex = _texture(ch, cw, "plain", 1, rng)

    def X(u: float) -> float:
        return (u if facing > 0 else 1 - u) * L

    cv.poly(
        [(X(0.0), 0.0), (X(0.74), 0.0), (X(0.74), 0.84 * H), (X(0.0), 0.84 * H)], body, 0.25, tex
    )
    cv.poly(
        [(X(0.0), 0.55 * H), (X(0.74), 0.55 * H), (X(0.74), 0.58 * H), (X(0.0), 0.58 * H)],
        (90, 90, 90),
        0.25,
    )
    cv.poly(
        [
            (X(0.75), 0.30 * H),
            (X(0.93), 0.30 * H),
            (X(1.0), 0.52 * H),
            (X(1.0), 0.84 * H),
            (X(0.75), 0.84 * H),
        ],
        (60, 70, 90),
        1.0,
        tex,
    )
    cv.poly(
        [(X(0.78), 0.34 * H), (X(0.91), 0.34 * H), (X(0.96), 0.50 * H), (X(0.78), 0.50 * H)],
        (70, 85, 105),
        0.15,
    )
    for u in (0.15, 0.32, 0.86):
        cv.ellipse((X(u), 0.86 * H), (0.065 * L, 0.13 * H), (20, 20, 20), 0.85)
    return cv.done()


def pillar(
    width_px: float, height_px: float, color: tuple[int, int, int], rng: np.random.Generator
) -> Sprite:
    """A static occluder (pole, pillar or wall segment); heat 0.05 (near ambient)."""
    cw, ch = math.ceil(width_px) + 1, math.ceil(height_px) + 1
    cv = _Canvas(cw, ch)
    tex = _texture(ch, cw, "plain", 1, rng)
    cv.poly([(0, 0), (width_px, 0), (width_px, height_px), (0, height_px)], color, 0.05, tex)
    # a lighter edge so it reads as a 3-D object
    cv.poly(
        [(0, 0), (width_px * 0.15, 0), (width_px * 0.15, height_px), (0, height_px)],
        tuple(min(int(c * 1.25), 255) for c in color),
        0.05,
        tex,
    )
    return cv.done()


def cyclist(
    height_px: float,
    palette: Palette,
    body: tuple[int, int, int],
    phase: float,
    rng: np.random.Generator,
    facing: int = 1,
) -> Sprite:
    """A person riding a bicycle, seen from the side, ``height_px`` tall (wheels to head), at pedal
    ``phase``.

    Heat: head 1.0, hands 0.9, torso 0.75, legs 0.7, tyres 0.35, frame 0.2.
    """
    H = height_px
    L = 1.05 * H  # wheelbase plus the wheels
    cw, ch = math.ceil(L) + 2, math.ceil(H) + 2
    cv = _Canvas(cw, ch)
    tex = _texture(ch, cw, palette.pattern, 0.035 * H, rng)
    plain = _texture(ch, cw, "plain", 1, rng)

    def X(u: float) -> float:
        return u if facing > 0 else L - u

    r = 0.19 * H
    wy = H - r - 0.01 * H
    back, front = 0.22 * H, L - 0.22 * H
    for wx in (back, front):  # tyres and a few spokes: the wheels are mostly see-through
        cv.ring((X(wx), wy), r, max(0.05 * H, 1.0), (25, 25, 25), 0.35)
        cv.ellipse((X(wx), wy), (0.1 * r, 0.1 * r), (60, 60, 60), 0.3)
    crank = (0.48 * L, wy - 0.02 * H)
    seat = (0.40 * L, 0.52 * H)
    bar = (0.74 * L, 0.45 * H)
    fw = 0.025 * H

    def beam(
        a: tuple[float, float],
        b: tuple[float, float],
        width: float,
        color,
        heat: float,
        texture=None,
    ) -> None:
        dx, dy = b[0] - a[0], b[1] - a[1]
        n = math.hypot(dx, dy) or 1.0
        px, py = -dy / n * width / 2, dx / n * width / 2
        cv.poly(
            [
                (X(a[0]) + (px if facing > 0 else -px), a[1] + py),
                (X(a[0]) - (px if facing > 0 else -px), a[1] - py),
                (X(b[0]) - (px if facing > 0 else -px), b[1] - py),
                (X(b[0]) + (px if facing > 0 else -px), b[1] + py),
            ],
            color,
            heat,
            texture,
        )

    for a, b in (
        ((back, wy), crank),
        (crank, seat),
        (seat, (back, wy)),
        (seat, bar),
        (crank, bar),
        (bar, (front, wy)),
    ):
        beam(a, b, fw, body, 0.2)
    # rider: legs to the pedals (one phase), torso leaning forward, arms to the bar, head
    ang = 2 * math.pi * phase
    hip = (seat[0] + 0.01 * H, seat[1] - 0.03 * H)
    for sgn in (1, -1):
        pedal = (
            crank[0] + sgn * 0.09 * H * math.cos(ang),
            crank[1] + sgn * 0.09 * H * math.sin(ang),
        )
        knee = ((hip[0] + pedal[0]) / 2 + 0.10 * H, (hip[1] + pedal[1]) / 2 - 0.05 * H)
        beam(hip, knee, 0.085 * H, palette.bottom, 0.7, plain)
        beam(knee, pedal, 0.07 * H, palette.bottom, 0.7, plain)
        beam(
            (pedal[0] - 0.03 * H, pedal[1]),
            (pedal[0] + 0.04 * H, pedal[1]),
            0.035 * H,
            palette.shoes,
            0.4,
        )
    shoulder = (0.58 * L, 0.20 * H)
    beam(hip, shoulder, 0.17 * H, palette.top, 0.75, tex)
    beam(shoulder, bar, 0.06 * H, palette.top, 0.8, tex)
    cv.ellipse((X(bar[0]), bar[1]), (0.035 * H, 0.035 * H), palette.skin, 0.9)
    head = (shoulder[0] + 0.06 * H, 0.085 * H)
    cv.ellipse((X(head[0]), head[1]), (0.065 * H, 0.075 * H), palette.skin, 1.0)
    cv.ellipse((X(head[0]), head[1] - 0.03 * H), (0.07 * H, 0.045 * H), palette.hair, 0.85)
    return cv.done()
