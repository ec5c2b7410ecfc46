// Pinhole camera; twin of CameraBasis::ray_dir in src/scene/camera.rs.
#ifndef ARBOR_CAMERA_GLSL
#define ARBOR_CAMERA_GLSL

vec3 camera_ray_dir(uint i, uint j, float fx, float fy) {
    float w = float(params.dims.x);
    float h = float(params.dims.y);
    precise float x = (2.0 * ((float(i) + fx) / w) - 1.0) * params.cam_eye.w * params.cam_right.w;
    precise float y = (1.0 - 2.0 * ((float(j) + fy) / h)) * params.cam_eye.w;
    precise vec3 d = params.cam_forward.xyz + params.cam_right.xyz * x + params.cam_up.xyz * y;
    return d / sqrt(dot3(d, d));
}

#endif
