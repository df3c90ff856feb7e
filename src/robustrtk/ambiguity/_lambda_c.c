/*
 * LAMBDA kernels in plain C99: LᵀDL, reduction, MLAMBDA search, back-transform.
 *
 * The same arithmetic, operation for operation and in the same order, as the pure-Python
 * references of robustrtk/ambiguity/lambda_pure.py (algorithms.md §7, §22). The library
 * has no Python API: it is loaded with ctypes by robustrtk/ambiguity/lambda_ckernels.py.
 *
 * Conventions: row-major double arrays, int64 operation rows (j, i, mu) (i = -1: the
 * permutation of j and j+1), outputs allocated by the caller. Every function returns an
 * error code (or a count) and never aborts.
 *
 * Bit-identity with the references needs IEEE double arithmetic without contraction
 * (no fused multiply-add) and without -ffast-math; rounding to an integer is rint() in the
 * default rounding mode, i.e. half to even, as Python's round() and numpy's rint.
 */
#ifdef RRTK_WITH_PYINIT
#include <Python.h> /* only for the empty module of PyInit__lambda_c at the end */
#endif

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF /* gcc: -ffp-contract=off (setup.py) */
#endif

#if defined(_WIN32)
#define RRTK_API __declspec(dllexport)
#else
#define RRTK_API __attribute__((visibility("default")))
#endif

enum {
    RRTK_OK = 0,
    RRTK_NOT_PD = 1,
    RRTK_SEARCH_LIMIT = 2,
    RRTK_NONFINITE_A = 3,
    RRTK_NONFINITE_Q = 4,
    RRTK_ASYMMETRIC_Q = 5,
    RRTK_NO_MEMORY = 6,
    RRTK_BAD_OPS = 7,
    RRTK_BAD_SIZE = 8
};

/* Tolerance that prevents endless swapping in the reduction (as in lambda_.py). */
static const double SWAP_TOL = 1e-6;

/* ABI version of this library (the wrapper checks it). */
RRTK_API int64_t rrtk_version(void) { return 1; }

/* ------------------------------------------------------------------------------------ */
/* LᵀDL: Q = Lᵀ diag(d) L by elimination from the last row to the first.                 */
/* q (n, n) is not modified; A (n, n) is work; L (n, n) and d (n) are outputs.          */
/* ------------------------------------------------------------------------------------ */
static int ltdl_core(int64_t n, const double *q, double *L, double *d, double *A)
{
    memcpy(A, q, (size_t)(n * n) * sizeof(double));
    memset(L, 0, (size_t)(n * n) * sizeof(double));
    memset(d, 0, (size_t)n * sizeof(double));
    for (int64_t i = n - 1; i >= 0; i--) {
        const double di = A[i * n + i];
        if (!(di > 0.0) || !isfinite(di)) return RRTK_NOT_PD;
        d[i] = di;
        const double s = sqrt(di);
        double *Li = L + i * n;
        for (int64_t j = 0; j < i; j++) Li[j] = A[i * n + j] / s; /* scaled (Cholesky) row */
        for (int64_t j = 0; j < i; j++) {
            const double lij = Li[j];
            double *Aj = A + j * n;
            for (int64_t k = 0; k <= j; k++) Aj[k] -= Li[k] * lij;
        }
        for (int64_t j = 0; j < i; j++) {
            Li[j] = Li[j] / s;
            if (!isfinite(Li[j])) return RRTK_NOT_PD;
        }
        Li[i] = 1.0;
    }
    return RRTK_OK;
}

RRTK_API int64_t rrtk_ltdl(int64_t n, const double *q, double *L, double *d)
{
    double *A = (double *)malloc((size_t)(n * n > 0 ? n * n : 1) * sizeof(double));
    if (A == NULL) return RRTK_NO_MEMORY;
    const int code = ltdl_core(n, q, L, d, A);
    free(A);
    return code;
}

