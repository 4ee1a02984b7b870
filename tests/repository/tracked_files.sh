#!/usr/bin/env bash
# ctest "tracked_files": no tracked file outside models/ is larger than 5 MiB. Run states and
# intermediate checkpoints stay outside git (commit shipped weights, logs and READMEs only), so
# that the repository stops growing. The files of legacy_large_files.txt were committed before
# this rule and are being untracked a few at a time (a commit that removes them all at once is
# too large to submit); the list may only shrink: an entry no longer tracked must leave it.
# Usage: tracked_files.sh SOURCE_DIR
set -euo pipefail
cd "$1"
git rev-parse --is-inside-work-tree >/dev/null 2>&1 || { echo "tracked_files: not a git checkout"; exit 77; }
legacy=tests/repository/legacy_large_files.txt
limit=$((5 * 1024 * 1024))
status=0
while IFS= read -r -d '' file; do
    [[ $file == models/* ]] && continue
    [[ -f $file ]] || continue
    size=$(stat -c %s "$file")
    ((size > limit)) || continue
    grep -qxF "$file" "$legacy" && continue
    echo "tracked_files: $file is $size bytes, over 5 MiB outside models/; keep run states and checkpoints outside git"
    status=1
done < <(git ls-files -z)
while IFS= read -r file; do
    [[ -z $file || $file == \#* ]] && continue
    git ls-files --error-unmatch -- "$file" >/dev/null 2>&1 ||
        { echo "tracked_files: $file is no longer tracked; remove it from $legacy"; status=1; }
done <"$legacy"
exit $status
