// The lights drawn where a ray meets them, as the ground truth shows them: the output pass for
// camera rays, the target mirror for reflected rays.
// - Added lights, at binding 19 (in E_add layer order) with this frame's intensities at binding
//   11: their radiance where one is met before any surface.
// - Declared original lights, at binding 29: on the proxy surface they sit on, their glow as
//   the photos show it, dimmed by α_dim (§4.1.4) and their own factor (binding 32,
//   frame/lighting.rs), plus their own surface's reflection of the
//   added lights (its albedo from the bake's albedo mesh around it). The ratio rule would scale
//   the glow as if it were reflected light.
#ifndef RELIT_EMITTERS_GLSL
#define RELIT_EMITTERS_GLSL
#extension GL_EXT_scalar_block_layout : require
#include "constants.glsl"
#include "lights.glsl"

layout(set = 0, binding = 11) readonly buffer Intensity { float intensity[]; };
layout(set = 0, binding = 19, scalar) readonly buffer Emitters { Light emitters[]; };
// A declared original light and the diffuse albedo of its own surface (frame::output::GpuOriginal).
struct Original { Light light; vec4 albedo; };
layout(set = 0, binding = 29, scalar) readonly buffer Originals { Original originals[]; };
// Each declared original light's factor (rgb; 1: as captured), per-light control.
layout(set = 0, binding = 32) readonly buffer Keep { vec4 keep[]; };

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

// Whether the proxy point y, seen along unit d, lies on the emitting side of a declared original
// light (within LIGHT_SKIN of its plane, inside its outline grown by `margin` metres: the pixels
// the photos' pixel filter spreads its glow into); then radiance is what it shows:
//   (1 − α_dim) · c_l · I + ρ · E_add / π,
// the ratio rule with the light's albedo ρ taken from its surroundings (the albedo mesh) rather
// than I / E_src: I holds glow, not only reflected light. I: the photos' radiance at y (`seen`);
// where no view sees y (black), the light's declared radiance on the light itself, nothing drawn
// beside it. ea: E_add at y.
bool original_light(vec3 y, vec3 d, uint norig, float alpha_dim, vec3 seen, vec3 ea,
                    float margin, out vec3 radiance) {
    radiance = vec3(0.0);
    bool hole = all(equal(seen, vec3(0.0)));
    for (uint l = 0u; l < norig; ++l) {
        Light o = originals[l].light;
        if (dot(d, light_normal(o)) >= 0.0 || !light_near(o, y, LIGHT_SKIN + margin, margin)) continue;
        if (hole && !light_near(o, y, LIGHT_SKIN, 0.0)) continue;
        vec3 glow = hole ? o.radiance.rgb : seen;
        radiance = (1.0 - alpha_dim) * keep[l].rgb * glow + originals[l].albedo.rgb / 3.14159265358979 * ea;
        return true;
    }
    return false;
}

#endif