/* ------------------------------------------------------------------------------------ */
/* Reduction: integer Gauss transformations and permutations (de Jonge & Tiberius order,   */
/* whole-column size reduction). L (n, n), d (n) are not modified; Lout (n, n) and dout   */
/* (n) receive the reduced factors; the first `cap` operations go to ops (cap, 3).        */
/* Returns the number of operations (all of them, also those beyond cap: the caller then   */
/* knows the room it needs; the factors are right in either case).                         */
/* ------------------------------------------------------------------------------------ */
static int64_t reduce_core(int64_t n, const double *L, const double *d, int64_t cap, int64_t *ops,
                           double *Lout, double *dout)
{
    double *Lc = Lout; /* Lc[j][r] = L[r][j]: column j of L is row j of Lc */
    for (int64_t r = 0; r < n; r++)
        for (int64_t c = 0; c < n; c++) Lc[c * n + r] = L[r * n + c];
    double *dl = dout;
    memcpy(dl, d, (size_t)n * sizeof(double));
    int64_t nops = 0;
    int64_t j = n - 2;
    int64_t k = n - 2;
    while (j >= 0) {
        double *cj = Lc + j * n;
        if (j <= k) {
            for (int64_t i = j + 1; i < n; i++) {
                const double v = cj[i];
                if (v > 0.5 || v < -0.5) {
                    const double mu = rint(v);
                    if (mu != 0.0) {
                        const double *ci = Lc + i * n;
                        for (int64_t r = i; r < n; r++) cj[r] = cj[r] - mu * ci[r];
                        if (nops < cap) {
                            ops[3 * nops] = j;
                            ops[3 * nops + 1] = i;
                            ops[3 * nops + 2] = (int64_t)mu;
                        }
                        nops++;
                    }
                }
            }
        }
        double *cj1 = Lc + (j + 1) * n;
        const double lj1 = cj[j + 1];
        const double delta = dl[j] + lj1 * lj1 * dl[j + 1];
        if (delta + SWAP_TOL < dl[j + 1]) {
            const double eta = dl[j] / delta;
            const double lam = dl[j + 1] * lj1 / delta;
            dl[j] = eta * dl[j + 1];
            dl[j + 1] = delta;
            for (int64_t c = 0; c < j; c++) {
                double *col = Lc + c * n;
                const double a0 = col[j];
                const double a1 = col[j + 1];
                col[j] = -lj1 * a0 + a1;
                col[j + 1] = eta * a0 + lam * a1;
            }
            cj[j + 1] = lam;
            for (int64_t r = j + 2; r < n; r++) {
                const double t = cj[r];
                cj[r] = cj1[r];
                cj1[r] = t;
            }
            if (nops < cap) {
                ops[3 * nops] = j;
                ops[3 * nops + 1] = -1;
                ops[3 * nops + 2] = 0;
            }
            nops++;
            k = j;
            j = n - 2;
        } else {
            j -= 1;
        }
    }
    /* back from column storage, in place */
    for (int64_t r = 0; r < n; r++)
        for (int64_t c = r + 1; c < n; c++) {
            const double t = Lc[r * n + c];
            Lc[r * n + c] = Lc[c * n + r];
            Lc[c * n + r] = t;
        }
    return nops;
}

RRTK_API int64_t rrtk_reduce(int64_t n, const double *L, const double *d, int64_t cap, int64_t *ops,
                             double *Lout, double *dout)
{
    return reduce_core(n, L, d, cap, ops, Lout, dout);
}

/* ------------------------------------------------------------------------------------ */
/* MLAMBDA search (Schnorr–Euchner zig-zag, shrinking ellipsoid).                          */
/* L (n, n), d (n), zs (n) inputs; Zfix (n, m) and s (m) outputs.                          */
/* ------------------------------------------------------------------------------------ */

/* a after b in numpy's ascending order (NaN last) */
static int after(double a, double b) { return (isnan(a) && !isnan(b)) || a > b; }

