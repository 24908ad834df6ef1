/* The loops of snapcore/select/_pma_kernel.pyx (issue 41, docs/speed.md).
 *
 * Plain C so the compiler vectorises the element-wise loops: their operands are local
 * arrays of a block (no aliasing with the outputs), the gathers and the per-bin sums
 * are separate scalar loops. Every expression repeats its NumPy reference's operations
 * in the same order; built with -ffp-contract=off (no fused multiply-adds), so packed or
 * not, each element is the same double. -fno-math-errno lets sqrt be an instruction.
 * On x86-64 Linux each loop is also compiled for AVX2 and the CPU picks at load time
 * (target_clones): 4 doubles per instruction instead of 2, the same results; measured
 * ~20 % less time for the two passes on the development VM.
 */
#ifndef PMA_CORE_H
#define PMA_CORE_H

#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#if defined(__GNUC__) && defined(__x86_64__) && defined(__linux__)
#define PMA_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PMA_CLONES
#endif

/* links per block of the swept triangles, vectors per block of the binning */
#define PMA_LB 64
#define PMA_VB 256

/* One character's PMA vectors, norms and quad areas (reference: view._swept_block).
 * x: (frames, joints, 3) C order; links: (nl, 2), every joint in 0..joints-1;
 * b0, b1, b2, bn: the rows of b and its norms from this character's first triangle
 * (2 (frames-1) nl of them); quads: from its first quad ((frames-1) nl). */
PMA_CLONES static void pma_swept_block(const double *restrict x, ptrdiff_t frames, ptrdiff_t joints,
                            const ptrdiff_t *restrict links, ptrdiff_t nl, double floor,
                            double *restrict b0, double *restrict b1, double *restrict b2,
                            double *restrict bn, double *restrict quads)
{
    const ptrdiff_t steps = frames - 1, n = steps * nl, row = 3 * joints;
    const double two_floor = 2.0 * floor;
    double e0[PMA_LB], e1[PMA_LB], e2[PMA_LB], g0[PMA_LB], g1[PMA_LB], g2[PMA_LB];
    double d0[PMA_LB], d1[PMA_LB], d2[PMA_LB];
    double a0[PMA_LB], a1[PMA_LB], a2[PMA_LB], c0[PMA_LB], c1[PMA_LB], c2[PMA_LB];
    double na[PMA_LB], nc[PMA_LB], q[PMA_LB], r[PMA_LB];
    for (ptrdiff_t s = 0; s < steps; s++) {
        const double *xs = x + s * row, *xs1 = xs + row;
        for (ptrdiff_t l0 = 0; l0 < nl; l0 += PMA_LB) {
            const ptrdiff_t m = nl - l0 < PMA_LB ? nl - l0 : PMA_LB;
            for (ptrdiff_t t = 0; t < m; t++) { /* gathers: link e, parent step g, diagonal d */
                const double *p = xs + 3 * links[2 * (l0 + t)];
                const double *c = xs + 3 * links[2 * (l0 + t) + 1];
                const double *p1 = xs1 + 3 * links[2 * (l0 + t)];
                const double *c1 = xs1 + 3 * links[2 * (l0 + t) + 1];
                e0[t] = c[0] - p[0];
                e1[t] = c[1] - p[1];
                e2[t] = c[2] - p[2];
                g0[t] = p1[0] - p[0];
                g1[t] = p1[1] - p[1];
                g2[t] = p1[2] - p[2];
                d0[t] = (c1[0] - p1[0]) + g0[t];
                d1[t] = (c1[1] - p1[1]) + g1[t];
                d2[t] = (c1[2] - p1[2]) + g2[t];
            }
            for (ptrdiff_t t = 0; t < m; t++) { /* twice the areas a = e x d, c = d x g */
                a0[t] = e1[t] * d2[t] - e2[t] * d1[t];
                a1[t] = e2[t] * d0[t] - e0[t] * d2[t];
                a2[t] = e0[t] * d1[t] - e1[t] * d0[t];
                c0[t] = d1[t] * g2[t] - d2[t] * g1[t];
                c1[t] = d2[t] * g0[t] - d0[t] * g2[t];
                c2[t] = d0[t] * g1[t] - d1[t] * g0[t];
                na[t] = sqrt(a0[t] * a0[t] + a1[t] * a1[t] + a2[t] * a2[t]);
                nc[t] = sqrt(c0[t] * c0[t] + c1[t] * c1[t] + c2[t] * c2[t]);
                q[t] = na[t] + nc[t];
                r[t] = 1.0 / q[t];
            }
            /* its own loop: in the one above the compiler would divide under the
             * branch, which it then cannot vectorise */
            const ptrdiff_t k = s * nl + l0;
            double *restrict o0 = b0 + k, *restrict o1 = b1 + k, *restrict o2 = b2 + k;
            double *restrict on = bn + k, *restrict oq = quads + k;
            for (ptrdiff_t t = 0; t < m; t++) {
                const double w = q[t] >= two_floor ? r[t] : 0.0;
                o0[t] = a0[t] * w;
                o1[t] = a1[t] * w;
                o2[t] = a2[t] * w;
                on[t] = na[t] * w;
                o0[n + t] = c0[t] * w;
                o1[n + t] = c1[t] * w;
                o2[n + t] = c2[t] * w;
                on[n + t] = nc[t] * w;
                oq[t] = q[t] * 0.5;
            }
        }
    }
}

