#!/usr/bin/env bash
# Plain test-time adaptation of a pretrained model on the validation tasks of a meta-training
# config, for several step sizes α: how CD after N inner steps compares with CD before, and
# the inner (self-supervised) loss before and after. This is how the inner_lr of the meta
# presets and the α of "TTA w/o meta" are chosen (validation data only; never the test sets).
#   scripts/tta-lr-sweep.sh configs/pugcn-x8-meta.json 0.001 0.01 0.03 0.1 0.3
# EXTRA_SET="--set init=runs/pugcn-x4/best.pt" adds config overrides (unquoted words).
set -euo pipefail
cd "$(dirname "$0")/.."
config=$1
shift
build=${PUMETA_BUILD_DIR:-build}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
printf '%-8s %-12s %-12s %-10s %s\n' alpha "CD before" "CD after" change "inner loss before -> after"
for alpha in "$@"; do
    "$build/pumeta" --threads "${THREADS:-1}" meta-train --config "$config" --set steps=0 ${EXTRA_SET:-} \
        --set meta.learn_inner_lr=false --set "meta.inner_lr=$alpha" \
        --set "run_dir=\"$work/$alpha\"" 2> "$work/log" > "$work/out.json" ||
        { cat "$work/log" >&2; exit 1; }
    python3 - "$alpha" "$work/out.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[2]))
before, after = r["val_cd_before"], r["val_cd_after"]
change = "diverged" if after is None or after != after else f"{100 * (after - before) / before:+.2f} %"
print(f"{sys.argv[1]:<8} {before:<12.5e} {after if after is None else format(after, '<12.5e')} {change:<10} {r['val_inner_before']:.4e} -> {r['val_inner_after']:.4e}")
PY
done
