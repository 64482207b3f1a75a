#!/usr/bin/env python3
"""Chart detection on altered copies of real photographs: is every reading still right?

For each photograph nsrm reads (`nsrm chart extract --chart cc24 --json`), altered copies are
written (JPEG, quality 90 unless said) and read again; each copy's patch centres must land within a
quarter pitch of the original reading mapped through the same alteration. That original reading is
the reference (check it by eye first, with `--overlay`): the copies test that detection does not
depend on the photograph's scale, orientation, exposure, white balance or framing, without any
other ground truth. Counts: found right, refused, found **wrong** (any patch off by more than a
quarter pitch). Photographs nsrm refuses are skipped.

    python3 benches/chart_altered_copies.py [--nsrm target/release/nsrm] [--out DIR] FILES…

The alterations: half and quarter size; JPEG quality 40; turned 180° and 30° (grey fill); long side
800 px; 1.5 stops darker and a warm cast (R ×1.25, B ×0.65), both in linear sRGB; cropped to the
chart (0.9 pitch beyond the outer patch centres). Needs numpy and Pillow.
"""
import argparse, json, math, os, subprocess, sys, tempfile

import numpy as np
from PIL import Image


def read(nsrm, path, tmp):
    csv, js = os.path.join(tmp, "r.csv"), os.path.join(tmp, "r.json")
    r = subprocess.run(
        [nsrm, "chart", "extract", "--chart", "cc24", path, "--output", csv, "--json", js, "--overwrite"],
        capture_output=True, text=True,
    )
    if r.returncode != 0:
        last = r.stderr.strip().splitlines()
        return None, (last[0] if last else "")[:160]
    with open(js) as f:
        return {p["label"]: p["centre"] for p in json.load(f)["patches"]}, ""


def linear(a):
    a = a / 255.0
    return np.where(a <= 0.04045, a / 12.92, ((a + 0.055) / 1.055) ** 2.4)


def encode(lin):
    lin = np.clip(lin, 0, 1)
    e = np.where(lin <= 0.0031308, lin * 12.92, 1.055 * lin ** (1 / 2.4) - 0.055)
    return Image.fromarray((e * 255 + 0.5).astype(np.uint8))


def copies(im, reading):
    """(name, image, map of an original pixel position, scale) for each alteration."""
    w, h = im.size
    out = []
    for s in (0.5, 0.25):
        out.append((f"s{s}", im.resize((int(w * s), int(h * s)), Image.LANCZOS), lambda p, s=s: (p[0] * s, p[1] * s), s))
    out.append(("q40", im, lambda p: p, 1.0))
    out.append(("r180", im.rotate(180), lambda p: (w - p[0], h - p[1]), 1.0))
    r = im.rotate(30, expand=True, fillcolor=(128, 128, 128))
    W, H = r.size
    t = math.radians(30)

    def turn(p):
        x, y = p[0] - w / 2, p[1] - h / 2
        return (W / 2 + x * math.cos(t) + y * math.sin(t), H / 2 - x * math.sin(t) + y * math.cos(t))

    out.append(("rot30", r, turn, 1.0))
    s = 800 / max(w, h)
    out.append(("s800", im.resize((int(w * s), int(h * s)), Image.LANCZOS), lambda p, s=s: (p[0] * s, p[1] * s), s))
    lin = linear(np.asarray(im).astype(float))
    out.append(("dark", encode(lin * 2 ** -1.5), lambda p: p, 1.0))
    out.append(("cast", encode(lin * np.array([1.25, 1.0, 0.65])), lambda p: p, 1.0))
    pitch = math.dist(reading["01 dark skin"], reading["02 light skin"])
    xs = [p[0] for p in reading.values()]
    ys = [p[1] for p in reading.values()]
    m = 0.9 * pitch
    x0, y0 = max(0, int(min(xs) - m)), max(0, int(min(ys) - m))
    x1, y1 = min(w, int(max(xs) + m)), min(h, int(max(ys) + m))
    out.append(("crop", im.crop((x0, y0, x1, y1)), lambda p: (p[0] - x0, p[1] - y0), 1.0))
    return pitch, out


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser()
    ap.add_argument("--nsrm", default=os.path.join(root, "target", "release", "nsrm"))
    ap.add_argument("--out", help="keep the copies here (default: a temporary folder)")
    ap.add_argument("files", nargs="+")
    a = ap.parse_args()
    tmp = tempfile.TemporaryDirectory()
    out = a.out or tmp.name
    os.makedirs(out, exist_ok=True)
    right = refused = wrong = 0
    for f in a.files:
        original, why = read(a.nsrm, f, tmp.name)
        if original is None:
            print(f"skipped {f}: {why}")
            continue
        base = os.path.splitext(os.path.basename(f))[0]
        pitch, alts = copies(Image.open(f).convert("RGB"), original)
        for name, img, move, scale in alts:
            path = os.path.join(out, f"{base}_{name}.jpg")
            img.save(path, quality=40 if name == "q40" else 90)
            got, why = read(a.nsrm, path, tmp.name)
            if got is None:
                refused += 1
                print(f"refused {base} {name}: {why}")
                continue
            worst = max(math.dist(got[l], move(original[l])) / (pitch * scale) for l in original)
            if worst > 0.25:
                wrong += 1
                print(f"WRONG {base} {name}: a patch {worst:.2f} pitch off")
            else:
                right += 1
    print(f"altered copies: right {right}, refused {refused}, wrong {wrong}")
    sys.exit(1 if wrong else 0)


if __name__ == "__main__":
    main()
