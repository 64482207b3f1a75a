#!/usr/bin/env bash
# Judges of the camera-profile exports (tests/all/profiles*.rs, icc.rs and
# src/model/dual_illuminant_tests.rs): RawTherapee develops a DNG with a DCP, lcms' transicc and
# ArgyllCMS' xicclu apply ICC profiles, exiftool lists DCP tags, colour-hdri (with tifffile and
# numpy) judges the two-illuminant weighting and writes test DNGs.
set -euo pipefail
need=()
command -v rawtherapee-cli >/dev/null || need+=(rawtherapee)
command -v transicc >/dev/null || need+=(liblcms2-utils)
command -v xicclu >/dev/null || need+=(argyll)
command -v exiftool >/dev/null || need+=(libimage-exiftool-perl)
if ((${#need[@]})); then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}"
fi
py=python3
for mod in colour_hdri:colour-hdri tifffile:tifffile numpy:numpy; do
    m=${mod%%:*} pkg=${mod##*:}
    if ! "$py" -c "import $m" 2>/dev/null; then
        pip install -q "$pkg" || pip install -q --break-system-packages "$pkg"
    fi
done
