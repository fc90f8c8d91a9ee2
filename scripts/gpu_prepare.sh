#!/usr/bin/env bash
# Makes what scripts/gpu_measure.sh expects (on the build machine, x86-64):
# the Vulkan loader's packages in .gl, a stripped release binary and test
# executables in .dev, and a copy of ../shared/scenes in .dev/scenes. All
# are git-ignored (.git/info/exclude); carry `.gl` and `.dev` with the run.
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
cargo build --release
cp target/release/izb .dev/izb && strip .dev/izb
for t in gpu_backend gpu_heavy_step gpu_soft_shadows baselines; do
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
du -sh .gl .dev
