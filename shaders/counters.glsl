// counters.glsl — frame counters added once per subgroup. Include after
// common.glsl and the `counters` binding.
//
// Every pixel (or triangle) adding to the same few counter words makes
// those words the frame's most contended atomics (evaluate did about nine
// per pixel). The subgroup's sum, added by one elected lane, is the same
// total with 1/32 of the atomics: sums and ORs do not depend on order, so
// the counters read the same.
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_KHR_memory_scope_semantics : require

// counters[at] += value, summed over the subgroup's active invocations.
void count_add(uint at, uint value) {
    uint sum = subgroupAdd(value);
    if (sum != 0u && subgroupElect()) atomicAdd(counters[at], sum);
}

// The 64-bit counter held as (lo, hi) words at `at`: += value, summed over
// the subgroup (a subgroup's sum of per-pixel counts stays far below 2^32).
void count_add64(uint at, uint value) {
    uint sum = subgroupAdd(value);
    if (sum != 0u && subgroupElect()) {
        uint before = atomicAdd(counters[at], sum);
        if (before + sum < before) atomicAdd(counters[at + 1u], 1u);
    }
}

// counters[at] |= bits, ORed over the subgroup.
void count_or(uint at, uint bits) {
    uint all_bits = subgroupOr(bits);
    if (all_bits != 0u && subgroupElect()) atomicOr(counters[at], all_bits);
}
