#!/usr/bin/env bash
# Builds the Debian package build/pumeta_<version>_amd64.deb: the pumeta binary, the library,
# its headers and CMake package, the Python module and the shipped models, under /usr.
#   scripts/package.sh && sudo apt install ./build/pumeta_*_amd64.deb
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh >/dev/null
PUMETA_BUILD_TARGETS="pumeta pumeta_cli pumeta_python" scripts/build.sh "$@"
cd build
cpack -G DEB >cpack.log 2>&1 || { cat cpack.log >&2; exit 1; }
ls "$PWD"/pumeta_*_amd64.deb
