// embree_rays: Embree 3 on the rays `arbor bench` traces for a mesh scene, so that
// arbor's Mrays/s can be set beside Embree's on the same machine. See
// scripts/peers/README.md for the build line and what each mode measures.
//
// The camera is arbor's, in float32 with the same operations in the same order:
//   framed_camera (src/scene/mod.rs), vfov 45 from Scene::from_mesh,
//   Camera::basis and CameraBasis::ray_dir (src/scene/camera.rs), glam 0.34's
//   normalize (v * (1 / |v|)) and cross; the bench's camera rays go through the pixel
//   centre (fx = fy = 0.5, sample 0 in shaders/trace.comp) with tmin 0, tmax +inf.
// The diffuse rays are arbor's DIFFUSE_PROBE rays (shaders/trace.comp): the same PCG
// stream per pixel, cosine_direction about the geometric normal facing the camera
// ray, and the origin moved off the surface by offset_ray_origin (error bounds of
// triangle_point), unless --eps asks for a fixed offset relative to the scene size.
// No fused multiply-adds: they would change the camera's bits (the pragma below, and
// -ffp-contract=off on the build line; main() warns if a*b+c was still fused).

#include <embree3/rtcore.h>
#include <pmmintrin.h>
#include <xmmintrin.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <sys/stat.h>
#include <thread>
#include <vector>

#if defined(__clang__)
#pragma clang fp contract(off)
#elif defined(__GNUC__)
#pragma GCC optimize("fp-contract=off")
#endif

