#!/usr/bin/env bash
# Installs everything pumeta needs from Debian's archive. Idempotent: installs only what is
# missing, so a second run takes a second.
set -euo pipefail

packages=(
    build-essential cmake ninja-build ccache pkg-config
    libtorch-dev libgloo-dev
    # Without an optimised BLAS LibTorch falls back to reference BLAS (about 7x slower).
    libopenblas0-openmp
    libnanoflann-dev libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev libeigen3-dev
    libstb-dev libgtest-dev libbenchmark-dev
    # HDF5 patch files (PU-GAN's and PU1K's training data) and the Python module with its tests.
    libhdf5-dev pybind11-dev python3-dev python3-numpy python3-pytest
    # The "format" test checks every source against .clang-format.
    clang-format
    # scripts/bench.sh turns benchmark JSON into ratio tables.
    python3
    # Malformed and odd model files for the parser tests.
    assimp-testmodels
    # The report test opens the HTML report in headless Chromium.
    chromium
    # CGAL (GPL-3, header-only) for the optional pumeta-ear baseline program only.
    libcgal-dev
)

missing=()
for p in "${packages[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
    echo "setup: installing ${missing[*]}"
    sudo_cmd=()
    [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
    "${sudo_cmd[@]}" apt-get update -qq
    DEBIAN_FRONTEND=noninteractive "${sudo_cmd[@]}" apt-get install -y -qq --no-install-recommends \
        "${missing[@]}"
fi
echo "setup: all packages present"
