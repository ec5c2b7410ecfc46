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
#ifdef HAS_INSTANCES
    uint inst;   // the entry hit (common/instances.glsl); valid where prim is
#endif
};

const uint NO_PRIM = 0xffffffffu;

// pbrt-v4 gamma(n) = n eps / (1 - n eps), eps = 2^-24: a bound on the relative error
// of n float operations. The values used are literals (gamma(n) of src/math/float.rs
// to 9 digits, which round to its exact bits; checked by a test there) because Vulkan's division is not
// correctly rounded, and error bounds must agree bit for bit with the CPU's.
const float GAMMA_1 = 5.96046519e-8;
const float GAMMA_5 = 2.98023309e-7;
const float GAMMA_7 = 4.17232684e-7;
const float GAMMA_32 = 1.90735227e-6;

// Reciprocal that is never inf or NaN; -0 counts as negative. See src/math/float.rs.
float safe_rcp(float x) {
    if (abs(x) > 1e-30) return 1.0 / x;
    return (floatBitsToUint(x) & 0x80000000u) != 0u ? -1e30 : 1e30;
}

vec3 safe_rcp3(vec3 d) {
    return vec3(safe_rcp(d.x), safe_rcp(d.y), safe_rcp(d.z));
}

// Next float toward +inf / -inf (pbrt-v4 NextFloatUp/Down); -0 and +0 alike.
float next_float_up(float x) {
    if (isinf(x) && x > 0.0) return x;
    if (x == 0.0) return uintBitsToFloat(1u);
    uint b = floatBitsToUint(x);
    return uintBitsToFloat(x > 0.0 ? b + 1u : b - 1u);
}

float next_float_down(float x) {
    if (isinf(x) && x < 0.0) return x;
    if (x == 0.0) return uintBitsToFloat(0x80000001u);
    uint b = floatBitsToUint(x);
    return uintBitsToFloat(x > 0.0 ? b - 1u : b + 1u);
}

// pbrt-v4 OffsetRayOrigin: the hit point p (error box err) moved off its surface
// along the geometric normal n toward the side w leaves to, by the error projected on
// n, then one ulp further. See src/math/float.rs.
vec3 offset_ray_origin(vec3 p, vec3 err, vec3 n, vec3 w) {
    precise float d = abs(n.x) * err.x + abs(n.y) * err.y + abs(n.z) * err.z;
    precise vec3 offset = n * d;
    precise float side = w.x * n.x + w.y * n.y + w.z * n.z;
    if (side < 0.0) offset = -offset;
    precise vec3 po = p + offset;
    for (int i = 0; i < 3; i++) {
        if (offset[i] > 0.0) po[i] = next_float_up(po[i]);
        else if (offset[i] < 0.0) po[i] = next_float_down(po[i]);
    }
    return po;
}

// Point on a triangle at barycentrics (u, v) of p1, p2, and its error bound for
// spawning rays: gamma(7) (|b0 p0| + |b1 p1| + |b2 p2|) (pbrt-v4) plus gamma(32) x the
// triangle's size. See src/math/float.rs.
void triangle_point(vec3 p0, vec3 p1, vec3 p2, float u, float v, out vec3 p, out vec3 err) {
    precise float b0 = 1.0 - u - v;
    precise vec3 a = p0 * b0;
    precise vec3 b = p1 * u;
    precise vec3 c = p2 * v;
    precise vec3 pp = a + b + c;
    vec3 ext = max(max(p0, p1), p2) - min(min(p0, p1), p2);
    precise float size = max(max(ext.x, ext.y), ext.z) * GAMMA_32;
    precise vec3 e = (abs(a) + abs(b) + abs(c)) * GAMMA_7 + vec3(size);
    p = pp;
    err = e;
}

// Hit point at t on the sphere, its error bound, and its offset from the centre
// rebuilt from the ray's closest approach (exact for spheres below the float spacing
// at their position). See sphere_point in src/math/float.rs.
void sphere_point(vec3 origin, vec3 dir, float t, vec3 center, float radius, out vec3 p, out vec3 err, out vec3 rel) {
    precise vec3 f = origin - center;
    precise float b = -(f.x * dir.x + f.y * dir.y + f.z * dir.z);
    precise vec3 l = f + dir * b;
    precise float disc = max(radius * radius - (l.x * l.x + l.y * l.y + l.z * l.z), 0.0);
    precise float sq = sqrt(disc);
    precise vec3 pc = t < b ? l - dir * sq : l + dir * sq;
    precise float len = sqrt(pc.x * pc.x + pc.y * pc.y + pc.z * pc.z);
    if (len > 0.0) {
        precise float k = radius / len;
        pc = pc * k;
    }
    precise vec3 pp = center + pc;
    precise vec3 e = abs(pc) * GAMMA_5 + abs(pp) * GAMMA_1;
    p = pp;
    err = e;
    rel = pc;
}

