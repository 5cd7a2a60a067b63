#!/usr/bin/env bash
# A second virtual environment for comparing with OpenCV's CSRT and KCF, which live in opencv-contrib: dualtrack with
# opencv-contrib-python-headless in place of opencv-python-headless (the two wheels both install cv2 and conflict).
# Every dualtrack tracker and every peer then run in one `dualtrack bench`, so their speeds are ratios of one run.
#
#   tools/peer_venv.sh [VENV_DIR]            (default .venv-peers)
#   VENV_DIR/bin/dualtrack bench SEQ... --trackers dual,csrt,kcf,mil
set -euo pipefail
here=$(cd "$(dirname "$0")/.." && pwd)
venv=${1:-.venv-peers}
python3 -m venv "$venv"
"$venv/bin/pip" install -q --upgrade pip
"$venv/bin/pip" install -q opencv-contrib-python-headless
# the project's own dependencies from pyproject.toml, all but the headless OpenCV wheel
deps=$("$venv/bin/python" - "$here/pyproject.toml" << 'PY'
import sys, tomllib
deps = tomllib.load(open(sys.argv[1], "rb"))["project"]["dependencies"]
print("\n".join(d for d in deps if not d.startswith("opencv-python-headless")))
PY
)
mapfile -t reqs <<< "$deps"
"$venv/bin/pip" install -q "${reqs[@]}"
"$venv/bin/pip" install -q --no-deps -e "$here"
"$venv/bin/dualtrack" trackers
