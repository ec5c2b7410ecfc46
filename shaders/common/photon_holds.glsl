// photon::holds: whether visible point v holds p within its radius, |p - x_v|^2 <
// r_v^2 summed in the host's order without fused multiply-adds, so that device and
// host agree at the radius. Needs PHOTON_POINT(v), visible point v's vec4 position +
// radius, defined before it (a storage buffer's element, or the photon pass's texel).
#ifndef ARBOR_PHOTON_HOLDS_GLSL
#define ARBOR_PHOTON_HOLDS_GLSL

bool photon_holds(uint v, vec3 p) {
    vec4 pr = PHOTON_POINT(v);
    precise vec3 d = p - pr.xyz;
    precise float d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    precise float r2 = pr.w * pr.w;
    return d2 < r2;
}

#endif
