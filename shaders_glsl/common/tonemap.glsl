// The tonemap of §5.2 that the network's images live in, tm(x) = log(1 + MU x) / log(1 + MU),
// and its inverse (Rust: relit_engine::constants::{tonemap, untonemap}).
#ifndef RELIT_TONEMAP_GLSL
#define RELIT_TONEMAP_GLSL
#include "constants.glsl"
vec3 tm(vec3 x) { return log(1.0 + MU * max(x, vec3(0.0))) / log(1.0 + MU); }
vec3 untm(vec3 y) { return (pow(vec3(1.0 + MU), max(y, vec3(0.0))) - 1.0) / MU; }
#endif
