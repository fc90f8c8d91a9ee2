#!/usr/bin/env bash
# The GPU measurements of paper-notes/performance.md ("On a real GPU"), as
# one script for a lent GPU machine (this workplace's `device` tool): a
# Vulkan-only bench (the GPU clocks down when the CPU twin works in the same
# process), the GPU = CPU tests on real hardware, and the soft-shadow bench.
#
# Run from the repository root. It expects, beside the tree and git-ignored
# (scripts/gpu_prepare.sh makes them on the build machine):
#   .gl/*.deb      the Vulkan loader (the device image has none);
#   .dev/izb       a stripped release binary;
#   .dev/embed_host  the worked host (examples/embed_host), stripped;
#   .dev/tests/*   stripped test executables (scripts/gpu_prepare.sh says
#                  which);
#   .dev/scenes    a copy of ../shared/scenes.
# or all of .dev packed as .devpack/dev.tar.xz, unpacked here first.
# Writes logs and bench JSON under $OUT. Each step has its own time limit
# so a slow step cannot cost the ones after it.
# Knobs: IZB_MEASURE_RES (hard bench resolutions), IZB_MEASURE_REPEAT,
# IZB_MEASURE_BASELINES_RES (the baselines step's resolution),
# IZB_MEASURE_STEPS (which steps of hard, heavy, tests, soft, baselines,
# embed, edges; default "hard tests soft"), IZB_MEASURE_FRAMES (the worked
# host's frames per run), IZB_MEASURE_TESTS and IZB_MEASURE_TEST_LIMIT
# (the test executables to run, in order, and each one's limit in s).
set -u
OUT=${OUT:-/tmp/izb-gpu-out}
mkdir -p "$OUT"
RES=${IZB_MEASURE_RES:-960x540,1920x1080}
REPEAT=${IZB_MEASURE_REPEAT:-7}
BASELINES_RES=${IZB_MEASURE_BASELINES_RES:-1920x1080}
STEPS=${IZB_MEASURE_STEPS:-hard tests soft}
FRAMES=${IZB_MEASURE_FRAMES:-60}
LOG=$OUT/log.txt
S=$PWD/.dev/scenes
SHARED="$S/deckchair.scene.json $S/tablefan.scene.json $S/ficus.scene.json $S/engine.scene.json $S/courtyard.scene.json"
PROCEDURAL="default wires hairball city grazing far analytic"

if [ ! -d .dev ] && [ -f .devpack/dev.tar.xz ]; then
    tar -xJf .devpack/dev.tar.xz
fi

