#!/usr/bin/env bash
# Fetches the real data pumeta uses from Debian's archive into data/raw/ (git-ignored).
# Idempotent: packages already extracted are skipped. Writes data/raw/manifest.tsv with
# package, version, path and SHA-256 of every extracted model file.
#   sweethome3d-furniture: ~820 OBJ furniture models in five catalogues (.sh3f zip files)
#   libcgal-demo:          CGAL's data.tar.gz (meshes, scanned statues, aerial LiDAR points)
#   assimp-testmodels:     format test files, including malformed ones
set -euo pipefail
cd "$(dirname "$0")/.."
raw=data/raw
mkdir -p "$raw/debs"

command -v unzip >/dev/null || {
    sudo_cmd=(); [ "$(id -u)" -ne 0 ] && sudo_cmd=(sudo)
    "${sudo_cmd[@]}" apt-get install -y -qq unzip
}

fetch_deb() {  # package -> path of the downloaded .deb
    local package=$1 deb
    deb=$(ls "$raw/debs/${package}"_*.deb 2>/dev/null | head -n 1 || true)
    if [ -z "$deb" ]; then
        (cd "$raw/debs" && apt-get download "$package" >/dev/null 2>&1) || {
            apt-get update -qq && (cd "$raw/debs" && apt-get download "$package" >/dev/null)
        }
        deb=$(ls "$raw/debs/${package}"_*.deb | head -n 1)
    fi
    echo "$deb"
}

version_of() { dpkg-deb -f "$1" Version; }

extract_furniture() {
    local deb=$1 out=$raw/furniture tmp
    [ -f "$out/.done" ] && return
    tmp=$(mktemp -d)
    dpkg-deb -x "$deb" "$tmp"
    rm -rf "$out" && mkdir -p "$out"
    for catalogue in "$tmp"/usr/share/sweethome3d/furniture/*.sh3f; do
        name=$(basename "$catalogue" .sh3f)
        mkdir -p "$out/$name"
        unzip -q -o "$catalogue" -d "$out/$name"
    done
    rm -rf "$tmp"
    touch "$out/.done"
}

extract_cgal() {
    local deb=$1 out=$raw/cgal tmp
    [ -f "$out/.done" ] && return
    tmp=$(mktemp -d)
    dpkg-deb -x "$deb" "$tmp"
    rm -rf "$out" && mkdir -p "$out"
    tar xzf "$tmp/usr/share/doc/libcgal-dev/data.tar.gz" -C "$out"
    rm -rf "$tmp"
    touch "$out/.done"
}

extract_assimp() {
    local deb=$1 out=$raw/assimp tmp
    [ -f "$out/.done" ] && return
    tmp=$(mktemp -d)
    dpkg-deb -x "$deb" "$tmp"
    rm -rf "$out" && mkdir -p "$out"
    cp -r "$tmp"/usr/share/assimp/models/. "$out"/
    rm -rf "$tmp"
    touch "$out/.done"
}

furniture_deb=$(fetch_deb sweethome3d-furniture)
cgal_deb=$(fetch_deb libcgal-demo)
assimp_deb=$(fetch_deb assimp-testmodels)
extract_furniture "$furniture_deb"
extract_cgal "$cgal_deb"
extract_assimp "$assimp_deb"

manifest=$raw/manifest.tsv
if [ ! -f "$manifest" ]; then
    {
        printf 'package\tversion\tpath\tsha256\n'
        for entry in "sweethome3d-furniture:$furniture_deb:furniture" "libcgal-demo:$cgal_deb:cgal"; do
            IFS=: read -r package deb dir <<<"$entry"
            version=$(version_of "$deb")
            find "$raw/$dir" -type f \( -name '*.obj' -o -name '*.off' -o -name '*.ply' \
                -o -name '*.xyz' -o -name '*.las' -o -name '*.stl' -o -name '*.properties' \) |
                LC_ALL=C sort | while read -r file; do
                    printf '%s\t%s\t%s\t%s\n' "$package" "$version" "${file#"$raw"/}" \
                        "$(sha256sum "$file" | cut -d' ' -f1)"
                done
        done
    } >"$manifest.tmp"
    mv "$manifest.tmp" "$manifest"
fi
echo "get-data: $(($(wc -l <"$manifest") - 1)) files in $manifest"