namespace {

// ---------------------------------------------------------------- float32 vectors

struct V3 {
    float x, y, z;
};
V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
V3 operator-(V3 a) { return {-a.x, -a.y, -a.z}; }
V3 operator*(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
V3 operator/(V3 a, float s) { return {a.x / s, a.y / s, a.z / s}; }
float dot(V3 a, V3 b) { return (a.x * b.x) + (a.y * b.y) + (a.z * b.z); }
float length(V3 a) { return std::sqrt(dot(a, a)); }
// glam: normalize = v * length_recip(), length_recip = 1 / length.
V3 normalize(V3 a) { return a * (1.0f / length(a)); }
// glam's operand order.
V3 cross(V3 a, V3 b) { return {a.y * b.z - b.y * a.z, a.z * b.x - b.z * a.x, a.x * b.y - b.x * a.y}; }
V3 vmin(V3 a, V3 b) { return {std::min(a.x, b.x), std::min(a.y, b.y), std::min(a.z, b.z)}; }
V3 vmax(V3 a, V3 b) { return {std::max(a.x, b.x), std::max(a.y, b.y), std::max(a.z, b.z)}; }
V3 vabs(V3 a) { return {std::fabs(a.x), std::fabs(a.y), std::fabs(a.z)}; }

// True when this file was compiled with a*b+c fused (then the camera is not arbor's):
// (1 + 2^-12)^2 - 1 is 2^-11 rounded, 2^-11 + 2^-24 fused.
bool fuses_multiply_add() {
    volatile float va = 1.0f + 0x1p-12f, vc = -1.0f;
    float a = va, c = vc;
    return a * a + c != 0x1p-11f;
}

// ---------------------------------------------------------------- errors

struct Fail : std::runtime_error {
    using std::runtime_error::runtime_error;
};

[[noreturn]] void die(const std::string& msg) {
    std::fprintf(stderr, "embree_rays: %s\n", msg.c_str());
    std::exit(2);
}

// ---------------------------------------------------------------- OBJ

struct Mesh {
    std::vector<V3> pos;
    std::vector<uint32_t> tri;  // 3 per triangle
    V3 lo{0, 0, 0}, hi{0, 0, 0};  // bounds of the vertices faces use (as arbor's loader keeps)
    size_t tris() const { return tri.size() / 3; }
};

std::string read_file(const std::string& path) {
    struct stat st{};
    if (stat(path.c_str(), &st) != 0) throw Fail(path + ": " + std::strerror(errno));
    if (!S_ISREG(st.st_mode)) throw Fail(path + ": not a regular file");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Fail(path + ": " + std::strerror(errno));
    std::ostringstream ss;
    ss << in.rdbuf();
    if (in.bad()) throw Fail(path + ": read error");
    return ss.str();
}

// `v` (x y z [w]; w divides only when exactly four numbers, as arbor's pre-pass) and
// `f` (v, v/vt, v/vt/vn, v//vn; negative = relative; polygons as fans from their
// first vertex, as tobj; faces of fewer than three vertices dropped). Everything else
// is ignored.
Mesh load_obj(const std::string& path) {
    std::string text = read_file(path);
    for (char& c : text)
        if (c == '\r' || c == '\t') c = ' ';
    Mesh m;
    std::vector<std::pair<int64_t, size_t>> refs;  // (0-based vertex, line), checked at the end
    std::vector<int64_t> poly;
    size_t line_no = 0;
    auto err = [&](const std::string& msg) { return Fail(path + ":" + std::to_string(line_no) + ": " + msg); };
    size_t start = 0;
    while (start < text.size()) {
        size_t end = text.find('\n', start);
        if (end == std::string::npos) end = text.size();
        std::string line(text, start, end - start);
        start = end + 1;
        ++line_no;
        const char* p = line.c_str();
        while (*p == ' ') ++p;
        if (p[0] == 'v' && p[1] == ' ') {
            float c[4];
            int n = 0;
            const char* q = p + 1;
            for (;;) {
                while (*q == ' ') ++q;
                if (!*q) break;
                char* e;
                float val = std::strtof(q, &e);
                if (e == q || (*e && *e != ' ')) throw err("vertex coordinate is not a number");
                if (n < 4) c[n] = val;
                ++n;
                q = e;
            }
            if (n < 3) throw err("vertex has " + std::to_string(n) + " coordinates; expected 3");
            V3 v{c[0], c[1], c[2]};
            if (n == 4) {
                if (c[3] == 0.0f) throw err("vertex has w = 0");
                v = v / c[3];
            }
            if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
                throw err("vertex has a non-finite coordinate");
            m.pos.push_back(v);
        } else if (p[0] == 'f' && p[1] == ' ') {
            poly.clear();
            const char* q = p + 1;
            for (;;) {
                while (*q == ' ') ++q;
                if (!*q) break;
                char* e;
                long long idx = std::strtoll(q, &e, 10);
                if (e == q || idx == 0) throw err("face vertex is not a non-zero integer");
                // Negative: relative to the vertices so far; positive: may come later.
                idx = idx < 0 ? idx + static_cast<long long>(m.pos.size()) : idx - 1;
                if (idx < 0) throw err("face refers to a vertex before the first");
                poly.push_back(idx);
                while (*e && *e != ' ') ++e;  // skip /vt/vn
                q = e;
            }
            for (size_t k = 2; k < poly.size(); ++k) {
                for (int64_t r : {poly[0], poly[k - 1], poly[k]}) refs.push_back({r, line_no});
            }
        }
    }
    m.tri.reserve(refs.size());
    std::vector<char> used(m.pos.size(), 0);
    for (auto [i, line] : refs) {
        if (i >= static_cast<int64_t>(m.pos.size()))
            throw Fail(path + ":" + std::to_string(line) + ": face refers to vertex " + std::to_string(i + 1) + " of " +
                       std::to_string(m.pos.size()));
        m.tri.push_back(static_cast<uint32_t>(i));
        used[i] = 1;
    }
    if (m.tri.empty()) throw Fail(path + ": no faces");
    const float inf = std::numeric_limits<float>::infinity();
    m.lo = {inf, inf, inf};
    m.hi = {-inf, -inf, -inf};
    for (size_t i = 0; i < m.pos.size(); ++i) {
        if (!used[i]) continue;
        m.lo = vmin(m.lo, m.pos[i]);
        m.hi = vmax(m.hi, m.pos[i]);
    }
    return m;
}

// ---------------------------------------------------------------- arbor's camera

struct Camera {
    V3 eye, look_at, right, up, forward;
    float tan_half, aspect;
    uint32_t w, h;

    // CameraBasis::ray_dir.
    V3 ray_dir(uint32_t i, uint32_t j, float fx, float fy) const {
        float x = (2.0f * ((static_cast<float>(i) + fx) / static_cast<float>(w)) - 1.0f) * tan_half * aspect;
        float y = (1.0f - 2.0f * ((static_cast<float>(j) + fy) / static_cast<float>(h))) * tan_half;
        V3 d = forward + right * x + up * y;
        return d / length(d);
    }
};

// Rust's f32::to_radians multiplies by the f32 constant PI / 180.
constexpr float kRadPerDeg = 3.14159265358979323846f / 180.0f;

// framed_camera + Camera::basis.
Camera framed_camera(V3 lo, V3 hi, float vfov, uint32_t w, uint32_t h) {
    Camera c{};
    V3 centre = (lo + hi) * 0.5f;
    float r = std::max(length(hi - lo) * 0.5f, 1e-20f);
    float dist = r / std::sin(vfov * kRadPerDeg * 0.5f);
    c.eye = centre + V3{0.0f, 0.0f, dist};
    c.look_at = centre;
    c.forward = normalize(c.look_at - c.eye);
    c.right = normalize(cross(c.forward, V3{0.0f, 1.0f, 0.0f}));
    c.up = cross(c.right, c.forward);
    c.tan_half = std::tan(vfov * kRadPerDeg * 0.5f);
    c.aspect = static_cast<float>(w) / static_cast<float>(h);
    c.w = w;
    c.h = h;
    return c;
}

// The bench's camera rays: pixel centre, tmin 0 (shaders/trace.comp, sample 0).
constexpr float kFx = 0.5f, kFy = 0.5f, kTmin = 0.0f;

// ---------------------------------------------------------------- arbor's diffuse probe

uint32_t pcg_hash(uint32_t v) {
    uint32_t state = v * 747796405u + 2891336453u;
    uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}
uint32_t rng_init(uint32_t pixel, uint32_t sample, uint32_t seed) {
    return pcg_hash(pixel ^ pcg_hash(sample ^ pcg_hash(seed)));
}
float rng_next(uint32_t& s) {
    s = pcg_hash(s);
    return static_cast<float>(s >> 8u) * (1.0f / 16777216.0f);
}

constexpr float kPi = 3.14159265358979f;

V3 cosine_direction(V3 n, float u1, float u2) {
    float cos_t = std::sqrt(std::max(0.0f, 1.0f - u1));
    float sgn = n.z >= 0.0f ? 1.0f : -1.0f;  // onb: Duff et al. 2017
    float a = -1.0f / (sgn + n.z);
    float b_ = n.x * n.y * a;
    V3 t{1.0f + sgn * n.x * n.x * a, sgn * b_, -sgn * n.x};
    V3 b{b_, sgn + n.y * n.y * a, -n.y};
    float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
    float phi = 2.0f * kPi * u2;
    return normalize(t * (sin_t * std::cos(phi)) + b * (sin_t * std::sin(phi)) + n * cos_t);
}

constexpr float gamma_n(int n) {
    float e = std::numeric_limits<float>::epsilon() * 0.5f * static_cast<float>(n);
    return e / (1.0f - e);
}

// next_float_up / next_float_down (shaders/common/ray.glsl), -0 and +0 alike.
float next_float(float x, bool up) {
    if (std::isinf(x) && (x > 0.0f) == up) return x;
    uint32_t b;
    if (x == 0.0f) {
        b = up ? 1u : 0x80000001u;
    } else {
        std::memcpy(&b, &x, 4);
        b = (x > 0.0f) == up ? b + 1u : b - 1u;
    }
    std::memcpy(&x, &b, 4);
    return x;
}

struct Ray1 {
    V3 org, dir;
    uint32_t from;  // triangle it leaves
};

struct Hit {
    float t, u, v;
    uint32_t prim;
};

constexpr uint32_t kNone = RTC_INVALID_GEOMETRY_ID;

// The diffuse ray from camera hit `h` of pixel `pixel` (ray direction `d`).
// eps > 0: origin = p + n * eps; else arbor's offset_ray_origin.
Ray1 bounce_ray(const Mesh& m, uint32_t pixel, V3 d, const Hit& h, uint32_t seed, float eps) {
    V3 p0 = m.pos[m.tri[3 * h.prim]], p1 = m.pos[m.tri[3 * h.prim + 1]], p2 = m.pos[m.tri[3 * h.prim + 2]];
    // triangle_point
    float b0 = 1.0f - h.u - h.v;
    V3 a = p0 * b0, b = p1 * h.u, c = p2 * h.v;
    V3 p = a + b + c;
    V3 ext = vmax(vmax(p0, p1), p2) - vmin(vmin(p0, p1), p2);
    float size = std::max(std::max(ext.x, ext.y), ext.z) * gamma_n(32);
    V3 err = (vabs(a) + vabs(b) + vabs(c)) * gamma_n(7) + V3{size, size, size};
    V3 gn = normalize(cross(p1 - p0, p2 - p0));
    V3 n = dot(gn, d) < 0.0f ? gn : -gn;
    uint32_t rng = rng_init(pixel, 0, seed);
    float u1 = rng_next(rng);
    float u2 = rng_next(rng);
    V3 w = cosine_direction(n, u1, u2);
    V3 o;
    if (eps > 0.0f) {
        o = p + n * eps;
    } else {  // offset_ray_origin
        float dd = std::fabs(n.x) * err.x + std::fabs(n.y) * err.y + std::fabs(n.z) * err.z;
        V3 off = n * dd;
        if (w.x * n.x + w.y * n.y + w.z * n.z < 0.0f) off = -off;
        o = p + off;
        float* po[3] = {&o.x, &o.y, &o.z};
        const float of[3] = {off.x, off.y, off.z};
        for (int k = 0; k < 3; ++k) {
            if (of[k] > 0.0f)
                *po[k] = next_float(*po[k], true);
            else if (of[k] < 0.0f)
                *po[k] = next_float(*po[k], false);
        }
    }
    return {o, w, h.prim};
}

// ---------------------------------------------------------------- Embree

void embree_error(void*, RTCError code, const char* str) {
    std::fprintf(stderr, "embree_rays: Embree error %d: %s\n", static_cast<int>(code), str ? str : "");
    std::exit(1);
}

RTCScene build_scene(RTCDevice dev, const Mesh& m, RTCBuildQuality q, double* ms) {
    RTCScene scene = rtcNewScene(dev);
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_NONE);
    rtcSetSceneBuildQuality(scene, q);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(g, q);
    auto* vb = static_cast<float*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m.pos.size()));
    for (size_t i = 0; i < m.pos.size(); ++i) {
        vb[3 * i] = m.pos[i].x;
        vb[3 * i + 1] = m.pos[i].y;
        vb[3 * i + 2] = m.pos[i].z;
    }
    auto* ib = static_cast<uint32_t*>(
        rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(uint32_t), m.tris()));
    std::copy(m.tri.begin(), m.tri.end(), ib);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    auto t0 = std::chrono::steady_clock::now();
    rtcCommitScene(scene);
    *ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    return scene;
}

