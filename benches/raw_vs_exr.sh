#!/usr/bin/env bash
# A camera raw input against an EXR input of the same size through `nsrm apply --timing`, in the
# same run (BENCHMARKS.md, "Raw frames through the fast writer"). Needs a release build
# (`cargo build --release --bin nsrm`).
#
#   benches/raw_vs_exr.sh [REPS=7] [RAW=../shared/data/colorchart.dng] [NSRM...]
#
# The EXR input is the raw input's own output (the same frame decoded and corrected, ZIP), so
# both rows encode a frame of the same size and statistics. Each repetition runs every binary
# (NSRM..., default ./target/release/nsrm; give an older one too to compare) on the raw file
# and on the EXR, alternately; the table holds the medians of the --timing figures (seconds) and
# of the raw/EXR ratios of the encode stage and of the time after decoding (wall − decode).
set -euo pipefail
cd "$(dirname "$0")/.."
reps="${1:-7}"
raw="${2:-../shared/data/colorchart.dng}"
shift $(($# < 2 ? $# : 2))
bins=("$@")
[ ${#bins[@]} -gt 0 ] || bins=(./target/release/nsrm)
for b in "${bins[@]}"; do
  [ -x "$b" ] || { echo "$b: not built (cargo build --release --bin nsrm)" >&2; exit 1; }
done
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"${bins[0]}" fit -o "$work/m.json" >/dev/null 2>&1
"${bins[0]}" apply --model "$work/m.json" --device cpu -o "$work/exr" "$raw" >/dev/null 2>&1
exr=$(ls "$work"/exr/*.exr)
echo "# $(date -u +%FT%TZ) $(nproc) CPUs ($(lscpu | sed -n 's/^Model name: *//p')), load $(cut -d' ' -f1-3 /proc/loadavg), $reps repetitions"
echo "# raw: $raw; EXR: its output ($(oiiotool --info "$exr" 2>/dev/null | sed 's/.*: *//' || echo ZIP))"
# One line per run: binary input wall decode encode
run() {
  rm -rf "$work/out"
  "$1" apply --model "$work/m.json" --device cpu --timing -o "$work/out" "$2" 2>&1 >/dev/null |
    sed -n "s|timing: wall \([0-9.]*\) s; decode \([0-9.]*\) s, correct [0-9.]* s, encode \([0-9.]*\) s.*|$1 $3 \1 \2 \3|p"
}
for ((i = 0; i < reps; i++)); do
  for b in "${bins[@]}"; do
    run "$b" "$raw" raw
    run "$b" "$exr" exr
  done
done >"$work/runs.txt"
printf '| binary | input | wall s | decode s | encode s | wall − decode s |\n|---|---|---:|---:|---:|---:|\n'
python3 - "$work/runs.txt" <<'EOF'
import sys, statistics as st
rows = [l.split() for l in open(sys.argv[1])]
med = lambda v: st.median(v)
bins = list(dict.fromkeys(r[0] for r in rows))
notes = []
for b in bins:
    by = {k: [r for r in rows if r[0] == b and r[1] == k] for k in ("raw", "exr")}
    for k, rs in by.items():
        w, d, e = ([float(r[i]) for r in rs] for i in (2, 3, 4))
        print(f"| {b} | {k} | {med(w):.3f} | {med(d):.3f} | {med(e):.3f} | {med([a - c for a, c in zip(w, d)]):.3f} |")
    raw, exr = by["raw"], by["exr"]
    enc = med([float(a[4]) / float(c[4]) for a, c in zip(raw, exr)])
    after = med([(float(a[2]) - float(a[3])) / (float(c[2]) - float(c[3])) for a, c in zip(raw, exr)])
    notes.append(f"{b}: raw/EXR encode **{enc:.2f}**, raw/EXR wall − decode **{after:.2f}**")
print("\n(medians of the per-repetition ratios)")
for n in notes:
    print(f"* {n}")
EOF
