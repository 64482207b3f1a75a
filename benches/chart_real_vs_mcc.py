#!/usr/bin/env python3
"""Chart detection on real photographs: nsrm against OpenCV mcc, in one run.

For each photograph: OpenCV mcc's detector call (`CCheckerDetector.process` on the 8-bit image,
MCC24, one chart) and nsrm's detection + extraction (`nsrm chart time`, the file read not timed,
as mcc's imread is not timed), each the median of --repeat runs, and what each found.

    python3 benches/chart_real_vs_mcc.py [--nsrm target/release/nsrm] [--repeat 5] [FILES…]

Default files: $NSRM_SHARED/realcharts/*.{jpg,tif} ($NSRM_SHARED defaults to ../shared). The 8-bit linear TIFF is read by nsrm with
--encoding linear (its NOTICE says so); mcc gets the same 8-bit pixels.
Needs: pip install opencv-contrib-python-headless (.ci/install.d/30-opencv.sh).
"""
import argparse, glob, json, os, statistics, subprocess, sys, time

import cv2


def mcc_time(path, repeat):
    img = cv2.imread(path, cv2.IMREAD_COLOR)
    times, found, box = [], False, None
    for _ in range(repeat):
        d = cv2.mcc.CCheckerDetector.create()
        if hasattr(d, "setColorChartType"):
            d.setColorChartType(cv2.mcc.MCC24)
            t0 = time.perf_counter()
            found = d.process(img, 1)
        else:  # OpenCV 4.x
            t0 = time.perf_counter()
            found = d.process(img, cv2.mcc.MCC24, 1)
        times.append(time.perf_counter() - t0)
        if found:
            box = d.getBestColorChecker().getBox().tolist()
    return statistics.median(times), bool(found), box


def nsrm_time(nsrm, path, repeat):
    enc = "linear" if "linear" in os.path.basename(path) else "auto"
    out = subprocess.run(
        [nsrm, "chart", "time", "--chart", "cc24", "--encoding", enc, "--repeat", str(repeat), path],
        capture_output=True, text=True)
    if out.returncode != 0:
        sys.exit(f"nsrm chart time failed on {path}: {out.stderr}")
    return json.loads(out.stdout.splitlines()[-1])


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.dirname(here)
    ap = argparse.ArgumentParser()
    ap.add_argument("--nsrm", default=os.path.join(root, "target", "release", "nsrm"))
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("files", nargs="*")
    a = ap.parse_args()
    shared = os.environ.get("NSRM_SHARED", os.path.join(root, "..", "shared"))
    files = a.files or sorted(
        glob.glob(os.path.join(shared, "realcharts", "*.jpg"))
        + glob.glob(os.path.join(shared, "realcharts", "*.tif")))
    if not files:
        sys.exit("no photographs (../shared/realcharts)")
    print(f"OpenCV {cv2.__version__}; {a.repeat} runs each, medians")
    print("| photo | pixels | nsrm | nsrm s | mcc | mcc s | nsrm/mcc time |")
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for f in files:
        n = nsrm_time(a.nsrm, f, a.repeat)
        mt, mfound, _ = mcc_time(f, a.repeat)
        ratios.append(n["median_s"] / mt)
        what = "found" if n["outcome"].startswith("found") else "refused"
        print(f"| {os.path.basename(f)} | {n['width']}×{n['height']} | {what} | {n['median_s']:.3f} | "
              f"{'found' if mfound else 'none'} | {mt:.3f} | {n['median_s'] / mt:.2f} |")
    print(f"median time ratio nsrm/mcc: {statistics.median(ratios):.2f}")


if __name__ == "__main__":
    main()
