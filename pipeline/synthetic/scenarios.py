"""The named synthetic scenarios (``dualtrack synth --list``).

Paths are fixed (so the events of a scenario happen at known frames, recorded in
``scene.json``); the seed changes textures, noise and sprite details.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pipeline.synthetic.scene import Actor, Scene, Shadow
from pipeline.synthetic.sprites import Palette

RED = Palette(top=(200, 40, 40), bottom=(40, 50, 110), pattern="stripes")
GREEN = Palette(top=(40, 150, 60), bottom=(90, 90, 95), pattern="checks")
YELLOW = Palette(top=(225, 190, 40), bottom=(25, 25, 30), skin=(190, 140, 110), pattern="stripes")
PURPLE = Palette(
    top=(120, 50, 160),
    bottom=(60, 60, 60),
    skin=(170, 120, 90),
    hair=(20, 20, 20),
    pattern="plain",
)
ORANGE = Palette(top=(235, 120, 30), bottom=(30, 60, 40), pattern="checks")


def _lin(t: float, t0: float, t1: float, a: float, b: float) -> float:
    """Linear ramp from a (t <= t0) to b (t >= t1)."""
    if t <= t0:
        return a
    if t >= t1:
        return b
    return a + (b - a) * (t - t0) / (t1 - t0)


def _smooth(t: float, t0: float, t1: float, a: float, b: float) -> float:
    """Smoothstep ramp from a to b."""
    u = min(max((t - t0) / (t1 - t0), 0.0), 1.0)
    return a + (b - a) * u * u * (3 - 2 * u)


def keyframes(
    points: list[tuple[float, float, float, float]],
) -> Callable[[float], tuple[float, float, float]]:
    """Piecewise-linear path through ``(frame, cx, cy, scale)`` keyframes (held at the ends)."""
    arr = np.asarray(points, np.float64)

    def path(t: float) -> tuple[float, float, float]:
        return (
            float(np.interp(t, arr[:, 0], arr[:, 1])),
            float(np.interp(t, arr[:, 0], arr[:, 2])),
            float(np.interp(t, arr[:, 0], arr[:, 3])),
        )

    return path


def _dusk() -> Scene:
    return Scene(
        "dusk",
        "illumination falls to near-darkness in the visible channel (IR unaffected)",
        320,
        240,
        220,
        (
            Actor(
                "person",
                58,
                keyframes([(1, 40, 150, 1.0), (110, 170, 140, 1.0), (220, 285, 155, 1.0)]),
                target_id=1,
                palette=RED,
            ),
        ),
        illumination=lambda t: _smooth(t, 40, 140, 1.0, 0.06),
        notes={"dark_from": 140},
    )


def _shadows() -> Scene:
    return Scene(
        "shadows",
        "the target walks through a building shadow and moving tree shadows (visible only)",
        320,
        240,
        220,
        (
            Actor(
                "person",
                60,
                keyframes([(1, 290, 150, 1.0), (220, 35, 145, 1.0)]),
                target_id=1,
                palette=GREEN,
                facing=-1,
            ),
        ),
        shadows=(
            Shadow(lambda t: (70.0, 150.0, 95.0, 120.0), 0.30, 8.0),
            Shadow(
                lambda t: (320.0 - 1.3 * t, 140.0 + 10 * math.sin(t / 15), 28.0, 18.0), 0.40, 5.0
            ),
            Shadow(lambda t: (40.0 + 1.1 * t, 165.0, 22.0, 30.0), 0.40, 5.0),
        ),
    )


def _approach() -> Scene:
    return Scene(
        "approach",
        "a person walks towards the camera: scale grows 3.3x",
        320,
        240,
        200,
        (
            Actor(
                "person",
                36,
                keyframes([(1, 120, 105, 1.0), (200, 190, 138, 3.3)]),
                target_id=1,
                palette=ORANGE,
            ),
        ),
    )


def _lookalike() -> Scene:
    cutout = Actor(
        "person",
        56,
        keyframes([(1, 300, 142, 1.0), (200, 20, 138, 1.0)]),
        depth=0.5,
        palette=RED,
        ir_contrast=0.0,
        facing=-1,
        name="colour look-alike cut-out (not warm)",
    )
    return Scene(
        "lookalike",
        "a colour look-alike that is not warm (a printed cut-out) passes close behind the target",
        320,
        240,
        200,
        (
            Actor(
                "person",
                58,
                keyframes([(1, 30, 152, 1.0), (200, 290, 150, 1.0)]),
                target_id=1,
                palette=RED,
            ),
            cutout,
        ),
        notes={"crossing_frame": 100},
    )


def _hot_distractor() -> Scene:
    hot_car = Actor(
        "car",
        90,
        keyframes([(1, 380, 128, 1.0), (200, -60, 132, 1.0)]),
        depth=0.5,
        body_color=(30, 80, 190),
        facing=-1,
        ir_contrast=95.0,
        name="hot car",
    )
    return Scene(
        "hot-distractor",
        "a hot car drives past just behind the target (different colour, hotter in IR)",
        320,
        240,
        200,
        (
            Actor(
                "person",
                58,
                keyframes([(1, 40, 150, 1.0), (200, 280, 148, 1.0)]),
                target_id=1,
                palette=GREEN,
            ),
            hot_car,
        ),
        notes={"crossing_frame": 95},
    )


def _crossover() -> Scene:
    def path(t: float) -> tuple[float, float, float]:
        return 40 + 1.1 * t, 148 + 14 * math.sin(t / 25), 1.0

    return Scene(
        "crossover",
        "thermal crossover: the target's IR contrast fades to ~3% for 60 frames and recovers",
        320,
        240,
        240,
        (
            Actor(
                "person",
                58,
                path,
                target_id=1,
                palette=YELLOW,
                ir_factor=lambda t: (
                    _smooth(t, 60, 90, 1.0, 0.03) if t < 150 else _smooth(t, 150, 180, 0.03, 1.0)
                ),
            ),
        ),
        notes={"faded": [90, 150]},
    )


def _occluder() -> Scene:
    return Scene(
        "occluder",
        "a static pillar hides the target in both channels while it walks past",
        320,
        240,
        220,
        (
            Actor(
                "person",
                56,
                keyframes([(1, 30, 150, 1.0), (220, 300, 148, 1.0)]),
                target_id=1,
                palette=RED,
            ),
            Actor(
                "pillar",
                30,
                lambda t: (160.0, 140.0, 1.0),
                depth=5.0,
                height_px=170,
                body_color=(150, 150, 150),
                name="pillar",
            ),
        ),
        notes={"hidden_centre_frame": 106},
    )


def _fast() -> Scene:
    w = 2 * math.pi / 90

    def path(t: float) -> tuple[float, float, float]:
        return 160 + 110 * math.sin(w * t), 145 + 40 * math.sin(2 * w * t), 1.0

    return Scene(
        "fast",
        "fast curved motion: a figure-of-eight at up to 8 px per frame",
        320,
        240,
        180,
        (Actor("person", 50, path, target_id=1, palette=PURPLE, walk_phase_per_px=1 / 40),),
    )


def _crossing2() -> Scene:
    return Scene(
        "crossing2",
        "two people cross; the nearer one fully hides the other",
        320,
        240,
        160,
        (
            Actor(
                "person",
                62,
                keyframes([(1, 30, 152, 1.0), (160, 290, 150, 1.0)]),
                target_id=1,
                depth=2.0,
                palette=RED,
            ),
            Actor(
                "person",
                48,
                keyframes([(1, 295, 149, 1.0), (160, 35, 151, 1.0)]),
                target_id=2,
                depth=1.0,
                palette=YELLOW,
                facing=-1,
            ),
        ),
        notes={"crossing_frame": 80},
    )


def _crossing3() -> Scene:
    return Scene(
        "crossing3",
        "three people, two crossings with depth order (640x480)",
        640,
        480,
        200,
        (
            Actor(
                "person",
                112,
                keyframes([(1, 60, 305, 1.0), (200, 560, 300, 1.0)]),
                target_id=1,
                depth=3.0,
                palette=RED,
            ),
            Actor(
                "person",
                96,
                keyframes([(1, 590, 298, 1.0), (200, 90, 300, 1.0)]),
                target_id=2,
                depth=2.0,
                palette=GREEN,
                facing=-1,
            ),
            Actor(
                "person",
                72,
                keyframes([(1, 250, 298, 1.0), (200, 620, 302, 1.0)]),
                target_id=3,
                depth=1.0,
                palette=PURPLE,
            ),
        ),
        notes={"crossings": {"1-2": 100, "2-3": 52}},
    )


def _meet_part() -> Scene:
    a = keyframes(
        [(1, 25, 150, 1.0), (70, 150, 150, 1.0), (130, 205, 150, 1.0), (220, 300, 120, 1.0)]
    )
    b = keyframes(
        [(1, 295, 145, 1.0), (70, 172, 146, 1.0), (130, 227, 146, 1.0), (220, 300, 186, 1.0)]
    )
    return Scene(
        "meet-part",
        "two look-alikes meet, walk together side by side, and part",
        320,
        240,
        220,
        (
            Actor("person", 60, a, target_id=1, depth=1.0, palette=RED),
            Actor("person", 60, b, target_id=2, depth=2.0, palette=RED, facing=-1),
        ),
        notes={"together": [70, 130]},
    )


def _group3() -> Scene:
    return Scene(
        "group3",
        "three people merge into one group at once and part again",
        320,
        240,
        200,
        (
            Actor(
                "person",
                58,
                keyframes(
                    [
                        (1, 30, 130, 1.0),
                        (80, 150, 145, 1.0),
                        (120, 160, 145, 1.0),
                        (200, 290, 125, 1.0),
                    ]
                ),
                target_id=1,
                depth=1.0,
                palette=RED,
            ),
            Actor(
                "person",
                60,
                keyframes(
                    [
                        (1, 290, 150, 1.0),
                        (80, 168, 148, 1.0),
                        (120, 158, 148, 1.0),
                        (200, 30, 160, 1.0),
                    ]
                ),
                target_id=2,
                depth=2.0,
                palette=GREEN,
                facing=-1,
            ),
            Actor(
                "person",
                62,
                keyframes(
                    [
                        (1, 160, 200, 1.0),
                        (80, 162, 156, 1.0),
                        (120, 165, 156, 1.0),
                        (200, 170, 200, 1.0),
                    ]
                ),
                target_id=3,
                depth=3.0,
                palette=YELLOW,
            ),
        ),
        notes={"group": [80, 120]},
    )


def _occluded_static() -> Scene:
    van = Actor(
        "truck",
        150,
        keyframes([(1, -110, 146, 1.0), (180, 430, 146, 1.0)]),
        depth=5.0,
        body_color=(60, 135, 70),
        ir_contrast=25.0,
        name="green box truck",
    )
    return Scene(
        "occluded-static",
        "a target standing still is hidden by a truck of its own shirt colour driving past",
        320,
        240,
        180,
        (
            Actor(
                "person",
                58,
                lambda t: (160.0 + 2 * math.sin(t / 9), 150.0, 1.0),
                target_id=1,
                palette=GREEN,
                walk_phase_per_px=1 / 200,
            ),
            van,
        ),
        notes={"hidden": [80, 95]},
    )


def _occluded_moving() -> Scene:
    return Scene(
        "occluded-moving",
        "a walking target disappears behind a wall and re-appears on the other side",
        320,
        240,
        220,
        (
            Actor(
                "person",
                56,
                keyframes([(1, 30, 150, 1.0), (220, 300, 150, 1.0)]),
                target_id=1,
                palette=RED,
            ),
            Actor(
                "pillar",
                72,
                lambda t: (165.0, 140.0, 1.0),
                depth=5.0,
                height_px=150,
                body_color=(160, 130, 110),
                name="wall",
            ),
        ),
    )


def _pole_fast() -> Scene:
    return Scene(
        "pole-fast",
        "a fast car (16 px per frame, a quarter of its length) passes behind a lamp post "
        "(640x360)",
        640,
        360,
        32,
        (
            Actor(
                "car",
                64,
                keyframes([(1, 52, 223, 1.0), (32, 548, 223, 1.0)]),
                target_id=1,
                body_color=(200, 30, 30),
                ir_contrast=80.0,
            ),
            Actor(
                "pillar",
                28,
                lambda t: (320.0, 180.0, 1.0),
                depth=5.0,
                height_px=288,
                body_color=(90, 90, 95),
                name="pole",
            ),
        ),
    )


def walkers(n: int) -> Scene:
    """``n`` people (1-8), each walking to and fro in its own cell of a 2 x 4 grid: the same
    per-target work at every n, for measuring how the cost grows with the number of targets."""
    if not 1 <= n <= 8:
        raise ValueError(f"walkers takes 1 to 8 people; got {n}")
    palettes = (RED, GREEN, YELLOW, PURPLE, ORANGE, RED, GREEN, YELLOW)
    actors = []
    for k in range(n):
        col, row = k % 2, k // 2
        x0, y = 40.0 + 160 * col, 36.0 + 56 * row
        actors.append(
            Actor(
                "person",
                44,
                keyframes([(1, x0, y, 1.0), (60, x0 + 80, y, 1.0), (120, x0, y, 1.0)]),
                target_id=k + 1,
                palette=palettes[k],
                facing=1,
            )
        )
    return Scene(
        f"walkers{n}",
        f"{n} people walking in separate lanes (cost vs number of targets)",
        320,
        240,
        120,
        tuple(actors),
    )


SCENARIO_BUILDERS: dict[str, Callable[[], Scene]] = {
    "dusk": _dusk,
    "shadows": _shadows,
    "approach": _approach,
    "lookalike": _lookalike,
    "hot-distractor": _hot_distractor,
    "crossover": _crossover,
    "occluder": _occluder,
    "fast": _fast,
    "crossing2": _crossing2,
    "crossing3": _crossing3,
    "meet-part": _meet_part,
    "group3": _group3,
    "occluded-static": _occluded_static,
    "occluded-moving": _occluded_moving,
    "pole-fast": _pole_fast,
    **{f"walkers{n}": (lambda n=n: walkers(n)) for n in (1, 2, 4, 8)},
}
