#!/usr/bin/env bash
# nsrm apply against oiiotool on the same noisy 24-Mpixel float plates, in the same run
# (BENCHMARKS.md, "Batch conversion against oiiotool"). Needs `oiiotool` (apt-get install -y
# openimageio-tools) and a release build (`cargo build --release --bin nsrm --example plates`).
#
#   [NSRM=BINARY] benches/batch_vs_oiiotool.sh [WORKDIR=/dev/shm/nsrm-bench] [COUNT=4] [SIZE=6000x4000] [ROWS]
#
# ROWS (default "zip zips piz none half") picks the table rows; `half` is ZIP in, half ZIP out.
# WORKDIR should be a tmpfs (both tools then write the same way: nsrm fsyncs each output, oiiotool
# does not, which on a slow disk measures the disk). It needs about 3 × COUNT frames of space at a
# time (~0.9 GB per 24-Mpixel float frame) and is removed at the end. Each row prints
# wall seconds for nsrm and oiiotool, their ratio, and nsrm's --timing breakdown and peak RSS.
set -euo pipefail
cd "$(dirname "$0")/.."
work="${1:-/dev/shm/nsrm-bench}"
count="${2:-4}"
size="${3:-6000x4000}"
rows="${4:-zip zips piz none half}"
nsrm="${NSRM:-./target/release/nsrm}"  # NSRM=path: another build, e.g. the previous one
plates=./target/release/examples/plates
command -v oiiotool >/dev/null || { echo "oiiotool not found (apt-get install -y openimageio-tools)" >&2; exit 1; }
[ -x "$nsrm" ] && [ -x "$plates" ] || { echo "build first: cargo build --release --bin nsrm --example plates" >&2; exit 1; }
rm -rf "$work"
mkdir -p "$work"
trap 'rm -rf "$work"' EXIT

"$nsrm" fit --model lrm -o "$work/lrm.json" >/dev/null 2>&1
"$nsrm" export --model "$work/lrm.json" --format clf --output-space xyz --output "$work/lrm.clf" >/dev/null 2>&1
# nsrm's folded matrix (XYZ = M · RGB); oiiotool's --ccmatrix multiplies row vectors: its transpose.
m=$(awk '/<Array/{f=1;next} /<\/Array>/{f=0} f{for(i=1;i<=NF;i++) a[n++]=$i} END{
  printf "%s,%s,%s,%s,%s,%s,%s,%s,%s", a[0],a[3],a[6],a[1],a[4],a[7],a[2],a[5],a[8]}' "$work/lrm.clf")
first=1001
last=$((first + count - 1))
echo "# $(date -u +%FT%TZ) $(nproc) CPUs, load $(cut -d' ' -f1-3 /proc/loadavg), $count × $size float RGB plates, workdir $work"
echo "# $(oiiotool --version 2>&1 | head -1)"
printf '| row | nsrm s | oiiotool s | nsrm/oiiotool | nsrm decode / correct / encode s | nsrm peak RSS | MB out nsrm / oiiotool | load |\n|---|---:|---:|---:|---|---:|---|---:|\n'
for row in $rows; do
  case $row in
    half) incomp=zip; outcomp=zip; half=(--half); depth=half ;;
    *) incomp=$row; outcomp=$row; half=(); depth=float ;;
  esac
  [ "$incomp" = piz ] && oc=piz || oc=$outcomp
  in="$work/in_$incomp"
  if [ ! -d "$in" ]; then
    rm -rf "$work"/in_*
    "$plates" "$in" "$count" "$size" "$incomp" >/dev/null
  fi
  rm -rf "$work/out_n" "$work/out_o"
  mkdir -p "$work/out_n" "$work/out_o"
  sync
  t0=$(date +%s.%N)
  "$nsrm" apply --model "$work/lrm.json" --device cpu --output-space xyz --compression "$outcomp" \
    "${half[@]}" --timing -o "$work/out_n" "$in"/plate.*.exr 2>"$work/timing.txt" >/dev/null
  t1=$(date +%s.%N)
  oiiotool --frames "$first-$last" "$in/plate.#.exr" --ccmatrix "$m" -d "$depth" \
    --compression "$oc" -o "$work/out_o/plate.#.exr"
  t2=$(date +%s.%N)
  tn=$(echo "$t1 - $t0" | bc -l)
  to=$(echo "$t2 - $t1" | bc -l)
  stages=$(sed -n 's/.*decode \([0-9.]*\) s, correct \([0-9.]*\) s, encode \([0-9.]*\) s.*/\1 \/ \2 \/ \3/p' "$work/timing.txt")
  rss=$(sed -n 's/.*peak RSS \([0-9.]*\) MiB.*/\1 MiB/p' "$work/timing.txt")
  mb() { du -sb "$1" | awk '{printf "%.0f", $1 / 1e6}'; }
  printf '| %s | %.2f | %.2f | **%.2f** | %s | %s | %s / %s | %s |\n' "$row" "$tn" "$to" "$(echo "$tn / $to" | bc -l)" \
    "$stages" "$rss" "$(mb "$work/out_n")" "$(mb "$work/out_o")" "$(cut -d' ' -f1 /proc/loadavg)"
  # The same pixels as oiiotool's (to float rounding; half: to half rounding), both read by OpenIIO.
  f=$(ls "$work/out_n" | head -1)
  [ "$depth" = half ] && tol=1e-3 || tol=1e-5
  oiiotool --diff --fail "$tol" --warn "$tol" "$work/out_n/$f" "$work/out_o/plate.$first.exr" >"$work/diff.txt" 2>&1 \
    || { echo "  $row: outputs differ:"; cat "$work/diff.txt"; }
done
