// Robustness helpers and primitive tests. Twins of src/math/{float,aabb,intersect}.rs
// with the same names and operation order; `precise` keeps the compiler from fusing
// multiply-adds so CPU and GPU round alike.
#ifndef ARBOR_RAY_GLSL
#define ARBOR_RAY_GLSL

struct Ray {
    vec3 origin;
    vec3 dir;
    float tmin;
    float tmax;
};

struct Hit {
    float t;
    uint prim;   // triangles first, then spheres; 0xffffffff = none
    float u;
    float v;
};

const uint NO_PRIM = 0xffffffffu;

// pbrt-v4 gamma(n): bound on the relative error of n float operations.
float gamma(uint n) {
    precise float e = 5.9604645e-8 * float(n);
    return e / (1.0 - e);
}

// Reciprocal that is never inf or NaN; -0 counts as negative. See src/math/float.rs.
float safe_rcp(float x) {
    if (abs(x) > 1e-30) return 1.0 / x;
    return (floatBitsToUint(x) & 0x80000000u) != 0u ? -1e30 : 1e30;
}

vec3 safe_rcp3(vec3 d) {
    return vec3(safe_rcp(d.x), safe_rcp(d.y), safe_rcp(d.z));
}

// Wachter & Binder, Ray Tracing Gems (2019) ch. 6. See src/math/float.rs.
vec3 offset_ray_origin(vec3 p, vec3 n) {
    const float ORIGIN = 1.0 / 32.0;
    const float FLOAT_SCALE = 1.0 / 65536.0;
    const float INT_SCALE = 256.0;
    ivec3 of_i = ivec3(INT_SCALE * n);
    vec3 p_i = vec3(
        intBitsToFloat(floatBitsToInt(p.x) + (p.x < 0.0 ? -of_i.x : of_i.x)),
        intBitsToFloat(floatBitsToInt(p.y) + (p.y < 0.0 ? -of_i.y : of_i.y)),
        intBitsToFloat(floatBitsToInt(p.z) + (p.z < 0.0 ? -of_i.z : of_i.z)));
    return vec3(
        abs(p.x) < ORIGIN ? p.x + FLOAT_SCALE * n.x : p_i.x,
        abs(p.y) < ORIGIN ? p.y + FLOAT_SCALE * n.y : p_i.y,
        abs(p.z) < ORIGIN ? p.z + FLOAT_SCALE * n.z : p_i.z);
}

// Slab test; far padded by 1 + 2 gamma(7) (Ize 2013; Vulkan's 2.5-ulp division). A
// zero direction component (|1/d| saturated at 1e30 by safe_rcp) makes its slab
// everything when the origin lies within it, faces included, else nothing. Returns
// false on a miss, else the clipped [enter, exit] interval. See src/math/aabb.rs.
bool ray_box(vec3 bmin, vec3 bmax, vec3 origin, vec3 inv_dir, float tmin, float tmax, out float enter, out float exit_t) {
    vec3 t0 = (bmin - origin) * inv_dir;
    vec3 t1 = (bmax - origin) * inv_dir;
    vec3 near_t = min(t0, t1);
    vec3 far_t = max(t0, t1) * (1.0 + 2.0 * gamma(7u));
    bvec3 flat_axis = greaterThanEqual(abs(inv_dir), vec3(1e30));
    bvec3 lo = greaterThanEqual(origin, bmin);
    bvec3 hi = lessThanEqual(origin, bmax);
    bvec3 inside = bvec3(lo.x && hi.x, lo.y && hi.y, lo.z && hi.z);
    const float BIG = 3.4028235e38;
    vec3 flat_near = mix(vec3(BIG), vec3(-BIG), inside);
    near_t = mix(near_t, flat_near, flat_axis);
    far_t = mix(far_t, -flat_near, flat_axis);
    enter = max(max(max(near_t.x, near_t.y), near_t.z), tmin);
    exit_t = min(min(min(far_t.x, far_t.y), far_t.z), tmax);
    return enter <= exit_t;
}

// a lies before b by more than the relative margin T_MARGIN = 1e-5 of the trees'
// and grids' cell boundaries (see `before` in src/accel/kdtree/mod.rs).
bool before(float a, float b) {
    precise float m = a * (1.0 + 1e-5);
    return m < b;
}

float dot3(vec3 a, vec3 b) {
    precise float r = a.x * b.x + a.y * b.y + a.z * b.z;
    return r;
}

vec3 cross3(vec3 a, vec3 b) {
    precise vec3 r = vec3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
    return r;
}

// Moller & Trumbore 1997, two-sided, no epsilon. See src/math/intersect.rs.
bool ray_triangle(Ray r, vec3 v0, vec3 v1, vec3 v2, out float t, out float u, out float v) {
    t = 0.0; u = 0.0; v = 0.0;
    precise vec3 e1 = v1 - v0;
    precise vec3 e2 = v2 - v0;
    vec3 p = cross3(r.dir, e2);
    float det = dot3(e1, p);
    if (det == 0.0 || isinf(det) || isnan(det)) return false;
    precise float inv = 1.0 / det;
    precise vec3 s = r.origin - v0;
    precise float uu = dot3(s, p) * inv;
    if (!(uu >= 0.0 && uu <= 1.0)) return false;
    vec3 q = cross3(s, e1);
    precise float vv = dot3(r.dir, q) * inv;
    if (vv < 0.0 || uu + vv > 1.0) return false;
    precise float tt = dot3(e2, q) * inv;
    t = tt; u = uu; v = vv;
    return tt > r.tmin && tt <= r.tmax;
}

// Haines, Gunther & Akenine-Moller, Ray Tracing Gems (2019) ch. 7. Unit direction.
bool ray_sphere(Ray r, vec3 center, float radius, out float t) {
    t = 0.0;
    precise vec3 f = r.origin - center;
    precise float b = -dot3(f, r.dir);
    precise vec3 l = f + b * r.dir;
    precise float r2 = radius * radius;
    precise float disc = r2 - dot3(l, l);
    if (disc < 0.0) return false;
    precise float c = dot3(f, f) - r2;
    precise float q = b >= 0.0 ? b + sqrt(disc) : b - sqrt(disc);
    if (q == 0.0) return false;
    precise float t0 = c / q;
    float t1 = q;
    float near_t = t0 < t1 ? t0 : t1;
    float far_t = t0 < t1 ? t1 : t0;
    if (near_t > r.tmin && near_t <= r.tmax) { t = near_t; return true; }
    if (far_t > r.tmin && far_t <= r.tmax) { t = far_t; return true; }
    return false;
}

#endif
