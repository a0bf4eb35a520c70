// The input views as the bake and frame passes read them: cameras, per-view G-buffers of the
// proxy mesh (position + camera depth, normal) and colour images, all views at one resolution,
// stored view-major. A shader that includes this declares one binding, VIEWS_BINDING: a uniform
// block with the five buffers' device addresses (bake::GpuViews). The buffers are read through
// buffer-device-address pointers because lavapipe (Mesa 25.0) compiles a storage-buffer load
// whose offset is not a compile-time constant (a view index from a loop, a pixel from a
// projection) into a loop over the lanes with a bounds check each, and a pointer load into one
// masked gather. The includer enables GL_EXT_buffer_reference, GL_EXT_buffer_reference_uvec2 and
// GL_EXT_scalar_block_layout.
#ifndef RELIT_VIEWS_GLSL
#define RELIT_VIEWS_GLSL
#include "camera.glsl"

layout(buffer_reference, scalar, buffer_reference_align = 16) readonly buffer CameraRef { Camera v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 16) readonly buffer Vec4Ref { vec4 v[]; };
layout(buffer_reference, scalar, buffer_reference_align = 4) readonly buffer UintRef { uint v[]; };
layout(set = 0, binding = VIEWS_BINDING, scalar) uniform Views {
    uvec2 cameras; uvec2 positions; uvec2 normals; uvec2 images; uvec2 tris;
} views_addr;
#define cams (CameraRef(views_addr.cameras).v)
#define gpos (Vec4Ref(views_addr.positions).v)
#define gnrm (Vec4Ref(views_addr.normals).v)
#define images (Vec4Ref(views_addr.images).v)
// Per view and pixel: the proxy triangle + 1 (0: none), from the views' G-buffers.
#define pixel_tri (UintRef(views_addr.tris).v)

// DEPTH_EPS, the visibility test's tolerance: the point is seen by view j when its camera depth
// agrees with view j's depth map within this fraction (MVS meshes are only this good).
#include "constants.glsl"

// Whether global pixel q clipped in its photo (images' w = 0): a lower bound of the radiance,
// which the gathers leave out.
bool clipped(int q) { return images[q].w <= 0.0; }

// Pixel index (into a view's maps) where p projects in view j when j sees p; -1 otherwise.
int visible_pixel(uint j, vec3 p, uint W, uint H) {
    Camera c = cams[j];
    vec3 q = cam_from_world(c, p);
    if (q.z <= 1e-3) return -1;
    vec2 px = vec2(c.intrinsics.x * q.x / q.z + c.intrinsics.z, c.intrinsics.y * q.y / q.z + c.intrinsics.w);
    if (px.x < 0.0 || px.y < 0.0 || px.x >= float(W) || px.y >= float(H)) return -1;
    uint idx = j * W * H + uint(px.y) * W + uint(px.x);
    float d = gpos[idx].w;
    if (d <= 0.0 || abs(d - q.z) > DEPTH_EPS * q.z) return -1;
    return int(idx);
}

// The pixel (global index) of the view, other than `exclude`, that sees y from the direction
// closest to `dir` (largest cos between camera→y and dir); -1 when no view sees y.
// Source irradiance (§4.1.1) and mirror images (§4.2) both choose their view this way.
int best_view(vec3 y, vec3 dir, uint exclude, uint nviews, uint W, uint H) {
    float best = -2.0;
    int best_px = -1;
    for (uint j = 0u; j < nviews; ++j) {
        if (j == exclude) continue;
        // The direction first: the depth test (a gather from the view's G-buffer) only for a
        // view that would beat the best so far.
        float c = dot(normalize(y - cam_center(cams[j])), dir);
        if (c <= best) continue;
        int q = visible_pixel(j, y, W, H);
        if (q >= 0) { best = c; best_px = q; }
    }
    return best_px;
}

#endif
