// The frame's constants (§4–§5.2): one push block shared by every novel-view frame pass
// (reproject, irradiance, target mirror, glossy sums and layer, features, output), filled once
// per frame by `Renderer::frame_constants` into `FrameConstants` (engine/src/frame/constants.rs,
// the same members in the same order; tests/gpu.rs holds its layout against every shader that
// includes this). 108 bytes: within the 128 that Vulkan guarantees. Each pass reads the members
// it needs; the output pass reads the novel camera from the `NovelCamera` buffer (80 bytes would
// not fit here).
#ifndef RELIT_FRAME_CONSTANTS_GLSL
#define RELIT_FRAME_CONSTANTS_GLSL

layout(push_constant) uniform FrameConstants {
    vec4 eye;          // the novel camera's centre (w = 1)
    uint width;        // the novel view's size in pixels
    uint height;
    uint view_w;       // the input views' size in pixels
    uint view_h;
    uint nviews;       // input views in the capture
    uint nactive;      // the frame's active views (`Active`)
    uint exclude;      // a view left out of the frame (0xFFFFFFFF: none)
    uint nlights;      // added lights
    uint norig;        // declared original lights (emitters.glsl)
    uint nlive;        // live lights (live.glsl): their count and which added lights they are
    uint live_mask;
    uint nsplit;       // per-light control (originals.glsl): the original lights with E_add
    uint split_layer;  // layers (0 or all), the first of those layers, and whether some
    uint per_light;    // original light has a factor of its own
    float alpha_dim;   // §4.1.4: 0 keeps the original lighting, 1 removes it
    uint mode;         // output: 0 network, 1 ULR, 2 ratio, 3 ratio-filled, 4 glossy
    float exposure;    // output: the display image's linear scale
    uint fill;         // output: 1: holes filled from the nearest covered pixels (`hole_fill`)
    uint base;         // NetBase: 0 none, 1 ratio, 2 glossy
    float shrink;      // NetConfig::shrink (0: none)
    float gate;        // NetConfig::gate (0: none)
    uint gain;         // NetConfig::gain (1: the diffuse correction is a gain on the base)
    float agree;       // NetConfig::agree (0: none)
} pc;

#endif
