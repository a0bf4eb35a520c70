// The added lights' emitters, drawn where a ray meets one before any surface, as the ground
// truth shows them: the output pass for camera rays, the target mirror for reflected rays.
// Shapes at binding 19 (the scene's added lights, in E_add layer order), this frame's
// intensities at binding 11.
#ifndef RELIT_EMITTERS_GLSL
#define RELIT_EMITTERS_GLSL
#extension GL_EXT_scalar_block_layout : require
#include "lights.glsl"

layout(set = 0, binding = 11) readonly buffer Intensity { float intensity[]; };
layout(set = 0, binding = 19, scalar) readonly buffer Emitters { Light emitters[]; };

// Whether the ray (o, unit d) meets a lit added light closer than t; then t becomes its
// distance and radiance its emitted radiance times its intensity.
bool nearest_emitter(vec3 o, vec3 d, uint nlights, inout float t, out vec3 radiance) {
    bool found = false;
    radiance = vec3(0.0);
    for (uint l = 0u; l < nlights; ++l) {
        if (intensity[l] <= 0.0) continue;
        float tl = light_hit(emitters[l], o, d);
        if (tl > 0.0 && tl < t) {
            t = tl;
            radiance = intensity[l] * emitters[l].radiance.rgb;
            found = true;
        }
    }
    return found;
}

#endif
