# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False, nonecheck=False, embedsignature=True
"""Compiled whole-array passes of the view search (issue 41, docs/speed.md).

The NumPy reference of each function is named in its docstring; the arithmetic is the
same operations in the same order (built with ``-ffp-contract=off``: no fused
multiply-adds), so the results are the same doubles. Typed wrappers and the choice
between this module and NumPy: :mod:`snapcore.select.kernels`.

Imports nothing (no NumPy): memoryviews of arrays the caller allocates, so importing it
costs microseconds.
"""

from libc.math cimport copysign, fabs, sqrt
from libc.stdint cimport int32_t
from libc.stdlib cimport calloc, free
from libc.string cimport memset


def swept_block(
    const double[:, :, ::1] x,
    const Py_ssize_t[:, ::1] links,
    double floor,
    double[:, ::1] b,
    double[::1] bn,
    double[::1] quads,
    Py_ssize_t off,
):
    """One character's swept-triangle PMA vectors, norms and quad areas, in one pass.

    ``x`` (F, J, 3) positions, ``links`` (L, 2) joint pairs (checked by the caller to lie
    in 0..J-1); writes triangles ``off .. off + 2(F-1)L`` of ``b`` (3, K) and ``bn`` (K,)
    and quads ``off/2 ..`` of ``quads``. Reference: ``view._swept_block``.
    """
    cdef Py_ssize_t steps = x.shape[0] - 1, nl = links.shape[0], n = steps * nl
    cdef Py_ssize_t s, l, jp, jc, k, q0 = off // 2
    cdef double p0, p1, p2, e0, e1, e2, g0, g1, g2, d0, d1, d2
    cdef double a0, a1, a2, c0, c1, c2, na, nc, q2, w
    cdef double two_floor = 2.0 * floor
    with nogil:
        for s in range(steps):
            for l in range(nl):
                jp = links[l, 0]
                jc = links[l, 1]
                p0 = x[s, jp, 0]
                p1 = x[s, jp, 1]
                p2 = x[s, jp, 2]
                # link vector e, parent displacement g, diagonal d = e(i+1) + g
                e0 = x[s, jc, 0] - p0
                e1 = x[s, jc, 1] - p1
                e2 = x[s, jc, 2] - p2
                g0 = x[s + 1, jp, 0] - p0
                g1 = x[s + 1, jp, 1] - p1
                g2 = x[s + 1, jp, 2] - p2
                d0 = (x[s + 1, jc, 0] - x[s + 1, jp, 0]) + g0
                d1 = (x[s + 1, jc, 1] - x[s + 1, jp, 1]) + g1
                d2 = (x[s + 1, jc, 2] - x[s + 1, jp, 2]) + g2
                # twice the vector areas: a = e × d, c = d × g
                a0 = e1 * d2 - e2 * d1
                a1 = e2 * d0 - e0 * d2
                a2 = e0 * d1 - e1 * d0
                c0 = d1 * g2 - d2 * g1
                c1 = d2 * g0 - d0 * g2
                c2 = d0 * g1 - d1 * g0
                na = sqrt(a0 * a0 + a1 * a1 + a2 * a2)
                nc = sqrt(c0 * c0 + c1 * c1 + c2 * c2)
                q2 = na + nc
                quads[q0 + s * nl + l] = q2 * 0.5
                w = 1.0 / q2 if q2 >= two_floor else 0.0
                k = off + s * nl + l
                b[0, k] = a0 * w
                b[1, k] = a1 * w
                b[2, k] = a2 * w
                bn[k] = na * w
                k = k + n
                b[0, k] = c0 * w
                b[1, k] = c1 * w
                b[2, k] = c2 * w
                bn[k] = nc * w


def bin_vectors(
    const double[:, ::1] b,
    int res,
    Py_ssize_t chunk,
    int32_t[::1] index,
    double[:, ::1] gen,
):
    """Fold ``b`` (3, K) onto y ≥ 0, write each vector's octahedral bin to ``index`` (K,)
    and add the folded vectors per bin to ``gen`` (res², 3), in one pass.

    The sums run in the order of ``np.bincount`` per chunk of ``chunk`` vectors, each
    chunk's sums then added to ``gen``: the reference's order, so the same doubles.
    Reference: ``sphere._bin_generators``. Raises ValueError on a non-finite vector
    (where ``np.bincount`` would refuse its index).
    """
    cdef Py_ssize_t nk = b.shape[1], nb = <Py_ssize_t>res * res
    cdef Py_ssize_t k, z, z1, idx, m
    cdef double h = res / 2.0, h_in = res / 2.0 * (1.0 - 1e-9), top = res
    cdef double bx, by, bz, sg, fx, fy, fz, den, fi, fj
    cdef bint bad = False
    cdef double *acc = <double *> calloc(nb * 3, sizeof(double))
    if acc == NULL:
        raise MemoryError()
    with nogil:
        z = 0
        while z < nk and not bad:
            z1 = min(nk, z + chunk)
            memset(acc, 0, nb * 3 * sizeof(double))
            for k in range(z, z1):
                bx = b[0, k]
                by = b[1, k]
                bz = b[2, k]
                sg = copysign(1.0, by)
                fx = bx * sg
                fy = fabs(by)
                fz = bz * sg
                den = fabs(fx) + fy
                den = den + fabs(fz)
                den = den + 1e-300
                den = h_in / den
                fi = (fx + fz) * den + h
                fj = (fz - fx) * den + h
                if not (fi >= 0.0 and fi < top and fj >= 0.0 and fj < top):
                    bad = True
                    break
                idx = (<Py_ssize_t> fi) * res + (<Py_ssize_t> fj)
                index[k] = <int32_t> idx
                acc[3 * idx] += fx
                acc[3 * idx + 1] += fy
                acc[3 * idx + 2] += fz
            if not bad:
                for m in range(nb):
                    gen[m, 0] += acc[3 * m]
                    gen[m, 1] += acc[3 * m + 1]
                    gen[m, 2] += acc[3 * m + 2]
            z = z1
    free(acc)
    if bad:
        raise ValueError("a vector to bin is not finite")


def near_members(
    const int32_t[::1] index,
    const unsigned char[::1] near_bin,
    Py_ssize_t[::1] out,
):
    """Write the positions k (increasing) with ``near_bin[index[k]]`` set to ``out`` and
    return how many: ``np.flatnonzero(np.take(near_bin, index))`` in one pass
    (``index`` entries lie in 0..len(near_bin)-1, as :func:`bin_vectors` writes them).
    """
    cdef Py_ssize_t k, n = 0, nk = index.shape[0]
    with nogil:
        for k in range(nk):
            out[n] = k
            n += near_bin[index[k]]
    return n
