#version 460
// Reads a layer of a sampled 2D-array texture back into a buffer, sampling at texel centres
// through the sampler (linear filtering on): tests that compressed view storage decodes and
// filters on the device as the frame passes will sample it.
layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) uniform sampler2DArray tex;
layout(set = 0, binding = 1) writeonly buffer Out { vec4 texels[]; };

layout(push_constant) uniform Push { uint width; uint height; uint layer; } pc;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= pc.width || p.y >= pc.height) return;
    vec2 uv = (vec2(p) + 0.5) / vec2(pc.width, pc.height);
    texels[p.y * pc.width + p.x] = texture(tex, vec3(uv, float(pc.layer)));
}
