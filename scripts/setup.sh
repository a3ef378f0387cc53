#!/usr/bin/env bash
# Set up contourmesh in ./.venv (idempotent).
#   bash scripts/setup.sh          core package (enough for `contourmesh reproduce` and `contourmesh mesh`)
#   bash scripts/setup.sh --dev    core + comparison peers (scikit-image, VTK, Open3D, PyMeshLab, DGtal),
#                                  file readers and the test tools
# System libraries that a dependency needs (Open3D needs libusb-1.0) are installed with apt-get when missing.
set -euo pipefail
cd "$(dirname "$0")/.."

extras=""
if [ "${1:-}" = "--dev" ]; then extras="[dev,compare,io]"; fi

py=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$py" -m venv .venv
fi
.venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || true
.venv/bin/python -m pip install -q -e ".${extras}"

if [ -n "$extras" ] && ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then
  echo "setup: installing libusb-1.0-0 (needed by Open3D)" >&2
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  if command -v apt-get >/dev/null 2>&1; then
    $SUDO apt-get update -qq >/dev/null && $SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null \
      || echo "setup: could not install libusb-1.0-0; Open3D methods will report 'not available'" >&2
  else
    echo "setup: no apt-get; install libusb-1.0 by hand for Open3D" >&2
  fi
fi
# compile the numba kernels once now (cached on disk), so the first mesh is not slowed by it
echo "setup: compiling the fast path (about 10 s, once)" >&2
.venv/bin/python -c "import numpy as np, contourmesh; contourmesh.mesh(np.pad(np.ones((3, 4, 5), bool), 1))" \
  || echo "setup: warming the numba cache failed; the first call will compile instead" >&2
echo "setup: ready (.venv)" >&2
