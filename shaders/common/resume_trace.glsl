// The traces the integrators call (trace_closest, trace_any and their coherent forms)
// around the scene's (scene_*, trace.comp), and the invocation's job: which pixel,
// which sample, what to replay (common/resume.glsl has the layout). In the trace
// kernel these only number the traces and stop a sample once one ran out of steps;
// families that cannot suspend a trace (no ACCEL_RESUMABLE) get the scene's traces as
// they are, their pixels flagged (g_overflow) when a trace runs out.
#ifndef ARBOR_RESUME_TRACE_GLSL
#define ARBOR_RESUME_TRACE_GLSL

uint g_trace = 0u;           // index of the next trace in the sample
uint g_resume_at = NO_TRACE; // the trace the input record continues
uint g_log_n = 0u;           // results the input record logs
uint g_log_i = 0u;           // the next of them to replay
uint g_log_next = NO_TRACE;  // its trace
uint g_rays_before = 0u;     // g_rays when the sample started
// The continued trace's result once it completes, for the next record's log.
bool g_cont = false;
uvec4 g_cont_a = uvec4(0u);
uvec4 g_cont_b = uvec4(0u);

#ifdef ACCEL_RESUMABLE
// The trace of log entry e of the input record.
uint log_trace(uint e) { return resume_pool[g_in + RESUME_HEAD_WORDS + e * RESUME_LOG_WORDS + 7u] & 0x7fffffffu; }

// Logged result g_log_i into h and the counters, as the trace left them; its hit.
bool log_replay(inout Hit h) {
    uint b = g_in + RESUME_HEAD_WORDS + g_log_i * RESUME_LOG_WORDS;
    h.t = uintBitsToFloat(resume_pool[b]);
    h.prim = resume_pool[b + 1u];
    h.u = uintBitsToFloat(resume_pool[b + 2u]);
    h.v = uintBitsToFloat(resume_pool[b + 3u]);
#ifdef HAS_INSTANCES
    h.inst = resume_pool[b + 4u];
#endif
    g_nodes = resume_pool[b + 5u];
    g_tests = resume_pool[b + 6u];
    bool hit = (resume_pool[b + 7u] >> 31u) != 0u;
    g_log_i += 1u;
    g_log_next = NO_TRACE;
    if (g_log_i < g_log_n) g_log_next = log_trace(g_log_i);
    return hit;
}

// The continued trace starts: the best hit so far and the counters from the head;
// the traversal restores the rest.
void resume_enter(inout Hit h) {
    g_resuming = true;
    g_level = 0u;
    h.t = uintBitsToFloat(resume_pool[g_in + 4u]);
    h.prim = resume_pool[g_in + 5u];
    h.u = uintBitsToFloat(resume_pool[g_in + 6u]);
    h.v = uintBitsToFloat(resume_pool[g_in + 7u]);
#ifdef HAS_INSTANCES
    h.inst = resume_pool[g_in + 8u];
#endif
    g_nodes = resume_pool[g_in + 2u];
    g_tests = resume_pool[g_in + 3u];
}

uint hit_inst(Hit h) {
#ifdef HAS_INSTANCES
    return h.inst;
#else
    return 0u;
#endif
}

// After trace i: a suspended one writes the head and the log (the input record's
// results, then the continued trace's if it completed); the continued one, complete,
// keeps its result for that log.
void trace_leave(uint i, bool hit, Hit h) {
    if (g_suspended) {
        if (g_out == NO_RECORD) return;
        resume_pool[g_out] = i;
        uint n = 0u;
        for (uint e = 0u; e < g_log_n; e++) {
            uint from = g_in + RESUME_HEAD_WORDS + e * RESUME_LOG_WORDS;
            uint to = g_out + RESUME_HEAD_WORDS + n * RESUME_LOG_WORDS;
            for (uint w = 0u; w < RESUME_LOG_WORDS; w++) resume_pool[to + w] = resume_pool[from + w];
            n += 1u;
        }
        if (g_cont) {
            uint to = g_out + RESUME_HEAD_WORDS + n * RESUME_LOG_WORDS;
            for (uint w = 0u; w < 4u; w++) {
                resume_pool[to + w] = g_cont_a[w];
                resume_pool[to + 4u + w] = g_cont_b[w];
            }
            n += 1u;
        }
        resume_pool[g_out + 1u] = n;
        resume_pool[g_out + 2u] = g_nodes;
        resume_pool[g_out + 3u] = g_tests;
        resume_pool[g_out + 4u] = floatBitsToUint(h.t);
        resume_pool[g_out + 5u] = h.prim;
        resume_pool[g_out + 6u] = floatBitsToUint(h.u);
        resume_pool[g_out + 7u] = floatBitsToUint(h.v);
        resume_pool[g_out + 8u] = hit_inst(h);
    } else if (i == g_resume_at) {
        g_cont = true;
        g_cont_a = uvec4(floatBitsToUint(h.t), h.prim, floatBitsToUint(h.u), floatBitsToUint(h.v));
        g_cont_b = uvec4(hit_inst(h), g_nodes, g_tests, i | (hit ? 0x80000000u : 0u));
    }
}
#endif

// Trace `i` of the sample before the structure runs: true when it is not to run, with
// its result in `hit` (after a suspension: none; in the resume kernel: a logged one).
bool trace_enter(uint i, inout Hit h, out bool hit) {
    hit = false;
    if (g_suspended) return true;
#ifdef ACCEL_RESUMABLE
    if (RESUME_PASS) {
        if (i == g_log_next) {
            hit = log_replay(h);
            return true;
        }
        if (i == g_resume_at) resume_enter(h);
    }
#endif
    return false;
}

