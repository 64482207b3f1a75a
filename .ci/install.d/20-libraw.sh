#!/usr/bin/env bash
# Judges of the camera-raw reader (tests/all/raw.rs, benches/raw_vs_rawpy.py): LibRaw through PyPI
# `rawpy` and Debian `libraw-bin` (`dcraw_emu`), and `tifffile` + numpy to write synthetic DNGs.
set -euo pipefail
export DEBIAN_FRONTEND=noninteractive
if ! command -v dcraw_emu >/dev/null 2>&1; then
  apt-get update -qq
  apt-get install -y -qq libraw-bin
fi
if ! python3 -c 'import rawpy, tifffile, numpy' >/dev/null 2>&1; then
  pip install -q rawpy tifffile numpy || pip install -q --break-system-packages rawpy tifffile numpy
fi
python3 -c 'import rawpy, tifffile, numpy'
command -v dcraw_emu >/dev/null
