"""The random scene family (``dualtrack synth random OUT --seed N``): whole scenes drawn from a seed.

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

ATTRIBUTES = ("occlusion", "shadow", "darkness", "clutter", "crossover", "out-of-view", "scale-change", "fast-motion")
"""Per-frame challenge flags, in ``scene.json`` order."""
MIN_ATTRIBUTE_FRAMES = 5
"""A scene carries an attribute when some target has it in at least this many frames."""
MAX_SPEED_PX = 12.0


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
        raise ValueError(f"seeds must be N or A-B with non-negative integers; got {text!r}") from None
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
        lo, hi = (int(parts[0]), int(parts[0])) if len(parts) == 1 else (int(parts[0]), int(parts[1]))
        if len(parts) > 2:
            raise ValueError
    except ValueError:
        raise ValueError(f"--targets must be K or A-B (1 to 8); got {s!r}") from None
    if not 1 <= lo <= hi <= 8:
        raise ValueError(f"--targets must be K or A-B with 1 <= A <= B <= 8; got {s!r}")
    return lo, hi


# ---------------------------------------------------------------------------------------------- drawing helpers


def _smoothstep(u: np.ndarray) -> np.ndarray:
    u = np.clip(u, 0.0, 1.0)
    return u * u * (3 - 2 * u)


def _random_palette(rng: np.random.Generator) -> Palette:
    def col(lo: int = 20, hi: int = 235) -> tuple[int, int, int]:
        return tuple(int(v) for v in rng.integers(lo, hi, 3))  # type: ignore[return-value]

    skins = ((224, 172, 140), (190, 140, 110), (150, 105, 80), (110, 75, 55), (240, 200, 170))
    return Palette(top=col(), bottom=col(15, 160), skin=skins[int(rng.integers(len(skins)))],
                   hair=col(10, 90), shoes=col(10, 70), pattern=str(rng.choice(["stripes", "checks", "plain"])))


def _lookalike_palette(p: Palette, rng: np.random.Generator) -> Palette:
    def near(c: tuple[int, int, int]) -> tuple[int, int, int]:
        return tuple(int(np.clip(v + rng.integers(-12, 13), 0, 255)) for v in c)  # type: ignore[return-value]

    return Palette(top=near(p.top), bottom=near(p.bottom), skin=p.skin, hair=p.hair, shoes=p.shoes, pattern=p.pattern)


def _array_path(xy: np.ndarray, scale: np.ndarray) -> Callable[[float], tuple[float, float, float]]:
    """Path through per-frame (cx, cy) and scale arrays (frame 1 at index 0), linear between frames."""
    frames = np.arange(1, xy.shape[0] + 1, dtype=np.float64)
    xs, ys, ss = xy[:, 0].copy(), xy[:, 1].copy(), scale.copy()

    def path(t: float) -> tuple[float, float, float]:
        return float(np.interp(t, frames, xs)), float(np.interp(t, frames, ys)), float(np.interp(t, frames, ss))

    return path


@dataclass
class _Body:
    """Size of an actor kind on screen at scale 1: ``size_px`` (what the sprite scales), w and h of its box."""

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


def _scale_profile(rng: np.random.Generator, n: int, kind: str, lo_ratio: float, hi_ratio: float
                   ) -> tuple[np.ndarray, dict[str, object]]:
    t = np.arange(n, dtype=np.float64)
    if kind == "constant":
        return np.ones(n), {"scale": "constant"}
    ratio = float(rng.uniform(1.3, max(hi_ratio, 1.3))) if kind == "approach" else float(rng.uniform(min(lo_ratio, 0.77), 0.77))
    a = float(rng.uniform(0, 0.35) * n)
    b = float(rng.uniform(0.65, 1.0) * n)
    u = _smoothstep((t - a) / max(b - a, 1.0))
    return np.exp(np.log(ratio) * u), {"scale": kind, "scale_ratio": round(ratio, 3), "scale_frames": [round(a) + 1, round(b) + 1]}


def _motion(rng: np.random.Generator, n: int, kind: str, speed: float, start: np.ndarray, heading: float,
            half: np.ndarray, bounds: tuple[float, float, float, float], leave_at: int | None,
            entry: bool, actor_kind: str = "person") -> tuple[np.ndarray, dict[str, object]]:
    """Per-frame centres for a motion ``kind``; bounces inside ``bounds`` (centre limits before the half-size)
    until ``leave_at``, after which the actor may walk out of the frame."""
    x_lo, x_hi, y_lo, y_hi = bounds
    pos = np.zeros((n, 2))
    p = start.astype(np.float64).copy()
    ang = heading
    info: dict[str, object] = {"motion": kind, "speed_px": round(speed, 2), "heading_deg": round(math.degrees(heading), 1)}
    turns: list[tuple[int, float, int]] = []
    stops: list[tuple[int, int]] = []
    vertical = abs(math.sin(heading)) < 0.2 and actor_kind == "car"  # a car only turns back along its lane
    if kind == "turning":
        for _ in range(int(rng.integers(1, 4))):
            d = math.pi if vertical else float(rng.uniform(math.radians(60), math.pi))
            turns.append((int(rng.integers(10, n - 10)), float(rng.choice([-1, 1]) * d), int(rng.integers(3, 12))))
        info["turns"] = [[f + 1, round(math.degrees(d), 1)] for f, d, _ in turns]
    if kind == "fast":
        f = int(rng.integers(10, 30))
        while f < n:
            d = math.pi if vertical else float(rng.uniform(math.radians(40), math.radians(150)))
            turns.append((f, float(rng.choice([-1, 1]) * d), int(rng.integers(2, 6))))
            f += int(rng.integers(12, 40))
        info["turns"] = len(turns)
    if kind == "stopping":
        for _ in range(int(rng.integers(1, 3))):
            s0 = int(rng.integers(15, max(n - 60, 16)))
            stops.append((s0, s0 + int(rng.integers(15, 50))))
        info["stops"] = [[a + 1, b + 1] for a, b in stops]
    amp, period = float(rng.uniform(math.radians(20), math.radians(60))), float(rng.uniform(40, 140))
    if kind == "curved":
        info.update({"curve_amplitude_deg": round(math.degrees(amp), 1), "curve_period_frames": round(period, 1)})
    phase = float(rng.uniform(0, 2 * math.pi))
    entering = entry  # walking in from outside the frame: no bounce until wholly inside
    turn_rate = np.zeros(n)
    for f, d, dur in turns:
        turn_rate[f : min(f + dur, n)] += d / dur
    curving = kind == "curved"
    for t in range(n):
        pos[t] = p
        v = speed
        for a, b in stops:  # slows down over 4 frames, stands, starts again over 4 frames
            if a <= t < b:
                v = speed * (1.0 - min(t - a, b - 1 - t, 4) / 4.0)
        leaving = leave_at is not None and t >= leave_at
        if leave_at is not None and t == leave_at:  # head for the nearer side and walk out
            ang = 0.0 if p[0] > (x_lo + x_hi) / 2 else math.pi
            turn_rate[t:] = 0.0
            curving = False
        heading_t = ang + (amp * math.sin(2 * math.pi * t / period + phase) if curving else 0.0)
        ang += turn_rate[t]
        step = np.array([math.cos(heading_t), math.sin(heading_t)]) * min(v, MAX_SPEED_PX)
        q = p + step
        hx, hy = half[min(t + 1, n - 1)]
        lo_x, hi_x = x_lo + hx, x_hi - hx
        if entering and lo_x <= q[0] <= hi_x:
            entering = False  # wholly inside: from now on it stays in the frame
        hold_x = not entering and not leaving
        if hold_x and (q[0] < lo_x or q[0] > hi_x):
            ang = math.pi - ang
            step[0] = -step[0]
        if q[1] < y_lo or q[1] > y_hi - hy:  # people and vehicles stay on the ground
            ang = -ang
            step[1] = -step[1]
        q = p + step
        if hold_x:
            q[0] = min(max(q[0], lo_x), hi_x)
        q[1] = min(max(q[1], y_lo), y_hi - hy)
        p = q
    return pos, info


# ---------------------------------------------------------------------------------------------- the scene


def draw_scene(seed: int, targets: tuple[int, int] | int | None = None, width: int = 320, height: int = 240,
               n_frames: int = 200) -> DrawnScene:
    """Draw one random scene.

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
    k_targets = int(rng.integers(targets[0], targets[1] + 1)) if targets else int(rng.integers(1, 4))
    n, W, H = n_frames, width, height

    bg = street_background(rng, W, H)
    horizon = bg.horizon_px
    night = bool(bg.params["night"])
    ambient = float(bg.params["ir_ambient"])
    actors: list[Actor] = []
    roles: dict[int, str] = {}
    params: dict[str, object] = {"family": "random", "seed": seed, "size": [W, H], "frames": n,
                                 "background": bg.params, "structures": bg.structures}
    target_params: list[dict[str, object]] = []
    tracks: list[tuple[np.ndarray, np.ndarray, _Body, float]] = []  # centres, scale, body, depth
    crossovers: list[tuple[float, float, float] | None] = []

    def ground_y_limits(body_h: np.ndarray) -> tuple[float, float]:
        return float(horizon - 0.25 * body_h.max()), float(H + 0.02 * H)

    max_h = min(150.0, 0.62 * H)
    for k in range(k_targets):
        kind = str(rng.choice(["person", "person", "person", "cyclist", "car"], p=None))
        scale_kind = str(rng.choice(["constant", "constant", "constant", "approach", "recede"]))
        h_px = float(np.clip(math.exp(rng.normal(math.log(45.0), 0.55)), 10.0, max_h))  # median 45 px
        if kind == "car":
            h_px = min(h_px, 0.45 * 0.5 * W)  # at most half the frame long
        # keep the scaled size within 10..150 px tall
        hi_ratio = min(3.0, max_h / h_px)
        lo_ratio = max(0.4, 10.0 / h_px)
        scale, sinfo = _scale_profile(rng, n, scale_kind, lo_ratio, hi_ratio)
        body = _body(kind, h_px)
        half = np.stack([0.5 * body.w * scale, 0.5 * body.h * scale], axis=1)
        motion = str(rng.choice(["straight", "curved", "stopping", "turning", "fast"], p=[0.25, 0.2, 0.15, 0.25, 0.15]))
        if kind == "car" and motion == "curved":  # cars keep to their lane
            motion = "straight"
        base = {"person": (0.012, 0.035), "cyclist": (0.03, 0.08), "car": (0.04, 0.12)}[kind]
        speed = float(rng.uniform(*base) * body.size_px)
        speed = float(np.clip(speed, 0.3, 4.0))
        if motion == "fast":
            speed = float(rng.uniform(6.0, MAX_SPEED_PX))
        y_lo, y_hi = ground_y_limits(body.h * scale)
        leave = bool(rng.random() < 0.2)
        entry = bool(rng.random() < 0.15)
        leave_at = int(rng.uniform(0.6, 0.9) * n) if leave else None
        heading = float(rng.choice([0.0, math.pi]) + rng.uniform(-0.45, 0.45) * (0.3 if kind == "car" else 1.0))
        if motion == "fast" and kind != "car":
            heading = float(rng.uniform(0, 2 * math.pi))
        hx0, hy0 = half[0]
        if entry:  # starts partly outside the frame, walking in
            side = int(rng.choice([-1, 1]))
            cx0 = (hx0 * rng.uniform(0.1, 0.6)) if side < 0 else (W - hx0 * rng.uniform(0.1, 0.6))
            heading = (0.0 if side < 0 else math.pi) + float(rng.uniform(-0.3, 0.3))
        else:
            cx0 = float(rng.uniform(hx0 + 1, max(W - hx0 - 1, hx0 + 2)))
        feet_lo = max(horizon + 0.15 * (H - horizon), y_lo + 2 * hy0)
        cy0 = float(rng.uniform(min(feet_lo, H - 2), H - 1)) - hy0
        # crossings between targets: a later target passes through an earlier one's position
        cross = None
        if k > 0 and rng.random() < 0.6:
            cross = (int(rng.integers(k)), int(rng.uniform(0.3, 0.7) * n))
        pos, minfo = _motion(rng, n, motion, speed, np.array([cx0, cy0]), heading, half, (0.0, float(W), y_lo, y_hi),
                             leave_at, entry, kind)
        if cross is not None:  # a detour that meets the other target's path at frame tc and rejoins its own
            other, tc = cross
            shift = tracks[other][0][tc] - pos[tc]
            shift[1] *= 0.6  # depth order shows as slightly different ground rows
            span = max(int(math.ceil(0.5 * float(np.hypot(*shift)))), 8)  # smoothstep: at most 3 px/frame extra
            if span <= tc and tc + span < n:
                t = np.arange(n, dtype=np.float64)
                wgt = np.where(t <= tc, _smoothstep((t - (tc - span)) / span), 1.0 - _smoothstep((t - tc) / span))
                pos = pos + shift[None, :] * wgt[:, None]
                minfo["crosses_target"] = [other + 1, tc + 1]
        depth = float(1.0 + k + rng.uniform(-0.3, 0.3))
        palette = _random_palette(rng)
        body_color = tuple(int(v) for v in rng.integers(20, 235, 3))
        contrast = float(rng.uniform(25, 75) if not night else rng.uniform(40, 100))
        if kind == "car":
            contrast = float(rng.uniform(40, 110))
        crossover = None
        if rng.random() < 0.25 and n > 60:
            c0 = float(rng.uniform(max(0.15 * n, 12.0), 0.6 * n))
            c1 = c0 + float(rng.uniform(20, 70))
            low = float(rng.uniform(0.0, 0.15))
            crossover = (c0, c1, low)
        ir_factor = None
        if crossover is not None:
            c0, c1, low = crossover

            def ir_factor(t: float, c0: float = c0, c1: float = c1, low: float = low) -> float:
                ramp = 10.0
                if t < c0 or t > c1 + ramp:
                    return 1.0
                if t < c0 + ramp:
                    return 1.0 + (low - 1.0) * float(_smoothstep(np.array((t - c0) / ramp)))
                if t <= c1:
                    return low
                return low + (1.0 - low) * float(_smoothstep(np.array((t - c1) / ramp)))

        tid = k + 1
        roles[len(actors)] = "target"
        actors.append(Actor(kind, body.size_px, _array_path(pos, scale), target_id=tid,
                            depth=depth, palette=palette, body_color=body_color,  # type: ignore[arg-type]
                            facing=1 if math.cos(heading) >= 0 else -1, ir_contrast=contrast, ir_factor=ir_factor,
                            facing_auto=kind in ("car", "cyclist"), name=f"target {tid}"))
        tracks.append((pos, scale, body, depth))
        crossovers.append(crossover)
        target_params.append({"id": tid, "kind": kind, "height_px": round(h_px, 1), "ir_contrast": round(contrast, 1),
                              "palette": {"top": list(palette.top), "bottom": list(palette.bottom), "pattern": palette.pattern},
                              "entering": entry, "leaves_at": leave_at + 1 if leave_at is not None else None,
                              "crossover": [round(crossover[0]) + 1, round(crossover[1]) + 1, round(crossover[2], 3)]
                              if crossover else None, **sinfo, **minfo})
    params["targets"] = target_params

    # events around the first target (each with a probability)
    events: list[dict[str, object]] = []
    pos1, scale1, body1, depth1 = tracks[0]
    t1 = actors[0]
    size1 = np.stack([body1.w * scale1, body1.h * scale1], axis=1)

    def crossing_path(tc: int, speed: float, from_left: bool) -> np.ndarray:
        x_c, y_c = pos1[tc]
        t = np.arange(n) - tc
        direction = 1.0 if from_left else -1.0
        y_off = float(rng.uniform(-0.15, 0.15) * size1[tc, 1])
        return np.stack([x_c + direction * speed * t, np.full(n, y_c + y_off)], axis=1)

    # crossing person or car (depth order drawn)
    if rng.random() < 0.35:
        tc = int(rng.uniform(0.25, 0.75) * n)
        kind = str(rng.choice(["person", "person", "car"]))
        hgt = float(np.clip(size1[tc, 1] * rng.uniform(0.8, 1.25), 10, max_h))
        b = _body(kind, hgt)
        sp = float(rng.uniform(1.0, 3.0))
        front = bool(rng.random() < 0.5)
        roles[len(actors)] = "crossing"
        actors.append(Actor(kind, b.size_px, _array_path(crossing_path(tc, sp, bool(rng.random() < 0.5)), np.ones(n)),
                            depth=depth1 + (0.5 if front else -0.5), palette=_random_palette(rng),
                            body_color=tuple(int(v) for v in rng.integers(20, 235, 3)),  # type: ignore[arg-type]
                            ir_contrast=float(rng.uniform(30, 90)), facing_auto=True, name="crossing"))
        events.append({"event": "crossing", "frame": tc + 1, "kind": kind, "in_front": front})
    # a cold colour look-alike (printed cut-out, a mannequin) passing near the target
    if rng.random() < 0.25:
        tc = int(rng.uniform(0.25, 0.75) * n)
        roles[len(actors)] = "look-alike"
        actors.append(Actor(t1.kind, t1.size_px * float(rng.uniform(0.9, 1.1)),
                            _array_path(crossing_path(tc, float(rng.uniform(0.8, 2.5)), bool(rng.random() < 0.5)),
                                        np.full(n, float(scale1[tc]))),
                            depth=depth1 - 0.5, palette=_lookalike_palette(t1.palette, rng), body_color=t1.body_color,
                            ir_contrast=0.0, facing_auto=True, name="cold look-alike"))
        events.append({"event": "cold-look-alike", "frame": tc + 1})
    # a warm distractor of another colour
    if rng.random() < 0.3:
        tc = int(rng.uniform(0.25, 0.75) * n)
        kind = str(rng.choice(["person", "car"]))
        hgt = float(np.clip(size1[tc, 1] * rng.uniform(0.8, 1.3), 10, max_h))
        b = _body(kind, hgt)
        roles[len(actors)] = "warm-distractor"
        actors.append(Actor(kind, b.size_px, _array_path(crossing_path(tc, float(rng.uniform(0.8, 3.0)), bool(rng.random() < 0.5)),
                                                          np.ones(n)),
                            depth=depth1 - 0.5, palette=_random_palette(rng),
                            body_color=tuple(int(v) for v in rng.integers(20, 235, 3)),  # type: ignore[arg-type]
                            ir_contrast=float(t1.ir_contrast * rng.uniform(0.9, 1.6)), facing_auto=True,
                            name="warm distractor"))
        events.append({"event": "warm-distractor", "frame": tc + 1, "kind": kind})
    # a second warm person walking beside the target for a while
    if t1.kind == "person" and rng.random() < 0.2:
        a = int(rng.uniform(0.1, 0.5) * n)
        b_ = min(a + int(rng.uniform(40, 120)), n - 1)
        side = float(rng.choice([-1, 1]))
        t = np.arange(n)
        near = float(rng.uniform(0.8, 1.3))
        far = 4.0
        u = np.where(t < a, _smoothstep((t - (a - 25)) / 25.0), np.where(t > b_, 1 - _smoothstep((t - b_) / 25.0), 1.0))
        offset = side * (far - (far - near) * u)
        path = pos1 + np.stack([offset * size1[:, 0], np.zeros(n)], axis=1)
        roles[len(actors)] = "companion"
        actors.append(Actor("person", t1.size_px * float(rng.uniform(0.9, 1.1)), _array_path(path, scale1),
                            depth=depth1 + float(rng.choice([-0.3, 0.3])), palette=_random_palette(rng),
                            ir_contrast=float(t1.ir_contrast * rng.uniform(0.8, 1.2)), name="companion"))
        events.append({"event": "companion", "frames": [a + 1, b_ + 1], "side": int(side)})
    # static occluders on the target's path: partial (a low wall or a pole) or full (a pillar)
    if rng.random() < 0.35:
        tc = int(rng.uniform(0.2, 0.8) * n)
        x_c, y_c = pos1[tc]
        tw, th = size1[tc]
        kind = str(rng.choice(["full", "low-wall", "pole"]))
        if kind == "full":
            ow, oh = float(tw * rng.uniform(1.1, 2.0)), float(th * rng.uniform(1.2, 2.0))
            oy = y_c + th / 2 - oh / 2 + 0.05 * th
        elif kind == "low-wall":
            ow, oh = float(tw * rng.uniform(1.5, 4.0)), float(th * rng.uniform(0.3, 0.6))
            oy = y_c + th / 2 - oh / 2 + 0.03 * th
        else:
            ow, oh = float(max(2.0, tw * rng.uniform(0.1, 0.35))), float(th * rng.uniform(1.5, 3.0))
            oy = y_c + th / 2 - oh / 2 + 0.05 * th
        colour = tuple(int(v) for v in rng.integers(60, 200, 3))
        ox = float(x_c)
        roles[len(actors)] = "occluder"
        actors.append(Actor("pillar", ow, (lambda t, ox=ox, oy=oy: (ox, oy, 1.0)), depth=50.0, height_px=oh,
                            body_color=colour, ir_contrast=float(rng.uniform(-10, 10)), name=f"occluder ({kind})"))  # type: ignore[arg-type]
        events.append({"event": "occluder", "kind": kind, "frame": tc + 1, "box": [round(ox - ow / 2, 1), round(oy - oh / 2, 1),
                                                                                   round(ow, 1), round(oh, 1)]})

    # cast shadows of drawn shapes (visible only; static ones have cooled the ground in IR)
    shadows: list[MaskShadow] = []
    if rng.random() < 0.5:
        for _ in range(int(rng.integers(1, 4))):
            kind = str(rng.choice(["building", "tree", "moving"]))
            factor = float(rng.uniform(0.25, 0.65))
            soft = float(rng.uniform(1.0, 6.0))
            tc = int(rng.uniform(0.15, 0.85) * n)
            x_c, y_c = pos1[tc]
            if kind == "building":  # a parallelogram with one sharp straight edge across the ground
                bw, mh = float(rng.uniform(0.3, 0.9) * W), int(H - horizon + 10)
                skew = float(rng.uniform(-0.6, 0.6) * mh)
                mw = int(bw + abs(skew)) + 2
                off = max(0.0, -skew)
                m = np.zeros((mh, mw), np.float32)
                pts = np.array([[off, 0], [off + bw, 0], [off + bw + skew, mh], [off + skew, mh]], np.float32)
                cv2.fillPoly(m, [pts.round().astype(np.int32)], 1.0, cv2.LINE_AA)
                pos0 = (float(x_c - mw / 2 + rng.uniform(-0.3, 0.3) * bw), float(horizon))
            elif kind == "tree":
                mw, mh = int(max(size1[tc, 0] * rng.uniform(2, 5), 20)), int(max(size1[tc, 1] * rng.uniform(0.8, 2.0), 20))
                m = np.zeros((mh, mw), np.float32)
                for _ in range(int(rng.integers(3, 8))):
                    cv2.ellipse(m, (int(rng.uniform(0.2, 0.8) * mw), int(rng.uniform(0.2, 0.8) * mh)),
                                (int(rng.uniform(0.1, 0.3) * mw) + 1, int(rng.uniform(0.1, 0.3) * mh) + 1),
                                float(rng.uniform(0, 180)), 0, 360, 1.0, -1, cv2.LINE_AA)
                pos0 = (float(x_c - mw / 2), float(y_c - mh / 2))
            else:
                mw, mh = int(max(size1[tc, 0] * rng.uniform(1.5, 4), 16)), int(max(size1[tc, 1] * rng.uniform(0.6, 1.5), 16))
                m = np.zeros((mh, mw), np.float32)
                cv2.ellipse(m, (mw // 2, mh // 2), (mw // 2 - 1, mh // 2 - 1), 0, 0, 360, 1.0, -1, cv2.LINE_AA)
                pos0 = (float(x_c - mw / 2), float(y_c - mh / 2))
            m = cv2.GaussianBlur(m, (0, 0), soft) if soft > 0.5 else m
            if kind == "moving":
                vx = float(rng.choice([-1, 1]) * rng.uniform(0.5, 3.0))
                path = (lambda t, p0=pos0, vx=vx, tc=tc: (p0[0] + vx * (t - 1 - tc), p0[1]))
                cooling = 0.0
            else:
                path = (lambda t, p0=pos0: p0)
                cooling = float(rng.uniform(1.0, 6.0))
            shadows.append(MaskShadow(m, path, factor, cooling))
            events.append({"event": "shadow", "kind": kind, "frame": tc + 1, "depth": round(1 - factor, 3),
                           "size": [mw, mh], "softness_px": round(soft, 1)})

    # illumination: a ramp down towards darkness (and maybe back) and flicker. Fairness rule of the family:
    # the channels complement each other, so the visible channel does not go dark while a target's IR has
    # faded (a crossover episode), and a scene that goes dark keeps its targets warm.
    gain0 = float(rng.uniform(0.75, 1.15)) if not night else float(rng.uniform(0.45, 0.8))
    ramp = None
    if rng.random() < 0.35:
        r0 = float(rng.uniform(0.1, 0.6) * n)
        r1 = r0 + float(rng.uniform(20, 80))
        low = float(rng.uniform(0.03, 0.35))
        back = bool(rng.random() < 0.4)
        r2 = r1 + float(rng.uniform(20, 60)) if back else None
        dark = (r0 + 0.5 * (r1 - r0), r2 + 30.0 if r2 is not None else float(n + 1))
        clashes = any(c is not None and c[0] < dark[1] and c[1] + 10.0 > dark[0] for c in crossovers)
        if not clashes:
            ramp = (r0, r1, low, r2)
            events.append({"event": "illumination-ramp", "frames": [round(r0) + 1, round(r1) + 1], "low": round(low, 3),
                           "recovers_at": round(r2) + 1 if r2 else None})
            for i, a in enumerate(actors):
                if roles.get(i) == "target" and a.ir_contrast < 40.0:
                    actors[i] = dataclasses.replace(a, ir_contrast=40.0)
                    target_params[a.target_id - 1]["ir_contrast"] = 40.0
    flicker = np.ones(n + 2)
    if rng.random() < 0.2:
        for _ in range(int(rng.integers(2, 8))):
            f0 = int(rng.integers(5, n))
            flicker[f0 : f0 + int(rng.integers(1, 4))] = float(rng.uniform(0.15, 0.6))
        events.append({"event": "flicker", "frames": [int(i) for i in np.nonzero(flicker[: n + 1] < 1)[0]]})

    def illumination(t: float, g0: float = gain0, ramp=ramp, flicker=flicker) -> float:
        g = g0
        if ramp is not None:
            r0, r1, low, r2 = ramp
            g *= 1.0 + (low - 1.0) * float(_smoothstep(np.array((t - r0) / max(r1 - r0, 1.0))))
            if r2 is not None and t > r2:
                g = g0 * (low + (1.0 - low) * float(_smoothstep(np.array((t - r2) / 30.0))))
        return g * float(flicker[min(int(t), n + 1)])

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
    sensor = Sensor(vis_blur_px=float(rng.uniform(0.3, 1.2)), ir_blur_px=float(rng.uniform(0.5, 1.6)),
                    vignetting=float(rng.uniform(0, 0.45)) if rng.random() < 0.5 else 0.0, ir_shift_px=shift,
                    jitter_px=jitter)
    vis_noise, ir_noise = float(rng.uniform(1.0, 7.0)), float(rng.uniform(1.0, 5.0))
    quality = (int(rng.integers(50, 96)), int(rng.integers(50, 96)))
    params["sensor"] = {"vis_blur_px": round(sensor.vis_blur_px, 3), "ir_blur_px": round(sensor.ir_blur_px, 3),
                        "vignetting": round(sensor.vignetting, 3), "misregistration_px": list(shift),
                        "vis_noise": round(vis_noise, 3), "ir_noise": round(ir_noise, 3),
                        "jpeg_quality": {"visible": quality[0], "infrared": quality[1]}}
    params["illumination_gain"] = round(gain0, 3)
    params["events"] = events
    scene = Scene(f"random-{seed}", f"random scene, seed {seed}: {k_targets} target(s), "
                  f"{', '.join(str(e['event']) for e in events) or 'no events'}", W, H, n, tuple(actors),
                  illumination=illumination, vis_noise=vis_noise, ir_noise=ir_noise, ir_ambient=ambient,
                  background_images=(bg.visible, bg.infrared), mask_shadows=tuple(shadows), sensor=sensor,
                  clip_truth=True, min_in_frame=0.1)
    render_seed = int(rng.integers(1 << 31))
    return DrawnScene(scene, params, render_seed, quality, roles)


# ---------------------------------------------------------------------------------------------- per-frame attributes


def frame_attributes(drawn: DrawnScene, t: int, frame: RenderedFrame, first_size: dict[int, float],
                     last_center: dict[int, tuple[float, float]]) -> dict[int, dict[str, bool]]:
    """The challenge flags of every target in frame ``t`` (see ``ATTRIBUTES``).

    ``first_size`` (target id -> sqrt of its first box area) and ``last_center`` (target id
    -> previous truth centre) are updated in place.
    """
    sc = drawn.scene
    gain = sc.illumination(float(t)) if sc.illumination else 1.0
    out: dict[int, dict[str, bool]] = {}
    others: list[tuple[int, tuple[float, float, float, float]]] = []
    for i, a in enumerate(sc.actors):
        if drawn.roles.get(i) in ("crossing", "look-alike", "warm-distractor", "companion") or a.target_id > 0:
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
            x1, y1 = min(int(math.ceil(x + w)), sc.width), min(int(math.ceil(y + h)), sc.height)
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
        flags["fast-motion"] = prev is not None and math.hypot(c[0] - prev[0], c[1] - prev[1]) > 6.0
        last_center[tid] = c
        gx0, gy0, gx1, gy1 = x - 0.5 * w, y - 0.5 * h, x + 1.5 * w, y + 1.5 * h
        flags["clutter"] = any(oid != tid and ob[0] < gx1 and ob[0] + ob[2] > gx0 and ob[1] < gy1 and ob[1] + ob[3] > gy0
                               for oid, ob in others)
        out[tid] = flags
    return out
