// Best-first k-nearest search over the kd-tree of box_tree.glsl (mirrors BoxTree::knn).
// TICK_LANE(n), if the includer defines it, counts this lane's loop iterations (the renderer's
// guard against llvmpipe's loop limit, render_march.glsl).
// The including shader defines KNN_MAX (the array size: a constant or a specialization
// constant) and STACK (tree depth bound), and includes box_tree_buffers.glsl (the nodes and the
// points in tree order) before including this file.

#ifndef TICK_LANE
#define TICK_LANE(n)
#endif

float node_distance2(vec3 x, uint i) { return box_distance2(x, node_lo(i), node_hi(i)); }

// The k ≤ KNN_MAX nearest points to x other than point `skip` (0xffffffff: none skipped),
// nearest first: distances kd, tree-order indices ki. Ties at equal distance keep the point
// found first. Entries past k are left at (3e38, 0).
void knn(vec3 x, uint k, uint skip, uint first_leaf, inout float kd[KNN_MAX], inout uint ki[KNN_MAX]) {
    for (int m = 0; m < KNN_MAX; ++m) { kd[m] = 3.0e38; ki[m] = 0; }
    uint stack[STACK];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        uint i = stack[--top];
        float worst = kd[k - 1];
        TICK_LANE(1);
        if (node_distance2(x, i) > worst * worst) continue;
        if (i >= first_leaf) {
            TICK_LANE(node_end(i) - node_begin(i) + 1u);
            for (uint j = node_begin(i); j < node_end(i); ++j) {
                float d = distance(x, point_at(j).xyz);
                if (d >= kd[k - 1] || j == skip) continue;
                int m = int(k) - 1;
                TICK_LANE(1);
                while (m > 0 && kd[m - 1] > d) { TICK_LANE(1); kd[m] = kd[m - 1]; ki[m] = ki[m - 1]; --m; }
                kd[m] = d;
                ki[m] = j;
            }
        } else {
            uint l = 2 * i + 1, r = 2 * i + 2;
            bool left_first = node_distance2(x, l) <= node_distance2(x, r);
            stack[top++] = left_first ? r : l;  // the nearer child is popped first
            stack[top++] = left_first ? l : r;
        }
    }
}