void init_ray(RTCRayHit& rh, V3 o, V3 d, float tmin) {
    rh.ray.org_x = o.x;
    rh.ray.org_y = o.y;
    rh.ray.org_z = o.z;
    rh.ray.tnear = tmin;
    rh.ray.dir_x = d.x;
    rh.ray.dir_y = d.y;
    rh.ray.dir_z = d.z;
    rh.ray.time = 0.0f;
    rh.ray.tfar = std::numeric_limits<float>::infinity();
    rh.ray.mask = ~0u;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = kNone;
    rh.hit.primID = kNone;
    rh.hit.instID[0] = kNone;
}

// ---------------------------------------------------------------- timing

void flush_denormals() {  // Embree asks for FTZ and DAZ on every thread that calls it
    _MM_SET_FLUSH_ZERO_MODE(_MM_FLUSH_ZERO_ON);
    _MM_SET_DENORMALS_ZERO_MODE(_MM_DENORMALS_ZERO_ON);
}

// Runs work(k) for k in [0, items) on `threads` threads (this one included) that take
// items from an atomic counter; returns the wall milliseconds.
template <class F>
double parallel(int threads, uint32_t items, const F& work) {
    std::atomic<uint32_t> next{0};
    auto body = [&] {
        flush_denormals();
        for (;;) {
            uint32_t k = next.fetch_add(1, std::memory_order_relaxed);
            if (k >= items) break;
            work(k);
        }
    };
    auto t0 = std::chrono::steady_clock::now();
    std::vector<std::thread> pool;
    for (int t = 1; t < threads; ++t) pool.emplace_back(body);
    body();
    for (auto& t : pool) t.join();
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

struct Times {
    double median, min, max;
};

// Median (mean of the middle two for an even count, as arbor's), min, max.
Times stats(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    size_t n = v.size();
    double med = n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
    return {med, v.front(), v.back()};
}

template <class F>
Times timed(int repeat, const F& run) {
    run();  // warm-up
    std::vector<double> ms;
    for (int r = 0; r < repeat; ++r) ms.push_back(run());
    return stats(ms);
}

// ---------------------------------------------------------------- options

struct Options {
    std::string mesh;
    uint32_t w = 1024, h = 1024;
    int threads = 2, repeat = 5;
    bool single = true, packet16 = true, diffuse = true;
    float vfov = 45.0f;
    uint32_t seed = 0;
    bool csv = false;
    RTCBuildQuality quality = RTC_BUILD_QUALITY_MEDIUM;
    float eps = 0.0f;  // relative to the bounding-box diagonal; 0 = arbor's offset
};

const char* kUsage =
    "usage: embree_rays MESH.obj [--size WxH] [--threads N] [--repeat N]\n"
    "                   [--modes single,packet16,diffuse] [--vfov DEG] [--seed N]\n"
    "                   [--quality low|medium|high] [--eps REL] [--csv]\n";

long parse_int(const std::string& opt, const std::string& s, long lo, long hi) {
    char* e;
    errno = 0;
    long v = std::strtol(s.c_str(), &e, 10);
    if (s.empty() || *e || errno || v < lo || v > hi)
        die(opt + " expects an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got '" + s + "'");
    return v;
}

Options parse_args(int argc, char** argv) {
    Options o;
    bool have_mesh = false;
    for (int i = 1; i < argc; ++i) {
        std::string a = argv[i];
        auto value = [&]() -> std::string {
            if (i + 1 >= argc) die(a + " needs a value");
            return argv[++i];
        };
        if (a == "-h" || a == "--help") {
            std::fputs(kUsage, stdout);
            std::exit(0);
        } else if (a == "--size") {
            std::string v = value();
            size_t x = v.find('x');
            if (x == std::string::npos) die("--size expects WxH, got '" + v + "'");
            o.w = static_cast<uint32_t>(parse_int("--size", v.substr(0, x), 1, 16384));
            o.h = static_cast<uint32_t>(parse_int("--size", v.substr(x + 1), 1, 16384));
        } else if (a == "--threads") {
            o.threads = static_cast<int>(parse_int(a, value(), 1, 1024));
        } else if (a == "--repeat") {
            o.repeat = static_cast<int>(parse_int(a, value(), 1, 1000));
        } else if (a == "--seed") {
            o.seed = static_cast<uint32_t>(parse_int(a, value(), 0, 4294967295L));
        } else if (a == "--vfov" || a == "--eps") {
            std::string v = value();
            char* e;
            float f = std::strtof(v.c_str(), &e);
            bool ok = !v.empty() && !*e && std::isfinite(f) && (a == "--vfov" ? f > 0 && f < 180 : f >= 0 && f < 1);
            if (!ok) die(a + (a == "--vfov" ? " expects degrees in (0, 180)" : " expects a fraction in [0, 1)") +
                         ", got '" + v + "'");
            (a == "--vfov" ? o.vfov : o.eps) = f;
        } else if (a == "--modes") {
            o.single = o.packet16 = o.diffuse = false;
            std::stringstream ss(value());
            std::string m;
            while (std::getline(ss, m, ',')) {
                if (m == "single") o.single = true;
                else if (m == "packet16") o.packet16 = true;
                else if (m == "diffuse") o.diffuse = true;
                else die("unknown mode '" + m + "' (single, packet16, diffuse)");
            }
        } else if (a == "--quality") {
            std::string v = value();
            if (v == "low") o.quality = RTC_BUILD_QUALITY_LOW;
            else if (v == "medium") o.quality = RTC_BUILD_QUALITY_MEDIUM;
            else if (v == "high") o.quality = RTC_BUILD_QUALITY_HIGH;
            else die("--quality expects low, medium or high, got '" + v + "'");
        } else if (a == "--csv") {
            o.csv = true;
        } else if (!a.empty() && a[0] == '-') {
            die("unknown option '" + a + "'\n" + kUsage);
        } else if (have_mesh) {
            die("one mesh only (got '" + o.mesh + "' and '" + a + "')");
        } else {
            o.mesh = a;
            have_mesh = true;
        }
    }
    if (!have_mesh) die(std::string("no mesh given\n") + kUsage);
    return o;
}

struct Row {
    std::string mode;
    Times trace;
    uint64_t rays, hits;
};

std::string csv_field(const std::string& s) {
    if (s.find_first_of(",\"\n") == std::string::npos) return s;
    std::string q = "\"";
    for (char c : s) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
}

}  // namespace

