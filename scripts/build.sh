#!/usr/bin/env bash
# Configures and builds pumeta into build/ (Release, Ninja, ccache).
#   scripts/build.sh [CMAKE_OPTION...]   everything: library, CLI, tests, benchmarks
# PUMETA_BUILD_TARGETS="pumeta_cli ..." builds only those targets (scripts/demo.sh builds the
# CLI alone, so that the first upsampled point does not wait for the test suite).
set -euo pipefail
cd "$(dirname "$0")/.."
export CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
targets=()
for target in ${PUMETA_BUILD_TARGETS:-}; do targets+=(--target "$target"); done
cmake --build build -j"$(nproc)" "${targets[@]}"
