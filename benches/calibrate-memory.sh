#!/bin/sh
# Peak memory and time of `robocal calibrate` on large campaigns, by /usr/bin/time -v (Linux):
# WLS on 1000 and 100,000 poses with 2 markers, and FGLS on 1000 poses with 4 markers (the
# noise estimated from the residuals). Prints, per run, the wall time and the peak resident
# set ("Maximum resident set size", kB); the input CSV's size is printed beside it.
#
# Run from the repository: sh benches/calibrate-memory.sh [ROBOCAL] (default: the release
# build, built first). Data go to ${TMPDIR:-/tmp}/robocal-campaigns.
set -eu
robocal=${1:-}
if [ -z "$robocal" ]; then
    cargo build --release --quiet
    robocal=target/release/robocal
fi
dir=${TMPDIR:-/tmp}/robocal-campaigns
mkdir -p "$dir"
for spec in 1000:2 100000:2 1000:4; do
    poses=${spec%:*} markers=${spec#*:}
    file=$dir/campaign-$poses-$markers.csv
    [ -f "$file" ] || cargo run --release --quiet --example make_campaign -- "$poses" "$markers" "$file"
done
marker_flags="--marker 50,0,150 --marker=-40,60,120 --marker 0,-60,90 --marker 40,40,60"
run() {
    label=$1; shift
    /usr/bin/time -v "$robocal" calibrate --model puma560 "$@" >/dev/null 2>"$dir/time.txt" || {
        cat "$dir/time.txt"; exit 1; }
    wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$dir/time.txt")
    peak=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$dir/time.txt")
    echo "$label: wall $wall, peak $peak kB"
}
sigmas="--joint-sigma-deg 0.007,0.007,0.007,0.002,0.002,0.002 --sigma-mm 0.01"
for poses in 1000 100000; do
    file=$dir/campaign-$poses-2.csv
    echo "input $file: $(wc -c <"$file") bytes"
    # shellcheck disable=SC2086
    run "wls, $poses poses, 2 markers" --data "$file" $sigmas --marker 50,0,150 --marker=-40,60,120
done
file=$dir/campaign-1000-4.csv
echo "input $file: $(wc -c <"$file") bytes"
# shellcheck disable=SC2086
run "fgls, 1000 poses, 4 markers" --data "$file" --estimator fgls $marker_flags
