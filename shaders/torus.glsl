// Torus math in float32, line for line the same as src/pat/torus_math.hpp (the CPU reference).

// Signed distance of a torus with curvatures (k1 along e1, k2 along e2) at y = (y1, y2, y3) in
// the frame (e1, e2, n) centered on the torus point q; grad receives the gradient in that frame.
float torus_sdf_local(float k1, float k2, vec3 y, out vec3 grad) {
    float y1 = y.x, y2 = y.y, y3 = y.z;
    float yp2 = y2 * y2 + y3 * y3;
    float tau = k1 != 0.0 ? clamp(k2 / k1, -1.0, 1.0) : 0.0;
    float u2 = k2 * y2, u3 = k2 * y3 - 1.0;
    float sqrtS = sqrt(u2 * u2 + u3 * u3);
    float D = sqrtS + (1.0 - tau);
    float E, F;
    if (D > 1e-30) {
        E = (k1 * k2 * yp2 - 2.0 * k1 * y3 + 2.0 - tau) / D;
        F = ((tau * k2 * yp2 - 2.0 * tau * y3) / (sqrtS + 1.0) - k2 * yp2 + 2.0 * y3) / D;
    } else {
        E = 0.0;
        F = 1.0 / k1;
    }
    float k1y1 = k1 * y1;
    float Q = sqrt(E * E + k1y1 * k1y1);
    float g = (F * (1.0 + E) - k1 * y1 * y1) / (1.0 + Q);
    if (Q > 1e-30) {
        float w = sqrtS > 1e-30 ? E / sqrtS : 0.0;
        grad = vec3(-k1y1, -w * u2, -w * u3) / Q;
    } else {
        grad = vec3(0.0, 0.0, 1.0);
    }
    return g;
}

// A torus stored as three vec4: (q, k1), (e1, k2), (n, 0). World-space SDF and gradient.
float torus_sdf(vec4 t0, vec4 t1, vec4 t2, vec3 x, out vec3 grad_world) {
    vec3 e1 = t1.xyz, n = t2.xyz;
    vec3 e2 = cross(n, e1);
    vec3 y = x - t0.xyz;
    vec3 gl;
    float g = torus_sdf_local(t0.w, t1.w, vec3(dot(y, e1), dot(y, e2), dot(y, n)), gl);
    grad_world = gl.x * e1 + gl.y * e2 + gl.z * n;
    return g;
}