static int search_core(int64_t n, const double *L, const double *d, const double *zs, int64_t m,
                       int64_t max_nodes, double *Zfix, double *s)
{
    if (n < 1 || m < 1) return RRTK_BAD_SIZE;
    const size_t nn = (size_t)n;
    const size_t mm = (size_t)m;
    double *buf = (double *)calloc(nn * nn + 5 * nn + mm * nn + mm + 1, sizeof(double));
    int64_t *order = (int64_t *)malloc((mm + 1) * sizeof(int64_t));
    if (buf == NULL || order == NULL) {
        free(buf);
        free(order);
        return RRTK_NO_MEMORY;
    }
    double *S = buf;
    double *dinv = S + nn * nn;
    double *dist = dinv + nn;
    double *zb = dist + nn;
    double *z = zb + nn;
    double *step = z + nn;
    double *cand_z = step + nn;
    double *cand_s = cand_z + mm * nn;
    for (int64_t i = 0; i < n; i++) dinv[i] = 1.0 / d[i];
    for (int64_t c = 0; c < m; c++) cand_s[c] = INFINITY;
    int64_t ncand = 0;
    double maxdist = INFINITY;
    int64_t imax = 0;
    int64_t k = n - 1;
    zb[k] = zs[k];
    z[k] = rint(zb[k]);
    double y = zb[k] - z[k];
    step[k] = y > 0.0 ? 1.0 : -1.0;
    int64_t nodes = 0;
    int code = RRTK_OK;
    for (;;) {
        nodes += 1;
        if (nodes > max_nodes) {
            code = RRTK_SEARCH_LIMIT;
            break;
        }
        const double newdist = dist[k] + y * y * dinv[k];
        if (newdist < maxdist) {
            if (k != 0) {
                const double dz = z[k] - zb[k];
                const int64_t k1 = k;
                k -= 1;
                dist[k] = newdist;
                double *Sk = S + k * n;
                const double *Sk1 = S + k1 * n;
                const double *Lk1 = L + k1 * n;
                for (int64_t t = 0; t <= k; t++) Sk[t] = Sk1[t] + dz * Lk1[t];
                zb[k] = zs[k] + Sk[k];
                z[k] = rint(zb[k]);
                y = zb[k] - z[k];
                step[k] = y > 0.0 ? 1.0 : -1.0;
            } else {
                if (ncand < m) {
                    memcpy(cand_z + ncand * n, z, nn * sizeof(double));
                    cand_s[ncand] = newdist;
                    ncand += 1;
                    if (ncand == m) {
                        imax = 0;
                        for (int64_t c = 1; c < m; c++)
                            if (cand_s[c] > cand_s[imax]) imax = c;
                        maxdist = cand_s[imax];
                    }
                } else {
                    if (newdist < cand_s[imax]) {
                        memcpy(cand_z + imax * n, z, nn * sizeof(double));
                        cand_s[imax] = newdist;
                        imax = 0;
                        for (int64_t c = 1; c < m; c++)
                            if (cand_s[c] > cand_s[imax]) imax = c;
                    }
                    maxdist = cand_s[imax];
                }
                z[0] += step[0];
                y = zb[0] - z[0];
                step[0] = -step[0] - (step[0] > 0.0 ? 1.0 : -1.0);
            }
        } else {
            if (k == n - 1) break;
            k += 1;
            z[k] += step[k];
            y = zb[k] - z[k];
            step[k] = -step[k] - (step[k] > 0.0 ? 1.0 : -1.0);
        }
    }
    /* stable ascending order of the norms (insertion sort, as a stable argsort) */
    for (int64_t c = 0; c < m; c++) {
        int64_t p = c;
        while (p > 0 && after(cand_s[order[p - 1]], cand_s[c])) {
            order[p] = order[p - 1];
            p--;
        }
        order[p] = c;
    }
    for (int64_t c = 0; c < m; c++) {
        const double *zc = cand_z + order[c] * n;
        for (int64_t i = 0; i < n; i++) Zfix[i * m + c] = zc[i];
        s[c] = cand_s[order[c]];
    }
    free(buf);
    free(order);
    return code;
}

RRTK_API int64_t rrtk_search(int64_t n, const double *L, const double *d, const double *zs, int64_t m,
                             int64_t max_nodes, double *Zfix, double *s)
{
    return search_core(n, L, d, zs, m, max_nodes, Zfix, s);
}

/* ------------------------------------------------------------------------------------ */
/* Zᵀ v and Z⁻ᵀ V from the operation list.                                                */
/* ------------------------------------------------------------------------------------ */
static void apply_zt_core(int64_t nops, const int64_t *ops, double *x)
{
    for (int64_t r = 0; r < nops; r++) {
        const int64_t j = ops[3 * r];
        const int64_t i = ops[3 * r + 1];
        if (i < 0) {
            const double t = x[j];
            x[j] = x[j + 1];
            x[j + 1] = t;
        } else {
            x[j] -= (double)ops[3 * r + 2] * x[i];
        }
    }
}

