// The frame's mesh (the bake mesh, whose triangle ids + 1 the G-buffer's g_tri holds): its
// vertices and each triangle's three vertex indices. The includer enables scalar layout.
#ifndef RELIT_FRAME_MESH_GLSL
#define RELIT_FRAME_MESH_GLSL

layout(set = 0, binding = 21, scalar) readonly buffer LiveVerts { vec3 live_verts[]; };
layout(set = 0, binding = 22) readonly buffer LiveIndices { uint live_indices[]; };

#endif
