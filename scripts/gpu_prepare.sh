#!/usr/bin/env bash
# Makes what scripts/gpu_measure.sh expects (on the build machine, x86-64):
# the Vulkan loader's packages in .gl, a stripped release binary, the
# worked host (examples/embed_host) and test executables in .dev, and a
# copy of ../shared/scenes in .dev/scenes. All are git-ignored
# (.git/info/exclude); carry `.gl` and `.devpack` (`.dev` packed) with
# the run. Built without
# the `embree` feature: the device machine has no libembree. The device
# tool carries 64 MiB at most, so IZB_PREPARE_TESTS names the tests to take
# (default: the GPU = CPU tests of every pass).
set -eu
cd "$(dirname "$0")/.."
grep -qx '/.gl/' .git/info/exclude || echo /.gl/ >>.git/info/exclude
grep -qx '/.dev/' .git/info/exclude || echo /.dev/ >>.git/info/exclude
if ! ls .gl/libglvnd0_*.deb >/dev/null 2>&1; then
    mkdir -p .gl /tmp/amd64/partial
    o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
    apt-get $o update >/dev/null
    (cd .gl && apt-get $o download libvulkan1 libglvnd0 libegl1 libgl1 libglx0 libopengl0 libgles2)
fi
rm -rf .dev && mkdir -p .dev/tests
TESTS=${IZB_PREPARE_TESTS:-gpu_backend gpu_edge_surfaces gpu_shadow_pass gpu_host_visibility gpu_host_depth gpu_host_multisampled embed_host}
cargo build --release --bin izb --example embed_host
cp target/release/izb .dev/izb && strip .dev/izb
cp target/release/examples/embed_host .dev/embed_host && strip .dev/embed_host
for t in $TESTS; do
    exe=$(cargo test --release --no-run --test "$t" --message-format=json 2>/dev/null |
        python3 -c 'import json, sys
for line in sys.stdin:
    m = json.loads(line)
    if m.get("target", {}).get("kind") == ["test"] and m.get("executable"):
        print(m["executable"])')
    cp "$exe" ".dev/tests/$t" && strip ".dev/tests/$t"
done
cp -rL ../shared/scenes .dev/scenes
chmod -R u+w .dev
# Packed: the tree the device tool carries is 64 MiB at most, and the
# binaries and scenes take 87 MiB as they are (16 MiB packed).
grep -qx '/.devpack/' .git/info/exclude || echo /.devpack/ >>.git/info/exclude
mkdir -p .devpack && tar -cf - .dev | xz -T0 -6 >.devpack/dev.tar.xz
du -sh .gl .dev .devpack
