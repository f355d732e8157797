#!/usr/bin/env bash
# The study benchmark of docs/benchmarks.md: 40 rig sessions (4 subjects, both hands, three
# conditions, 3 s each at 640×400; two of them corrupt) processed by `tremorscan batch` into the table, the
# per-session outputs, C3D and Motion-BIDS; then the same command again (everything up to date).
# Prints the timings and the outcome. Usage: scripts/study-benchmark.sh TREMORSCAN_BINARY WORKDIR
set -euo pipefail
bin=$1
work=$2
rm -rf "$work"
mkdir -p "$work/study"
subjects=(P-101 P-102 P-103 P-104)
hands=(left right)
conditions=(rest posture "rest, dual task")
amplitudes=(2 5 8 12 3 6 10 4)
start=$(date +%s.%N)
# Eight distinct recordings (rendering is the slow part: about 20 s each at 640×400), each used
# by five trials: a trial is a copy (frames hard-linked) with its own trial metadata.
for b in $(seq 0 7); do
    "$bin" simulate --out "$work/base/$b" --frames 363 --amplitude-mm "${amplitudes[$b]}" \
        --seed "$((b + 1))" --subject base --control-point "index tip=210,134" \
        --control-point "wrist=450,190" >/dev/null
done
k=0
for subject in "${subjects[@]}"; do
    for trial in $(seq 1 10); do
        dir="$work/study/$subject/trial-$trial"
        mkdir -p "$dir"
        cp -al "$work/base/$((k % 8))/frames" "$dir/frames"
        python3 - "$work/base/$((k % 8))/session.json" "$dir/session.json" "$subject" \
            "${hands[$((trial % 2))]}" "${conditions[$((trial % 3))]}" <<'PY'
import json, sys
src, dst, subject, hand, condition = sys.argv[1:]
m = json.load(open(src))
m["trial"].update(subject_id=subject, hand=hand, condition=condition)
json.dump(m, open(dst, "w"))
PY
        k=$((k + 1))
    done
done
simulated=$(date +%s.%N)
# Two corrupt sessions: a manifest cut short, and a frame cut short.
head -c 200 "$work/study/P-102/trial-3/session.json" >"$work/study/P-102/trial-3/session.json.cut"
mv "$work/study/P-102/trial-3/session.json.cut" "$work/study/P-102/trial-3/session.json"
frame="$work/study/P-104/trial-7/frames/000200.png"
head -c 1000 "$frame" >"$frame.cut" && mv "$frame.cut" "$frame"

run() {
    local t0 t1
    t0=$(date +%s.%N)
    "$bin" batch "$work/study" --out "$work/results" --bids "$work/bids" "$@" \
        >>"$work/batch.log" 2>&1 || true
    t1=$(date +%s.%N)
    echo "$t1 - $t0" | bc
}
first=$(run)
second=$(run)
echo "simulate: $(echo "$simulated - $start" | bc) s"
echo "batch, first run: $first s"
echo "batch, second run: $second s ($(echo "scale=2; 100 * $second / $first" | bc) % of the first)"
echo "rows: $(($(wc -l <"$work/results/study.csv") - 1))"
echo "rows with an error: $(($(grep -c -v ',$' "$work/results/study.csv" || true) - 1))"
tail -n 2 "$work/batch.log"
echo "C3D files: $(find "$work/results" -name '*.c3d' | wc -l)"
echo "BIDS motion files: $(find "$work/bids" -name '*_motion.tsv' | wc -l)"
if command -v bids-validator-deno >/dev/null; then
    bids-validator-deno --format json --max-rows -1 "$work/bids" | python3 -c '
import json, sys, collections
d = json.load(sys.stdin)
c = collections.Counter(i["severity"] for i in d["issues"]["issues"])
print("BIDS validator (%s): %d errors, %d warnings" % ("bids-validator-deno", c["error"], c["warning"]))'
fi