void trace_done(uint i, bool hit, Hit h) {
#ifdef ACCEL_RESUMABLE
    if (RESUME_PASS) trace_leave(i, hit, h);
#endif
}

Hit no_hit(Ray r) {
    Hit h;
    h.t = r.tmax; h.prim = NO_PRIM; h.u = 0.0; h.v = 0.0;
#ifdef HAS_INSTANCES
    h.inst = 0u;
#endif
    return h;
}

bool trace_closest(Ray r, inout Hit h) {
    uint i = g_trace;
    g_trace = i + 1u;
    bool hit;
    if (trace_enter(i, h, hit)) return hit;
    hit = scene_closest(r, h);
    trace_done(i, hit, h);
    return hit;
}

bool trace_closest_coherent(Ray r, inout Hit h) {
    uint i = g_trace;
    g_trace = i + 1u;
    bool hit;
    if (trace_enter(i, h, hit)) return hit;
    hit = scene_closest_coherent(r, h);
    trace_done(i, hit, h);
    return hit;
}

bool trace_any(Ray r) {
    uint i = g_trace;
    g_trace = i + 1u;
    Hit h = no_hit(r);
    bool hit;
    if (trace_enter(i, h, hit)) return hit;
    hit = scene_any(r);
    trace_done(i, hit, h);
    return hit;
}

bool trace_any_coherent(Ray r) {
    uint i = g_trace;
    g_trace = i + 1u;
    Hit h = no_hit(r);
    bool hit;
    if (trace_enter(i, h, hit)) return hit;
    hit = scene_any_coherent(r);
    trace_done(i, hit, h);
    return hit;
}

// --- the invocation's job -------------------------------------------------------

// The pixel this invocation renders, false when it has none: pixel range.x + gid of
// the trace pass; of the sweep, only a pixel behind (fewer samples than range.w, the
// probe kernel's and the ray batch's, which run as INTEGRATOR 2: none); job range.x + gid of a list pass, with its record when it
// has one (the host runs the jobs with a record in a dispatch of their own, first).
bool job_begin(out uint local) {
    uint gid = gl_GlobalInvocationID.x;
    local = DISPATCH_FIRST + gid;
    if (gid >= DISPATCH_COUNT) return false;
#ifdef ACCEL_RESUMABLE
    if (RESUME_PASS && DISPATCH_PASS == PASS_SWEEP) {
        uint held = uint(pixels[local - DISPATCH_BASE].radiance.w);
        bool behind = INTEGRATOR == 2u ? held == 0u : DISPATCH_ZERO_SAMPLE + held < DISPATCH_SAMPLE_END;
        if (!behind) return false;
    } else if (RESUME_PASS) {
        uint list = DISPATCH_PASS == PASS_LIST0 ? 0u : 1u;
        uint job = DISPATCH_FIRST + gid;
        local = resume_pool[list * RESUME_JOBS + job];
        if (job < RESUME_RECORDS) {
            g_in = 2u * RESUME_JOBS + (list * RESUME_RECORDS + job) * RECORD_WORDS;
            g_resume_at = resume_pool[g_in];
            g_log_n = resume_pool[g_in + 1u];
            if (g_log_n > 0u) g_log_next = log_trace(0u);
        }
    }
#endif
    g_local = local;
    return true;
}

// A sample starts: its traces count from 0.
void sample_start() {
    g_trace = 0u;
    g_rays_before = g_rays;
}

// A sample is complete: the input record was its own.
void sample_done() {
    g_in = NO_RECORD;
    g_resume_at = NO_TRACE;
    g_log_n = 0u;
    g_log_i = 0u;
    g_log_next = NO_TRACE;
    g_cont = false;
}

// Rays of the invocation's complete samples.
uint job_rays() { return g_suspended ? g_rays_before : g_rays; }

// A trace dispatch that finds its pixel behind: holding fewer samples than the
// dispatch starts from, because an earlier dispatch stopped one of them and its resume
// passes had not run yet (dispatches in flight; docs/kernels.md, "Resumed traces"). The pixel
// is left as it is and counted like a stopped sample, so the resume sweep after this
// dispatch brings it to the dispatch's end, its samples still summed in index order.
bool pixel_behind(Pixel p) {
#ifdef ACCEL_RESUMABLE
    if (!RESUME_PASS && DISPATCH_ZERO_SAMPLE + uint(p.radiance.w) < DISPATCH_SAMPLE_BEGIN) {
        atomicAdd(DISPATCH_COUNTER, 1u);
        return true;
    }
#endif
    return false;
}

// The job of a sampling integrator (path, Whitted): the invocation's pixel
// (job_begin), its slot in the pixel buffer, the pixel of the full image with its
// column i and row j (window_pixel), and its state before this dispatch (pixel_start,
// into px); false where there is no job or the pixel is behind.
struct PixelJob {
    uint slot;
    uint pixel;
    uint i;
    uint j;
};
bool pixel_job(out PixelJob job, out Pixel px) {
    uint local;
    if (!job_begin(local)) return false;
    job.slot = local - DISPATCH_BASE;
    uvec3 at = window_pixel(local);
    job.pixel = at.x;
    job.i = at.y;
    job.j = at.z;
    px = pixel_start(job.slot);
    return !pixel_behind(px);
}

// The invocation ends: the trace kernel counts a stopped sample in the header (the
// resume kernel counted its jobs as it gave them out).
void job_end() {
#ifdef ACCEL_RESUMABLE
    if (!RESUME_PASS && g_suspended) atomicAdd(DISPATCH_COUNTER, 1u);
#endif
}

#endif
