// The buffers of a point cloud's kd-tree (box_tree.glsl) as the blend, the renderer and the
// k-nearest search read them: points in tree order, the nodes and, where the includer defines
// TERMS_BINDING, the per-point terms. The includer defines POINTS_BINDING and NODES_BINDING.
// Built with GSD_SOFTWARE_SHAPED (the kernels software devices run, gpu::software_shaped) they
// are uniform texel buffers of vec4 — a Node is two: (lo, begin), (hi, end) —, which llvmpipe
// reads with one gather where it reads a storage buffer one lane and one float at a time; else
// storage buffers. Kernels read them through point_at, term_at and node_lo/hi/begin/end.
#ifdef GSD_SOFTWARE_SHAPED
layout(binding = POINTS_BINDING) uniform samplerBuffer point_texels;
layout(binding = NODES_BINDING) uniform samplerBuffer node_texels;
vec4 point_at(uint j) { return texelFetch(point_texels, int(j)); }
vec3 node_lo(uint i) { return texelFetch(node_texels, int(2u * i)).xyz; }
vec3 node_hi(uint i) { return texelFetch(node_texels, int(2u * i + 1u)).xyz; }
uint node_begin(uint i) { return floatBitsToUint(texelFetch(node_texels, int(2u * i)).w); }
uint node_end(uint i) { return floatBitsToUint(texelFetch(node_texels, int(2u * i + 1u)).w); }
#ifdef TERMS_BINDING
layout(binding = TERMS_BINDING) uniform samplerBuffer term_texels;
vec4 term_at(uint k) { return texelFetch(term_texels, int(k)); }
#endif
#else
layout(std430, binding = POINTS_BINDING) readonly buffer Points { vec4 pts[]; };
layout(std430, binding = NODES_BINDING) readonly buffer Nodes { Node nodes[]; };
vec4 point_at(uint j) { return pts[j]; }
vec3 node_lo(uint i) { return nodes[i].lo; }
vec3 node_hi(uint i) { return nodes[i].hi; }
uint node_begin(uint i) { return nodes[i].begin; }
uint node_end(uint i) { return nodes[i].end; }
#ifdef TERMS_BINDING
layout(std430, binding = TERMS_BINDING) readonly buffer Terms { vec4 terms[]; };
vec4 term_at(uint k) { return terms[k]; }
#endif
#endif
