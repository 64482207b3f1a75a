#!/usr/bin/env python3
"""Rebuilds the committed seed corpus of the fuzz targets (fuzz/seeds/TARGET/).

Usage: python3 fuzz/seeds/make.py [NSRM]   (NSRM: the nsrm binary, default target/debug/nsrm;
needs numpy, tifffile and OpenEXR's Python bindings). Run from the repository root. Each target
gets a few valid inputs (written by nsrm itself or by the reference libraries) and damaged copies
of them (truncated, bytes flipped, a size field made huge); `.ci/fuzz-run` replays them all.
"""
import os
import subprocess
import sys
import tempfile

import numpy as np
import OpenEXR
import tifffile

NSRM = sys.argv[1] if len(sys.argv) > 1 else "target/debug/nsrm"
S = "fuzz/seeds"
TARGETS = ["exr_read", "tiff_read", "model_json", "measured_csv", "chart_reference"]


def write(path, data):
    with open(path, "wb" if isinstance(data, bytes) else "w") as f:
        f.write(data)


def damage(src, prefix):
    """A truncated copy and one with every seventh of the last two thirds' bytes flipped."""
    b = open(src, "rb").read()
    write(prefix + ".truncated", b[: len(b) // 2])
    m = bytearray(b)
    for i in range(len(m) // 3, len(m), max(1, len(m) // 7)):
        m[i] ^= 0xA5
    write(prefix + ".flipped", bytes(m))


def nsrm(*args):
    subprocess.run([NSRM, *args], check=True, stdout=subprocess.DEVNULL)


for t in TARGETS:
    os.makedirs(f"{S}/{t}", exist_ok=True)

with tempfile.TemporaryDirectory() as tmp:
    # A 7×7 chart frame of four patches, as `nsrm render-chart` writes it (EXR and TIFF).
    chart = ["--patches", "patch1,patch2,patch3,patch19", "--patch-size", "2", "--gap", "1",
             "--columns", "2"]
    os.mkdir(f"{tmp}/t")  # each frame writes its layout beside it
    nsrm("render-chart", *chart, "-o", f"{tmp}/c.exr")
    nsrm("render-chart", *chart, "-o", f"{tmp}/t/c.tif")
    os.replace(f"{tmp}/c.exr", f"{S}/exr_read/chart_7x7.exr")
    os.replace(f"{tmp}/t/c.tif", f"{S}/tiff_read/chart_7x7.tif")
    # Fitted models of each kind, as `nsrm fit` writes them.
    for kind, order in [("lrm", 1), ("rprm", 2), ("nsrm", 2), ("prm", 3)]:
        nsrm("fit", "--kind", kind, "--order", str(order), "-o", f"{S}/model_json/{kind}.json",
             "--overwrite")

y, x = np.mgrid[0:18, 0:18].astype(np.float32)
planes = np.stack([x / 17, y / 17, (x + y) / 34]).astype(np.float32)
rgb = np.ascontiguousarray(np.moveaxis(planes, 0, -1)[:5, :6])
# Planar-separate, tiled float TIFF with partial edge tiles (issue 19, family 4), 16-bit RGB,
# deflate-compressed float RGB.
tifffile.imwrite(f"{S}/tiff_read/planar_tiled.tif", planes, planarconfig="separate",
                 tile=(16, 16), photometric="rgb", compression="zlib")
tifffile.imwrite(f"{S}/tiff_read/rgb16.tif", (rgb * 65535).astype(np.uint16), photometric="rgb")
tifffile.imwrite(f"{S}/tiff_read/rgb_deflate.tif", rgb, photometric="rgb", compression="zlib")
# Scan-line EXRs: ZIP and uncompressed float, PIZ half.
for comp, name, px in [(OpenEXR.ZIP_COMPRESSION, "zip", rgb),
                       (OpenEXR.PIZ_COMPRESSION, "piz", rgb.astype(np.float16)),
                       (OpenEXR.NO_COMPRESSION, "none", rgb)]:
    header = {"compression": comp, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": px}).write(f"{S}/exr_read/small_{name}.exr")

for t, f in [("exr_read", "chart_7x7.exr"), ("exr_read", "small_piz.exr"),
             ("tiff_read", "chart_7x7.tif"), ("tiff_read", "planar_tiled.tif"),
             ("model_json", "rprm.json")]:
    damage(f"{S}/{t}/{f}", f"{S}/{t}/damaged_" + f.rsplit(".", 1)[0])

# An EXR header whose data window claims 2^20 × 2^20 pixels (refused by the reader's limit).
b = bytearray(open(f"{S}/exr_read/small_none.exr", "rb").read())
i = b.find(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
b[i + 8 : i + 16] = (1 << 20).to_bytes(4, "little") * 2
write(f"{S}/exr_read/huge_data_window.exr", bytes(b))

# Model JSON: an overflowing coefficient, an unknown kind.
lrm = open(f"{S}/model_json/lrm.json").read()
write(f"{S}/model_json/overflow.json",
      lrm.replace('"matrix": [\n    [\n', '"matrix": [\n    [\n      1e309,\n', 1))
write(f"{S}/model_json/unknown_kind.json", lrm.replace('"kind": "lrm"', '"kind": "xyz"'))

# Measured patches (`--training`), by hand.
M = f"{S}/measured_csv"
D50 = "# white: 96.42,100,82.49\n"
write(f"{M}/xyz_with_white.csv", D50 + "label,R,G,B,X,Y,Z\nA1,0.12,0.08,0.05,11.1,10.0,5.2\n"
      "A2,0.40,0.35,0.28,38.5,35.8,26.9\nA3,0.9,0.95,0.85,90.1,94.0,78.2\n")
write(f"{M}/lab.csv", "label,R,G,B,L,a,b\nA1,0.12,0.08,0.05,37.5,14.4,14.9\n"
      "A2,0.40,0.35,0.28,64.7,19.3,17.5\nA3,0.9,0.95,0.85,96.5,-0.4,1.2\n")
write(f"{M}/short_row.csv", D50 + "label,R,G,B,X,Y,Z\nA1,0.12,0.08,0.05,11.1,10.0\n")
write(f"{M}/non_finite.csv", D50 + "label,R,G,B,X,Y,Z\nA1,nan,0.08,0.05,11.1,10.0,5.2\n"
      "A2,1e309,0.35,0.28,38.5,35.8,26.9\n")
write(f"{M}/white_conflict.csv",
      "# white: 95.04,100,108.88\nlabel,R,G,B,X,Y,Z\nA1,0.12,0.08,0.05,11.1,10.0,5.2\n")

# Chart references: the first byte picks (bit 0 CGATS, bit 1 SG, bit 2 a white given).
R = f"{S}/chart_reference"
ref = open("assets/chart_cc24_after2014_d50.csv").read()
rows = ref.strip().split("\n")[1:]
cg = ("CGATS.17\nORIGINATOR \"hand\"\nNUMBER_OF_FIELDS 4\nBEGIN_DATA_FORMAT\n"
      "SAMPLE_ID LAB_L LAB_A LAB_B\nEND_DATA_FORMAT\n"
      f"NUMBER_OF_SETS {len(rows)}\nBEGIN_DATA\n")
for row in rows:
    p = row.split(",")
    cg += f"{p[0].split()[0]} {p[4]} {p[5]} {p[6]}\n"
cg += "END_DATA\n"
write(f"{R}/cc24_lab_csv", "\x04" + ref)
write(f"{R}/cc24_lab_cgats", "\x05" + cg)
write(f"{R}/cc24_lab_cgats_no_white", "\x01" + cg)
write(f"{R}/sg_given_cc24_csv", "\x06" + ref)
write(f"{R}/cc24_truncated_csv", "\x04" + ref[: len(ref) // 2])
write(f"{R}/cc24_cgats_bad_sets", "\x05" + cg.replace("NUMBER_OF_SETS 24", "NUMBER_OF_SETS 99999999999"))

# The lossless-JPEG DNG and JPEG seeds (Pillow).
subprocess.run([sys.executable, "fuzz/seeds/make_jpeg.py"], check=True)
