#!/usr/bin/env python3
"""Chart detection on real photographs: nsrm against OpenCV mcc, in one run.

For each photograph, two comparisons, each the median of --repeat runs, and what each found:
* detection alone: OpenCV mcc's detector call (`CCheckerDetector.process` on the 8-bit image,
  MCC24, one chart) against nsrm's detection + extraction (`nsrm chart time`, the file read not
  timed, as mcc's imread is not);
* the whole job: the whole `nsrm chart extract` process (start, read, decode, detect, write the
  CSV) against mcc's `cv2.imread` + detector call in an already running Python (its start and
  import not counted: in mcc's favour).

    python3 benches/chart_real_vs_mcc.py [--nsrm target/release/nsrm] [--repeat 5] [FILES…]

Default files: $NSRM_SHARED/realcharts/*.{jpg,tif} ($NSRM_SHARED defaults to ../shared). The 8-bit linear TIFF is read by nsrm with
--encoding linear (its NOTICE says so); mcc gets the same 8-bit pixels.
Needs: pip install opencv-contrib-python-headless (.ci/install.d/30-opencv.sh).
"""
import argparse, glob, json, os, shutil, statistics, subprocess, sys, tempfile, time

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


def mcc_whole(path, repeat):
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        img = cv2.imread(path, cv2.IMREAD_COLOR)
        d = cv2.mcc.CCheckerDetector.create()
        if hasattr(d, "setColorChartType"):
            d.setColorChartType(cv2.mcc.MCC24)
            d.process(img, 1)
        else:  # OpenCV 4.x
            d.process(img, cv2.mcc.MCC24, 1)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def nsrm_whole(nsrm, path, repeat, out):
    enc = "linear" if "linear" in os.path.basename(path) else "auto"
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        subprocess.run([nsrm, "chart", "extract", "--chart", "cc24", "--encoding", enc, "--overwrite",
                        "-o", out, path], capture_output=True)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


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
    print("| photo | pixels | nsrm | nsrm detect s | mcc | mcc detect s | detect nsrm/mcc "
          "| nsrm process s | mcc read+detect s | whole nsrm/mcc |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    ratios, whole = [], []
    out = os.path.join(tempfile.mkdtemp(prefix="nsrm-mcc-"), "patches.csv")
    for f in files:
        n = nsrm_time(a.nsrm, f, a.repeat)
        mt, mfound, _ = mcc_time(f, a.repeat)
        nw, mw = nsrm_whole(a.nsrm, f, a.repeat, out), mcc_whole(f, a.repeat)
        ratios.append(n["median_s"] / mt)
        whole.append((nw / mw, os.path.basename(f)))
        what = "found" if n["outcome"].startswith("found") else "refused"
        print(f"| {os.path.basename(f)} | {n['width']}×{n['height']} | {what} | {n['median_s']:.3f} | "
              f"{'found' if mfound else 'none'} | {mt:.3f} | {n['median_s'] / mt:.2f} | "
              f"{nw:.3f} | {mw:.3f} | {nw / mw:.2f} |")
    shutil.rmtree(os.path.dirname(out), ignore_errors=True)
    print(f"median time ratio nsrm/mcc, detection: {statistics.median(ratios):.2f}")
    print(f"median time ratio nsrm/mcc, whole job: {statistics.median(r for r, _ in whole):.2f}; "
          f"slowest relative to mcc: {max(whole)[1]} ({max(whole)[0]:.2f})")

if __name__ == "__main__":
    main()
