// The SumTree of src/sums/sum_tree.hpp as kernels walk it (uploaded by src/sums/sums_gpu.cpp).
// The including shader declares, before this file (as storage or texel buffers):
//   node_lo(i), node_hi(i), node_begin(i), node_end(i): boxes and element ranges
//                     (box_tree.glsl's Node; children 2i+1, 2i+2)
//   MOMENT(i)         the moments' vec4 i: 9 per node, flat index k: 0–2 center c, 3 radius ρ,
//                     4–6 M0, 7 area,
//                     8–16 M1 (3a+i), 17–34 M2 (6a + xx yy zz xy xz yz)
//   ELEM(i)           the elements' vec4 i: 3 per element: (a, v.x), (b, v.y), (c, v.z)

const float FOUR_PI = 12.566370614359172;

// Software devices: llvmpipe (lavapipe) stops every loop of a shader, silently, once the SIMD
// group running it has iterated 65535 times in all. Kernels count their own iterations and
// flag a query at `lane_cap` = 65535 / lanes per group; the host redoes flagged groups on the
// CPU (sums_gpu.hpp).

float mom(uint node, uint k) { return MOMENT(9u * node + (k >> 2))[k & 3u]; }
vec3 mom3(uint node, uint k) { return vec3(mom(node, k), mom(node, k + 1u), mom(node, k + 2u)); }

// uᵀ S u and S u for the symmetric S at flat index k (xx yy zz xy xz yz).
float sym_quad(uint node, uint k, vec3 u) {
    return mom(node, k) * u.x * u.x + mom(node, k + 1u) * u.y * u.y + mom(node, k + 2u) * u.z * u.z +
           2.0 * (mom(node, k + 3u) * u.x * u.y + mom(node, k + 4u) * u.x * u.z + mom(node, k + 5u) * u.y * u.z);
}
float sym_trace(uint node, uint k) { return mom(node, k) + mom(node, k + 1u) + mom(node, k + 2u); }
float sym_row(uint node, uint k, uint a, vec3 u) {
    if (a == 0u) return mom(node, k) * u.x + mom(node, k + 3u) * u.y + mom(node, k + 4u) * u.z;
    if (a == 1u) return mom(node, k + 3u) * u.x + mom(node, k + 1u) * u.y + mom(node, k + 5u) * u.z;
    return mom(node, k + 4u) * u.x + mom(node, k + 5u) * u.y + mom(node, k + 2u) * u.z;
}

// Signed solid angle of a triangle seen from x, / 4π (Van Oosterom–Strackee).
float triangle_winding(vec3 x, vec3 a, vec3 b, vec3 c) {
    a -= x; b -= x; c -= x;
    float la = length(a), lb = length(b), lc = length(c);
    float num = dot(a, cross(b, c));
    float den = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb;
    return 2.0 * atan(num, den) / FOUR_PI;
}

// Squared distance from x to the segment pq.
float segment_distance2(vec3 x, vec3 p, vec3 q) {
    vec3 e = q - p;
    float l2 = dot(e, e);
    float t = l2 > 0.0 ? clamp(dot(x - p, e) / l2, 0.0, 1.0) : 0.0;
    vec3 d = x - (p + t * e);
    return dot(d, d);
}

// Squared distance from x to the triangle (a, b, c): Voronoi regions, as on the CPU.
float triangle_distance2(vec3 x, vec3 a, vec3 b, vec3 c) {
    vec3 ab = b - a, ac = c - a, ap = x - a;
    vec3 n = cross(ab, ac);
    if (!(dot(n, n) > 1e-12 * dot(ab, ab) * dot(ac, ac)))
        return min(segment_distance2(x, a, b), min(segment_distance2(x, b, c), segment_distance2(x, c, a)));
    float d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0.0 && d2 <= 0.0) return dot(ap, ap);
    vec3 bp = x - b;
    float d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0.0 && d4 <= d3) return dot(bp, bp);
    float vc = d1 * d4 - d3 * d2;
    if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) { vec3 e = x - (a + d1 / (d1 - d3) * ab); return dot(e, e); }
    vec3 cp = x - c;
    float d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0.0 && d5 <= d6) return dot(cp, cp);
    float vb = d5 * d2 - d1 * d6;
    if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) { vec3 e = x - (a + d2 / (d2 - d6) * ac); return dot(e, e); }
    float va = d3 * d6 - d5 * d4;
    if (va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0) {
        vec3 e = x - (b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b));
        return dot(e, e);
    }
    float s = dot(n, ap);
    return s * s / dot(n, n);
}
