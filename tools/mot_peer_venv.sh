#!/usr/bin/env bash
# The environment of the field's multi-object trackers for tools/mot_peers.py: Roboflow's `trackers` (clean-room
# ByteTrack, OC-SORT, SORT) and `supervision`, which depends on the non-headless OpenCV wheel and so cannot share
# dualtrack's environment. Nothing of dualtrack is installed here: tools/mot_peer_worker.py reads detection files.
#
#   tools/mot_peer_venv.sh [VENV_DIR]            (default .venv-mot)
#   python tools/mot_peers.py --seeds 1500-1519 --out runs/mot-peers
set -euo pipefail
venv=${1:-.venv-mot}
python3 -m venv "$venv"
"$venv/bin/pip" install -q --upgrade pip
"$venv/bin/pip" install -q "trackers==2.6.1" "supervision==0.31.2"
"$venv/bin/python" -c "import trackers, supervision; print('trackers', supervision.__version__)"