# The loader and glvnd (the NVIDIA ICD's libGLX_nvidia needs libGLdispatch).
if [ -d .gl ]; then
    for f in .gl/*.deb; do dpkg -x "$f" /; done
    ldconfig
fi
icd=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
[ -f "$icd" ] && export VK_DRIVER_FILES=$icd

# step LIMIT_S NAME COMMAND...: runs COMMAND under a limit, logged.
step() {
    local limit=$1 name=$2
    shift 2
    local start=$SECONDS
    echo "== $name (limit ${limit} s): $*" | tee -a "$LOG"
    timeout "$limit" "$@" 2>&1 | tee -a "$LOG"
    echo "== $name: exit ${PIPESTATUS[0]} after $((SECONDS - start)) s" | tee -a "$LOG"
}

step 20 gpu nvidia-smi --query-gpu=name,driver_version,clocks.sm,clocks.max.sm,clocks.mem,temperature.gpu,power.draw --format=csv
step 20 devices .dev/izb devices

for s in $STEPS; do
    case $s in
    hard)
        # izb32 against the GPU ray tracer (rt32-rays) on every scene at
        # two resolutions; the ground truth at 1 spp (only the metrics
        # need it).
        step 150 hard .dev/izb bench $PROCEDURAL $SHARED --backend vulkan \
            --methods izb32,rt32-rays --resolution "$RES" --repeat "$REPEAT" \
            --spp 1 --out /tmp/izb-bench/hard.json
        cp /tmp/izb-bench/hard.json "$OUT/" 2>/dev/null
        ;;
    heavy)
        # Evaluate's heavy step: its threshold (0 = off) on the scenes with
        # long candidate lists, 1080p.
        for e in 0 64 128 256 512; do
            IZB_GPU_HEAVY_ENTRIES=$e step 60 "heavy-$e" .dev/izb bench \
                "$S/courtyard.scene.json" "$S/ficus.scene.json" "$S/engine.scene.json" \
                grazing hairball --backend vulkan --methods izb32 \
                --resolution 1920x1080 --repeat 3 --spp 1 --out "/tmp/izb-bench/heavy-$e.json"
            cp "/tmp/izb-bench/heavy-$e.json" "$OUT/" 2>/dev/null
        done
        ;;
    tests)
        # The tests find ../shared/scenes beside the checkout they were
        # built in (/work/main).
        if [ ! -e /work/shared/scenes ]; then
            mkdir -p /work/shared && ln -s "$S" /work/shared/scenes
        fi
        # IZB_MEASURE_TESTS: which of them, in that order (default all).
        for t in ${IZB_MEASURE_TESTS:-$(ls .dev/tests)}; do
            t=.dev/tests/$t
            IZB_REQUIRE_GPU=1 IZB_REQUIRE_SCENES=1 step "${IZB_MEASURE_TEST_LIMIT:-60}" "$(basename "$t")" "$t"
        done
        ;;
    baselines)
        # Issue 17: the IZB against the hardware-rasterised maps, the
        # filtered maps, contact shadows and shadow volumes, 1080p, every
        # scene; the truth at 4 spp (the metrics rank, the times compare).
        # One bench per scene, each under its own limit: a bench writes its
        # JSON only when it finishes, so a slow scene costs only itself.
        for scene in $PROCEDURAL $SHARED; do
            name=$(basename "$scene" .scene.json)
            step 90 "baselines-$name" .dev/izb bench "$scene" --backend vulkan \
                --methods izb1,izb32,volumes,sm-2048,pcf3-2048,pcf5-4096,csm4-pcf3-2048,vsm-2048,msm-2048,pcf3-2048+contact,sm-8192,msm-4096 \
                --resolution "$BASELINES_RES" --repeat 3 --spp 4 --out "/tmp/izb-bench/baselines-$name.json"
            cp "/tmp/izb-bench/baselines-$name.json" "$OUT/" 2>/dev/null
        done
        ;;
    embed)
        # Issue 29: the worked host's steady-state 1080p frame, per pass
        # (its --stats: gpu_ms medians from timestamps), on courtyard and
        # deckchair, for each G-buffer input: the raster visibility buffer,
        # D32 depth + normal, and the 4x multisampled visibility buffer;
        # then the visibility buffer in exact mode, whose frame-0 twin check
        # must find 0 mask mismatches. Each --stats has record_us (the
        # loop's, alone warm and cold: the 50 us target).
        mkdir -p /tmp/izb-embed
        for scene in courtyard deckchair; do
            for input in visibility d32 msaa4 exact; do
                case $input in
                visibility) flags=() ;;
                d32) flags=(--depth d32) ;;
                msaa4) flags=(--msaa 4) ;;
                exact) flags=(--exact) ;;
                esac
                step 40 "embed-$scene-$input" .dev/embed_host "$S/$scene.scene.json" \
                    --resolution 1920x1080 --frames "$FRAMES" "${flags[@]}" \
                    --stats "/tmp/izb-embed/$scene-$input.json"
                tar -C /tmp -czf "$OUT/embed.tar.gz" izb-embed
            done
        done
        ;;
    edges)
        # Issue 27: izb32 with edge surfaces (the GPU's own ray-cast
        # G-buffer, its edge_surfaces pass included) against izb32-flat,
        # 1080p, every scene; one bench per scene so a slow one costs only
        # itself. The JSON files are gathered into one tarball (the tool
        # brings back 8 files at most), anew after each scene: a run stopped at
        # its limit still brings back the scenes done.
        mkdir -p /tmp/izb-bench/edges
        for scene in $PROCEDURAL $SHARED; do
            name=$(basename "$scene" .scene.json)
            step 45 "edges-$name" .dev/izb bench "$scene" --backend vulkan \
                --methods izb32,izb32-flat --resolution 1920x1080 --repeat 5 \
                --spp 1 --out "/tmp/izb-bench/edges/$name.json"
            tar -C /tmp/izb-bench -czf "$OUT/edges.tar.gz" edges
        done
        ;;
    soft)
        # Area lights: the paired and LUT soft masks and PCSS, 1080p.
        step 90 soft .dev/izb bench default $SHARED --backend vulkan \
            --methods izb32,izb32-paired,pcss-2048 --light-size 0.5,2 \
            --resolution 1920x1080 --repeat 5 --spp 1 --out /tmp/izb-bench/soft.json
        cp /tmp/izb-bench/soft.json "$OUT/" 2>/dev/null
        ;;
    esac
done
step 20 gpu-after nvidia-smi --query-gpu=clocks.sm,temperature.gpu,power.draw --format=csv
