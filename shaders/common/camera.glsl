// Pinhole camera; twin of CameraBasis::ray_dir in src/scene/camera.rs.
#ifndef ARBOR_CAMERA_GLSL
#define ARBOR_CAMERA_GLSL

vec3 camera_ray_dir(uint i, uint j, float fx, float fy) {
    float w = float(params.width);
    float h = float(params.height);
    precise float x = (2.0 * ((float(i) + fx) / w) - 1.0) * params.tan_half_fov * params.aspect;
    precise float y = (1.0 - 2.0 * ((float(j) + fy) / h)) * params.tan_half_fov;
    precise vec3 d = params.cam_forward + params.cam_right * x + params.cam_up * y;
    return d / sqrt(dot3(d, d));
}

#endif