static void apply_zinvt_core(int64_t nops, const int64_t *ops, int64_t kk, double *X)
{
    for (int64_t r = nops - 1; r >= 0; r--) {
        const int64_t j = ops[3 * r];
        const int64_t i = ops[3 * r + 1];
        double *Xj = X + j * kk;
        if (i < 0) {
            double *Xj1 = Xj + kk;
            for (int64_t c = 0; c < kk; c++) {
                const double t = Xj[c];
                Xj[c] = Xj1[c];
                Xj1[c] = t;
            }
        } else {
            const double mu = (double)ops[3 * r + 2];
            const double *Xi = X + i * kk;
            for (int64_t c = 0; c < kk; c++) Xj[c] += mu * Xi[c];
        }
    }
}

/* every row (j, i, mu) indexes a vector of length n (i = -1: a permutation of j, j+1) */
static int ops_valid(int64_t nops, const int64_t *ops, int64_t n)
{
    for (int64_t r = 0; r < nops; r++) {
        const int64_t j = ops[3 * r];
        const int64_t i = ops[3 * r + 1];
        if (j < 0 || i < -1 || i >= n || (i < 0 ? j + 1 >= n : j >= n)) return 0;
    }
    return 1;
}

/* x (n) holds v on entry and Zᵀ v on return */
RRTK_API int64_t rrtk_apply_zt(int64_t n, int64_t nops, const int64_t *ops, double *x)
{
    if (!ops_valid(nops, ops, n)) return RRTK_BAD_OPS;
    apply_zt_core(nops, ops, x);
    return RRTK_OK;
}

/* X (n, kk) holds V on entry and Z⁻ᵀ V on return */
RRTK_API int64_t rrtk_apply_zinvt(int64_t n, int64_t nops, const int64_t *ops, int64_t kk, double *X)
{
    if (!ops_valid(nops, ops, n)) return RRTK_BAD_OPS;
    apply_zinvt_core(nops, ops, kk, X);
    return RRTK_OK;
}

/* ------------------------------------------------------------------------------------ */
/* Search on reduced factors and back-transform: F = round(Z⁻ᵀ ž) + round(â).            */
/* a (n), ops (nops, 3), L (n, n), d (n) inputs; F (n, m), s (m) outputs.                 */
/* ------------------------------------------------------------------------------------ */
static int ils_from_reduced_core(int64_t n, const double *a, int64_t nops, const int64_t *ops,
                                 const double *L, const double *d, int64_t m, int64_t max_nodes,
                                 double *F, double *s)
{
    double *w = (double *)malloc((size_t)(2 * n + 1) * sizeof(double));
    if (w == NULL) return RRTK_NO_MEMORY;
    double *a0 = w;
    double *zh = w + n;
    for (int64_t i = 0; i < n; i++) {
        a0[i] = rint(a[i]);
        zh[i] = a[i] - a0[i];
    }
    apply_zt_core(nops, ops, zh);
    const int code = search_core(n, L, d, zh, m, max_nodes, F, s);
    if (code == RRTK_NO_MEMORY) {
        free(w);
        return code;
    }
    apply_zinvt_core(nops, ops, m, F);
    for (int64_t i = 0; i < n; i++)
        for (int64_t c = 0; c < m; c++) F[i * m + c] = rint(F[i * m + c]);
    for (int64_t i = 0; i < n; i++)
        for (int64_t c = 0; c < m; c++) F[i * m + c] += a0[i];
    free(w);
    return code;
}

RRTK_API int64_t rrtk_ils_from_reduced(int64_t n, const double *a, int64_t nops, const int64_t *ops,
                                       const double *L, const double *d, int64_t m, int64_t max_nodes,
                                       double *F, double *s)
{
    if (!ops_valid(nops, ops, n)) return RRTK_BAD_OPS;
    return ils_from_reduced_core(n, a, nops, ops, L, d, m, max_nodes, F, s);
}

static void zero_outputs(int64_t n, int64_t m, double *F, double *s)
{
    memset(F, 0, (size_t)(n * m) * sizeof(double));
    memset(s, 0, (size_t)m * sizeof(double));
}

