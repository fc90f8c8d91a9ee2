// loop_budget.glsl — the guard against lavapipe's loop cap, shared by the
// passes whose loops are data-dependent (bin, evaluate). Include after
// common.glsl and the counters and frame bindings, with LOOP_BUDGET_SLOTS
// defined as the workgroup's invocation count.
//
// lavapipe (gallivm) ends a shader invocation's loops after 65535
// iterations without a word. It vectorises a subgroup's invocations into
// one SIMD loop and counts that loop's iterations for the whole subgroup:
// one pass of a loop counts once however many lanes run it, and lanes that
// loop in different places add up. A per-lane count missed the second part
// and let the cap cut a courtyard pixel's candidates silently (160×90,
// skips off, one sample lost), and the bin pass's cell loops lost entries
// the same way (hairball with 40 000-cell triangles). So on a capped
// device each pass of a loop is counted once per subgroup, by the one lane
// `subgroupElect` picks among those running it, in shared memory; past
// frame.loop_budget the invocation stops and raises C_LOOP_BUDGET_EXCEEDED,
// and the host refuses the frame (GpuError::LoopCap) instead of returning
// a wrong one.
#extension GL_KHR_shader_subgroup_basic : require

// What one counted pass costs: 1, or more for a pass whose loops are
// entered often with few iterations (lavapipe also counts each loop's
// exit test, which a pass count misses).
#ifndef LOOP_TRIP_COST
#define LOOP_TRIP_COST 1u
#endif

shared uint sm_subgroup_trips[LOOP_BUDGET_SLOTS];
// Loop trips of this invocation so far, and whether it ran out.
uint trips = 0u;
bool over_budget = false;

// Zeroes the workgroup's counts; every invocation must call it before any
// returns (it has a barrier).
void loop_budget_reset() {
    sm_subgroup_trips[gl_LocalInvocationIndex] = 0u;
    barrier();
}

// Counts one pass of a loop; false once the budget is spent.
bool spend_trip() {
    trips += 1u;
    if (frame.loop_budget != 0xFFFFFFFFu) {
        if (subgroupElect()) atomicAdd(sm_subgroup_trips[gl_SubgroupID], LOOP_TRIP_COST);
        if (atomicAdd(sm_subgroup_trips[gl_SubgroupID], 0u) >= frame.loop_budget) over_budget = true;
    }
    return !over_budget;
}

// Raises C_LOOP_BUDGET_EXCEEDED if this invocation ran out.
void loop_budget_report() {
    if (over_budget) atomicMax(counters[C_LOOP_BUDGET_EXCEEDED], trips);
}
