// The kd-tree of src/spatial/box_tree.hpp as kernels walk it. Node i has children 2i+1 and
// 2i+2; nodes at or past `first_leaf` are leaves holding points [begin, end) in tree order.
// The including shader declares `Node nodes[]` and `vec4 pts[]` buffers before this file.

struct Node { vec3 lo; uint begin; vec3 hi; uint end; };

float box_distance2(vec3 x, vec3 lo, vec3 hi) {
    vec3 e = max(max(lo - x, x - hi), vec3(0.0));
    return dot(e, e);
}
