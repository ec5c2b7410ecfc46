// Resumed traces: the state a traversal saves when it runs out of steps, and where
// (docs/kernels.md, "Resumed traces"; the host side is src/render/resume.rs).
//
// A trace that reaches its step budget (TREE_STEPS) stops its sample. The trace kernel
// (RESUME_PASS false) then leaves the pixel holding the samples before that one and
// counts it in the dispatch header (DISPATCH_COUNTER); it saves nothing, so none of
// this file's saving code is in it. The resume kernel (RESUME_PASS true: the same
// variant with this constant set) runs that sample again: the first resume pass over
// the dispatch's pixels (PASS_SWEEP) takes those behind, later passes take a job list.
// When one of its traces runs out of steps, the pixel gets a job in the next list and,
// while the half has one free (jobs with a record run first, src/render/resume.rs, so
// they keep one), a record: the trace's index, the best hit so far and
// the counters (the head), the results of the sample's traces that were themselves
// resumed (the log), and each traversal level's state. The next pass replays the
// logged results, traces the sample's other earlier traces again (each fit its budget
// from the start), continues the saved one with a fresh budget, and traces the rest;
// a job without a record runs its sample from the start.
//
// Pool (binding BINDING_RESUME), in words:
//   job lists 0 and 1, RESUME_JOBS words each: the pixel of each job (window-relative,
//     `local` in the kernels)
//   record halves 0 and 1, RESUME_RECORDS records of RECORD_WORDS each: job j of list
//     L owns record j of half L when j < RESUME_RECORDS
// A record:
//   head, RESUME_HEAD_WORDS: 0 trace index, 1 logged results, 2 g_nodes, 3 g_tests,
//     4..8 best hit so far (t, prim, u, v bits), 8 its instance
//   log, RESUME_LOG entries of RESUME_LOG_WORDS, in trace order:
//     uvec4(t, prim, u, v), uvec4(instance, g_nodes, g_tests, trace | hit << 31)
//   levels, RS_LEVEL words each: the top level's traversal state, then (instanced
//     scenes) the bottom level's. Each accel/*.glsl documents its words; a stack starts
//     at word RESUME_LEVEL_WORDS (a second array, the kd-tree's, STACK_SIZE further).
#ifndef ARBOR_RESUME_GLSL
#define ARBOR_RESUME_GLSL

layout(constant_id = SPEC_RESUME_PASS) const bool RESUME_PASS = false;
layout(constant_id = SPEC_RESUME_LOG) const uint RESUME_LOG = 1u;
layout(constant_id = SPEC_RESUME_RECORDS) const uint RESUME_RECORDS = 1u;
layout(constant_id = SPEC_RESUME_JOBS) const uint RESUME_JOBS = 1u;

const uint RS_LEVEL = RESUME_LEVEL_WORDS + 2u * STACK_SIZE;
#ifdef HAS_INSTANCES
const uint RS_LEVELS = 2u;
#else
const uint RS_LEVELS = 1u;
#endif
const uint RS_STATE = RESUME_HEAD_WORDS + RESUME_LOG_WORDS * RESUME_LOG;
const uint RECORD_WORDS = RS_STATE + RS_LEVELS * RS_LEVEL;
const uint NO_RECORD = 0xffffffffu;
const uint NO_TRACE = 0xffffffffu;

// Only the families that resume (ACCEL_RESUMABLE, set by their accel/*.glsl) use it,
// and only their kernels bind it.
layout(std430, set = 0, binding = BINDING_RESUME) buffer ResumePool {
    uint resume_pool[];
};

bool g_suspended = false; // a trace of this sample ran out of steps: the sample stops
bool g_resuming = false;  // the next traversal (level) continues from the input record
uint g_in = NO_RECORD;    // first word of the record this invocation continues
uint g_out = NO_RECORD;   // first word of the record it writes
uint g_level = 0u;        // first state word of the level being traversed
uint g_local = 0u;        // the pixel

uint rs_get(uint i) { return resume_pool[g_in + RS_STATE + g_level + i]; }
float rs_getf(uint i) { return uintBitsToFloat(rs_get(i)); }
void rs_put(uint i, uint w) { resume_pool[g_out + RS_STATE + g_level + i] = w; }
void rs_putf(uint i, float f) { rs_put(i, floatBitsToUint(f)); }

// Called by a traversal that ran out of steps: stops the sample and, in the resume
// kernel, gives the pixel a job in the next list (and a record, while the half has
// one). True when the traversal is to save its state (rs_put).
bool trace_suspend() {
    if (!RESUME_PASS) {
        g_suspended = true;
        return false;
    }
    if (!g_suspended) {
        g_suspended = true;
        uint j = atomicAdd(DISPATCH_COUNTER, 1u);
        uint list = DISPATCH_PASS == PASS_LIST0 ? 1u : 0u;
        resume_pool[list * RESUME_JOBS + j] = g_local;
        if (j < RESUME_RECORDS) g_out = 2u * RESUME_JOBS + (list * RESUME_RECORDS + j) * RECORD_WORDS;
    }
    return g_out != NO_RECORD;
}

#endif
