#version 460
// The window's picture (engine/src/view/compose.rs): the rendered frame (RGBA8 at its own size)
// scaled bilinearly into the window with its aspect kept (black bars), and the HUD's text drawn
// over it in white on a dimmed box. Written in the swapchain's byte order for a buffer copy.
layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) readonly buffer Src { uint src[]; };
layout(set = 0, binding = 1) writeonly buffer Dst { uint dst[]; };
// 128 ASCII glyphs, 8 rows of 8 bits (bit 0 leftmost), four rows to a word.
layout(set = 0, binding = 2) readonly buffer Font { uint font[]; };
// rows × cols character codes.
layout(set = 0, binding = 3) readonly buffer Text { uint text[]; };

layout(push_constant) uniform Push {
    uint src_w; uint src_h; uint dst_w; uint dst_h;
    // Where the frame lands in the window.
    uint fit_x; uint fit_y; uint fit_w; uint fit_h;
    // The text's top-left pixel, its size in cells (rows 0: no HUD), pixels per font pixel.
    uint hud_x; uint hud_y; uint cols; uint rows;
    uint scale; uint bgr;
} pc;

vec4 texel(int x, int y) {
    return unpackUnorm4x8(src[uint(y) * pc.src_w + uint(x)]) * 255.0;
}

// Bilinear at the window pixel's centre mapped into the frame; pixel centres align.
uvec3 frame_colour(uint x, uint y) {
    if (x < pc.fit_x || y < pc.fit_y || x >= pc.fit_x + pc.fit_w || y >= pc.fit_y + pc.fit_h)
        return uvec3(0);
    float u = (float(x - pc.fit_x) + 0.5) * (float(pc.src_w) / float(pc.fit_w)) - 0.5;
    float v = (float(y - pc.fit_y) + 0.5) * (float(pc.src_h) / float(pc.fit_h)) - 0.5;
    u = clamp(u, 0.0, float(pc.src_w - 1));
    v = clamp(v, 0.0, float(pc.src_h - 1));
    int x0 = int(u), y0 = int(v);
    int x1 = min(x0 + 1, int(pc.src_w) - 1), y1 = min(y0 + 1, int(pc.src_h) - 1);
    float fx = u - float(x0), fy = v - float(y0);
    vec4 top = texel(x0, y0) * (1.0 - fx) + texel(x1, y0) * fx;
    vec4 bot = texel(x0, y1) * (1.0 - fx) + texel(x1, y1) * fx;
    vec4 c = top * (1.0 - fy) + bot * fy;
    return uvec3(c.rgb + 0.5);
}

// The HUD over colour c: inside the box dimmed to 90/256, a glyph's pixels white.
uvec3 hud(uint x, uint y, uvec3 c) {
    uint s = pc.scale, margin = 2u * s;
    uint cw = 8u * s, lh = 10u * s;
    if (pc.rows == 0u || x + margin < pc.hud_x || y + margin < pc.hud_y) return c;
    if (x >= pc.hud_x + pc.cols * cw + margin || y >= pc.hud_y + pc.rows * lh + margin) return c;
    c = (c * 90u) >> 8;
    if (x < pc.hud_x || y < pc.hud_y) return c;
    uint col = (x - pc.hud_x) / cw, row = (y - pc.hud_y) / lh;
    uint gx = (x - pc.hud_x) % cw / s, gy = (y - pc.hud_y) % lh / s;
    if (col >= pc.cols || row >= pc.rows || gy >= 8u) return c;
    uint ch = text[row * pc.cols + col] & 127u;
    uint bits = font[ch * 2u + gy / 4u] >> (8u * (gy % 4u));
    return ((bits >> gx) & 1u) != 0u ? uvec3(255u) : c;
}

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= pc.dst_w || p.y >= pc.dst_h) return;
    uvec3 c = hud(p.x, p.y, frame_colour(p.x, p.y));
    if (pc.bgr != 0u) c = c.bgr;
    dst[p.y * pc.dst_w + p.x] = c.r | (c.g << 8) | (c.b << 16) | (255u << 24);
}
