// Camera convention (see README): OpenCV camera space, +X right, +Y down, +Z forward.
// A world point p maps to camera space as q = R * p + t, and to pixel coordinates as
// (fx * q.x / q.z + cx, fy * q.y / q.z + cy), the centre of pixel (i, j) being (i + 0.5, j + 0.5).
#ifndef RELIT_CAMERA_GLSL
#define RELIT_CAMERA_GLSL

struct Camera {
    vec4 r0;          // rows of the world-to-camera matrix [R | t]
    vec4 r1;
    vec4 r2;
    vec4 intrinsics;  // fx, fy, cx, cy
    vec4 size_clip;   // width, height, near, far
};

vec3 cam_from_world(Camera c, vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(c.r0, h), dot(c.r1, h), dot(c.r2, h));
}

// World-space position of the camera centre: -R^T t.
vec3 cam_center(Camera c) {
    vec3 t = vec3(c.r0.w, c.r1.w, c.r2.w);
    return -(c.r0.xyz * t.x + c.r1.xyz * t.y + c.r2.xyz * t.z);
}

// World-space direction (unnormalized) through continuous pixel coordinate `px`.
vec3 cam_ray_dir(Camera c, vec2 px) {
    vec3 d = vec3((px.x - c.intrinsics.z) / c.intrinsics.x, (px.y - c.intrinsics.w) / c.intrinsics.y, 1.0);
    return c.r0.xyz * d.x + c.r1.xyz * d.y + c.r2.xyz * d.z;
}

#endif
