// Per-light control of the declared original lights (frame/lighting.rs): the share of E_src their
// factors (emitters.glsl's `keep`) remove. The includer includes frame.glsl and emitters.glsl.
#ifndef RELIT_ORIGINALS_GLSL
#define RELIT_ORIGINALS_GLSL

// The share of one input view's E_src that the original lights' factors remove (beyond α_dim),
// at its pixel px: Σ_l (1 − c_l)·E_l / Σ_l E_l per channel, E_l the simulated irradiance of
// original l (E_add layer first + l·nviews + j of `t`; nsplit of them: 0 or norig); the mean of
// (1 − c_l) where less than SHARE_MIN arrives or no light has layers (frame/lighting.rs).
vec3 removed_share(sampler2DArray t, vec2 px, uint j, uint nviews, uint norig, uint nsplit,
                   uint first) {
    vec3 mean = vec3(0.0), num = vec3(0.0), den = vec3(0.0);
    for (uint l = 0u; l < norig; ++l) mean += vec3(1.0) - keep[l].rgb;
    mean /= float(max(norig, 1u));
    for (uint l = 0u; l < nsplit; ++l) {
        vec3 e = sample_map(t, px, first + l * nviews + j);
        num += (vec3(1.0) - keep[l].rgb) * e;
        den += e;
    }
    return mix(mean, num / max(den, vec3(SHARE_MIN)), greaterThan(den, vec3(SHARE_MIN)));
}

#endif
