#!/usr/bin/env bash
# Fails (listing the files) when a C++ source differs from what clang-format makes of it with
# the repository's .clang-format. Run by ctest as the "format" test; fix with
#   clang-format -i $(git ls-files '*.cpp' '*.h')
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || { echo "check-format: clang-format is not installed" >&2; exit 1; }
mapfile -t files < <(find src tests bench tools fuzz python -name '*.cpp' -o -name '*.h' | sort)
bad=()
for f in "${files[@]}"; do
    clang-format --dry-run --Werror "$f" >/dev/null 2>&1 || bad+=("$f")
done
if ((${#bad[@]})); then
    echo "check-format: ${#bad[@]} of ${#files[@]} files need clang-format: ${bad[*]}" >&2
    exit 1
fi
echo "check-format: ${#files[@]} files formatted"
