#version 460
// Pass 2, `bin`, its prefix sum — GPU twin of the scan in
// `izb::cpu::bin::bin`: the per-cell counts of STEP_COUNT (bin.comp)
// become, in place, each cell's inclusive end in cell_start, which the
// scatter decrements down to the cell's first entry. Reduce, then scan,
// over blocks of SCAN_BLOCK_CELLS cells (Blelloch 1990), the block sums
// kept after cell_start's max_cells + 1 words, in three dispatches:
//   STEP_SCAN_BLOCKS (a workgroup per block) each block's sum;
//   STEP_SCAN_TOP    (1 workgroup) the block sums become exclusive
//                    offsets; the total is stored after the cells and
//                    checked against the cell list's capacity
//                    (C_CAPACITY_EXCEEDED: the host grows the list and
//                    runs the frame again);
//   STEP_SCAN_APPLY  (a workgroup per block) each cell's inclusive end.
// (The first version, one workgroup over every cell, kept one
// multiprocessor busy while 256 threads each walked thousands of cells.)
#extension GL_GOOGLE_include_directive : require
#include "common.glsl"

layout(local_size_x = WORKGROUP_LINEAR) in;

layout(scalar, binding = B_FRAME) readonly buffer FrameBuf { FrameParams frame; };
layout(scalar, binding = B_LIGHT) readonly buffer LightBuf { LightState light; };
layout(scalar, binding = B_COUNTERS) buffer CountBuf { uint counters[]; };
layout(scalar, binding = B_CELL_START) buffer StartBuf { uint cell_start[]; };

#define LOOP_BUDGET_SLOTS WORKGROUP_LINEAR
#include "loop_budget.glsl"

shared uint partial[WORKGROUP_LINEAR];

// partial[] becomes its inclusive prefix sum (Hillis–Steele); every
// invocation must call it.
void scan_partial(uint k) {
    for (uint offset = 1u; offset < WORKGROUP_LINEAR; offset <<= 1) {
        uint add = k >= offset ? partial[k - offset] : 0u;
        barrier();
        partial[k] += add;
        barrier();
    }
}

// Where block b's sum (then its exclusive offset) is kept: after the
// cells' ends and the total.
uint block_slot(uint b) {
    return frame.max_cells + 1u + b;
}

#if defined(STEP_SCAN_BLOCKS) || defined(STEP_SCAN_APPLY)
// Invocation k of block b owns SCAN_BLOCK_CELLS / WORKGROUP_LINEAR
// contiguous cells.
void block_cells(uint b, uint k, out uint begin, out uint end) {
    uint cells = light.total_cells;
    uint per = uint(SCAN_BLOCK_CELLS) / uint(WORKGROUP_LINEAR);
    begin = min(b * uint(SCAN_BLOCK_CELLS) + k * per, cells);
    end = min(begin + per, cells);
}
#endif

void main() {
    loop_budget_reset();
#if defined(STEP_SCAN_BLOCKS) || defined(STEP_SCAN_APPLY)
    // Per block of SCAN_BLOCK_CELLS cells (blocks past the grid leave at
    // once, the whole workgroup together).
    uint block = gl_WorkGroupID.x;
    if (block * uint(SCAN_BLOCK_CELLS) >= light.total_cells) return;
    uint k = gl_LocalInvocationID.x;
    uint begin, end;
    block_cells(block, k, begin, end);
    uint sum = 0u;
    for (uint c = begin; c < end && spend_trip(); ++c) sum += cell_start[c];
    partial[k] = sum;
    barrier();
    scan_partial(k);
#ifdef STEP_SCAN_BLOCKS
    if (k == WORKGROUP_LINEAR - 1u) cell_start[block_slot(block)] = partial[k];
#else
    // In place: each cell's count becomes its inclusive end, which the
    // scatter decrements down to the cell's first entry.
    uint running = cell_start[block_slot(block)] + partial[k] - sum;
    for (uint c = begin; c < end && spend_trip(); ++c) {
        running += cell_start[c];
        cell_start[c] = running;
    }
#endif
    loop_budget_report();
#endif

#ifdef STEP_SCAN_TOP
    // One workgroup: the block sums become exclusive offsets (thread k owns
    // a contiguous run of blocks), the total is checked and stored.
    uint cells = light.total_cells;
    uint blocks = (cells + uint(SCAN_BLOCK_CELLS) - 1u) / uint(SCAN_BLOCK_CELLS);
    uint k = gl_LocalInvocationID.x;
    uint chunk = (blocks + WORKGROUP_LINEAR - 1u) / WORKGROUP_LINEAR;
    uint begin = min(k * chunk, blocks), end = min(begin + chunk, blocks);
    uint sum = 0u;
    for (uint b = begin; b < end && spend_trip(); ++b) sum += cell_start[block_slot(b)];
    partial[k] = sum;
    barrier();
    scan_partial(k);
    uint running = partial[k] - sum;
    for (uint b = begin; b < end && spend_trip(); ++b) {
        uint block_sum = cell_start[block_slot(b)];
        cell_start[block_slot(b)] = running;
        running += block_sum;
    }
    if (k == WORKGROUP_LINEAR - 1u) {
        uint total = partial[k];
        cell_start[cells] = total;
        counters[C_CELL_ENTRIES] = total;
        if (total > frame.cell_capacity) counters[C_CAPACITY_EXCEEDED] = 1u;
    }
    loop_budget_report();
#endif
}