// Slab test; far padded by 1 + 2 gamma(7) (Ize 2013; Vulkan's 2.5-ulp division). A
// zero direction component (|1/d| saturated at 1e30 by safe_rcp) makes its slab
// everything when the origin lies within it, faces included, else nothing. Returns
// false on a miss, else the clipped [enter, exit] interval. See src/math/aabb.rs.
bool ray_box(vec3 bmin, vec3 bmax, vec3 origin, vec3 inv_dir, float tmin, float tmax, out float enter, out float exit_t) {
    vec3 t0 = (bmin - origin) * inv_dir;
    vec3 t1 = (bmax - origin) * inv_dir;
    vec3 near_t = min(t0, t1);
    vec3 far_t = max(t0, t1) * (1.0 + 2.0 * GAMMA_7);
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

// Dekker's exact error a b - p of the rounded product p (Veltkamp split).
float two_product_error(float a, float b, float p) {
    precise float ca = 4097.0 * a;
    precise float ah = ca - (ca - a);
    precise float al = a - ah;
    precise float cb = 4097.0 * b;
    precise float bh = cb - (cb - b);
    precise float bl = b - bh;
    precise float e = ((ah * bh - p) + ah * bl + al * bh) + al * bl;
    return e;
}

// a b - c d, re-evaluated exactly where it rounds to zero. See edge_function in
// src/math/intersect.rs.
float edge_function(float a, float b, float c, float d) {
    precise float p1 = a * b;
    precise float p2 = c * d;
    precise float r = p1 - p2;
    if (r != 0.0) return r;
    precise float e = two_product_error(a, b, p1) - two_product_error(c, d, p2);
    return e;
}

// Woop, Benthin & Wald 2013: shear to ray space, edge functions from the shared
// transformed vertices (zero counts as inside for both signs), two-sided. See
// ray_triangle_watertight in src/math/intersect.rs for the argument; same operations.
bool ray_triangle_watertight(Ray r, vec3 v0, vec3 v1, vec3 v2, out float t, out float u, out float v) {
    t = 0.0; u = 0.0; v = 0.0;
    vec3 ad = abs(r.dir);
    uint kz = ad.x > ad.y ? (ad.x > ad.z ? 0u : 2u) : (ad.y > ad.z ? 1u : 2u);
    uint kx = (kz + 1u) % 3u;
    uint ky = (kz + 2u) % 3u;
    if (r.dir[kz] < 0.0) { uint tmp = kx; kx = ky; ky = tmp; }
    precise float sz = 1.0 / r.dir[kz];
    precise float sx = r.dir[kx] * sz;
    precise float sy = r.dir[ky] * sz;
    precise vec3 a = v0 - r.origin;
    precise vec3 b = v1 - r.origin;
    precise vec3 c = v2 - r.origin;
    precise float ax = a[kx] - sx * a[kz];
    precise float ay = a[ky] - sy * a[kz];
    precise float bx = b[kx] - sx * b[kz];
    precise float by = b[ky] - sy * b[kz];
    precise float cx = c[kx] - sx * c[kz];
    precise float cy = c[ky] - sy * c[kz];
    float eu = edge_function(cx, by, cy, bx);
    float ev = edge_function(ax, cy, ay, cx);
    float ew = edge_function(bx, ay, by, ax);
    if ((eu < 0.0 || ev < 0.0 || ew < 0.0) && (eu > 0.0 || ev > 0.0 || ew > 0.0)) return false;
    precise float det = eu + ev + ew;
    if (det == 0.0 || isinf(det) || isnan(det)) return false;
    precise float az = sz * a[kz];
    precise float bz = sz * b[kz];
    precise float cz = sz * c[kz];
    precise float ts = eu * az + ev * bz + ew * cz;
    precise float inv = 1.0 / det;
    precise float tt = ts * inv;
    t = tt; u = ev * inv; v = ew * inv;
    return tt > r.tmin && tt <= r.tmax;
}

// Moller & Trumbore 1997, two-sided, no epsilon. See src/math/intersect.rs.
bool ray_triangle_fast(Ray r, vec3 v0, vec3 v1, vec3 v2, out float t, out float u, out float v) {
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
    precise float hx = f.x * f.x;
    precise float hy = f.y * f.y;
    precise float hz = f.z * f.z;
    precise float lo = two_product_error(f.x, f.x, hx) + two_product_error(f.y, f.y, hy) + two_product_error(f.z, f.z, hz);
    precise float c = ((hx + hy + hz) - r2) + (lo - two_product_error(radius, radius, r2));
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
