#!/usr/bin/env bash
# Fuzzes pumeta's readers and checkpoint loader with libFuzzer, AddressSanitizer and
# UndefinedBehaviorSanitizer (clang from Debian), in build-fuzz/.
#   scripts/fuzz.sh [SECONDS] [TARGET...]   each target for SECONDS (default 60); targets:
#                                           read_ply read_pcd read_las read_obj read_off
#                                           read_stl read_xyz load_checkpoint (default: all)
#   PUMETA_FUZZ_JOBS=N                      targets fuzzed at once (default: the core count)
#   PUMETA_FUZZ_FORK=N                      N processes per target (libFuzzer -fork), for a
#                                           slow target such as load_checkpoint
# Starts from fuzz/corpus/<target>/ (seeds written by fuzz_make_seeds, plus inputs kept by
# earlier runs) and merges the new inputs that add coverage back into it, minimised. A crash
# is kept as build-fuzz/findings/<target>/crash-* and makes the script fail; turn it into a
# regression file under fuzz/regressions/<target>/ once fixed (ctest replays those).
# Prints one Markdown row per target: executions, executions per second, edges and features
# covered, corpus size.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
shift || true
targets=("$@")
((${#targets[@]})) || targets=(read_ply read_pcd read_las read_obj read_off read_stl read_xyz
                               load_checkpoint)
parallel=${PUMETA_FUZZ_JOBS:-$(nproc)}

packages=(clang libclang-rt-14-dev)
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || {
        sudo_cmd=(); [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
        "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends "${packages[@]}"
        break
    }
done

flags="-fsanitize=address,undefined -fno-sanitize=vptr -fno-sanitize-recover=undefined"
flags+=" -fsanitize=fuzzer-no-link -g -O1"
export CCACHE_SLOPPINESS=pch_defines,time_macros,include_file_mtime,include_file_ctime
cmake -S . -B build-fuzz -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_CXX_FLAGS="$flags" \
    -DPUMETA_BUILD_FUZZERS=ON -DPUMETA_BUILD_TESTS=OFF -DPUMETA_BUILD_BENCH=OFF >/dev/null
cmake --build build-fuzz -j"$(nproc)" --target fuzz_make_seeds \
    $(printf -- '--target fuzz_%s ' "${targets[@]}")

# Seeds first: a corpus folder missing a seed gets it back.
seeds=build-fuzz/seeds
rm -rf "$seeds"
ASAN_OPTIONS=detect_leaks=0 build-fuzz/fuzz_make_seeds "$seeds"
for target in "${targets[@]}"; do
    mkdir -p "fuzz/corpus/$target"
    cp -n "$seeds/$target"/* "fuzz/corpus/$target/"
done

export ASAN_OPTIONS=detect_leaks=0:allocator_may_return_null=0
export UBSAN_OPTIONS=print_stacktrace=1
fuzz_one() {
    local target=$1 findings=build-fuzz/findings/$1 fresh=build-fuzz/fresh/$1
    mkdir -p "$findings" "$fresh"
    echo failed > "build-fuzz/findings/$target.status"
    # -rss_limit_mb: a reader must never need GiBs for a small file; -timeout: nor seconds.
    # Checkpoints are larger than geometry files (the PU-Dense seed is 147 kB).
    local max_len=8192
    [[ $target == load_checkpoint ]] && max_len=262144
    local fork=()
    [[ -n ${PUMETA_FUZZ_FORK:-} ]] && fork=(-fork="$PUMETA_FUZZ_FORK")
    "build-fuzz/fuzz_$target" "${fork[@]}" "$fresh" "fuzz/corpus/$target" \
        -max_total_time="$seconds" -max_len="$max_len" -timeout=10 -rss_limit_mb=3072 \
        -print_final_stats=1 -artifact_prefix="$findings/" \
        > "build-fuzz/findings/$target.log" 2>&1 || return 0
    "build-fuzz/fuzz_$target" -merge=1 "fuzz/corpus/$target" "$fresh" \
        > "build-fuzz/findings/$target.merge.log" 2>&1
    echo ok > "build-fuzz/findings/$target.status"
}
for target in "${targets[@]}"; do
    while (($(jobs -rp | wc -l) >= parallel)); do sleep 1; done
    fuzz_one "$target" &
done
wait
failed=0
for target in "${targets[@]}"; do
    if [[ $(cat "build-fuzz/findings/$target.status") != ok ]]; then
        echo "fuzz: $target found a defect; see build-fuzz/findings/$target.log" >&2
        failed=1
    fi
done

echo "| target | seconds | executions | exec/s | edges (cov) | features (ft) | corpus files |"
echo "|---|---:|---:|---:|---:|---:|---:|"
for target in "${targets[@]}"; do
    log=build-fuzz/findings/$target.log
    # The final stats of a single process, else (fork mode) the last status line's count.
    last=$(grep -E '^#[0-9]+' "$log" | tail -n 1)
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' ||
           grep -o '^#[0-9]*' <<<"$last" | tr -d '#')
    speed=$(grep -o 'stat::average_exec_per_sec: *[0-9]*' "$log" | grep -o '[0-9]*$' ||
            echo $((runs / seconds)))
    cov=$(grep -o 'cov: [0-9]*' <<<"$last" | grep -o '[0-9]*$' || echo "?")
    ft=$(grep -o 'ft: [0-9]*' <<<"$last" | grep -o '[0-9]*$' || echo "?")
    files=$(find "fuzz/corpus/$target" -type f | wc -l)
    echo "| $target | $seconds | $runs | $speed | $cov | $ft | $files |"
done
exit $failed
