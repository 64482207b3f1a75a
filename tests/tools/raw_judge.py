#!/usr/bin/env python3
"""Synthetic CFA DNGs and LibRaw's reading of them, for tests/all/raw.rs and the raw benchmark.

  raw_judge.py dng OUT.dng --width W --height H --pattern RGGB --black B0,B1,B2,B3 --white W
               [--seed N] [--smooth | --flat R,G,B] [--make M --model M] [--bits 16]
               [--orientation 1..8]
      Writes an uncompressed CFA DNG with tifffile (tags of the DNG 1.4 spec, written by hand),
      then checks with rawpy (LibRaw) that it reads back exactly the mosaic written, and writes
      beside it: OUT.dng.half.f32 — the exact block means of max(value - black, 0) /
      (white - smallest black), LibRaw's scale (per colour, the mean of its sites in each 2x2
      block, or 3x3 block for a 36-letter 6x6 X-Trans pattern; row-major, float32
      little-endian) — the truth `half` must give. --flat writes each colour's sites as one
      fraction of the range. --orientation writes the TIFF Orientation tag (274).
  raw_judge.py linear IN.dng OUT.f32 [--flip] [--half]
      LibRaw's LINEAR (bilinear) demosaic of IN, linear camera RGB without white balance or
      matrix, as float32 in [0, 1] (the 16-bit output / 65535), row-major RGB; prints W H.
      Without --flip the sensor's orientation (user_flip=0); with it, the file's orientation
      applied as LibRaw applies it by default. --half: LibRaw's half-size decode instead.
  raw_judge.py same A.dng B.dng
      Whether LibRaw reads the same mosaic, black levels, white level and CFA pattern from both
      files, and the TIFF Compression of each file's CFA image (7: lossless JPEG); prints JSON.
  raw_judge.py bench IN.dng REPEAT
      Seconds per LibRaw decode of IN: postprocess LINEAR, and half_size; prints JSON.
"""
import json
import sys
import time

import numpy as np

COLOURS = {"R": 0, "G": 1, "B": 2}


