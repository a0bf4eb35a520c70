// Shared by the novel-view frame passes (§4.2.2, §4.3, §4.4): one binding number per resource
// across all of them (each pass declares only what it reads), the novel view's G-buffer, the
// per-frame list of active input views and sampling of the per-view maps (texture arrays, one
// layer per view; E_add one layer per light and view, layer = light * nviews + view).
#ifndef RELIT_FRAME_GLSL
#define RELIT_FRAME_GLSL

#define VIEWS_BINDING 0
#include "views.glsl"

// The novel view's G-buffer (raster/gbuffer.*): world position + camera depth, normal.
layout(set = 0, binding = 4, rgba32f) readonly uniform image2D g_pos;
layout(set = 0, binding = 5, rgba32f) readonly uniform image2D g_nrm;

// MAX_ACTIVE: at most this many input views take part in a frame's reprojection.
#include "constants.glsl"

// Rec. 709 luminance of linear RGB.
float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); }

// Continuous pixel coordinate of world point p in view j.
vec2 project_px(uint j, vec3 p) {
    Camera c = cams[j];
    vec3 q = cam_from_world(c, p);
    return vec2(c.intrinsics.x * q.x / q.z + c.intrinsics.z, c.intrinsics.y * q.y / q.z + c.intrinsics.w);
}

// Bilinear sample of a per-view map at continuous pixel coordinate px (clamp to edge). The
// texture may be padded to whole 4x4 blocks (BC6H): normalize by its own extent.
vec3 sample_map(sampler2DArray t, vec2 px, uint layer) {
    vec2 size = vec2(textureSize(t, 0).xy);
    return textureLod(t, vec3(px / size, float(layer)), 0.0).rgb;
}

// The novel-view surface at pixel p: position, normal facing `eye`, and whether there is one.
bool surface(uint p, uint width, vec3 eye, out vec3 x, out vec3 n, out float depth) {
    ivec2 xy = ivec2(p % width, p / width);
    vec4 xp = imageLoad(g_pos, xy);
    depth = xp.w;
    x = xp.xyz;
    n = imageLoad(g_nrm, xy).xyz;
    if (dot(n, eye - x) < 0.0) n = -n;
    return xp.w > 0.0;
}

#endif
