// The kd-tree of src/spatial/box_tree.hpp as kernels walk it. Node i has children 2i+1 and
// 2i+2; nodes at or past `first_leaf` are leaves holding points [begin, end) in tree order.
// box_tree_buffers.glsl declares the buffers (or a kernel its own, with the same accessors).

struct Node { vec3 lo; uint begin; vec3 hi; uint end; };

float box_distance2(vec3 x, vec3 lo, vec3 hi) {
    vec3 e = max(max(lo - x, x - hi), vec3(0.0));
    return dot(e, e);
}

// The node after `node` in depth-first order, skipping `node`'s subtree; 0 when the walk is
// over. With k = node + 1 (1-based heap numbering: left children even, right children odd),
// climb past the trailing 1 bits — the right children — and step to the right sibling; all
// ones is the root's rightmost path.
uint next_in_depth_first(uint node) {
    uint k = node + 1u;
    return k >> uint(findLSB(~k));  // the sibling k + 1, 0-based
}
