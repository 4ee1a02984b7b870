#!/usr/bin/env bash
# The test command on a busy machine: one CPU-bound process per core runs beside it, as on a
# developer's workstation during a build or on a shared CI runner. The load is started and
# stopped here, and ends by itself after PUMETA_LOAD_SECONDS (default 5400) whatever happens.
#   scripts/test-under-load.sh [CTEST_ARGUMENT...]   e.g. -R BlasCheck
set -euo pipefail
cd "$(dirname "$0")/.."
limit=${PUMETA_LOAD_SECONDS:-5400}
pids=()
stop_load() { ((${#pids[@]})) && kill "${pids[@]}" 2>/dev/null; wait 2>/dev/null || true; }
trap stop_load EXIT
scripts/setup.sh
scripts/build.sh
for ((core = 0; core < $(nproc); ++core)); do
    timeout "$limit" sh -c 'while :; do :; done' &
    pids+=($!)
done
echo "test-under-load: ${#pids[@]} busy processes for at most ${limit} s"
cd build
status=0
ctest --output-on-failure -j"$(nproc)" --timeout 1800 "$@" >test-under-load.log 2>&1 || status=$?
stop_load
# ctest's summary: the pass count, any failures, the time.
sed -n '/tests passed/,$p' test-under-load.log
echo "test-under-load: full log in build/test-under-load.log"
exit "$status"
