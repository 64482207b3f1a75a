#!/usr/bin/env python3
"""An independent oracle for the paper's experiment (Table 1): colour-science and numpy only.

Simulates camera RGB and XYZ from spectra, fits LRM, PRM, RPRM (colour-science's
Finlayson 2015 expansions) and NSRM (the paper's definition, written here from it) by plain
least squares (numpy's lstsq) in every leave-one-out fold, and prints each patch's CIEDE2000
(colour-science's) as JSON: {"<illuminant>/<model>": {"<label>": dE00, ...}, ...}.

Nothing here comes from nsrm's code: the spectral sums, the term expansions, the solve, Lab
and CIEDE2000 are numpy's and colour-science's. tests/all/table1_oracle.rs compares the
result with `nsrm eval --json`.

usage: table1_oracle.py CAMERA.csv REFLECTANCES.csv CMF.csv PATCHES ILLUMINANT.csv...
  PATCHES: `all`, or a block `B2:M9` of a chart whose labels are a letter and a number.
"""
import csv
import json
import re
import sys
import warnings

import numpy as np

warnings.filterwarnings("ignore")
import colour  # noqa: E402
from colour.characterisation import polynomial_expansion_Finlayson2015  # noqa: E402

GRID = np.arange(400.0, 701.0, 10.0)


def table(path):
    """A CSV's header and its rows as floats."""
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r and not r[0].startswith("#")]
    header = rows[0]
    data = np.array([[float(v) for v in r] for r in rows[1:]])
    return header, data


def on_grid(wl, values):
    """Linear interpolation onto GRID, zero outside the table's range."""
    return np.interp(GRID, wl, values, left=0.0, right=0.0)


def columns(path):
    header, data = table(path)
    wl = data[:, 0]
    return header[1:], np.stack([on_grid(wl, data[:, j]) for j in range(1, data.shape[1])], axis=1)


def select(labels, spec):
    if spec == "all":
        return list(range(len(labels)))
    m = re.fullmatch(r"([A-Z])(\d+):([A-Z])(\d+)", spec)
    r0, c0, r1, c1 = m.group(1), int(m.group(2)), m.group(3), int(m.group(4))
    keep = []
    for i, lab in enumerate(labels):
        lm = re.fullmatch(r"([A-Z])(\d+)", lab)
        if lm and r0 <= lm.group(1) <= r1 and c0 <= int(lm.group(2)) <= c1:
            keep.append(i)
    return keep


def expand(kind, rgb):
    """The design rows of each model (order 3) and the per-patch output scale."""
    ones = np.ones(len(rgb))
    if kind == "lrm":
        return rgb, ones
    if kind == "prm":
        return polynomial_expansion_Finlayson2015(rgb, 3, False), ones
    if kind == "rprm":
        return polynomial_expansion_Finlayson2015(rgb, 3, True), ones
    # NSRM: s = R+G+B, r = R/s, g = G/s, (alpha, beta, gamma) = M p(r, g), XYZ = s (alpha, beta, gamma),
    # p every monomial r^i g^j with i + j <= 3.
    s = rgb.sum(axis=1)
    r, g = rgb[:, 0] / s, rgb[:, 1] / s
    p = np.stack([r**i * g ** (d - i) for d in range(4) for i in range(d, -1, -1)], axis=1)
    return p, s


def loo(kind, rgb, xyz):
    """Leave-one-out predictions of XYZ."""
    a, s = expand(kind, rgb)
    t = xyz / s[:, None]
    out = np.empty_like(xyz)
    for i in range(len(rgb)):
        keep = np.arange(len(rgb)) != i
        m, *_ = np.linalg.lstsq(a[keep], t[keep], rcond=None)
        out[i] = (a[i] @ m) * s[i]
    return out


def main(argv):
    camera, refl, cmf, patches, *illuminants = argv
    _, cam = columns(camera)
    labels, rho = columns(refl)
    _, xbar = columns(cmf)
    keep = select(labels, patches)
    labels, rho = [labels[i] for i in keep], rho[:, keep]
    result = {}
    for ill_path in illuminants:
        _, e = columns(ill_path)
        e = e[:, 0]
        name = re.sub(r"^illuminant_|\.csv$", "", ill_path.rsplit("/", 1)[-1])
        white_xyz = (xbar * e[:, None]).sum(axis=0)
        white_rgb = (cam * e[:, None]).sum(axis=0)
        xyz = (rho.T * e) @ xbar * (100.0 / white_xyz[1])
        rgb = (rho.T * e) @ cam / white_rgb[1]
        white = white_xyz * (100.0 / white_xyz[1])
        white_xy = colour.XYZ_to_xy(white / 100.0)
        lab_ref = colour.XYZ_to_Lab(xyz / 100.0, white_xy)
        for kind in ["lrm", "prm", "rprm", "nsrm"]:
            pred = loo(kind, rgb, xyz)
            lab = colour.XYZ_to_Lab(pred / 100.0, white_xy)
            de = colour.delta_E(lab_ref, lab, method="CIE 2000")
            result[f"{name}/{kind}"] = dict(zip(labels, (float(v) for v in de)))
    json.dump(result, sys.stdout)


if __name__ == "__main__":
    main(sys.argv[1:])
