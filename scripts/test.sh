#!/usr/bin/env bash
# The test command: set-up, configure, build, run every test.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
scripts/build.sh -DPUMETA_WERROR=ON
cd build
ctest --output-on-failure -j"$(nproc)" --timeout 900
