"""The random scene family (``dualtrack synth random OUT --seed N``): whole scenes drawn from a
seed.

Where a named scenario fixes its paths and events, a random scene draws all of them:

* a street background (:mod:`pipeline.synthetic.backgrounds`) whose infrared levels are
  drawn per material, independently of the visible colours;
* 1 to K targets (people, cyclists, cars) with drawn colours, patterns, heat, sizes
  (10 to 150 px tall) and paths: straight, curved, stopping, turning or fast (up to
  12 px per frame), approaching or receding (scale 0.4x to 3x), starting partly outside
  or leaving the frame;
* events, each with a probability: cast shadows of drawn shape and depth (static and
  moving), illumination ramps and flicker down to darkness, thermal crossover episodes,
  static occluders (partial and full), crossings with depth order, cold colour
  look-alikes, warm distractors of other colours, a second warm person walking beside
  the target;
* sensor effects: noise, optics blur, vignetting, JPEG quality 50-95 per channel, a
  misregistration of 0-3 px between the channels, camera jitter (16-bit IR is an option
  of the writer).

Everything is drawn from ``numpy.random.default_rng([seed, FAMILY_SALT, targets...])``,
so the same seed and options give the same scene, byte for byte. :func:`draw_scene`
returns the :class:`~pipeline.synthetic.scene.Scene` and every drawn parameter;
:func:`frame_attributes` turns a rendered frame into the per-frame challenge flags that
``scene.json`` records (occlusion, shadow, darkness, clutter, crossover, out of view,
scale change, fast motion).

Seeds are split for honest scoring (``DEV_SEEDS`` for tuning, ``TEST_SEEDS`` only ever
scored); see the README.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from pipeline.synthetic.backgrounds import street_background
from pipeline.synthetic.scene import Actor, MaskShadow, RenderedFrame, Scene, Sensor
from pipeline.synthetic.sprites import Palette

FAMILY_SALT = 0x5EED_F00D
DEV_SEEDS = range(0, 1000)
"""Seeds for tuning and development."""
TEST_SEEDS = range(1000, 2000)
"""Seeds that are only ever scored: never look at them while choosing parameters."""

ATTRIBUTES = (
    "occlusion",
    "shadow",
    "darkness",
    "clutter",
    "crossover",
    "out-of-view",
    "scale-change",
    "fast-motion",
)
"""Per-frame challenge flags, in ``scene.json`` order."""
MIN_ATTRIBUTE_FRAMES = 5
"""A scene carries an attribute when some target has it in at least this many frames."""
MAX_SPEED_PX = 12.0


DISTRACTOR_ROLES = ("crossing", "look-alike", "warm-distractor", "companion")
"""Roles of the moving actors that are not targets (written as distractor rows of a multi-target
``gt.txt``)."""


@dataclass(frozen=True)
class DrawnScene:
    """A random scene: what to render, every drawn parameter, and how to flag its frames."""

    scene: Scene
    params: dict[str, object]
    render_seed: int
    jpeg_quality: tuple[int, int]  # visible, infrared
    roles: dict[int, str]  # actor index -> role ("target", "look-alike", "warm-distractor", ...)


def parse_seed_range(text: str) -> range:
    """``"A-B"`` (inclusive) or ``"A"`` -> a range of non-negative seeds."""
    parts = text.split("-")
    try:
        if len(parts) == 1:
            a = b = int(parts[0])
        elif len(parts) == 2:
            a, b = int(parts[0]), int(parts[1])
        else:
            raise ValueError
    except ValueError:
        raise ValueError(
            f"seeds must be N or A-B with non-negative integers; got {text!r}"
        ) from None
    if a < 0 or b < a:
        raise ValueError(f"seeds must be N or A-B with 0 <= A <= B; got {text!r}")
    return range(a, b + 1)


def parse_target_count(text: str | int | None) -> tuple[int, int] | None:
    """``--targets``: ``K`` or ``A-B`` (1 <= A <= B <= 8), or None for the default draw (1-3)."""
    if text is None:
        return None
    s = str(text)
    parts = s.split("-")
    try:
        lo, hi = (
            (int(parts[0]), int(parts[0])) if len(parts) == 1 else (int(parts[0]), int(parts[1]))
        )
        if len(parts) > 2:
            raise ValueError
    except ValueError:
        raise ValueError(f"--targets must be K or A-B (1 to 8); got {s!r}") from None
    if not 1 <= lo <= hi <= 8:
        raise ValueError(f"--targets must be K or A-B with 1 <= A <= B <= 8; got {s!r}")
    return lo, hi


# --------------------------------------------------------------------------------- drawing helpers


def _smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3 - 2 * u)


def _random_palette(rng: np.random.Generator) -> Palette:
    def col(lo: int = 20, hi: int = 235) -> tuple[int, int, int]:
        return tuple(int(v) for v in rng.integers(lo, hi, 3))  # type: ignore[return-value]

    skins = ((224, 172, 140), (190, 140, 110), (150, 105, 80), (110, 75, 55), (240, 200, 170))
    return Palette(
        top=col(),
        bottom=col(15, 160),
        skin=skins[int(rng.integers(len(skins)))],
        hair=col(10, 90),
        shoes=col(10, 70),
        pattern=str(rng.choice(["stripes", "checks", "plain"])),
    )


def _lookalike_palette(p: Palette, rng: np.random.Generator) -> Palette:
    def near(c: tuple[int, int, int]) -> tuple[int, int, int]:
        # type: ignore[return-value]
        return tuple(int(np.clip(v + rng.integers(-12, 13), 0, 255)) for v in c)

    return Palette(
        top=near(p.top),
        bottom=near(p.bottom),
        skin=p.skin,
        hair=p.hair,
        shoes=p.shoes,
        pattern=p.pattern,
    )


def _array_path(
    xy: np.ndarray, scale: np.ndarray
) -> Callable[[float], tuple[float, float, float]]:
    """Path through per-frame (cx, cy) and scale arrays (frame 1 at index 0), linear between
    frames."""
    frames = np.arange(1, xy.shape[0] + 1, dtype=np.float64)
    xs, ys, ss = xy[:, 0].copy(), xy[:, 1].copy(), scale.copy()

    def path(t: float) -> tuple[float, float, float]:
        return (
            float(np.interp(t, frames, xs)),
            float(np.interp(t, frames, ys)),
            float(np.interp(t, frames, ss)),
        )

    return path


@dataclass
class _Body:
    """Size of an actor kind on screen at scale 1: ``size_px`` (what the sprite scales), w and h of
    its box."""

    kind: str
    size_px: float
    w: float
    h: float


def _body(kind: str, height_px: float) -> _Body:
    if kind == "person":
        return _Body(kind, height_px, 0.42 * height_px, height_px)
    if kind == "cyclist":
        return _Body(kind, height_px, 1.0 * height_px, height_px)
    length = height_px / 0.45
    return _Body(kind, length, length, height_px)  # car


REAL_HEIGHT_M = {"person": 1.7, "cyclist": 1.75, "car": 1.5}
"""Real heights of the kinds, which set their image size from the ground row they stand on."""


def _scale_profile(
    rng: np.random.Generator, n: int, kind: str, lo_ratio: float, hi_ratio: float
) -> tuple[np.ndarray, dict[str, object]]:
    t = np.arange(n, dtype=np.float64)
    if kind == "approach" and hi_ratio < 1.3:
        kind = "constant"
    if kind == "recede" and lo_ratio > 0.77:
        kind = "constant"
    if kind == "constant":
        return np.ones(n), {"scale": "constant"}
    ratio = (
        float(rng.uniform(1.3, hi_ratio))
        if kind == "approach"
        else float(rng.uniform(lo_ratio, 0.77))
    )
    a = float(rng.uniform(0, 0.35) * n)
    b = float(rng.uniform(0.65, 1.0) * n)
    u = _smoothstep((t - a) / max(b - a, 1.0))
    return np.exp(np.log(ratio) * u), {
        "scale": kind,
        "scale_ratio": round(ratio, 3),
        "scale_frames": [round(a) + 1, round(b) + 1],
    }


def _x_motion(
    rng: np.random.Generator,
    n: int,
    kind: str,
    speed: float,
    x0: float,
    direction: float,
    half_w: np.ndarray,
    width: float,
    leave_at: int | None,
    entry: bool,
    actor_kind: str,
) -> tuple[np.ndarray, dict[str, object]]:
    """Per-frame centre x for a motion ``kind`` along the ground (the depth motion is the scale
    profile's).

    Bounces off the frame's sides (wholly inside) unless it is walking in (``entry``) or out
    (after ``leave_at``, towards the nearer side). Reversals slow down to a stand first, for
    a few frames (people) or longer (vehicles)."""
    x = np.zeros(n)
    p = float(x0)
    d = 1.0 if direction >= 0 else -1.0
    info: dict[str, object] = {"motion": kind, "speed_px": round(speed, 2), "direction": int(d)}
    turns: list[int] = []
    stops: list[tuple[int, int]] = []
    slow = 6 if actor_kind == "car" else 2
    if kind == "turning":
        turns = sorted(int(rng.integers(10, n - 10)) for _ in range(int(rng.integers(1, 4))))
        info["turns"] = [f + 1 for f in turns]
    if kind == "fast":
        f = int(rng.integers(10, 30))
        while f < n:
            turns.append(f)
            f += int(rng.integers(12, 40))
        info["turns"] = len(turns)
    for f in turns:
        stops.append((max(f - slow, 0), f + slow))
    if kind == "stopping":
        for _ in range(int(rng.integers(1, 3))):
            s0 = int(rng.integers(15, max(n - 60, 16)))
            stops.append((s0, s0 + int(rng.integers(15, 50))))
        info["stops"] = [[a + 1, b + 1] for a, b in stops]
    amp, period, phase = (
        float(rng.uniform(0.3, 0.7)),
        float(rng.uniform(40, 140)),
        float(rng.uniform(0, 2 * np.pi)),
    )
    if kind == "curved":
        info.update({"speed_wave": round(amp, 2), "wave_frames": round(period, 1)})
    turn_at = set(turns)
    entering = entry
    for t in range(n):
        x[t] = p
        v = speed
        for a, b in stops:  # slows down to a stand and starts again
            if a <= t < b:
                ramp = max(min(t - a, b - 1 - t), 0) / max(min(4, (b - a) // 2), 1)
                v = speed * max(0.0, 1.0 - min(ramp, 1.0))
        if kind == "curved":
            v *= 1.0 + amp * np.sin(2 * np.pi * t / period + phase)
        if t in turn_at:
            d = -d
        leaving = leave_at is not None and t >= leave_at
        if leave_at is not None and t == leave_at:
            d = 1.0 if p > width / 2 else -1.0
            turn_at.clear()
        q = p + d * min(v, MAX_SPEED_PX)
        hw = half_w[min(t + 1, n - 1)]
        lo, hi = hw, width - hw
        if entering and lo <= q <= hi:
            entering = False  # wholly inside: from now on it stays in the frame
        if not entering and not leaving and (q < lo or q > hi):
            d = -d
            q = min(max(p + d * min(v, MAX_SPEED_PX), lo), hi)
        p = q
    return x, info


def _wiggle(rng: np.random.Generator, n: int, amplitude: float) -> np.ndarray:
    """A slow smooth wander in [-amplitude, amplitude] (the feet row of someone walking roughly
    straight)."""
    w = cv2.GaussianBlur(rng.normal(0, 1, (1, n + 60)).astype(np.float64), (0, 0), 15.0)[
        0, 30 : 30 + n
    ]
    return amplitude * w / max(float(np.abs(w).max()), 1e-9)


# --------------------------------------------------------------------------------------- the scene


def _moving_shadow(t: int, p0: tuple[float, float], vx: float, tc: int) -> tuple[float, float]:
    """Top-left corner of a shadow moving ``vx`` px a frame, at ``p0`` on frame ``tc + 1``."""
    return (p0[0] + vx * (t - 1 - tc), p0[1])


def _still_shadow(t: int, p0: tuple[float, float]) -> tuple[float, float]:
    """Top-left corner of a shadow that stays at ``p0``."""
    return p0


def draw_scene(
    seed: int,
    targets: tuple[int, int] | int | None = None,
    width: int = 320,
    height: int = 240,
    n_frames: int = 200,
) -> DrawnScene:
    """Draw one random scene.

    The camera looks at a flat ground: everything stands on it, an object's image height
    follows the row its feet are on (``feet - horizon = k * height``, with ``k`` drawn per
    scene from the camera height), approaching means walking down the image and growing,
    and whoever stands lower in the image is in front.

    Parameters
    ----------
    seed : int
        Non-negative; the scene is a pure function of ``seed`` and the other arguments.
    targets : int or (int, int), optional
        Number of ground-truth targets, or an inclusive range to draw it from; default
        drawn in 1-3.
    width, height : int
        Frame size in px (at least 160 x 120).
    n_frames : int
        Sequence length, at least 30.
    """
    if not (isinstance(seed, int) and seed >= 0):
        raise ValueError(f"seed must be a non-negative integer; got {seed!r}")
    if width < 160 or height < 120:
        raise ValueError(f"random scenes need at least 160 x 120 px; got {width} x {height}")
    if n_frames < 30:
        raise ValueError(f"random scenes need at least 30 frames; got {n_frames}")
    if isinstance(targets, int):
        targets = (targets, targets)
    key = [seed, FAMILY_SALT, *(targets or (0, 0)), width, height, n_frames]
    rng = np.random.default_rng(key)
    k_targets = (
        int(rng.integers(targets[0], targets[1] + 1)) if targets else int(rng.integers(1, 4))
    )
    n, W, H = n_frames, width, height

    bg = street_background(rng, W, H)
    horizon = float(bg.horizon_px)
    night = bool(bg.params["night"])
    ambient = float(bg.params["ir_ambient"])
    k_cam = float(rng.uniform(0.55, 1.8))  # camera height, in person heights

    def k_of(kind: str) -> float:
        return k_cam * REAL_HEIGHT_M["person"] / REAL_HEIGHT_M[kind]

    def height_at(kind: str, feet: float) -> float:
        return max((feet - horizon) / k_of(kind), 1.0)

    def center_y(feet: np.ndarray | float, h: np.ndarray | float) -> np.ndarray | float:
        return feet - 0.5 * h

    actors: list[Actor] = []
    roles: dict[int, str] = {}
    params: dict[str, object] = {
        "family": "random",
        "seed": seed,
        "size": [W, H],
        "frames": n,
        "camera_height_person_heights": round(k_cam, 3),
        "background": bg.params,
        "structures": bg.structures,
    }
    target_params: list[dict[str, object]] = []
    # per target: centre x, feet row, image height per frame, body, the visible crossover window
    tracks: list[dict[str, object]] = []
    max_h = min(150.0, 0.62 * H)
    for k in range(k_targets):
        kind = str(rng.choice(["person", "person", "person", "cyclist", "car"]))
        kk = k_of(kind)
        h_cap = min(max_h, 0.45 * 0.5 * W) if kind == "car" else max_h
        h_cap = min(h_cap, (1.02 * H - horizon) / kk)  # its feet on the ground in the frame
        h_px = float(np.clip(np.exp(rng.normal(np.log(45.0), 0.55)), 10.0, max(h_cap, 10.0)))
        scale_kind = str(rng.choice(["constant", "constant", "constant", "approach", "recede"]))
        hi_ratio = min(
            3.0, max_h / h_px, (1.08 * H - horizon) / (kk * h_px)
        )  # feet may leave through the bottom
        lo_ratio = max(0.4, 10.0 / h_px)
        scale, sinfo = _scale_profile(rng, n, scale_kind, lo_ratio, hi_ratio)
        motion = str(
            rng.choice(
                ["straight", "curved", "stopping", "turning", "fast"],
                p=[0.25, 0.2, 0.15, 0.25, 0.15],
            )
        )
        if motion == "curved":  # a curve over the ground: the depth wanders while it goes along
            scale = scale * (
                1.0
                + float(rng.uniform(0.05, 0.15))
                * np.sin(np.arange(n) / float(rng.uniform(25, 60)))
            )
        feet = horizon + kk * h_px * scale + _wiggle(rng, n, 0.015 * (H - horizon))
        hgt = (feet - horizon) / kk
        body = _body(kind, h_px)
        half_w = 0.5 * body.w * hgt / h_px
        base = {"person": (0.015, 0.04), "cyclist": (0.04, 0.1), "car": (0.05, 0.25)}[kind]
        speed = float(np.clip(rng.uniform(*base) * h_px, 0.3, 6.0))
        if motion == "fast":
            speed = float(rng.uniform(6.0, MAX_SPEED_PX))
        leave = bool(rng.random() < 0.2)
        entry = bool(rng.random() < 0.15)
        leave_at = int(rng.uniform(0.6, 0.9) * n) if leave else None
        direction = float(rng.choice([-1.0, 1.0]))
        hw0 = half_w[0]
        if entry:  # starts partly outside the frame, walking in
            side = float(rng.choice([-1.0, 1.0]))
            x0 = hw0 * rng.uniform(0.1, 0.6) if side < 0 else W - hw0 * rng.uniform(0.1, 0.6)
            direction = -side
        else:
            x0 = float(rng.uniform(hw0 + 1, max(W - hw0 - 1, hw0 + 2)))
            # every target is seen when it is given: none stands in front of another at frame 1
            for _ in range(20):
                clear = all(
                    abs(x0 - float(tr["x"][0])) > hw0 + 0.5 * float(tr["w0"])
                    or abs(feet[0] - float(tr["feet"][0]))  # type: ignore[index]
                    > 0.5 * min(hgt[0], float(tr["h"][0]))
                    for tr in tracks
                )  # type: ignore[index]
                if clear:
                    break
                x0 = float(rng.uniform(hw0 + 1, max(W - hw0 - 1, hw0 + 2)))
        xs, minfo = _x_motion(
            rng, n, motion, speed, x0, direction, half_w, float(W), leave_at, entry, kind
        )
        # a detour that meets an earlier target at frame tc, in front or behind
        if k > 0 and rng.random() < 0.6:
            other = int(rng.integers(k))
            tc = int(rng.uniform(0.3, 0.7) * n)
            shift = float(tracks[other]["x"][tc] - xs[tc])  # type: ignore[index]
            span = max(int(np.ceil(0.5 * abs(shift))), 8)  # smoothstep: at most 3 px/frame extra
            if span <= tc and tc + span < n:
                t = np.arange(n, dtype=np.float64)
                wgt = np.where(
                    t <= tc,
                    _smoothstep((t - (tc - span)) / span),
                    1.0 - _smoothstep((t - tc) / span),
                )
                xs = xs + shift * wgt
                # the same ground row as the other there, a little in front or behind
                target_row = float(tracks[other]["feet"][tc]) + float(
                    rng.choice([-1, 1]) * rng.uniform(3, 10)
                )  # type: ignore[index]
                dy = target_row - feet[tc]
                feet = feet + dy * wgt
                hgt = (feet - horizon) / kk
                minfo["crosses_target"] = [other + 1, tc + 1]
        hgt = np.clip(
            (feet - horizon) / kk, max(0.4 * h_px, 8.0), 3.0 * h_px
        )  # within 0.4-3x of frame 1
        feet = horizon + kk * hgt
        scale = hgt / h_px
        palette = _random_palette(rng)
        body_color = tuple(int(v) for v in rng.integers(20, 235, 3))
        contrast = float(rng.uniform(25, 75) if not night else rng.uniform(40, 100))
        if kind == "car":
            contrast = float(rng.uniform(40, 110))
        crossover = None
        if rng.random() < 0.25 and n > 60:
            c0 = float(rng.uniform(max(0.15 * n, 12.0), 0.6 * n))
            crossover = (c0, c0 + float(rng.uniform(20, 70)), float(rng.uniform(0.0, 0.15)))
        tid = k + 1
        roles[len(actors)] = "target"
        feet_arr = feet.copy()
        actors.append(
            Actor(
                kind,
                body.size_px,
                _array_path(np.column_stack([xs, center_y(feet, hgt)]), scale),
                target_id=tid,
                depth=_array_depth(feet_arr),
                palette=palette,
                body_color=body_color,  # type: ignore[arg-type]
                facing=int(direction),
                ir_contrast=contrast,
                ir_factor=_crossover_fn(crossover),
                facing_auto=kind in ("car", "cyclist"),
                name=f"target {tid}",
            )
        )
        tracks.append(
            {
                "x": xs,
                "feet": feet_arr,
                "h": hgt,
                "body": body,
                "kind": kind,
                "crossover": crossover,
                "actor": len(actors) - 1,
                "w0": float(2 * half_w[0]),
            }
        )
        target_params.append(
            {
                "id": tid,
                "kind": kind,
                "height_px": round(h_px, 1),
                "ir_contrast": round(contrast, 1),
                "palette": {
                    "top": list(palette.top),
                    "bottom": list(palette.bottom),
                    "pattern": palette.pattern,
                },
                "entering": entry,
                "leaves_at": leave_at + 1 if leave_at is not None else None,
                "crossover": None,
                **sinfo,
                **minfo,
            }
        )
    params["targets"] = target_params

    # events around the first target (each with a probability)
    events: list[dict[str, object]] = []
    t1 = tracks[0]
    x1, feet1, h1 = t1["x"], t1["feet"], t1["h"]  # type: ignore[assignment]
    a1 = actors[0]
    vx1 = np.gradient(x1)  # type: ignore[arg-type]

    w1 = np.array([_body(a1.kind, float(h)).w for h in h1])  # type: ignore[union-attr]

    def covered(t: int, ox: float, ow: float, top: float, row: float) -> float:
        """Share of the target's box that something at ground row ``row`` spanning x in ox +- ow/2
        and y from ``top`` to ``row`` covers at frame t (0 when the target stands in front of it).
        """
        if float(feet1[t]) >= row:  # type: ignore[index]
            return 0.0
        bx0, bx1 = float(x1[t]) - 0.5 * w1[t], float(x1[t]) + 0.5 * w1[t]  # type: ignore[index]
        by0, by1 = float(feet1[t] - h1[t]), float(feet1[t])  # type: ignore[index,operator]
        ix = max(min(bx1, ox + 0.5 * ow) - max(bx0, ox - 0.5 * ow), 0.0)
        iy = max(min(by1, row) - max(by0, top), 0.0)
        return ix * iy / max((bx1 - bx0) * (by1 - by0), 1e-9)

    def crossing(
        kind: str, tc: int, size_of: float | None
    ) -> tuple[np.ndarray, np.ndarray, float, float, float]:
        """A path across the target's at frame tc, against its motion, on a ground row a little in
        front of or behind it: (centre x, feet row, image height, row offset, width). Fast enough
        to pass in under 40 frames (relative speed >= 1.5 px/frame and >= the two widths / 40)."""
        d_t = float(np.sign(vx1[tc])) or float(rng.choice([-1, 1]))  # type: ignore[index]
        dy = float(rng.choice([-1, 1]) * rng.uniform(3, 12))
        row = float(feet1[tc]) + dy  # type: ignore[index]
        hc = size_of if size_of is not None else height_at(kind, row)
        wc = _body(kind, hc).w
        v_rel = max(
            float(rng.uniform(1.0, 3.5)) + abs(float(vx1[tc])), 1.5, (float(w1[tc]) + wc) / 40.0
        )  # type: ignore[index]
        v = -d_t * min(v_rel - abs(float(vx1[tc])), MAX_SPEED_PX)  # type: ignore[index]
        t = np.arange(n, dtype=np.float64) - tc
        return float(x1[tc]) + v * t, np.full(n, row), hc, dy, wc  # type: ignore[index]

    def add_crossing(
        role: str,
        kind: str,
        tc: int,
        palette: Palette,
        contrast: float,
        body_color,
        name: str,
        size_of: float | None = None,
    ) -> bool | None:
        """Add an actor crossing the target at frame tc; None (nothing added) if it would cover the
        target in the first five frames (the family's rule: a target is seen when it is given)."""
        xs, row, hc, dy, wc = crossing(kind, tc, size_of)
        if hc < 6 or any(
            covered(t, float(xs[t]), wc, float(row[0]) - hc, float(row[0])) > 0.3 for t in range(5)
        ):
            return None
        b = _body(kind, hc)
        roles[len(actors)] = role
        actors.append(
            Actor(
                kind,
                b.size_px,
                _array_path(np.column_stack([xs, center_y(row, hc)]), np.ones(n)),
                depth=float(row[0]),
                palette=palette,
                body_color=body_color,
                ir_contrast=contrast,
                facing_auto=True,
                name=name,
            )
        )
        return dy > 0

    # a person or car crossing (its depth order follows the ground rows)
    if rng.random() < 0.35:
        tc = int(rng.uniform(0.25, 0.75) * n)
        kind = str(rng.choice(["person", "person", "car"]))
        front = add_crossing(
            "crossing",
            kind,
            tc,
            _random_palette(rng),
            float(rng.uniform(30, 90)),
            tuple(int(v) for v in rng.integers(20, 235, 3)),
            "crossing",
        )
        if front is not None:
            events.append({"event": "crossing", "frame": tc + 1, "kind": kind, "in_front": front})
    # a cold colour look-alike (printed cut-out, a mannequin) passing close to the target
    if rng.random() < 0.25:
        tc = int(rng.uniform(0.25, 0.75) * n)
        if (
            add_crossing(
                "look-alike",
                a1.kind,
                tc,
                _lookalike_palette(a1.palette, rng),
                0.0,
                a1.body_color,
                "cold look-alike",
                size_of=float(h1[tc]) * float(rng.uniform(0.9, 1.1)),
            )
            is not None
        ):  # type: ignore[index]
            events.append({"event": "cold-look-alike", "frame": tc + 1})
    # a warm distractor of another colour
    if rng.random() < 0.3:
        tc = int(rng.uniform(0.25, 0.75) * n)
        kind = str(rng.choice(["person", "car"]))
        if (
            add_crossing(
                "warm-distractor",
                kind,
                tc,
                _random_palette(rng),
                float(a1.ir_contrast * rng.uniform(0.9, 1.6)),
                tuple(int(v) for v in rng.integers(20, 235, 3)),
                "warm distractor",
            )
            is not None
        ):
            events.append({"event": "warm-distractor", "frame": tc + 1, "kind": kind})
    # a second warm person walking beside the target for a while
    if a1.kind == "person" and rng.random() < 0.2:
        a = int(rng.uniform(0.1, 0.5) * n)
        b_ = min(a + int(rng.uniform(40, 120)), n - 1)
        side = float(rng.choice([-1, 1]))
        t = np.arange(n)
        near, far = float(rng.uniform(0.8, 1.3)), 4.0
        u = np.where(
            t < a,
            _smoothstep((t - (a - 25)) / 25.0),
            np.where(t > b_, 1 - _smoothstep((t - b_) / 25.0), 1.0),
        )
        offset = side * (far - (far - near) * u)
        w1 = _body("person", 1.0).w * h1  # type: ignore[operator]
        row = feet1 + float(rng.choice([-1, 1]) * rng.uniform(2, 6))  # type: ignore[operator]
        hc = (row - horizon) / k_of("person")
        size = float(rng.uniform(0.9, 1.1))
        roles[len(actors)] = "companion"
        actors.append(
            Actor(
                "person",
                float(hc[0]) * size,
                _array_path(
                    # type: ignore[operator]
                    np.column_stack([x1 + offset * w1, center_y(row, hc * size)]),
                    hc / hc[0],
                ),
                depth=_array_depth(row),
                palette=_random_palette(rng),
                ir_contrast=float(a1.ir_contrast * rng.uniform(0.8, 1.2)),
                name="companion",
            )
        )
        events.append({"event": "companion", "frames": [a + 1, b_ + 1], "side": int(side)})
    # a static occluder on the target's path, standing just in front of it: partial (a low wall, a
    # pole) or full
    if rng.random() < 0.35:
        tc = int(rng.uniform(0.2, 0.8) * n)
        tw, th = float(w1[tc]), float(h1[tc])  # type: ignore[index]
        row = float(feet1[tc]) + float(rng.uniform(2, 8))  # type: ignore[index]
        kind = str(rng.choice(["full", "low-wall", "pole"]))
        if kind == "full":
            ow, oh = tw * float(rng.uniform(1.1, 2.0)), th * float(rng.uniform(1.2, 2.0))
        elif kind == "low-wall":
            ow, oh = tw * float(rng.uniform(1.5, 4.0)), th * float(rng.uniform(0.3, 0.6))
        else:
            ow, oh = (
                max(2.0, tw * float(rng.uniform(0.1, 0.35))),
                th * float(rng.uniform(1.5, 3.0)),
            )
        colour = tuple(int(v) for v in rng.integers(60, 200, 3))
        ox, oy = float(x1[tc]), row - oh / 2  # type: ignore[index]

        # the family's rules: the target is seen when it is given, and hidden (70 % covered) for at
        # most 40 frames in a row (narrower occluders where it is slow); an occluder that cannot
        # keep them is left out
        def hidden_run(width: float) -> tuple[float, int]:
            cov = [covered(t, ox, width, row - oh, row) for t in range(n)]
            run = best = 0
            for c in cov:
                run = run + 1 if c > 0.7 else 0
                best = max(best, run)
            return max(cov[:5]), best

        start_cov, run = hidden_run(ow)
        while run > 40 and ow > 0.5 * tw:
            ow *= 0.8
            start_cov, run = hidden_run(ow)
        contrast_o = float(rng.uniform(-10, 10))
        if start_cov <= 0.3 and run <= 40:
            roles[len(actors)] = "occluder"
            actors.append(
                Actor(
                    "pillar",
                    ow,
                    (lambda t, ox=ox, oy=oy: (ox, oy, 1.0)),
                    depth=row,
                    height_px=oh,
                    body_color=colour,
                    ir_contrast=contrast_o,
                    name=f"occluder ({kind})",
                )
            )  # type: ignore[arg-type]
            events.append(
                {
                    "event": "occluder",
                    "kind": kind,
                    "frame": tc + 1,
                    "box": [
                        round(ox - ow / 2, 1),
                        round(oy - oh / 2, 1),
                        round(ow, 1),
                        round(oh, 1),
                    ],
                }
            )

    # cast shadows of drawn shapes (visible only; static ones have cooled the ground in IR)
    shadows: list[MaskShadow] = []
    if rng.random() < 0.5:
        for _ in range(int(rng.integers(1, 4))):
            kind = str(rng.choice(["building", "tree", "moving"]))
            factor = float(rng.uniform(0.25, 0.65))
            soft = float(rng.uniform(1.0, 6.0))
            tc = int(rng.uniform(0.15, 0.85) * n)
            # type: ignore[index,operator]
            x_c, y_c = float(x1[tc]), float(feet1[tc] - 0.5 * h1[tc])
            s_w, s_h = float(_body(a1.kind, float(h1[tc])).w), float(h1[tc])  # type: ignore[index]
            # a parallelogram with one sharp straight edge across the ground
            if kind == "building":
                bw, mh = float(rng.uniform(0.3, 0.9) * W), int(H - horizon + 10)
                skew = float(rng.uniform(-0.6, 0.6) * mh)
                mw = int(bw + abs(skew)) + 2
                off = max(0.0, -skew)
                m = np.zeros((mh, mw), np.float32)
                pts = np.array(
                    [[off, 0], [off + bw, 0], [off + bw + skew, mh], [off + skew, mh]], np.float32
                )
                cv2.fillPoly(m, [pts.round().astype(np.int32)], 1.0, cv2.LINE_AA)
                pos0 = (float(x_c - mw / 2 + rng.uniform(-0.3, 0.3) * bw), float(horizon))
            elif kind == "tree":
                mw, mh = (
                    int(max(s_w * rng.uniform(2, 5), 20)),
                    int(max(s_h * rng.uniform(0.8, 2.0), 20)),
                )
                m = np.zeros((mh, mw), np.float32)
                for _ in range(int(rng.integers(3, 8))):
                    cv2.ellipse(
                        m,
                        (int(rng.uniform(0.2, 0.8) * mw), int(rng.uniform(0.2, 0.8) * mh)),
                        (int(rng.uniform(0.1, 0.3) * mw) + 1, int(rng.uniform(0.1, 0.3) * mh) + 1),
                        float(rng.uniform(0, 180)),
                        0,
                        360,
                        1.0,
                        -1,
                        cv2.LINE_AA,
                    )
                pos0 = (float(x_c - mw / 2), float(y_c - mh / 2))
            else:
                mw, mh = (
                    int(max(s_w * rng.uniform(1.5, 4), 16)),
                    int(max(s_h * rng.uniform(0.6, 1.5), 16)),
                )
                m = np.zeros((mh, mw), np.float32)
                cv2.ellipse(
                    m,
                    (mw // 2, mh // 2),
                    (mw // 2 - 1, mh // 2 - 1),
                    0,
                    0,
                    360,
                    1.0,
                    -1,
                    cv2.LINE_AA,
                )
                pos0 = (float(x_c - mw / 2), float(y_c - mh / 2))
            m = cv2.GaussianBlur(m, (0, 0), soft) if soft > 0.5 else m
            if kind == "moving":
                vx = float(rng.choice([-1, 1]) * rng.uniform(0.5, 3.0))
                path = functools.partial(_moving_shadow, p0=pos0, vx=vx, tc=tc)
                cooling = 0.0
            else:
                path = functools.partial(_still_shadow, p0=pos0)
                cooling = float(rng.uniform(1.0, 6.0))
            shadows.append(MaskShadow(m, path, factor, cooling))
            events.append(
                {
                    "event": "shadow",
                    "kind": kind,
                    "frame": tc + 1,
                    "depth": round(1 - factor, 3),
                    "size": [mw, mh],
                    "softness_px": round(soft, 1),
                }
            )

    # illumination: a ramp down towards darkness (and maybe back) and flicker
    gain0 = float(rng.uniform(0.75, 1.15)) if not night else float(rng.uniform(0.45, 0.8))
    ramp = None
    if rng.random() < 0.35:
        r0 = float(rng.uniform(0.1, 0.6) * n)
        r1 = r0 + float(rng.uniform(20, 80))
        low = float(rng.uniform(0.03, 0.35))
        r2 = r1 + float(rng.uniform(20, 60)) if rng.random() < 0.4 else None
        ramp = (r0, r1, low, r2)
        events.append(
            {
                "event": "illumination-ramp",
                "frames": [round(r0) + 1, round(r1) + 1],
                "low": round(low, 3),
                "recovers_at": round(r2) + 1 if r2 else None,
            }
        )
    flicker = np.ones(n + 2)
    if rng.random() < 0.2:
        for _ in range(int(rng.integers(2, 8))):
            f0 = int(rng.integers(5, n))
            flicker[f0 : f0 + int(rng.integers(1, 4))] = float(rng.uniform(0.15, 0.6))
        events.append(
            {"event": "flicker", "frames": [int(i) for i in np.nonzero(flicker[: n + 1] < 1)[0]]}
        )

    def illumination(t: float, g0: float = gain0, ramp=ramp, flicker=flicker) -> float:
        g = g0
        if ramp is not None:
            r0, r1, low, r2 = ramp
            g *= 1.0 + (low - 1.0) * float(_smoothstep(np.array((t - r0) / max(r1 - r0, 1.0))))
            if r2 is not None and t > r2:
                g = g0 * (low + (1.0 - low) * float(_smoothstep(np.array((t - r2) / 30.0))))
        return g * float(flicker[min(int(t), n + 1)])

    # The family's fairness rule: the channels complement each other. Where a target stands in
    # darkness (the illumination and the shadows over it leave under 0.35 of the light), its IR has
    # not faded: a crossover episode is moved to frames in the light or dropped, and a target that
    # meets darkness is warm (>= 40).
    for tr in tracks:
        light = np.array([illumination(float(t + 1)) for t in range(n)])
        cy_t = tr["feet"] - 0.5 * tr["h"]  # type: ignore[operator]
        for ms in shadows:
            for t in range(n):
                ox, oy = ms.path(float(t + 1))
                mx, my = (
                    round(float(tr["x"][t]) - round(ox)),
                    round(float(cy_t[t]) - round(oy)),
                )  # type: ignore[index]
                if 0 <= my < ms.mask.shape[0] and 0 <= mx < ms.mask.shape[1]:
                    light[t] *= 1.0 - (1.0 - ms.factor) * float(ms.mask[my, mx])
        dark = light < 0.35
        i = int(tr["actor"])  # type: ignore[call-overload]
        tid = actors[i].target_id
        c = tr["crossover"]
        if c is not None:
            length = c[1] - c[0]
            free = [
                s
                for s in range(12, n - int(length) - 12)
                if not dark[max(s - 2, 0) : min(int(s + length + 12), n)].any()
            ]
            if free:
                s0 = min(free, key=lambda s: abs(s - c[0]))
                c = (float(s0), float(s0) + length, c[2])
            else:
                c = None
            actors[i] = dataclasses.replace(actors[i], ir_factor=_crossover_fn(c))
            target_params[tid - 1]["crossover"] = (
                [round(c[0]) + 1, round(c[1]) + 1, round(c[2], 3)] if c else None
            )
        if dark.any() and actors[i].ir_contrast < 40.0:
            actors[i] = dataclasses.replace(actors[i], ir_contrast=40.0)
            target_params[tid - 1]["ir_contrast"] = 40.0

    # sensor
    jitter = None
    if rng.random() < 0.3:
        sigma = float(rng.uniform(0.3, 1.5))
        e = rng.normal(0, sigma, (n, 2))
        jitter = np.zeros((n, 2))
        for t in range(1, n):
            jitter[t] = 0.7 * jitter[t - 1] + e[t]
        jitter -= jitter[0]
        params["camera_jitter_px"] = round(sigma, 3)
    r = float(rng.uniform(0, 3.0))
    a = float(rng.uniform(0, 2 * math.pi))
    shift = (round(r * math.cos(a), 3), round(r * math.sin(a), 3))
    sensor = Sensor(
        vis_blur_px=float(rng.uniform(0.3, 1.2)),
        ir_blur_px=float(rng.uniform(0.5, 1.6)),
        vignetting=float(rng.uniform(0, 0.45)) if rng.random() < 0.5 else 0.0,
        ir_shift_px=shift,
        jitter_px=jitter,
    )
    vis_noise, ir_noise = float(rng.uniform(1.0, 7.0)), float(rng.uniform(1.0, 5.0))
    quality = (int(rng.integers(50, 96)), int(rng.integers(50, 96)))
    params["sensor"] = {
        "vis_blur_px": round(sensor.vis_blur_px, 3),
        "ir_blur_px": round(sensor.ir_blur_px, 3),
        "vignetting": round(sensor.vignetting, 3),
        "misregistration_px": list(shift),
        "vis_noise": round(vis_noise, 3),
        "ir_noise": round(ir_noise, 3),
        "jpeg_quality": {"visible": quality[0], "infrared": quality[1]},
    }
    params["illumination_gain"] = round(gain0, 3)
    params["events"] = events
    scene = Scene(
        f"random-{seed}",
        f"random scene, seed {seed}: {k_targets} target(s), "
        f"{', '.join(str(e['event']) for e in events) or 'no events'}",
        W,
        H,
        n,
        tuple(actors),
        illumination=illumination,
        vis_noise=vis_noise,
        ir_noise=ir_noise,
        ir_ambient=ambient,
        background_images=(bg.visible, bg.infrared),
        mask_shadows=tuple(shadows),
        sensor=sensor,
        clip_truth=True,
        min_in_frame=0.1,
        mask_truth=True,
    )
    render_seed = int(rng.integers(1 << 31))
    return DrawnScene(scene, params, render_seed, quality, roles)


def _array_depth(feet: np.ndarray) -> Callable[[float], float]:
    """Depth order from the ground row: lower in the image is nearer."""
    frames = np.arange(1, feet.shape[0] + 1, dtype=np.float64)
    rows = feet.copy()
    return lambda t: float(np.interp(t, frames, rows))


def _crossover_fn(c: tuple[float, float, float] | None) -> Callable[[float], float] | None:
    """IR contrast factor of a crossover episode ``(start, end, low)``: 10-frame ramps down to
    ``low`` and back."""
    if c is None:
        return None
    c0, c1, low = c

    def ir_factor(t: float) -> float:
        ramp = 10.0
        if t < c0 or t > c1 + ramp:
            return 1.0
        if t < c0 + ramp:
            return 1.0 + (low - 1.0) * float(_smoothstep(np.array((t - c0) / ramp)))
        if t <= c1:
            return low
        return low + (1.0 - low) * float(_smoothstep(np.array((t - c1) / ramp)))

    return ir_factor


# ---------------------------------------------------------------------------- per-frame attributes


def frame_attributes(
    drawn: DrawnScene,
    t: int,
    frame: RenderedFrame,
    first_size: dict[int, float],
    last_center: dict[int, tuple[float, float]],
) -> dict[int, dict[str, bool]]:
    """The challenge flags of every target in frame ``t`` (see ``ATTRIBUTES``).

    ``first_size`` (target id -> sqrt of its first box area) and ``last_center`` (target id
    -> previous truth centre) are updated in place.
    """
    sc = drawn.scene
    gain = sc.illumination(float(t)) if sc.illumination else 1.0
    out: dict[int, dict[str, bool]] = {}
    others: list[tuple[int, tuple[float, float, float, float]]] = []
    for i, a in enumerate(sc.actors):
        if drawn.roles.get(i) in DISTRACTOR_ROLES or a.target_id > 0:
            cx, cy, s = a.path(float(t))
            if a.kind == "person":
                w, h = 0.42 * a.size_px * s, a.size_px * s
            elif a.kind == "cyclist":
                w, h = a.size_px * s, a.size_px * s
            else:
                w, h = a.size_px * s, 0.45 * a.size_px * s
            others.append((a.target_id, (cx - w / 2, cy - h / 2, w, h)))
    for tid, box in frame.truth_visible.items():
        flags = dict.fromkeys(ATTRIBUTES, False)
        flags["out-of-view"] = box is None or frame.in_frame[tid] < 0.95
        if box is None:
            out[tid] = flags
            last_center.pop(tid, None)
            continue
        x, y, w, h = box
        flags["occlusion"] = frame.visibility[tid] < 0.75
        shade = 1.0
        if frame.shade is not None:
            x0, y0 = max(int(x), 0), max(int(y), 0)
            x1, y1 = min(math.ceil(x + w), sc.width), min(math.ceil(y + h), sc.height)
            if x1 > x0 and y1 > y0:
                shade = float(frame.shade[y0:y1, x0:x1].mean())
        flags["shadow"] = shade < 0.85
        flags["darkness"] = gain * shade < 0.35
        actor = next(a for a in sc.actors if a.target_id == tid)
        flags["crossover"] = actor.ir_contrast * actor.ir_factor_at(float(t)) < 15.0
        size = math.sqrt(w * h)
        first_size.setdefault(tid, size)
        ratio = size / first_size[tid]
        flags["scale-change"] = ratio > 1.5 or ratio < 1 / 1.5
        c = (x + w / 2, y + h / 2)
        prev = last_center.get(tid)
        flags["fast-motion"] = (
            prev is not None and math.hypot(c[0] - prev[0], c[1] - prev[1]) > 6.0
        )
        last_center[tid] = c
        gx0, gy0, gx1, gy1 = x - 0.5 * w, y - 0.5 * h, x + 1.5 * w, y + 1.5 * h
        flags["clutter"] = any(
            oid != tid
            and ob[0] < gx1
            and ob[0] + ob[2] > gx0
            and ob[1] < gy1
            and ob[1] + ob[3] > gy0
            for oid, ob in others
        )
        out[tid] = flags
    return out
