// Coupling between cell c and its +axis neighbor on the level described by pc.dims/axes_off;
// requires `AxisEntry axes[]` declared by the including shader.
float coupling(uvec3 c, int a) {
    int b = (a + 1) % 3, d = (a + 2) % 3;
    float face = axes[pc.axes_off[b] + c[b]].size * axes[pc.axes_off[d] + c[d]].size;
    float dist = 0.5 * (axes[pc.axes_off[a] + c[a]].size + axes[pc.axes_off[a] + c[a] + 1].size);
    return face / dist * pc.inv_h2[a];
}
