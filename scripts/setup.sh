#!/usr/bin/env bash
# Set up contourmesh in ./.venv (idempotent).
#   bash scripts/setup.sh          core package (enough for `contourmesh reproduce` and `contourmesh mesh`)
#   bash scripts/setup.sh --dev    core + comparison peers (scikit-image, VTK, Open3D, PyMeshLab, DGtal, Dask),
#                                  file readers, Zarr for chunked label volumes and the test tools
# System libraries that a dependency needs (Open3D needs libusb-1.0) are installed with apt-get when missing.
# Every step says what it is doing on stderr, with the seconds it took.
set -euo pipefail
cd "$(dirname "$0")/.."

say() { echo "setup: $*" >&2; }
t_start=$SECONDS
t_step=$SECONDS
done_step() { say "  done in $((SECONDS - t_step)) s"; t_step=$SECONDS; }

extras=""
if [ "${1:-}" = "--dev" ]; then extras="[dev,compare,io,scale]"; fi

py=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  say "creating the virtual environment .venv with $("$py" --version 2>&1) ..."
  "$py" -m venv .venv
  done_step
else
  say "using the existing virtual environment .venv"
fi
say "upgrading pip ..."
.venv/bin/python -m pip install -q --upgrade pip >/dev/null 2>&1 || say "  (could not upgrade pip; going on)"
done_step
if [ -n "$extras" ]; then
  say "installing contourmesh${extras} (editable) with the comparison peers, file readers and test tools; this takes about a minute ..."
else
  say "installing contourmesh (editable) and its core dependencies (numpy, numba, scipy, trimesh, ...) ..."
fi
.venv/bin/python -m pip install -q -e ".${extras}"
done_step

if [ -n "$extras" ] && ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then
  say "installing libusb-1.0-0 (needed by Open3D) ..."
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  if command -v apt-get >/dev/null 2>&1; then
    $SUDO apt-get update -qq >/dev/null && $SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null \
      || say "  could not install libusb-1.0-0; Open3D methods will report 'not available'"
  else
    say "  no apt-get; install libusb-1.0 by hand for Open3D"
  fi
  done_step
fi
# compile the numba kernels that the README's commands use, once (cached on disk), so that the
# first reproduce, contour-file mesh, --refine band and volume do not stop to compile
say "compiling the numba kernels once (about 3 minutes the first time on 2 cores, cached on disk) ..."
.venv/bin/python scripts/warm_kernels.py \
  || say "warming some kernels failed (see above); those first calls will compile instead"
done_step
say "ready in $((SECONDS - t_start)) s: .venv/bin/contourmesh (or: source .venv/bin/activate)"
