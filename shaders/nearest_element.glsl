// The nearest element to x for every lane of a subgroup, the subgroup walking the tree together
// (shm_diffuse.comp's step 1 and sdf_nearest.comp's software build): a node is opened when any
// lane's best so far reaches its box, children first in the order most of those lanes prefer,
// and each lane takes the elements of the leaves it still needed. Exact for every lane: a node
// no lane needs holds nothing nearer for any. Uniform control flow.
//
// The including shader declares, before this file: the tree (box_tree.glsl's node_lo, node_hi,
// node_begin, node_end), element_distance2(x, j), STACK (the stack's entries), NONE and
// pc.first_leaf.
//
// The pushes are not under a branch: llvmpipe would store them under the lanes' mask,
// reloading each masked-off lane's old value first — for every leaf and every node no lane
// needs (docs/gpu.md, "Kernels shaped for software devices"). They go to the spare slot STACK
// where there is nothing to push.

// The nearest element's index (NONE if none), its squared distance in best2. `group_iters`
// counts the walk's iterations (llvmpipe's loop limit); the walk stops once they reach `cap`
// (0: never).
uint nearest_element_together(vec3 x, bool live, uint cap, inout uint group_iters, out float best2) {
    best2 = 3.0e38;
    uint best = NONE;
    uint stack[STACK + 1];
    int top = 0;
    stack[top++] = 0u;
    while (top > 0) {
        uint i = stack[--top];
        ++group_iters;
        bool need = live && box_distance2(x, node_lo(i), node_hi(i)) < best2;
        bool opened = subgroupAny(need), leaf = i >= pc.first_leaf;
        if (opened && leaf) {
            group_iters += node_end(i) - node_begin(i);
            for (uint j = node_begin(i); j < node_end(i); ++j) {
                float d2 = element_distance2(x, j);
                if (need && d2 < best2) {
                    best2 = d2;
                    best = j;
                }
            }
        }
        uint l = leaf ? i : 2u * i + 1u, r = leaf ? i : 2u * i + 2u;
        bool prefers_left = box_distance2(x, node_lo(l), node_hi(l)) <= box_distance2(x, node_lo(r), node_hi(r));
        uint left = subgroupBallotBitCount(subgroupBallot(need && prefers_left));
        uint right = subgroupBallotBitCount(subgroupBallot(need && !prefers_left));
        bool left_first = left >= right, push = opened && !leaf;
        stack[push ? top : STACK] = left_first ? r : l;  // the preferred child is popped first
        stack[push ? top + 1 : STACK] = left_first ? l : r;
        top += push ? 2 : 0;
        if (cap != 0u && group_iters >= cap) break;
    }
    return best;
}
