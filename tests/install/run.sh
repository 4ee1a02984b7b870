#!/usr/bin/env bash
# ctest "install": installs the build into a temporary prefix, builds tests/install/consumer
# (a project of its own, one .cpp) against the installed CMake package and runs it with the
# installed models. Usage: run.sh CMAKE BUILD_DIR
set -euo pipefail
cmake=$1
build=$2
consumer=$(cd "$(dirname "$0")/consumer" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

"$cmake" --install "$build" --prefix "$tmp/prefix" >"$tmp/install.log" 2>&1 || { cat "$tmp/install.log" >&2; exit 1; }
prefix=$tmp/prefix
for file in include/pumeta/pumeta.h lib/cmake/pumeta/pumetaConfig.cmake bin/pumeta \
    share/pumeta/models/defaults.json; do
    [[ -e $prefix/$file ]] || { echo "install: $file missing under the prefix" >&2; exit 1; }
done
"$prefix/bin/pumeta" --help >/dev/null

# The compile against LibTorch's headers dominates; no optimisation needed for one file.
"$cmake" -S "$consumer" -B "$tmp/consumer" -DCMAKE_PREFIX_PATH="$prefix" \
    -DCMAKE_BUILD_TYPE= >"$tmp/configure.log" 2>&1 || { cat "$tmp/configure.log" >&2; exit 1; }
"$cmake" --build "$tmp/consumer" >"$tmp/build.log" 2>&1 || { cat "$tmp/build.log" >&2; exit 1; }

# The consumer points the library at the installed models itself (PUMETA_MODELS, from the
# package's pumeta_MODELS_DIR) and checks that the model it loads is one of them.
env -u PUMETA_MODELS "$tmp/consumer/consumer" "$prefix" "$tmp"