def write_dng(out, w, h, pattern, black, white, seed, smooth, make, model, bits, flat=None,
              orientation=None, rgb=None):
    import tifffile

    rng = np.random.default_rng(seed)
    # A 2x2 Bayer pattern (4 letters) or a 6x6 X-Trans one (36 letters).
    n = {4: 2, 36: 6}[len(pattern)]
    pat = np.array([COLOURS[c] for c in pattern], dtype=np.uint8).reshape(n, n)
    black = np.array(black, dtype=np.float64).reshape(2, 2)
    if rgb is not None:
        # A given image (little-endian f32 R, G, B per pixel, row by row, in fractions of the
        # range): each site takes its colour's value, above 1 clipped to the white level as a
        # sensor clips.
        img = np.fromfile(rgb, dtype="<f4").reshape(h, w, 3).astype(np.float64)
        col = pat[np.arange(h)[:, None] % n, np.arange(w)[None, :] % n]
        frac = np.minimum(np.take_along_axis(img, col[:, :, None], 2)[:, :, 0], 1.0)
    elif flat is not None:
        # A flat field: each colour's sites hold one value.
        col = pat[np.arange(h)[:, None] % n, np.arange(w)[None, :] % n]
        frac = np.array(flat, dtype=np.float64)[col]
    elif smooth:
        # A smooth colour field (so the interior of a demosaic is well defined) plus noise.
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
        field = np.stack(
            [
                0.5 + 0.4 * np.sin(xx / 23.0 + c) * np.cos(yy / 17.0 - c)
                for c in range(3)
            ]
        )
        col = pat[np.arange(h)[:, None] % n, np.arange(w)[None, :] % n]
        frac = np.take_along_axis(field, col[None], 0)[0]
        frac += rng.normal(0, 0.01, size=frac.shape)
    else:
        frac = rng.uniform(-0.02, 1.0, size=(h, w))
    blk = np.tile(black, (h // 2 + 1, w // 2 + 1))[:h, :w]
    mosaic = np.clip(np.round(blk + frac * (white - blk)), 0, 2**bits - 1).astype(np.uint16)
    cfa_pattern = bytes(int(v) for v in pat.flatten())
    tags = [
        (33421, "H", 2, (n, n), True),  # CFARepeatPatternDim
        (33422, "B", n * n, cfa_pattern, True),  # CFAPattern
        (50706, "B", 4, (1, 4, 0, 0), True),  # DNGVersion
        (50707, "B", 4, (1, 1, 0, 0), True),  # DNGBackwardVersion
        (50708, "s", 0, f"{make} {model}", True),  # UniqueCameraModel
        (50713, "H", 2, (2, 2), True),  # BlackLevelRepeatDim
        (50714, "H", 4, tuple(int(v) for v in black.flatten()), True),  # BlackLevel
        (50717, "I", 1, int(white), True),  # WhiteLevel
        (50721, "2i", 9, (10000, 10000, 0, 10000, 0, 10000, 0, 10000, 10000, 10000,
                          0, 10000, 0, 10000, 0, 10000, 0, 10000), True),  # ColorMatrix1 (identity)
        (50778, "H", 1, 21, True),  # CalibrationIlluminant1: D65
        (50728, "2I", 3, (1, 2, 1, 1, 2, 3), True),  # AsShotNeutral 0.5 1 0.667
        (271, "s", 0, make, True),  # Make
        (272, "s", 0, model, True),  # Model
        (33434, "2I", 1, (1, 125), True),  # ExposureTime
        (34855, "H", 1, 400, True),  # ISOSpeedRatings
    ]
    if orientation is not None:
        tags.append((274, "H", 1, int(orientation), True))  # Orientation
    tifffile.imwrite(
        out,
        mosaic,
        photometric=32803,
        compression=None,
        planarconfig=None,
        extratags=tags,
        metadata=None,
        subfiletype=0,
    )
    # LibRaw must read back exactly what was written.
    import rawpy

    with rawpy.imread(out) as r:
        got = r.raw_image_visible
        if got.shape != mosaic.shape or not np.array_equal(got, mosaic):
            sys.exit(f"LibRaw reads another mosaic than the one written ({got.shape})")
        rp = r.raw_pattern.copy()
        rp[rp == 3] = 1
        if not np.array_equal(rp, pat):
            sys.exit(f"LibRaw reads pattern {r.raw_pattern.tolist()}, written {pat.tolist()}")
        if int(r.white_level) != int(white):
            sys.exit(f"LibRaw reads white {r.white_level}, written {white}")
    # LibRaw's scale: each position's black subtracted, divided by (white - the smallest black).
    scaled = np.maximum(mosaic.astype(np.float64) - blk, 0) / (white - black.min())
    # `half`: one pixel per 2x2 (Bayer) or 3x3 (X-Trans) block, each colour the mean of its
    # sites in the block.
    b = 2 if n == 2 else 3
    oh, ow = h // b, w // b
    half = np.zeros((oh, ow, 3))
    count = np.zeros((oh, ow, 3))
    col = pat[np.arange(h)[:, None] % n, np.arange(w)[None, :] % n]
    for dy in range(b):
        for dx in range(b):
            cs = col[dy : b * oh : b, dx : b * ow : b]
            vs = scaled[dy : b * oh : b, dx : b * ow : b]
            for c in range(3):
                half[:, :, c] += np.where(cs == c, vs, 0)
                count[:, :, c] += cs == c
    half /= count
    half.astype("<f4").tofile(out + ".half.f32")


def libraw_params(rawpy, flip=False, **kw):
    return dict(
        gamma=(1, 1),
        no_auto_bright=True,
        output_bps=16,
        use_camera_wb=False,
        use_auto_wb=False,
        user_wb=[1.0, 1.0, 1.0, 1.0],
        output_color=rawpy.ColorSpace.raw,
        adjust_maximum_thr=0.0,
        user_flip=None if flip else 0,
        **kw,
    )


def linear(inp, out, flip=False, half=False):
    import rawpy

    kw = dict(half_size=True) if half else dict(demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR)
    with rawpy.imread(inp) as r:
        rgb = r.postprocess(**libraw_params(rawpy, flip=flip, **kw))
    (rgb.astype(np.float64) / 65535.0).astype("<f4").tofile(out)
    print(rgb.shape[1], rgb.shape[0])


def bench(inp, repeat):
    import rawpy

    def once(**kw):
        t = time.perf_counter()
        with rawpy.imread(inp) as r:
            r.postprocess(**libraw_params(rawpy, **kw))
        return time.perf_counter() - t

    res = {}
    for name, kw in [
        ("linear", dict(demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR)),
        ("half", dict(half_size=True)),
    ]:
        once(**kw)
        ts = sorted(once(**kw) for _ in range(repeat))
        res[name] = ts[len(ts) // 2]
    print(json.dumps(res))


def cfa_compression(path):
    import tifffile

    with tifffile.TiffFile(path) as t:
        pages = []
        for page in t.pages:
            pages.append(page)
            pages.extend(getattr(page, "pages", []) or [])
            for sub in page.tags.get(330).value if 330 in page.tags else []:
                pages.append(tifffile.TiffPage(t, index=0, offset=sub))
        for page in pages:
            if int(page.photometric) == 32803:
                return int(page.compression)
    return None


def same(a, b):
    import rawpy

    def mosaic(p):
        with rawpy.imread(p) as r:
            return (
                r.raw_image_visible.copy(),
                list(r.black_level_per_channel),
                int(r.white_level),
                r.raw_pattern.tolist(),
            )

    ma, mb = mosaic(a), mosaic(b)
    print(
        json.dumps(
            {
                "mosaic_equal": bool(ma[0].shape == mb[0].shape and (ma[0] == mb[0]).all()),
                "shape": list(mb[0].shape),
                "levels_equal": ma[1:] == mb[1:],
                "compression": [cfa_compression(a), cfa_compression(b)],
            }
        )
    )


def main():
    a = sys.argv[1:]
    if a[0] == "dng":
        import argparse

        p = argparse.ArgumentParser()
        p.add_argument("out")
        p.add_argument("--width", type=int, required=True)
        p.add_argument("--height", type=int, required=True)
        p.add_argument("--pattern", default="RGGB")
        p.add_argument("--black", default="0,0,0,0")
        p.add_argument("--white", type=int, default=65535)
        p.add_argument("--seed", type=int, default=1)
        p.add_argument("--smooth", action="store_true")
        p.add_argument("--make", default="Acme")
        p.add_argument("--model", default="Synth 1")
        p.add_argument("--bits", type=int, default=16)
        p.add_argument("--flat", default=None, help="R,G,B fractions of the range: a flat field")
        p.add_argument("--orientation", type=int, default=None)
        p.add_argument("--rgb", default=None, help="an f32 RGB image (fractions of the range)")
        o = p.parse_args(a[1:])
        flat = [float(v) for v in o.flat.split(",")] if o.flat else None
        black = [float(v) for v in o.black.split(",")]
        if len(black) == 1:
            black = black * 4
        write_dng(o.out, o.width, o.height, o.pattern, black, o.white, o.seed, o.smooth,
                  o.make, o.model, o.bits, flat, o.orientation, o.rgb)
    elif a[0] == "same":
        same(a[1], a[2])
    elif a[0] == "linear":
        linear(a[1], a[2], flip="--flip" in a[3:], half="--half" in a[3:])
    elif a[0] == "bench":
        bench(a[1], int(a[2]))
    else:
        sys.exit(__doc__)


if __name__ == "__main__":
    main()