/* Bin index and per-bin sums of the folded vectors (reference: sphere._bin_sums):
 * bx, by, bz: the rows of b (nk); index (nk) written; gen (res*res, 3) added to, per
 * chunk of `chunk` vectors as np.bincount sums them; acc: res*res*3 doubles of scratch.
 * Returns 0, or -1 at a non-finite vector (gen then unchanged). */
PMA_CLONES static int pma_bin_vectors(const double *restrict bx, const double *restrict by,
                           const double *restrict bz, ptrdiff_t nk, int res, ptrdiff_t chunk,
                           int32_t *restrict index, double *restrict gen,
                           double *restrict acc)
{
    const ptrdiff_t nb = (ptrdiff_t)res * res;
    const double h = res / 2.0, h_in = res / 2.0 * (1.0 - 1e-9), top = res;
    double fx[PMA_VB], fy[PMA_VB], fz[PMA_VB];
    int32_t ii[PMA_VB];
    for (ptrdiff_t z = 0; z < nk; z += chunk) {
        const ptrdiff_t z1 = nk - z < chunk ? nk : z + chunk;
        memset(acc, 0, (size_t)nb * 3 * sizeof(double));
        for (ptrdiff_t k0 = z; k0 < z1; k0 += PMA_VB) {
            const ptrdiff_t m = z1 - k0 < PMA_VB ? z1 - k0 : PMA_VB;
            const double *px = bx + k0, *py = by + k0, *pz = bz + k0;
            for (ptrdiff_t t = 0; t < m; t++) { /* element-wise: fold, map, index */
                const double sg = copysign(1.0, py[t]);
                fx[t] = px[t] * sg;
                fy[t] = fabs(py[t]);
                fz[t] = pz[t] * sg;
                double den = fabs(fx[t]) + fy[t];
                den = den + fabs(fz[t]);
                den = den + 1e-300;
                den = h_in / den;
                double fi = (fx[t] + fz[t]) * den + h;
                double fj = (fz[t] - fx[t]) * den + h;
                /* only a non-finite vector maps outside [0, res)²: its index is
                 * made out of range (res² and up) without converting a NaN */
                const int ok = (fi >= 0.0) & (fi < top) & (fj >= 0.0) & (fj < top);
                fi = ok ? fi : top;
                fj = ok ? fj : 0.0;
                ii[t] = (int32_t)fi * res + (int32_t)fj;
            }
            for (ptrdiff_t t = 0; t < m; t++)
                if ((uint32_t)ii[t] >= (uint32_t)nb)
                    return -1;
            memcpy(index + k0, ii, (size_t)m * sizeof(int32_t));
            for (ptrdiff_t t = 0; t < m; t++) { /* the sums, in order */
                double *a = acc + 3 * (ptrdiff_t)ii[t];
                a[0] += fx[t];
                a[1] += fy[t];
                a[2] += fz[t];
            }
        }
        for (ptrdiff_t j = 0; j < 3 * nb; j++)
            gen[j] += acc[j];
    }
    return 0;
}

/* Members of the flagged bins (near_bin[index[k]] is 1, else 0): how many. */
static ptrdiff_t pma_count_near(const int32_t *restrict index, ptrdiff_t nk,
                                const unsigned char *restrict near_bin)
{
    ptrdiff_t n = 0;
    for (ptrdiff_t k = 0; k < nk; k++)
        n += near_bin[index[k]];
    return n;
}

/* Their columns of b (rows b0, b1, b2) and norms bn, in increasing k, to o0, o1, o2, on
 * (as many as pma_count_near counts). */
static void pma_gather_near(const int32_t *restrict index, ptrdiff_t nk,
                            const unsigned char *restrict near_bin,
                            const double *restrict b0, const double *restrict b1,
                            const double *restrict b2, const double *restrict bn,
                            double *restrict o0, double *restrict o1, double *restrict o2,
                            double *restrict on)
{
    ptrdiff_t n = 0;
    for (ptrdiff_t k = 0; k < nk; k++) {
        if (near_bin[index[k]]) {
            o0[n] = b0[k];
            o1[n] = b1[k];
            o2[n] = b2[k];
            on[n] = bn[k];
            n++;
        }
    }
}

#endif
