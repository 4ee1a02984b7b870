#!/usr/bin/env bash
# ctest "package": builds the Debian package (cpack -G DEB) from BUILD_DIR, checks its name and
# Depends, unpacks it into a temporary root (dpkg -x), upsamples a small cloud with the packaged
# binary and models, and upsamples one with the packaged Python module.
# Usage: package.sh BUILD_DIR PYTHON
set -euo pipefail
build=$1
python=$2
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail() { echo "package: $*" >&2; exit 1; }

(cd "$build" && cpack -G DEB -B "$tmp/out") >"$tmp/cpack.log" 2>&1 ||
    { cat "$tmp/cpack.log" >&2; fail "cpack failed"; }
deb=$(ls "$tmp"/out/pumeta_*_amd64.deb) || fail "no pumeta_*_amd64.deb"
version=$(dpkg-deb -f "$deb" Version)
[[ $(basename "$deb") == "pumeta_${version}_amd64.deb" ]] || fail "file name $(basename "$deb")"
depends=$(dpkg-deb -f "$deb" Depends)
for runtime in libtorch python3-numpy libopenblas; do
    [[ $depends == *"$runtime"* ]] || fail "Depends lacks $runtime: $depends"
done

root=$tmp/root
dpkg -x "$deb" "$root"
for file in usr/bin/pumeta usr/include/pumeta/pumeta.h usr/lib/cmake/pumeta/pumetaConfig.cmake \
    usr/share/pumeta/models/defaults.json usr/share/pumeta/models/pugcn-x4.pt; do
    [[ -e $root/$file ]] || fail "$file missing"
done
module=$(ls "$root"/usr/lib/python3/dist-packages/pumeta*.so) || fail "no Python module"

# A small sphere, upsampled 4x by the packaged binary with the models packaged beside it.
"$python" - "$tmp/sphere.xyz" <<'PY'
import sys, numpy as np
rng = np.random.default_rng(1)
p = rng.normal(size=(500, 3))
np.savetxt(sys.argv[1], p / np.linalg.norm(p, axis=1, keepdims=True), fmt="%.6f")
PY
env -u PUMETA_MODELS "$root/usr/bin/pumeta" --threads 1 upsample "$tmp/sphere.xyz" \
    -o "$tmp/dense.xyz" --json >"$tmp/upsample.json" || fail "packaged pumeta upsample failed"
[[ $(grep -c . "$tmp/dense.xyz") -eq 2000 ]] || fail "expected 2000 points"
grep -q "$root/usr/share/pumeta/models/" "$tmp/upsample.json" ||
    fail "the packaged binary did not use the packaged models: $(cat "$tmp/upsample.json")"
"$root/usr/bin/pumeta" --version | grep -q "$version" || fail "--version does not say $version"

# The packaged Python module, on the packaged models.
PYTHONPATH=$(dirname "$module") PUMETA_MODELS=$root/usr/share/pumeta/models "$python" - <<'PY' ||
import numpy as np, pumeta
rng = np.random.default_rng(2)
p = rng.normal(size=(400, 3)).astype(np.float32)
p /= np.linalg.norm(p, axis=1, keepdims=True)
d = pumeta.upsample(p, ratio=4)
assert d.shape == (1600, 3), d.shape
PY
    fail "the packaged Python module failed"
echo "package: $(basename "$deb") ok"
