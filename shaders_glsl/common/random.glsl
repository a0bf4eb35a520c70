// Counter-based random numbers: the same (a, b, c) gives the same numbers on the GPU and in the
// CPU references (engine/src/cpu.rs mirrors these functions bit for bit).
#ifndef RELIT_RANDOM_GLSL
#define RELIT_RANDOM_GLSL

// PCG-style 3D hash (Jarzynski & Olano 2020, "pcg3d").
uvec3 pcg3d(uvec3 v) {
    v = v * 1664525u + 1013904223u;
    v.x += v.y * v.z; v.y += v.z * v.x; v.z += v.x * v.y;
    v ^= v >> 16u;
    v.x += v.y * v.z; v.y += v.z * v.x; v.z += v.x * v.y;
    return v;
}

// Two uniform numbers in [0, 1) with 24 bits each (exact in fp32).
vec2 rand2(uvec3 key) {
    uvec3 h = pcg3d(key);
    return vec2(h.xy >> 8u) * (1.0 / 16777216.0);
}

// Orthonormal basis around unit n (Duff et al. 2017).
void onb(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// Cosine-weighted direction about n from u in [0,1)^2.
vec3 cosine_dir(vec3 n, vec2 u) {
    vec3 t, b;
    onb(n, t, b);
    float r = sqrt(u.x);
    float phi = 6.28318530718 * u.y;
    return normalize(t * (r * cos(phi)) + b * (r * sin(phi)) + n * sqrt(max(0.0, 1.0 - u.x)));
}

#endif
