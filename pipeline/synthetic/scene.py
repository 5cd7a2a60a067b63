"""Scene model and renderer: registered visible + IR frames with exact ground truth.

A :class:`Scene` is a static background, actors that move along paths (people, cars,
static occluders), visible-only effects (global illumination, moving shadows) and IR
effects (each actor's heat contrast over time, e.g. thermal crossover). Each frame:

1. actors are drawn far to near (``depth``), each sprite placed by a sub-pixel affine
   warp (pre-blurred against aliasing); in IR an actor's pixels are
   ``ambient + contrast(t) * heat`` with softened edges;
2. visible only: shadows multiply the image, then the global illumination gain;
3. optics blur and sensor noise per channel, 8-bit quantisation (the writer adds JPEG).

Ground truth is the warp of the sprite's exact alpha box (amodal: the full extent even
when occluded or partly outside the frame); a target entirely outside the frame has no
truth. Visibility is the share of the target's own pixels that no nearer actor or
occluder covers, inside the frame.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import cv2
import numpy as np

from pipeline.synthetic.sprites import Palette, Sprite, car, cyclist, person, pillar, truck

PathFn = Callable[[float], tuple[float, float, float]]
"""frame number (1-based, float) -> (cx, cy, scale): box centre in px and size factor."""


@dataclass(frozen=True)
class Actor:
    """Something drawn in the scene.

    ``target_id`` > 0 makes it a ground-truth target; 0 is a distractor or occluder.
    ``size_px`` is the on-screen height (person), length (car, truck) or width (pillar) at
    scale 1. ``ir_contrast`` is the IR grey-level rise over ambient at heat 1 and
    ``ir_factor(t)`` scales it over time (thermal crossover). ``depth``: larger is nearer.
    """

    kind: str
    size_px: float
    path: PathFn
    target_id: int = 0
    depth: float | Callable[[float], float] = 1.0
    palette: Palette = field(default_factory=Palette)
    body_color: tuple[int, int, int] = (40, 90, 200)
    facing: int = 1
    ir_contrast: float = 70.0
    ir_factor: Callable[[float], float] | None = None
    height_px: float = 0.0  # pillar height
    walk_phase_per_px: float = 0.0  # walk cycles per px moved (0: derived from size)
    name: str = ""
    facing_auto: bool = (
        False  # turn the sprite to face the way it moves (cars, cyclists that turn back)
    )

    def depth_at(self, t: float) -> float:
        return self.depth(t) if callable(self.depth) else float(self.depth)

    def ir_factor_at(self, t: float) -> float:
        return 1.0 if self.ir_factor is None else float(self.ir_factor(t))


@dataclass(frozen=True)
class Shadow:
    """A soft visible-only shadow: ellipse path ``t -> (cx, cy, rx, ry)``, brightness factor."""

    path: Callable[[float], tuple[float, float, float, float]]
    factor: float = 0.35
    softness_px: float = 6.0


@dataclass(frozen=True)
class MaskShadow:
    """A visible-channel shadow of any drawn shape: a soft mask (0..1) whose top-left corner
    follows ``path``.

    ``factor`` is the brightness left under the mask's core (0 black, 1 no shadow);
    ``ir_cooling`` grey levels are taken off the infrared where a static shadow has
    cooled the ground (0 for moving shadows).
    """

    mask: np.ndarray
    path: Callable[[float], tuple[float, float]]
    factor: float = 0.5
    ir_cooling: float = 0.0


@dataclass(frozen=True)
class Sensor:
    """Optics and sensor effects applied to every frame.

    ``vis_blur_px`` / ``ir_blur_px``: Gaussian optics blur (sigma, px). ``vignetting``:
    the visible image falls off by this share towards the corners (0 none).
    ``ir_shift_px``: misregistration, the infrared image is displaced by (dx, dy) px from
    the visible one (its truth with it). ``jitter_px``: ``(n_frames, 2)`` camera shake,
    both images (and the truth) displaced by (dx, dy) px at each frame, or None.
    """

    vis_blur_px: float = 0.5
    ir_blur_px: float = 0.7
    vignetting: float = 0.0
    ir_shift_px: tuple[float, float] = (0.0, 0.0)
    jitter_px: np.ndarray | None = None


@dataclass(frozen=True)
class RenderedFrame:
    """One rendered frame pair and its exact truth.

    ``truth_visible`` / ``truth_infrared``: per target id the box in each channel (None when
    the target is out of view); ``visibility``: share of the target's own in-frame pixels
    that nothing nearer covers; ``in_frame``: share of the target's full box inside the
    frame; ``shade``: the visible shadow multiplier (H, W) or None; ``masks``: per target
    its amodal alpha (H, W) in visible-frame px, when asked for; ``others``: per actor index
    the visible-frame box of every actor that is not a target (None when out of view).
    """

    visible: np.ndarray
    infrared: np.ndarray
    infrared_float: np.ndarray
    truth_visible: dict[int, tuple[float, float, float, float] | None]
    truth_infrared: dict[int, tuple[float, float, float, float] | None]
    visibility: dict[int, float]
    in_frame: dict[int, float]
    shade: np.ndarray | None = None
    masks: dict[int, np.ndarray] | None = None
    others: dict[int, tuple[float, float, float, float] | None] | None = None


@dataclass(frozen=True)
class Scene:
    """Everything needed to render a scenario.

    ``background_images``: a drawn ``(visible RGB 0..1, IR grey)`` pair used instead of the
    default facade-and-pavement background; ``clip_truth``: boxes are clipped to the frame
    (the visible extent, as annotators draw it) and a target with less than
    ``min_in_frame`` of its box inside has no truth (default: the amodal box, absent only
    when wholly outside); ``mask_truth``: the truth of each channel is the pixel box of the
    target's rendered silhouette there (its own alpha >= 0.5, amodal: occluders do not cut
    it, moved with the camera jitter and, in infrared, the misregistration) instead of the
    warped box of the high-resolution sprite, which thin limbs can overhang by a pixel or two.
    """

    name: str
    description: str
    width: int
    height: int
    n_frames: int
    actors: tuple[Actor, ...]
    shadows: tuple[Shadow, ...] = ()
    illumination: Callable[[float], float] | None = None
    vis_noise: float = 3.0  # grey levels (0..255)
    ir_noise: float = 2.5
    ir_ambient: float = 95.0
    notes: dict[str, object] = field(default_factory=dict)
    background_images: tuple[np.ndarray, np.ndarray] | None = None
    mask_shadows: tuple[MaskShadow, ...] = ()
    sensor: Sensor = field(default_factory=Sensor)
    clip_truth: bool = False
    min_in_frame: float = 0.0
    mask_truth: bool = False


def _smooth_noise(rng: np.random.Generator, h: int, w: int, sigma: float) -> np.ndarray:
    n = rng.normal(0, 1, (h, w)).astype(np.float32)
    n = cv2.GaussianBlur(n, (0, 0), sigma)
    return n / max(float(n.std()), 1e-6)


def background(scene: Scene, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Static urban background: building facade with windows, pavement, grass strip.

    Returns visible RGB float32 (0..1) and IR float32 (grey levels).
    """
    h, w = scene.height, scene.width
    horizon = int(0.32 * h)
    grass = int(0.9 * h)
    vis = np.zeros((h, w, 3), np.float32)
    ir = np.full((h, w), scene.ir_ambient, np.float32)
    jitter = rng.uniform(-0.04, 0.04, 3).astype(np.float32)
    facade = np.array([0.78, 0.72, 0.62], np.float32) + jitter
    pave = np.array([0.55, 0.55, 0.57], np.float32) + jitter / 2
    green = np.array([0.30, 0.50, 0.22], np.float32)
    vis[:horizon] = facade
    vis[horizon:grass] = pave
    vis[grass:] = green
    ir[:horizon] += 6.0
    ir[grass:] -= 8.0
    # windows on the facade
    ww, wh = max(w // 16, 6), max(horizon // 4, 5)
    for x0 in range(w // 32, w - ww, w // 8):
        for y0 in range(horizon // 6, horizon - wh, horizon // 2):
            vis[y0 : y0 + wh, x0 : x0 + ww] = np.array([0.35, 0.42, 0.50], np.float32)
            ir[y0 : y0 + wh, x0 : x0 + ww] -= 12.0
    # pavement tiles
    step = max(h // 12, 8)
    for y0 in range(horizon, grass, step):
        vis[y0 : y0 + 1, :, :] *= 0.85
    for x0 in range(0, w, 2 * step):
        vis[horizon:grass, x0 : x0 + 1] *= 0.88
    tex = (
        _smooth_noise(rng, h, w, 1.2)[..., None] * 0.035
        + _smooth_noise(rng, h, w, 8.0)[..., None] * 0.05
    )
    vis = np.clip(vis * (1.0 + tex), 0, 1)
    ir += _smooth_noise(rng, h, w, 6.0) * 4.0 + _smooth_noise(rng, h, w, 1.0) * 1.0
    return vis, ir


class Renderer:
    """Renders a :class:`Scene` frame by frame (deterministic given the seed)."""

    def __init__(self, scene: Scene, seed: int):
        self.scene = scene
        self.rng = np.random.default_rng(seed)
        if scene.background_images is not None:
            self.bg_vis = np.asarray(scene.background_images[0], np.float32).copy()
            self.bg_ir = np.asarray(scene.background_images[1], np.float32).copy()
        else:
            self.bg_vis, self.bg_ir = background(scene, self.rng)
        for ms in scene.mask_shadows:  # static shadows have cooled the ground under them
            if ms.ir_cooling:
                self._paste(
                    self.bg_ir, ms.mask, ms.path(1.0), lambda roi, m, c=ms.ir_cooling: roi - c * m
                )
        self._sprites: list[dict[int, list[Sprite]]] = []
        self._layer_cache: dict[tuple[int, int, int], np.ndarray] = {}
        self._vis_bank = [
            self.rng.standard_normal((scene.height, scene.width, 3), dtype=np.float32)
            for _ in range(6)
        ]
        self._ir_bank = [
            self.rng.standard_normal((scene.height, scene.width), dtype=np.float32)
            for _ in range(6)
        ]
        # reference box centre x, y and height (canvas px), per facing
        self._ref: list[dict[int, tuple[float, float, float]]] = []
        self._dist: list[float] = [0.0] * len(scene.actors)
        self._last_pos: list[tuple[float, float] | None] = [None] * len(scene.actors)
        self._facing: list[int] = [a.facing for a in scene.actors]
        for a in scene.actors:
            seed_a = int(self.rng.integers(1 << 31))
            facings = (1, -1) if a.facing_auto else (a.facing,)
            sets = {f: self._make_sprites(a, np.random.default_rng(seed_a), f) for f in facings}
            self._sprites.append(sets)
            refs = {}
            for f, sprites in sets.items():
                b = sprites[0].box
                ref_dim = (
                    b[3] - b[1] if a.kind in ("person", "cyclist") else b[2] - b[0]
                )  # height of people
                refs[f] = ((b[0] + b[2]) / 2, (b[1] + b[3]) / 2, ref_dim)
            self._ref.append(refs)
        sen = scene.sensor
        self._vignette = None
        if sen.vignetting > 0:
            yy, xx = np.mgrid[0 : scene.height, 0 : scene.width].astype(np.float32)
            r2 = ((xx + 0.5 - scene.width / 2) ** 2 + (yy + 0.5 - scene.height / 2) ** 2) / (
                (scene.width / 2) ** 2 + (scene.height / 2) ** 2
            )
            self._vignette = (1.0 - np.float32(sen.vignetting) * r2)[..., None].astype(np.float32)

    def _make_sprites(self, a: Actor, srng: np.random.Generator, facing: int) -> list[Sprite]:
        max_scale = max(a.path(t)[2] for t in np.linspace(1, self.scene.n_frames, 50))
        res = 3.0 * a.size_px * max_scale  # canvas px of the reference dimension
        if a.kind == "person":
            return [person(res, a.palette, ph, srng) for ph in np.arange(8) / 8]
        if a.kind == "cyclist":
            state = srng.bit_generator.state
            out = []
            for ph in np.arange(4) / 4:  # the same textures in every pedal phase
                srng.bit_generator.state = state
                out.append(cyclist(res, a.palette, a.body_color, ph, srng, facing))
            return out
        if a.kind == "car":
            return [car(res, a.body_color, srng, facing)]
        if a.kind == "truck":
            return [truck(res, a.body_color, srng, facing)]
        if a.kind == "pillar":
            k = res / a.size_px
            return [pillar(res, a.height_px * k, a.body_color, srng)]
        raise ValueError(f"unknown actor kind {a.kind!r}")

    @staticmethod
    def _paste(img: np.ndarray, mask: np.ndarray, pos: tuple[float, float], op) -> None:
        """``img[region] = op(img[region], mask[part])`` for ``mask`` placed with its top-left
        corner at ``pos``."""
        h, w = img.shape[:2]
        ox, oy = round(pos[0]), round(pos[1])
        x0, y0 = max(ox, 0), max(oy, 0)
        x1, y1 = min(ox + mask.shape[1], w), min(oy + mask.shape[0], h)
        if x1 <= x0 or y1 <= y0:
            return
        m = mask[y0 - oy : y1 - oy, x0 - ox : x1 - ox]
        img[y0:y1, x0:x1] = op(img[y0:y1, x0:x1], m)

    def _placement(
        self, i: int, t: float
    ) -> tuple[Sprite, np.ndarray, tuple[float, float, float, float]]:
        a = self.scene.actors[i]
        cx, cy, s = a.path(t)
        if a.facing_auto:
            vx = a.path(t + 0.5)[0] - a.path(t - 0.5)[0]
            if abs(vx) > 0.05:
                self._facing[i] = 1 if vx > 0 else -1
        facing = self._facing[i]
        sprites = self._sprites[i][facing]
        if len(sprites) > 1:
            last = self._last_pos[i]
            if last is not None:
                self._dist[i] += math.hypot(cx - last[0], cy - last[1])
            self._last_pos[i] = (cx, cy)
            per_px = a.walk_phase_per_px or 1.0 / (0.9 * a.size_px * s)
            sprite = sprites[int((self._dist[i] * per_px * len(sprites)) % len(sprites))]
        else:
            sprite = sprites[0]
        rx, ry, rdim = self._ref[i][facing]
        k = a.size_px * s / rdim
        M = np.array([[k, 0.0, cx - k * rx], [0.0, k, cy - k * ry]], np.float64)
        b = sprite.box
        box = (k * b[0] + M[0, 2], k * b[1] + M[1, 2], k * (b[2] - b[0]), k * (b[3] - b[1]))
        return sprite, M, box

    def _layers(self, i: int, sprite: Sprite, k: float) -> np.ndarray:
        """The sprite's 5 layers (RGB, alpha, heat), pre-blurred against aliasing for scale ``k``
        (cached)."""
        sigma = 0.45 / k if k < 1 else 0.0
        key = (i, id(sprite), round(sigma * 10))
        layers = self._layer_cache.get(key)
        if layers is None:
            layers = np.dstack(
                [sprite.rgb, sprite.alpha[..., None], sprite.heat[..., None]]
            ).astype(np.float32)
            if sigma > 0.3:
                layers = cv2.GaussianBlur(layers, (0, 0), round(sigma * 10) / 10)
            self._layer_cache[key] = layers
        return layers

    def _noise(self, bank: list[np.ndarray]) -> np.ndarray:
        """Sensor noise for one frame: a bank frame circularly shifted by a random offset
        (independent enough, 10x cheaper)."""
        a = bank[int(self.rng.integers(len(bank)))]
        dy, dx = int(self.rng.integers(a.shape[0])), int(self.rng.integers(a.shape[1]))
        sign = np.float32(1 if self.rng.integers(2) else -1)
        return np.roll(a, (dy, dx), axis=(0, 1)) * sign

    def render(
        self, t: int
    ) -> tuple[
        np.ndarray, np.ndarray, dict[int, tuple[tuple[float, float, float, float] | None, float]]
    ]:
        """Frame ``t`` (1-based): visible BGR uint8, IR uint8, and per target ``(box or None,
        visibility)``."""
        f = self.render_frame(t)
        return (
            f.visible,
            f.infrared,
            {tid: (box, f.visibility[tid]) for tid, box in f.truth_visible.items()},
        )

    def _truth_box(
        self, box: tuple[float, float, float, float], dx: float, dy: float
    ) -> tuple[tuple[float, float, float, float] | None, float]:
        """The truth box displaced by (dx, dy) and the share of it inside the frame (clipped if the
        scene says)."""
        sc = self.scene
        w, h = sc.width, sc.height
        x, y, bw, bh = box[0] + dx, box[1] + dy, box[2], box[3]
        ix0, iy0 = max(x, 0.0), max(y, 0.0)
        ix1, iy1 = min(x + bw, float(w)), min(y + bh, float(h))
        inside_area = max(ix1 - ix0, 0.0) * max(iy1 - iy0, 0.0)
        frac = inside_area / (bw * bh) if bw * bh > 0 else 0.0
        if not sc.clip_truth:
            inside = x < w and y < h and x + bw > 0 and y + bh > 0
            return ((x, y, bw, bh) if inside else None), frac
        if inside_area <= 0 or frac < sc.min_in_frame:
            return None, frac
        return (ix0, iy0, ix1 - ix0, iy1 - iy0), frac

    @staticmethod
    def _shift(
        img: np.ndarray, dx: float, dy: float, border: int = cv2.BORDER_REFLECT_101
    ) -> np.ndarray:
        M = np.array([[1.0, 0.0, dx], [0.0, 1.0, dy]], np.float64)
        return cv2.warpAffine(
            img, M, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR, borderMode=border
        )

    def _mask_box(
        self, crop: tuple[int, int, np.ndarray], dx: float, dy: float
    ) -> tuple[float, float, float, float] | None:
        """Pixel box of a target's alpha >= 0.5 after moving it by (dx, dy), inside the frame (None
        if empty)."""
        x0, y0, alpha = crop
        pad = int(np.ceil(max(abs(dx), abs(dy)))) + 2
        a = cv2.copyMakeBorder(alpha, pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=0)
        if dx or dy:
            a = self._shift(a, dx, dy, border=cv2.BORDER_CONSTANT)
        ys, xs = np.nonzero(a >= 0.5)
        if xs.size == 0:
            return None
        w, h = self.scene.width, self.scene.height
        bx0, by0 = max(int(xs.min()) + x0 - pad, 0), max(int(ys.min()) + y0 - pad, 0)
        bx1, by1 = min(int(xs.max()) + 1 + x0 - pad, w), min(int(ys.max()) + 1 + y0 - pad, h)
        if bx1 <= bx0 or by1 <= by0:
            return None
        return (float(bx0), float(by0), float(bx1 - bx0), float(by1 - by0))

    def render_frame(self, t: int, masks: bool = False) -> RenderedFrame:
        """Frame ``t`` (1-based) with its truth per channel; ``masks`` adds each target's amodal
        alpha."""
        sc = self.scene
        sen = sc.sensor
        h, w = sc.height, sc.width
        vis = self.bg_vis.copy()
        ir = self.bg_ir.copy()
        owner = np.zeros((h, w), np.int16)
        own_area: dict[int, int] = {}
        boxes: dict[int, tuple[float, float, float, float]] = {}
        alphas: dict[int, np.ndarray] = {}
        crops: dict[
            int, tuple[int, int, np.ndarray]
        ] = {}  # target id -> (x0, y0, alpha of its crop)
        order = sorted(range(len(sc.actors)), key=lambda i: sc.actors[i].depth_at(t))
        placements = {i: self._placement(i, float(t)) for i in range(len(sc.actors))}
        for i in order:
            a = sc.actors[i]
            sprite, M, box = placements[i]
            if a.target_id > 0:
                boxes[a.target_id] = box
            k = M[0, 0]
            x0 = max(math.floor(M[0, 2]) - 2, 0)
            y0 = max(math.floor(M[1, 2]) - 2, 0)
            x1 = min(math.ceil(M[0, 2] + k * sprite.alpha.shape[1]) + 2, w)
            y1 = min(math.ceil(M[1, 2] + k * sprite.alpha.shape[0]) + 2, h)
            if x1 <= x0 or y1 <= y0:
                continue
            Mr = M.copy()
            Mr[0, 2] -= x0
            Mr[1, 2] -= y0
            layers = self._layers(i, sprite, k)
            warped = cv2.warpAffine(
                layers,
                Mr,
                (x1 - x0, y1 - y0),
                flags=cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_CONSTANT,
                borderValue=0,
            )
            rgb, alpha, heat = warped[..., :3], warped[..., 3], warped[..., 4]
            a3 = alpha[..., None]
            with np.errstate(invalid="ignore", divide="ignore"):
                color = np.where(
                    a3 > 1e-4, rgb / np.maximum(a3, 1e-4), 0
                )  # un-premultiply the blur
                hv = np.where(alpha > 1e-4, heat / np.maximum(alpha, 1e-4), 0)
            roi = vis[y0:y1, x0:x1]
            roi[:] = roi * (1 - a3) + np.clip(color, 0, 1) * a3
            a_ir = cv2.GaussianBlur(alpha, (0, 0), 1.0)
            temp = sc.ir_ambient + a.ir_contrast * a.ir_factor_at(t) * cv2.GaussianBlur(
                hv * alpha, (0, 0), 1.0
            ) / np.maximum(a_ir, 1e-4)
            iroi = ir[y0:y1, x0:x1]
            iroi[:] = iroi * (1 - a_ir) + temp * a_ir
            solid = alpha > 0.5
            code = a.target_id if a.target_id > 0 else -1
            owner[y0:y1, x0:x1][solid] = code
            if a.target_id > 0:
                own_area[a.target_id] = int(solid.sum())
                if sc.mask_truth:
                    crops[a.target_id] = (x0, y0, alpha)
                if masks:
                    full = np.zeros((h, w), np.float32)
                    full[y0:y1, x0:x1] = alpha
                    alphas[a.target_id] = full
        for shd in sc.shadows:
            cx, cy, rx, ry = shd.path(float(t))
            pad = 3.0 * shd.softness_px
            sx0, sy0 = max(int(cx - rx - pad), 0), max(int(cy - ry - pad), 0)
            sx1, sy1 = min(int(cx + rx + pad) + 1, w), min(int(cy + ry + pad) + 1, h)
            if sx1 <= sx0 or sy1 <= sy0:
                continue
            m = np.zeros((sy1 - sy0, sx1 - sx0), np.float32)
            cv2.ellipse(
                m,
                (round((cx - sx0) * 4), round((cy - sy0) * 4)),
                (max(round(rx * 4), 1), max(round(ry * 4), 1)),
                0,
                0,
                360,
                1.0,
                -1,
                cv2.LINE_AA,
                shift=2,
            )
            m = cv2.GaussianBlur(m, (0, 0), shd.softness_px, borderType=cv2.BORDER_REPLICATE)
            vis[sy0:sy1, sx0:sx1] *= (1.0 - (1.0 - shd.factor) * m)[..., None]
        shade = None
        if sc.mask_shadows:
            shade = np.ones((h, w), np.float32)
            for ms in sc.mask_shadows:
                self._paste(
                    shade,
                    ms.mask,
                    ms.path(float(t)),
                    lambda roi, m, f=ms.factor: roi * (1.0 - np.float32(1.0 - f) * m),
                )
            vis *= shade[..., None]
        gain = sc.illumination(float(t)) if sc.illumination else 1.0
        if self._vignette is not None:
            vis *= self._vignette
        jx, jy = (
            (float(sen.jitter_px[t - 1, 0]), float(sen.jitter_px[t - 1, 1]))
            if sen.jitter_px is not None
            else (0.0, 0.0)
        )
        ix, iy = jx + sen.ir_shift_px[0], jy + sen.ir_shift_px[1]
        if jx or jy:
            vis = self._shift(vis, jx, jy)
            for tid in alphas:
                alphas[tid] = self._shift(alphas[tid], jx, jy, border=cv2.BORDER_CONSTANT)
        if ix or iy:
            ir = self._shift(ir, ix, iy)
        vis = cv2.GaussianBlur(vis, (0, 0), sen.vis_blur_px)
        vis *= np.float32(255.0 * gain)
        vis += self._noise(self._vis_bank) * np.float32(sc.vis_noise)
        ir = cv2.GaussianBlur(ir, (0, 0), sen.ir_blur_px)
        ir += self._noise(self._ir_bank) * np.float32(sc.ir_noise)
        vis += np.float32(0.5)
        ir += np.float32(0.5)
        ir_float = ir.copy()
        vis_u8 = cv2.cvtColor(np.clip(vis, 0, 255, out=vis).astype(np.uint8), cv2.COLOR_RGB2BGR)
        ir_u8 = np.clip(ir, 0, 255, out=ir).astype(np.uint8)
        truth_vis: dict[int, tuple[float, float, float, float] | None] = {}
        truth_ir: dict[int, tuple[float, float, float, float] | None] = {}
        visibility: dict[int, float] = {}
        in_frame: dict[int, float] = {}
        for tid, box in boxes.items():
            truth_vis[tid], in_frame[tid] = self._truth_box(box, jx, jy)
            truth_ir[tid], _ = self._truth_box(box, ix, iy)
            if sc.mask_truth:
                crop = crops.get(tid)
                for tb, (dx, dy) in ((truth_vis, (jx, jy)), (truth_ir, (ix, iy))):
                    if tb[tid] is not None:
                        tb[tid] = self._mask_box(crop, dx, dy) if crop is not None else None
            area = own_area.get(tid, 0)
            visible = int((owner == tid).sum())
            visibility[tid] = (visible / area) if area else 0.0
        others = {
            i: self._truth_box(placements[i][2], jx, jy)[0]
            for i, a in enumerate(sc.actors)
            if a.target_id <= 0
        }
        return RenderedFrame(
            vis_u8,
            ir_u8,
            ir_float,
            truth_vis,
            truth_ir,
            visibility,
            in_frame,
            shade,
            alphas if masks else None,
            others,
        )
