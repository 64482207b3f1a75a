#!/usr/bin/env python3
"""Seeds of the fuzz targets `ljpeg_dng` and `jpeg_read` (run by make.py; needs Pillow).

ljpeg_dng: lossless-JPEG DNGs written by hand (a 32×32 RGGB mosaic in one 32×32 tile, or in
two strips; the entropy data is every difference 0, a 5-bit code each: a valid stream of a
flat frame) and the hostile variants of issue 42 (a frame header of 65535×65535, data that
stops after ten bytes, a Huffman table with no code, a tile larger than the image, an IFD chain
that loops). jpeg_read: JPEGs from Pillow, cut at 80 %, and one whose header declares
16000×16000 over its few kilobytes.
"""
import io
import os
import struct

from PIL import Image

S = "fuzz/seeds"


def write(path, data):
    with open(path, "wb") as f:
        f.write(data)


def ljpeg(w, h, rows=None):
    """A lossless-JPEG stream of w×h one-component 16-bit samples, every difference 0."""
    sof = struct.pack(">BHHB", 16, h, w, 1) + bytes([1, 0x11, 0])
    counts = bytes([0, 0, 0, 0, 17] + [0] * 11)
    dht = bytes([0]) + counts + bytes(range(17))
    sos = bytes([1, 1, 0x00, 1, 0, 0])
    seg = lambda m, body: bytes([0xFF, m]) + struct.pack(">H", len(body) + 2) + body
    data = bytes((w * h * 5 + 7) // 8)
    return b"\xff\xd8" + seg(0xC3, sof) + seg(0xC4, dht) + seg(0xDA, sos) + data + b"\xff\xd9"


def dng(w, h, segments, tiled, next_ifd=0, tile=None):
    """A little-endian DNG with one raw IFD (IFD0) of JPEG-compressed (7) CFA data."""
    entries = []
    extra = bytearray()
    n_tags = 20
    ifd_at = 8
    data_at = ifd_at + 2 + 12 * n_tags + 4
    blobs = []

    def place(b):
        at = data_at + len(extra) + sum(len(x) for x in blobs)
        blobs.append(b)
        return at

    seg_offs = [place(s) for s in segments]
    counts = [len(s) for s in segments]

    def arr(vals):
        if len(vals) == 1:
            return 4, 1, vals[0]
        return 4, len(vals), place(struct.pack(f"<{len(vals)}I", *vals))

    tw, th = tile or (w, h)
    tags = {
        254: (4, 1, 0), 256: (4, 1, w), 257: (4, 1, h), 258: (3, 1, 16), 259: (3, 1, 7),
        262: (3, 1, 32803), 271: (2, 4, int.from_bytes(b"Nsr\0", "little")),
        272: (2, 4, int.from_bytes(b"Fuz\0", "little")), 277: (3, 1, 1),
        33421: (3, 2, 2 | (2 << 16)), 33422: (1, 4, int.from_bytes(bytes([0, 1, 1, 2]), "little")),
        50706: (1, 4, int.from_bytes(bytes([1, 4, 0, 0]), "little")),
        50708: (2, 4, int.from_bytes(b"Fuz\0", "little")),
        50714: (4, 1, 0), 50717: (4, 1, 65535),
    }
    if tiled:
        tags[322] = (4, 1, tw)
        tags[323] = (4, 1, th)
        tags[324] = arr(seg_offs)
        tags[325] = arr(counts)
    else:
        tags[273] = arr(seg_offs)
        tags[278] = (4, 1, h // len(segments))
        tags[279] = arr(counts)
    while len(tags) < n_tags:
        tags[65000 + len(tags)] = (1, 1, 0)
    ifd = struct.pack("<H", n_tags)
    for t in sorted(tags):
        typ, cnt, val = tags[t]
        ifd += struct.pack("<HHII", t, typ, cnt, val)
    ifd += struct.pack("<I", next_ifd)
    return b"II*\0" + struct.pack("<I", ifd_at) + ifd + bytes(extra) + b"".join(blobs)


D = f"{S}/ljpeg_dng"
J = f"{S}/jpeg_read"
os.makedirs(D, exist_ok=True)
os.makedirs(J, exist_ok=True)
write(f"{D}/tile_32x32.dng", dng(32, 32, [ljpeg(32, 32)], True))
write(f"{D}/strips_32x32.dng", dng(32, 32, [ljpeg(32, 16), ljpeg(32, 16)], False))
huge = bytearray(ljpeg(32, 32))
huge[7:11] = b"\xff\xff\xff\xff"
write(f"{D}/sof_65535.dng", dng(32, 32, [bytes(huge)], True))
short = ljpeg(32, 32)
write(f"{D}/ten_bytes.dng", dng(32, 32, [short[: short.find(b"\xff\xda") + 10 + 10] + b"\xff\xd9"], True))
empty = bytearray(ljpeg(32, 32))
at = empty.find(b"\xff\xc4") + 5
empty[at : at + 16] = bytes(16)
write(f"{D}/empty_table.dng", dng(32, 32, [bytes(empty)], True))
write(f"{D}/tile_too_large.dng", dng(32, 32, [ljpeg(128, 128)], True, tile=(128, 128)))
write(f"{D}/ifd_loop.dng", dng(32, 32, [ljpeg(32, 32)], True, next_ifd=8))

img = Image.new("RGB", (64, 48))
img.putdata([((x * 4) % 256, (y * 5) % 256, ((x + y) * 3) % 256) for y in range(48) for x in range(64)])
buf = io.BytesIO()
img.save(buf, "JPEG", quality=90)
whole = buf.getvalue()
write(f"{J}/whole_64x48.jpg", whole)
buf = io.BytesIO()
img.save(buf, "JPEG", quality=75, progressive=True)
write(f"{J}/progressive_64x48.jpg", buf.getvalue())
write(f"{J}/cut_80.jpg", whole[: len(whole) * 8 // 10])
sof = whole.find(b"\xff\xc0")
inflated = bytearray(whole)
inflated[sof + 5 : sof + 9] = struct.pack(">HH", 16000, 16000)
write(f"{J}/inflated_16000.jpg", bytes(inflated))
