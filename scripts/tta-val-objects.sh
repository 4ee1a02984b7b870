#!/usr/bin/env bash
# Test-time adaptation on whole validation objects (data/dataset/cases/val/x<r>, made by
# make-dataset), for several step sizes α of one adaptation unit: mean CD against the same
# model without adaptation, the self-supervised loss before and after, and the share of
# objects that improved. Validation data only; never the test sets.
#   scripts/tta-val-objects.sh MODEL UNIT STEPS α...
#   scripts/tta-val-objects.sh models/pugcn-x4.pt cloud 5 0.01 0.1 0.3
#   scripts/tta-val-objects.sh models/pugcn-x4-meta.pt object 5 learned   # Meta-SGD sizes
# UNIT "oracle" adapts on each object's ground truth instead of X↓ -> X: what the same N
# steps gain with a perfect signal, a diagnostic reference (docs/design.md), never a result.
# "plain" is the same model without adaptation (for a meta-trained model: its own weights).
# MAX_CASES=N limits the objects (default: all 40); THREADS (default 1); TTA_ARGS: more
# options of every adapted run, e.g. TTA_ARGS="--tta-downsampler fps".
set -euo pipefail
cd "$(dirname "$0")/.."
model=$1 unit=$2 steps=$3
shift 3
build=${PUMETA_BUILD_DIR:-build}
ratio=$("$build/pumeta" info "$model" --json | python3 -c 'import json,sys; print(json.load(sys.stdin)["ratio"])')
cases=data/dataset/cases/val/x$ratio
[ -f "$cases/cases.json" ] || { echo "tta-val-objects: $cases missing (make-dataset builds it)" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
run() {  # name, extra eval args...
    local name=$1
    shift
    "$build/pumeta" --threads "${THREADS:-1}" eval --cases "$cases" --model "$model" \
        ${MAX_CASES:+--max-cases $MAX_CASES} "$@" -o "$work/$name" 2> "$work/log" > /dev/null ||
        { cat "$work/log" >&2; exit 1; }
}
run plain --tta-steps 0
printf '%-8s %-8s %-12s %-12s %-22s %s\n' unit alpha "CD" change "inner loss" "objects better"
for alpha in "$@"; do
    lr=(--tta-lr "$alpha")
    [ "$alpha" = learned ] && lr=()
    # shellcheck disable=SC2086  # TTA_ARGS is a list of options
    run "a$alpha" --tta-steps "$steps" "${lr[@]}" --tta-unit "$unit" ${TTA_ARGS:-}
    python3 - "$unit" "$alpha" "$work/plain/cases.csv" "$work/a$alpha" <<'PY'
import csv, json, sys
unit, alpha, plain_csv, adapted = sys.argv[1:5]
plain = {r["case"]: float(r["cd"]) for r in csv.DictReader(open(plain_csv))}
rows = {r["case"]: float(r["cd"]) for r in csv.DictReader(open(adapted + "/cases.csv"))}
s = json.load(open(adapted + "/summary.json"))
before, after = sum(plain.values()) / len(plain), s["cd"]["mean"]
better = sum(rows[c] < plain[c] for c in rows)
t = s["tta"]
change = "diverged" if after != after else f"{100 * (after - before) / before:+.2f} %"
loss = f"{t['loss_before']['mean']:.3e}->{t['loss_after']['mean']:.3e}"
print(f"{unit:<8} {alpha:<8} {after:<12.5e} {change:<12} {loss:<22} {better}/{len(rows)}")
PY
done
echo "plain CD $(python3 -c "import json;print(json.load(open('$work/plain/summary.json'))['cd']['mean'])")"
