/* The element Hessian by the split of femshell/shell/element.py (docs/theory.md §2):
 *   H = J^T W_zz J + sum_ij W_a_ij Hess(a_ij) + sum_k W_q_k Hess(q_k),
 * z = (a11, a12, a22, q0, q1, q2), with q_k's value, gradient and Hessian in its 10 relative unknowns
 * from the generated q_<kind> and W's from w_<law> (kernel_codegen.py, prepended to this file with
 * the edge-kind constants INTERIOR, FREE, CLAMPED, SYMMETRY and SCRATCH).
 * Arrays row-major: q (m, 21), abar_inv and bbar (m, 2, 2), area and hbar (m), kind (m, 3),
 * direction (m, 3, 3), sign (m, 3); out: Hessians (m, 21, 21), energies (m) and gradients (m, 21) (these two
 * may be NULL). element_gradients: the energies and gradients alone, by the reverse sweeps alone. */

/* symmetry edges: the plane's in-plane normal across the edge, on the face normal's side (the frozen
   sign of bending._prescribed_or_turned) */
static double symmetry_flip(const double *u, double sign, const double *d)
{
    const double *b = u, *c = u + 3;
    double n[3] = {b[1] * c[2] - b[2] * c[1], b[2] * c[0] - b[0] * c[2], b[0] * c[1] - b[1] * c[0]};
    double t[3] = {sign * b[0], sign * b[1], sign * b[2]};
    double s[3] = {d[1] * t[2] - d[2] * t[1], d[2] * t[0] - d[0] * t[2], d[0] * t[1] - d[1] * t[0]};
    return s[0] * n[0] + s[1] * n[1] + s[2] * n[2] + 1e-300 >= 0.0 ? 1.0 : -1.0;
}

static double edge(int64_t kind, const double *u, double sign, const double *d, double *D, double *E, double *g,
                   double *h)
{
    if (kind == INTERIOR) return q_interior(u, sign, d[0], d[1], d[2], 1.0, D, E, g, h);
    if (kind == FREE) return q_free(u, sign, d[0], d[1], d[2], 1.0, D, E, g, h);
    if (kind == CLAMPED) return q_clamped(u, sign, d[0], d[1], d[2], 1.0, D, E, g, h);
    return q_symmetry(u, sign, d[0], d[1], d[2], symmetry_flip(u, sign, d), D, E, g, h);
}

/* edge() without the Hessian: the same value and gradient bits */
static double edge_gradient(int64_t kind, const double *u, double sign, const double *d, double *g)
{
    if (kind == INTERIOR) return q_interior_gradient(u, sign, d[0], d[1], d[2], 1.0, g);
    if (kind == FREE) return q_free_gradient(u, sign, d[0], d[1], d[2], 1.0, g);
    if (kind == CLAMPED) return q_clamped_gradient(u, sign, d[0], d[1], d[2], 1.0, g);
    return q_symmetry_gradient(u, sign, d[0], d[1], d[2], symmetry_flip(u, sign, d), g);
}

/* the metric's z = (a11, a12, a22) and their rows of J; J's other rows zeroed */
static void metric_rows(const double *q, double J[6][21], double *z)
{
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 21; j++) J[i][j] = 0.0;
    z[0] = z[1] = z[2] = 0.0;
    for (int c = 0; c < 3; c++) {
        double e1 = q[3 + c] - q[c], e2 = q[6 + c] - q[c];
        J[0][c] = -2.0 * e1; J[0][3 + c] = 2.0 * e1;
        J[1][c] = -(e1 + e2); J[1][3 + c] = e2; J[1][6 + c] = e1;
        J[2][c] = -2.0 * e2; J[2][6 + c] = 2.0 * e2;
        z[0] += e1 * e1; z[1] += e1 * e2; z[2] += e2 * e2;
    }
}

/* u = (x_b - x_a, x_c - x_a, p_k - x_a, theta_k) of edge k: entry i is unknown plus[i] minus unknown minus[i] */
static void relative(const double *q, int k, double *u, int *plus, int *minus)
{
    int a = (k + 1) % 3, b = (k + 2) % 3;
    for (int c = 0; c < 3; c++) {
        u[c] = q[3 * b + c] - q[3 * a + c];
        u[3 + c] = q[3 * k + c] - q[3 * a + c];
        u[6 + c] = q[9 + 3 * k + c] - q[3 * a + c];
        plus[c] = 3 * b + c; plus[3 + c] = 3 * k + c; plus[6 + c] = 9 + 3 * k + c;
        minus[c] = minus[3 + c] = minus[6 + c] = 3 * a + c;
    }
    u[9] = q[18 + k];
    plus[9] = 18 + k; minus[9] = -1;
}

/* row 3 + k of J: q_k's gradient in the element's 21 unknowns */
static void edge_row(double J[6][21], int k, const double *gq, const int *plus, const int *minus)
{
    for (int i = 0; i < 10; i++) {
        J[3 + k][plus[i]] += gq[i];
        if (minus[i] >= 0) J[3 + k][minus[i]] -= gq[i];
    }
}

/* the energy's gradient J^T W_z */
static void chain(const double J[6][21], const double *gw, double *gradient)
{
    for (int j = 0; j < 21; j++) {
        double s = 0.0;
        for (int m = 0; m < 6; m++) s += gw[m] * J[m][j];
        gradient[j] = s;
    }
}

