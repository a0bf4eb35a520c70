// Which view pixels show a declared original light, or bleed from one: such a pixel is no
// radiance sample of the surface behind it (the image's pixel filter spreads the emitter up to
// LEAK_PX pixels into its neighbours). The includer declares views.glsl's buffers and
// `lights[]` (the declared lights) first.
#ifndef RELIT_NEAR_LIGHT_GLSL
#define RELIT_NEAR_LIGHT_GLSL
#include "constants.glsl"
#include "lights.glsl"

// Whether view pixel q (global index into views of W×H pixels) shows or bleeds from a light.
bool near_light(int q, uint W, uint H, uint nlights) {
    vec4 g = gpos[q];
    uint j = uint(q) / (W * H);
    float margin = LEAK_PX * g.w / cams[j].intrinsics.x;
    for (uint l = 0u; l < nlights; ++l) {
        if (light_near(lights[l], g.xyz, LIGHT_SKIN + margin, margin)) return true;
    }
    return false;
}

#endif
