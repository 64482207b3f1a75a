"""A chart photograph to a colour-corrected frame, from Python (a notebook-style walk-through).

    python examples/python/calibrate.py [PHOTO] [--chart cc24] [--out DIR]

PHOTO: a camera raw file (DNG, CR2, …) or a linear TIFF/EXR of a ColorChecker; default: the
project's colorchart.dng in $NSRM_SHARED/data (or ../shared/data). Steps:

1. read the chart (nsrm.read_chart, as `nsrm chart extract`);
2. choose a model by leave-one-out ΔE00 (nsrm.eval_loo, as `nsrm eval`) and fit it (nsrm.fit);
3. correct the photograph (nsrm.read_frame + Model.apply, as `nsrm apply`) to linear sRGB;
4. plot the per-patch errors and the corrected frame with matplotlib, if it is installed;
5. save the model (the JSON `nsrm apply --model` reads) and export a .cube.
"""

import argparse
import os
import pathlib

import numpy as np

import nsrm

# %% 0. The photograph.
ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("photo", nargs="?")
ap.add_argument("--chart", default="cc24")
ap.add_argument("--out", default="calibrate-out")
a = ap.parse_args()
here = pathlib.Path(__file__).resolve().parents[2]
shared = pathlib.Path(os.environ.get("NSRM_SHARED", here.parent / "shared"))
photo = pathlib.Path(a.photo) if a.photo else shared / "data" / "colorchart.dng"
out = pathlib.Path(a.out)
out.mkdir(parents=True, exist_ok=True)

# %% 1. Read the chart: patches, their reference XYZ, flags, the corners found.
chart = nsrm.read_chart(photo, a.chart)
t = chart["training"]
print(f"{photo.name}: {sum(chart['usable'])} of {len(chart['labels'])} patches usable; "
      f"corners {np.round(chart['corners']).astype(int).tolist()}")

# %% 2. Choose the model by leave-one-out ΔE00, then fit it on every usable patch.
candidates = [("lrm", 1), ("prm", 2), ("rprm", 2), ("nsrm", 2)]
scores = {}
for kind, order in candidates:
    r = nsrm.eval_loo(t["camera_rgb"], t["xyz"], kind, order, white=t["white_xyz"],
                      labels=t["labels"])
    scores[(kind, order)] = r
    print(f"  {kind.upper()} {order}: leave-one-out ΔE00 mean {r['mean']:.2f}, max {r['max']:.2f}")
kind, order = min(scores, key=lambda k: scores[k]["mean"])
model = nsrm.fit(t["camera_rgb"], t["xyz"], kind, order, white=t["white_xyz"], labels=t["labels"])
print(f"chosen: {model!r}")

# %% 3. Correct the photograph (the GPU where there is one, else the CPU's fast kernels).
rgb = nsrm.read_frame(photo)
try:
    srgb = model.apply(rgb, device="gpu", output_space="linear-srgb")
except nsrm.GpuUnavailableError:
    srgb = model.apply(rgb, output_space="linear-srgb")
print(f"corrected {rgb.shape[1]}x{rgb.shape[0]} pixels")

# %% 4. Plot, if matplotlib is there.
try:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
except ImportError:
    plt = None
    print("matplotlib is not installed: no plot")
if plt is not None:
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 4.5))
    r = scores[(kind, order)]
    ax1.bar(range(len(r["per_patch"])), r["per_patch"])
    ax1.set_xticks(range(len(r["labels"])), [l.split()[0] for l in r["labels"]], fontsize=7)
    ax1.set_ylabel("leave-one-out ΔE00")
    ax1.set_title(f"{kind.upper()} {order}")
    display = np.clip(srgb / max(np.percentile(srgb, 99), 1e-6), 0, 1) ** (1 / 2.2)
    ax2.imshow(display)
    # The chart was read at its own resolution (a raw file: half, one pixel per CFA block).
    corners = chart["corners"] * (rgb.shape[1] / chart["report"]["width"])
    ax2.plot(*np.vstack([corners, corners[:1]]).T, "r-")
    ax2.set_title("corrected (linear sRGB, display gamma)")
    ax2.axis("off")
    fig.tight_layout()
    fig.savefig(out / "calibrate.png", dpi=100)
    print(f"plot: {out / 'calibrate.png'}")

# %% 5. Keep the model; export a LUT for other tools.
model.save(out / "model.json")
e = nsrm.export(model, "cube", out / "model.cube", output_space="linear-srgb")
print(f"model: {out / 'model.json'}; .cube max ΔE00 {e['max_de00']:.3f}")
