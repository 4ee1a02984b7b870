#!/usr/bin/env bash
# Runs the test suite under the BLAS kernels and thread counts that machines differ in, so that
# no test depends on one OpenBLAS kernel's or one thread count's rounding:
#   scripts/test-matrix.sh              the default kernel, Haswell and Sandybridge, each with
#                                       OMP_NUM_THREADS=1 and 2 (six ctest runs)
#   scripts/test-matrix.sh KERNEL:THREADS ...   chosen settings ("default" for no override),
#                                       e.g. scripts/test-matrix.sh Haswell:1 default:2
# Builds first (scripts/build.sh). Any run failing makes the script fail; a summary line per
# setting says which.
set -euo pipefail
cd "$(dirname "$0")/.."
settings=("$@")
((${#settings[@]})) || settings=(default:1 default:2 Haswell:1 Haswell:2 Sandybridge:1
                                 Sandybridge:2)
scripts/setup.sh >/dev/null
scripts/build.sh
summary=() failed=0
for setting in "${settings[@]}"; do
    kernel=${setting%%:*} threads=${setting##*:}
    env=(env -u OPENBLAS_CORETYPE OMP_NUM_THREADS="$threads")
    [[ $kernel == default ]] || env+=(OPENBLAS_CORETYPE="$kernel")
    echo "== OPENBLAS_CORETYPE=$kernel OMP_NUM_THREADS=$threads"
    if (cd build && "${env[@]}" ctest --output-on-failure -j"$(nproc)" --timeout 900); then
        summary+=("pass  OPENBLAS_CORETYPE=$kernel OMP_NUM_THREADS=$threads")
    else
        summary+=("FAIL  OPENBLAS_CORETYPE=$kernel OMP_NUM_THREADS=$threads")
        failed=1
    fi
done
printf '%s\n' "${summary[@]}"
exit $failed
