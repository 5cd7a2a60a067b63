"""Make the README's pictures from the current code: ``docs/images/recording.jpg``.

Usage::

    python tools/readme_pictures.py [--shot ../shared/tools/rrd-screenshot]

Renders the named scene ``crossing2`` (two people cross; seed 0), runs the default tracker on
its first 100 frames (the recording then ends, and the viewer opens, just after the two have
passed each other: the occlusion's events are in the log), and takes a screenshot of the
recording in the stock Rerun web viewer with ``rrd-screenshot`` (headless Chromium; the shared
tools' script, which installs what it needs on first use), saved as a JPEG under 400 kB.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCENE, FRAMES = "crossing2", 100


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--shot", type=Path, default=ROOT.parent / "shared" / "tools" / "rrd-screenshot"
    )
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "images" / "recording.jpg")
    ap.add_argument("--wait-ms", type=int, default=60000, help="how long the viewer loads")
    a = ap.parse_args()
    if not a.shot.is_file():
        print(f"no screenshot tool at {a.shot}", file=sys.stderr)
        return 1
    sys.path.insert(0, str(ROOT))
    import cv2

    from pipeline.run import RunOptions, run_track
    from pipeline.synthetic import synthesize

    with tempfile.TemporaryDirectory(prefix="dualtrack-pictures-") as tmp:
        scene = synthesize(SCENE, Path(tmp) / SCENE, seed=0, progress=False)
        run = Path(tmp) / "run"
        run_track(scene, RunOptions(out_dir=run, plots=False, stop_frame=FRAMES, progress=False))
        png = Path(tmp) / "shot.png"
        subprocess.run([str(a.shot), str(run / "run.rrd"), str(png), str(a.wait_ms)], check=True)
        img = cv2.imread(str(png))
        for quality in (85, 75, 65, 55):
            ok, jpg = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
            if ok and jpg.size < 400_000:
                break
        a.out.write_bytes(jpg.tobytes())
    print(f"wrote {a.out} ({jpg.size // 1024} kB)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
