#!/usr/bin/env bash
# Installs Blender as a Python module (bpy, from PyPI) in its own environment, for the
# benchmarks that render with Cycles (benchmarks/blender_compare.py, the Cycles test sets).
# bpy pins its own Python packages, so it gets a venv of its own: /opt/bpyenv by default.
#
#   bash scripts/install_blender.sh [VENV=/opt/bpyenv]
set -euo pipefail
VENV="${1:-/opt/bpyenv}"
export PIP_ROOT_USER_ACTION=ignore
[ -x "$VENV/bin/python" ] || python3 -m venv "$VENV"
"$VENV/bin/python" -m pip install -q bpy numpy
"$VENV/bin/python" -c "import bpy; print('bpy', bpy.app.version_string, 'in $VENV')"