int main(int argc, char** argv) {
    Options o = parse_args(argc, argv);
    if (fuses_multiply_add())
        std::fprintf(stderr, "embree_rays: warning: built with fused multiply-add; rebuild with -ffp-contract=off "
                             "or the camera rays differ from arbor's in the last bits\n");
    Mesh mesh;
    try {
        mesh = load_obj(o.mesh);
    } catch (const Fail& e) {
        die(e.what());
    }
    if (mesh.pos.size() > std::numeric_limits<uint32_t>::max()) die(o.mesh + ": more than 2^32 vertices");
    FILE* info = o.csv ? stderr : stdout;  // with --csv, stdout is only the CSV
    // The camera in IEEE arithmetic, as arbor's (before denormals are flushed).
    const Camera cam = framed_camera(mesh.lo, mesh.hi, o.vfov, o.w, o.h);
    flush_denormals();

    const std::string config = "threads=" + std::to_string(o.threads);
    RTCDevice dev = rtcNewDevice(config.c_str());
    if (!dev) die("rtcNewDevice failed: " + std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))));
    rtcSetDeviceErrorFunction(dev, embree_error, nullptr);
    const char* tasking[] = {"internal", "TBB", "PPL"};
    long task = static_cast<long>(rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_TASKING_SYSTEM));
    std::fprintf(info, "Embree %s (tasking %s, native ray16 %s, backface culling %s), device \"%s\"\n",
                 RTC_VERSION_STRING, task >= 0 && task < 3 ? tasking[task] : "?",
                 rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_NATIVE_RAY16_SUPPORTED) ? "yes" : "no",
                 rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED) ? "on" : "off",
                 config.c_str());

    // Build: one warm-up, then --repeat builds; the last one is traced.
    RTCScene scene = nullptr;
    std::vector<double> build_ms;
    for (int r = 0; r <= o.repeat; ++r) {
        if (scene) rtcReleaseScene(scene);
        double ms;
        scene = build_scene(dev, mesh, o.quality, &ms);
        if (r > 0) build_ms.push_back(ms);
    }
    Times build = stats(build_ms);
    const char* qname[] = {"low", "medium", "high"};
    std::fprintf(info, "mesh %s: %zu triangles, %zu vertices; build (quality %s) median %.2f ms (min %.2f, max %.2f)\n",
                 o.mesh.c_str(), mesh.tris(), mesh.pos.size(), qname[o.quality], build.median, build.min, build.max);

    std::fprintf(info,
                 "camera: vfov %g, eye (%.9g, %.9g, %.9g), look_at (%.9g, %.9g, %.9g), tan_half %.9g, "
                 "aspect %.9g; pixel offsets (%g, %g), tmin %g\n",
                 o.vfov, cam.eye.x, cam.eye.y, cam.eye.z, cam.look_at.x, cam.look_at.y, cam.look_at.z, cam.tan_half,
                 cam.aspect, kFx, kFy, kTmin);

    const uint32_t W = o.w, H = o.h;
    const uint64_t pixels = uint64_t(W) * H;
    constexpr uint32_t kTile = 16;
    const uint32_t tiles_x = (W + kTile - 1) / kTile, tiles_y = (H + kTile - 1) / kTile;
    const uint32_t tiles = tiles_x * tiles_y;
    const V3 eye = cam.eye;

    // Camera hits per pixel (untimed, single rays): the reference for the other modes
    // and the diffuse rays' starting points.
    std::vector<Hit> cam_hit(pixels);
    parallel(o.threads, tiles, [&](uint32_t k) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        uint32_t x0 = (k % tiles_x) * kTile, y0 = (k / tiles_x) * kTile;
        for (uint32_t j = y0; j < std::min(y0 + kTile, H); ++j)
            for (uint32_t i = x0; i < std::min(x0 + kTile, W); ++i) {
                RTCRayHit rh;
                init_ray(rh, eye, cam.ray_dir(i, j, kFx, kFy), kTmin);
                rtcIntersect1(scene, &ctx, &rh);
                cam_hit[uint64_t(j) * W + i] = {rh.ray.tfar, rh.hit.u, rh.hit.v, rh.hit.primID};
            }
    });
    uint64_t cam_hits = 0;
    for (const Hit& h : cam_hit) cam_hits += h.prim != kNone;
    std::fprintf(info, "camera rays %llu: hit %llu, miss %llu (%.1f per million)\n",
                 static_cast<unsigned long long>(pixels), static_cast<unsigned long long>(cam_hits),
                 static_cast<unsigned long long>(pixels - cam_hits), (pixels - cam_hits) * 1e6 / pixels);

    std::vector<Row> rows;
    std::vector<uint32_t> prim(pixels);
    auto differ_from_reference = [&] {
        uint64_t n = 0;
        for (uint64_t p = 0; p < pixels; ++p) n += prim[p] != cam_hit[p].prim;
        return n;
    };

    if (o.single) {
        Times t = timed(o.repeat, [&] {
            return parallel(o.threads, tiles, [&](uint32_t k) {
                RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                uint32_t x0 = (k % tiles_x) * kTile, y0 = (k / tiles_x) * kTile;
                for (uint32_t j = y0; j < std::min(y0 + kTile, H); ++j)
                    for (uint32_t i = x0; i < std::min(x0 + kTile, W); ++i) {
                        RTCRayHit rh;
                        init_ray(rh, eye, cam.ray_dir(i, j, kFx, kFy), kTmin);
                        rtcIntersect1(scene, &ctx, &rh);
                        prim[uint64_t(j) * W + i] = rh.hit.primID;
                    }
            });
        });
        rows.push_back({"single", t, pixels, cam_hits});
        if (uint64_t d = differ_from_reference()) std::fprintf(info, "single: %llu pixels differ between runs\n",
                                                               static_cast<unsigned long long>(d));
    }

    if (o.packet16) {
        Times t = timed(o.repeat, [&] {
            return parallel(o.threads, tiles, [&](uint32_t k) {
                RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                uint32_t x0 = (k % tiles_x) * kTile, y0 = (k / tiles_x) * kTile;
                for (uint32_t py = y0; py < std::min(y0 + kTile, H); py += 4)
                    for (uint32_t px = x0; px < std::min(x0 + kTile, W); px += 4) {
                        RTCRayHit16 rh;
                        alignas(64) int valid[16];
                        for (uint32_t l = 0; l < 16; ++l) {
                            uint32_t i = px + (l & 3), j = py + (l >> 2);
                            valid[l] = i < W && j < H ? -1 : 0;
                            V3 d = valid[l] ? cam.ray_dir(i, j, kFx, kFy) : V3{0.0f, 0.0f, 1.0f};
                            rh.ray.org_x[l] = eye.x;
                            rh.ray.org_y[l] = eye.y;
                            rh.ray.org_z[l] = eye.z;
                            rh.ray.tnear[l] = kTmin;
                            rh.ray.dir_x[l] = d.x;
                            rh.ray.dir_y[l] = d.y;
                            rh.ray.dir_z[l] = d.z;
                            rh.ray.time[l] = 0.0f;
                            rh.ray.tfar[l] = std::numeric_limits<float>::infinity();
                            rh.ray.mask[l] = ~0u;
                            rh.ray.id[l] = l;
                            rh.ray.flags[l] = 0;
                            rh.hit.geomID[l] = kNone;
                            rh.hit.primID[l] = kNone;
                            rh.hit.instID[0][l] = kNone;
                        }
                        rtcIntersect16(valid, scene, &ctx, &rh);
                        for (uint32_t l = 0; l < 16; ++l)
                            if (valid[l]) prim[uint64_t(py + (l >> 2)) * W + px + (l & 3)] = rh.hit.primID[l];
                    }
            });
        });
        uint64_t hits = 0;
        for (uint32_t p : prim) hits += p != kNone;
        rows.push_back({"packet16", t, pixels, hits});
        std::fprintf(info, "packet16: %llu pixels hit another triangle than single rays\n",
                     static_cast<unsigned long long>(differ_from_reference()));
    }

    if (o.diffuse) {
        const float diag = length(mesh.hi - mesh.lo);
        const float eps = o.eps * diag;
        // The bounce rays, in pixel order, made before timing.
        std::vector<Ray1> bounce;
        bounce.reserve(cam_hits);
        auto g0 = std::chrono::steady_clock::now();
        for (uint32_t j = 0; j < H; ++j)
            for (uint32_t i = 0; i < W; ++i) {
                const Hit& h = cam_hit[uint64_t(j) * W + i];
                if (h.prim != kNone)
                    bounce.push_back(bounce_ray(mesh, j * W + i, cam.ray_dir(i, j, kFx, kFy), h, o.seed, eps));
            }
        const double gen_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - g0).count();
        const uint32_t nb = static_cast<uint32_t>(bounce.size());
        constexpr uint32_t kChunk = 256;
        std::vector<uint32_t> bprim(nb);
        Times t = timed(o.repeat, [&] {
            return parallel(o.threads, (nb + kChunk - 1) / kChunk, [&](uint32_t k) {
                RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                for (uint32_t r = k * kChunk; r < std::min(nb, (k + 1) * kChunk); ++r) {
                    RTCRayHit rh;
                    init_ray(rh, bounce[r].org, bounce[r].dir, 0.0f);
                    rtcIntersect1(scene, &ctx, &rh);
                    bprim[r] = rh.hit.primID;
                }
            });
        });
        uint64_t bhits = 0, self = 0;
        for (uint32_t r = 0; r < nb; ++r) {
            bhits += bprim[r] != kNone;
            self += bprim[r] == bounce[r].from;
        }
        rows.push_back({"diffuse", t, nb, bhits});
        char offset[64] = "arbor's offset_ray_origin";
        if (eps > 0.0f) std::snprintf(offset, sizeof offset, "fixed %.3g along the normal", eps);
        std::fprintf(info,
                     "diffuse rays %u (origin offset: %s; made untimed in %.2f ms on one thread): hit %llu, "
                     "of which their own triangle %llu\n",
                     nb, offset, gen_ms,
                     static_cast<unsigned long long>(bhits), static_cast<unsigned long long>(self));

        // Camera and bounce together, as arbor's diffuse rows count them: per pixel the
        // camera ray, then (on a hit) its bounce ray made and traced.
        std::vector<uint8_t> bhit(pixels);
        Times tc = timed(o.repeat, [&] {
            return parallel(o.threads, tiles, [&](uint32_t k) {
                RTCIntersectContext ctx;
                rtcInitIntersectContext(&ctx);
                uint32_t x0 = (k % tiles_x) * kTile, y0 = (k / tiles_x) * kTile;
                for (uint32_t j = y0; j < std::min(y0 + kTile, H); ++j)
                    for (uint32_t i = x0; i < std::min(x0 + kTile, W); ++i) {
                        RTCRayHit rh;
                        V3 d = cam.ray_dir(i, j, kFx, kFy);
                        init_ray(rh, eye, d, kTmin);
                        rtcIntersect1(scene, &ctx, &rh);
                        uint64_t p = uint64_t(j) * W + i;
                        prim[p] = rh.hit.primID;
                        bhit[p] = 0;
                        if (rh.hit.primID == kNone) continue;
                        Ray1 b = bounce_ray(mesh, static_cast<uint32_t>(p), d,
                                            {rh.ray.tfar, rh.hit.u, rh.hit.v, rh.hit.primID}, o.seed, eps);
                        init_ray(rh, b.org, b.dir, 0.0f);
                        rtcIntersect1(scene, &ctx, &rh);
                        bhit[p] = rh.hit.primID != kNone;
                    }
            });
        });
        uint64_t hits = 0;
        for (uint64_t p = 0; p < pixels; ++p) hits += (prim[p] != kNone) + bhit[p];
        rows.push_back({"diffuse+camera", tc, pixels + nb, hits});
    }

    // Report.
    std::string base = o.mesh.substr(o.mesh.find_last_of('/') == std::string::npos ? 0 : o.mesh.find_last_of('/') + 1);
    if (o.csv) {
        std::printf(
            "mesh,triangles,width,height,threads,mode,build_ms,trace_ms_median,trace_ms_min,trace_ms_max,rays,"
            "mrays_per_s,hit_fraction\n");
        for (const Row& r : rows)
            std::printf("%s,%zu,%u,%u,%d,%s,%.3f,%.3f,%.3f,%.3f,%llu,%.3f,%.6f\n", csv_field(base).c_str(),
                        mesh.tris(), W, H, o.threads, r.mode.c_str(), build.median, r.trace.median, r.trace.min,
                        r.trace.max, static_cast<unsigned long long>(r.rays), r.rays / (r.trace.median * 1e3),
                        r.rays ? double(r.hits) / r.rays : 0.0);
    } else {
        std::printf("\n%-16s %9s %9s %9s %9s %9s %10s %9s %8s\n", "mode", "triangles", "build_ms", "trace_ms",
                    "min", "max", "rays", "Mrays/s", "hit");
        for (const Row& r : rows)
            std::printf("%-16s %9zu %9.2f %9.2f %9.2f %9.2f %10llu %9.2f %8.4f\n", r.mode.c_str(), mesh.tris(),
                        build.median, r.trace.median, r.trace.min, r.trace.max,
                        static_cast<unsigned long long>(r.rays), r.rays / (r.trace.median * 1e3),
                        r.rays ? double(r.hits) / r.rays : 0.0);
    }
    rtcReleaseScene(scene);
    rtcReleaseDevice(dev);
    return 0;
}
