"""Speed of nsrm's Model.apply from Python, against colour-science and numpy, in one run.

Times correcting a 24-Mpixel float32 RGB frame (6000 × 4000):

* nsrm ``Model.apply`` (CPU fast kernels, every core; the GIL released) for LRM, RPRM 3, NSRM 3;
* colour-science's ``apply_matrix_colour_correction`` with the same RPRM 3 (Finlayson 2015 root
  polynomial, degree 3) and LRM matrices fitted on the same patches;
* a plain numpy 3×3 ``rgb @ M.T``.

Prints each time (median of --reps after one warm-up) and the ratios. Nothing is asserted: the
figures depend on the machine (name its CPU when quoting them).

    python examples/python/bench.py [--size 6000x4000] [--reps 3]
"""

import argparse
import platform
import statistics
import time
import warnings

import numpy as np

import nsrm

try:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        from colour.characterisation import (
            apply_matrix_colour_correction,
            matrix_colour_correction,
        )
except ImportError:  # colour-science is optional here
    apply_matrix_colour_correction = None


def timed(f, reps):
    f()  # warm-up
    times = []
    for _ in range(reps):
        t = time.perf_counter()
        f()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", default="6000x4000")
    ap.add_argument("--reps", type=int, default=3)
    a = ap.parse_args()
    w, h = (int(v) for v in a.size.split("x"))
    d = nsrm.builtin_training("nikon-d5100", "D65", "cc24")
    rgb = np.random.default_rng(1).uniform(0.0, 1.0, (h, w, 3)).astype(np.float32)
    mpix = w * h / 1e6
    print(f"{w}x{h} float32 RGB ({mpix:.0f} Mpixel); {platform.processor() or platform.machine()}")

    results = {}
    lrm = nsrm.fit(d["camera_rgb"], d["xyz"], "lrm", white=d["white_xyz"])
    rprm = nsrm.fit(d["camera_rgb"], d["xyz"], "rprm", 3, white=d["white_xyz"], ridge=0)
    nsrm3 = nsrm.fit(d["camera_rgb"], d["xyz"], "nsrm", 3, white=d["white_xyz"])
    results["nsrm LRM"] = timed(lambda: lrm.apply(rgb), a.reps)
    results["nsrm RPRM3"] = timed(lambda: rprm.apply(rgb), a.reps)
    results["nsrm NSRM3"] = timed(lambda: nsrm3.apply(rgb), a.reps)
    out = np.empty_like(rgb)
    results["nsrm LRM, out= preallocated"] = timed(lambda: lrm.apply(rgb, out=out), a.reps)
    results["nsrm NSRM3, out= preallocated"] = timed(lambda: nsrm3.apply(rgb, out=out), a.reps)
    m = lrm.matrix.astype(np.float32)
    results["numpy np.matmul(rgb, M.T, out=) preallocated"] = timed(
        lambda: np.matmul(rgb, m.T, out=out), a.reps
    )
    results["numpy rgb @ M.T (3x3)"] = timed(lambda: rgb @ m.T, a.reps)
    if apply_matrix_colour_correction is not None:
        kw = {"degree": 3, "root_polynomial_expansion": True}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            ccm = matrix_colour_correction(d["camera_rgb"], d["xyz"], "Finlayson 2015", **kw)
            ccm1 = matrix_colour_correction(d["camera_rgb"], d["xyz"], "Finlayson 2015", degree=1)
            results["colour-science RPRM3 (Finlayson 2015)"] = timed(
                lambda: apply_matrix_colour_correction(rgb, ccm, "Finlayson 2015", **kw), a.reps
            )
            results["colour-science LRM (Finlayson 2015, degree 1)"] = timed(
                lambda: apply_matrix_colour_correction(rgb, ccm1, "Finlayson 2015", degree=1),
                a.reps,
            )
    for k, t in results.items():
        print(f"{k:48s} {t * 1e3:9.1f} ms  {mpix / t:8.1f} Mpixel/s")
    print("ratios (time of the other / time of nsrm; > 1: nsrm is faster):")
    pairs = [
        ("numpy rgb @ M.T (3x3)", "nsrm LRM"),
        ("numpy rgb @ M.T (3x3)", "nsrm NSRM3"),
        ("numpy np.matmul(rgb, M.T, out=) preallocated", "nsrm LRM, out= preallocated"),
        ("numpy np.matmul(rgb, M.T, out=) preallocated", "nsrm NSRM3, out= preallocated"),
        ("colour-science LRM (Finlayson 2015, degree 1)", "nsrm LRM"),
        ("colour-science RPRM3 (Finlayson 2015)", "nsrm RPRM3"),
        ("colour-science RPRM3 (Finlayson 2015)", "nsrm NSRM3"),
    ]
    for other, ours in pairs:
        if other in results:
            print(f"  {other} / {ours}: {results[other] / results[ours]:.1f}x")


if __name__ == "__main__":
    main()