static void element(const double *q, const double *ai, const double *bb, double area, double hbar, double alpha,
                    double beta, const int64_t *kind, const double *direction, const double *sign, int law, double *H,
                    double *energy, double *gradient)
{
    double D[SCRATCH], E[SCRATCH], J[6][21], z[6], u[10], gq[3][10], hq[3][100], gw[6], hw[36], T[6][21];
    int plus[3][10], minus[3][10];
    metric_rows(q, J, z);
    for (int k = 0; k < 3; k++) {
        relative(q, k, u, plus[k], minus[k]);
        z[3 + k] = edge(kind[k], u, sign[k], direction + 3 * k, D, E, gq[k], hq[k]);
        edge_row(J, k, gq[k], plus[k], minus[k]);
    }
    double w;
    if (law == 0)
        w = w_svk(z, ai[0], ai[1], ai[2], ai[3], bb[0], bb[1], bb[2], bb[3], area, hbar, alpha, beta, D, E, gw, hw);
    else
        w = w_neo_hookean(z, ai[0], ai[1], ai[2], ai[3], bb[0], bb[1], bb[2], bb[3], area, hbar, alpha, beta, D, E, gw, hw);
    if (energy) *energy = w;
    if (gradient) chain(J, gw, gradient);
    for (int i = 0; i < 6; i++)                                   /* J^T W_zz J */
        for (int j = 0; j < 21; j++) {
            double s = 0.0;
            for (int m = 0; m < 6; m++) s += hw[6 * i + m] * J[m][j];
            T[i][j] = s;
        }
    for (int i = 0; i < 21; i++)
        for (int j = 0; j < 21; j++) {
            double s = 0.0;
            for (int m = 0; m < 6; m++) s += J[m][i] * T[m][j];
            H[21 * i + j] = s;
        }
    /* the metric's constant Hessians (times I3): a11 = e1.e1, a12 = e1.e2, a22 = e2.e2 */
    double w11 = gw[0], w12 = gw[1], w22 = gw[2];
    double hxx[3][3] = {{2.0 * (w11 + w12 + w22), -2.0 * w11 - w12, -w12 - 2.0 * w22},
                        {-2.0 * w11 - w12, 2.0 * w11, w12},
                        {-w12 - 2.0 * w22, w12, 2.0 * w22}};
    for (int v = 0; v < 3; v++)
        for (int w = 0; w < 3; w++)
            for (int c = 0; c < 3; c++) H[21 * (3 * v + c) + 3 * w + c] += hxx[v][w];
    for (int k = 0; k < 3; k++) {
        double wk = gw[3 + k];
        for (int i = 0; i < 10; i++) {
            int pi = plus[k][i], mi = minus[k][i];
            for (int j = 0; j < 10; j++) {
                double val = wk * hq[k][10 * i + j];
                int pj = plus[k][j], mj = minus[k][j];
                H[21 * pi + pj] += val;
                if (mj >= 0) H[21 * pi + mj] -= val;
                if (mi >= 0) {
                    H[21 * mi + pj] -= val;
                    if (mj >= 0) H[21 * mi + mj] += val;
                }
            }
        }
    }
    for (int i = 0; i < 21; i++)
        for (int j = i + 1; j < 21; j++) {
            double s = 0.5 * (H[21 * i + j] + H[21 * j + i]);
            H[21 * i + j] = s;
            H[21 * j + i] = s;
        }
}

/* the Hessians (and energies, gradients) of elements [start, stop) */
void element_hessians(int64_t start, int64_t stop, const double *q, const double *abar_inv, const double *bbar,
                      const double *area, const double *hbar, double alpha, double beta, const int64_t *kind,
                      const double *direction, const double *sign, int law, double *out, double *energy,
                      double *gradient)
{
    for (int64_t e = start; e < stop; e++)
        element(q + 21 * e, abar_inv + 4 * e, bbar + 4 * e, area[e], hbar[e], alpha, beta, kind + 3 * e,
                direction + 9 * e, sign + 3 * e, law, out + 441 * e, energy ? energy + e : NULL,
                gradient ? gradient + 21 * e : NULL);
}

/* the energies and gradients of elements [start, stop) without their Hessians: the same bits as
   element_hessians' energies and gradients */
void element_gradients(int64_t start, int64_t stop, const double *q, const double *abar_inv, const double *bbar,
                       const double *area, const double *hbar, double alpha, double beta, const int64_t *kind,
                       const double *direction, const double *sign, int law, double *energy, double *gradient)
{
    double J[6][21], z[6], u[10], gq[10], gw[6];
    int plus[10], minus[10];
    for (int64_t e = start; e < stop; e++) {
        const double *qe = q + 21 * e, *ai = abar_inv + 4 * e, *bb = bbar + 4 * e;
        metric_rows(qe, J, z);
        for (int k = 0; k < 3; k++) {
            relative(qe, k, u, plus, minus);
            z[3 + k] = edge_gradient(kind[3 * e + k], u, sign[3 * e + k], direction + 9 * e + 3 * k, gq);
            edge_row(J, k, gq, plus, minus);
        }
        if (law == 0)
            energy[e] = w_svk_gradient(z, ai[0], ai[1], ai[2], ai[3], bb[0], bb[1], bb[2], bb[3], area[e], hbar[e],
                                       alpha, beta, gw);
        else
            energy[e] = w_neo_hookean_gradient(z, ai[0], ai[1], ai[2], ai[3], bb[0], bb[1], bb[2], bb[3], area[e],
                                               hbar[e], alpha, beta, gw);
        chain(J, gw, gradient + 21 * e);
    }
}