/* ------------------------------------------------------------------------------------ */
/* Whole ILS on a checked, symmetric q: LᵀDL, reduction, search, back-transform.          */
/* a (n), q (n, n) inputs; F (n, m), s (m), dout (n) outputs.                              */
/* ------------------------------------------------------------------------------------ */
static int ils_core(int64_t n, const double *a, const double *q, int64_t m, int64_t max_nodes, double *F,
                    double *s, double *dout)
{
    const size_t nn = (size_t)n;
    double *w = (double *)malloc((3 * nn * nn + nn + 1) * sizeof(double));
    if (w == NULL) return RRTK_NO_MEMORY;
    double *A = w;
    double *L0 = A + nn * nn;
    double *Lr = L0 + nn * nn;
    double *d0 = Lr + nn * nn;
    int code = ltdl_core(n, q, L0, d0, A);
    if (code != RRTK_OK) {
        zero_outputs(n, m, F, s);
        memcpy(dout, d0, nn * sizeof(double));
        free(w);
        return code;
    }
    int64_t cap = 8 * n * n + 16;
    int64_t *ops = (int64_t *)malloc((size_t)cap * 3 * sizeof(int64_t));
    if (ops == NULL) {
        free(w);
        return RRTK_NO_MEMORY;
    }
    int64_t nops = reduce_core(n, L0, d0, cap, ops, Lr, dout);
    if (nops > cap) { /* room for all of them, and again */
        free(ops);
        cap = nops;
        ops = (int64_t *)malloc((size_t)cap * 3 * sizeof(int64_t));
        if (ops == NULL) {
            free(w);
            return RRTK_NO_MEMORY;
        }
        nops = reduce_core(n, L0, d0, cap, ops, Lr, dout);
    }
    code = ils_from_reduced_core(n, a, nops, ops, Lr, dout, m, max_nodes, F, s);
    free(ops);
    free(w);
    return code;
}

RRTK_API int64_t rrtk_ils(int64_t n, const double *a, const double *q, int64_t m, int64_t max_nodes, double *F,
                          double *s, double *dout)
{
    return ils_core(n, a, q, m, max_nodes, F, s, dout);
}

/* ------------------------------------------------------------------------------------ */
/* Input checks of check_q (finite, symmetric to 1e-9 max|Q|), symmetrisation (Q + Qᵀ)/2  */
/* and the whole ILS, in one call. a (n), Q (n, n) inputs; F (n, m), s (m) outputs.        */
/* ------------------------------------------------------------------------------------ */
RRTK_API int64_t rrtk_lambda_all(int64_t n, const double *a, const double *Q, int64_t m, int64_t max_nodes,
                                 double *F, double *s)
{
    for (int64_t i = 0; i < n; i++)
        if (!isfinite(a[i])) {
            zero_outputs(n, m, F, s);
            return RRTK_NONFINITE_A;
        }
    double scale = 0.0;
    for (int64_t i = 0; i < n * n; i++) {
        const double v = fabs(Q[i]);
        if (!isfinite(v)) {
            zero_outputs(n, m, F, s);
            return RRTK_NONFINITE_Q;
        }
        if (v > scale) scale = v;
    }
    const size_t nn = (size_t)n;
    double *q = (double *)malloc((nn * nn + nn + 1) * sizeof(double));
    if (q == NULL) return RRTK_NO_MEMORY;
    double *dd = q + nn * nn;
    double asym = 0.0;
    for (int64_t i = 0; i < n; i++)
        for (int64_t j = 0; j < n; j++) {
            const double e = fabs(Q[i * n + j] - Q[j * n + i]);
            if (e > asym) asym = e;
            q[i * n + j] = 0.5 * (Q[i * n + j] + Q[j * n + i]);
        }
    if (asym > 1e-9 * scale) {
        free(q);
        zero_outputs(n, m, F, s);
        return RRTK_ASYMMETRIC_Q;
    }
    const int code = ils_core(n, a, q, m, max_nodes, F, s, dd);
    free(q);
    return code;
}

#ifdef RRTK_WITH_PYINIT
/* An empty module, so that the file is also a valid extension module (it is loaded with
   ctypes, never imported for its contents). */
static struct PyModuleDef rrtk_module = {PyModuleDef_HEAD_INIT, "_lambda_c",
                                         "LAMBDA kernels in C (loaded with ctypes).", -1, NULL};

PyMODINIT_FUNC PyInit__lambda_c(void) { return PyModule_Create(&rrtk_module); }
#endif
