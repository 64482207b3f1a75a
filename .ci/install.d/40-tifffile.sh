#!/usr/bin/env bash
# tifffile (and numpy) write the TIFF layouts nsrm must read that its own encoder cannot make:
# planar-separate tiled floats with partial edge tiles, RGB + extra samples (tests/all/harden_tiff.rs).
set -euo pipefail
if ! python3 -c 'import tifffile, numpy' >/dev/null 2>&1; then
  pip install -q tifffile numpy || pip install -q --break-system-packages tifffile numpy
fi
