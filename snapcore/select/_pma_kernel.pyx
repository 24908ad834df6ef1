# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True
# cython: initializedcheck=False, nonecheck=False, embedsignature=True
"""Compiled whole-array passes of the view search (issue 41, docs/speed.md).

The loops are in ``_pma_core.h`` (plain C, so the compiler vectorises them); this module
checks the arrays' shapes and hands their memory over. Each loop repeats its NumPy
reference's operations in the same order (built with ``-ffp-contract=off``: no fused
multiply-adds), so the results are the same doubles. Typed wrappers and the choice
between this module and NumPy: :mod:`snapcore.select.kernels`.

Imports nothing (no NumPy): memoryviews of arrays the caller allocates, so importing it
costs well under a millisecond.
"""

from libc.stdint cimport int32_t
from libc.stdlib cimport free, malloc


cdef extern from "_pma_core.h" nogil:
    void pma_swept_block(const double *x, Py_ssize_t frames, Py_ssize_t joints,
                         const Py_ssize_t *links, Py_ssize_t nl, double floor,
                         double *b0, double *b1, double *b2, double *bn, double *quads)
    int pma_bin_vectors(const double *bx, const double *by, const double *bz,
                        Py_ssize_t nk, int res, Py_ssize_t chunk, int32_t *index,
                        double *gen, double *acc)
    Py_ssize_t pma_count_near(const int32_t *index, Py_ssize_t nk,
                              const unsigned char *near_bin)
    void pma_gather_near(const int32_t *index, Py_ssize_t nk, const unsigned char *near_bin,
                         const double *b0, const double *b1, const double *b2,
                         const double *bn, double *o0, double *o1, double *o2, double *on)


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
    if links.shape[1] != 2 or x.shape[2] != 3 or b.shape[0] != 3:
        raise ValueError("swept_block: x (F, J, 3), links (L, 2), b (3, K)")
    if steps < 1 or nl < 1:
        return
    if off < 0 or off % 2 or off + 2 * n > b.shape[1] or b.shape[1] > bn.shape[0]:
        raise ValueError("swept_block: the triangles do not fit the outputs")
    if off // 2 + n > quads.shape[0]:
        raise ValueError("swept_block: the quads do not fit the output")
    with nogil:
        pma_swept_block(&x[0, 0, 0], x.shape[0], x.shape[1], &links[0, 0], nl, floor,
                        &b[0, off], &b[1, off], &b[2, off], &bn[off], &quads[off // 2])


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
    Reference: ``sphere._bin_sums``. Raises ValueError on a non-finite vector (where
    ``np.bincount`` refuses its index).
    """
    cdef Py_ssize_t nk = b.shape[1], nb = <Py_ssize_t> res * res
    cdef int err
    if b.shape[0] != 3 or index.shape[0] != nk or gen.shape[0] != nb or gen.shape[1] != 3:
        raise ValueError("bin_vectors: b (3, K), index (K,), gen (res², 3)")
    if res < 1 or chunk < 1:
        raise ValueError("bin_vectors: res and chunk must be positive")
    if nk == 0:
        return
    cdef double *acc = <double *> malloc(nb * 3 * sizeof(double))
    if acc == NULL:
        raise MemoryError()
    with nogil:
        err = pma_bin_vectors(&b[0, 0], &b[1, 0], &b[2, 0], nk, res, chunk, &index[0],
                              &gen[0, 0], acc)
    free(acc)
    if err:
        raise ValueError("a vector to bin is not finite")


def count_near(const int32_t[::1] index, const unsigned char[::1] near_bin):
    """How many vectors lie in the flagged bins: ``near_bin[index[k]]`` (0 or 1) summed
    (``index`` entries lie in 0..len(near_bin)-1, as :func:`bin_vectors` writes them)."""
    cdef Py_ssize_t n, nk = index.shape[0]
    if nk == 0:
        return 0
    with nogil:
        n = pma_count_near(&index[0], nk, &near_bin[0])
    return n


def gather_near(
    const int32_t[::1] index,
    const unsigned char[::1] near_bin,
    const double[:, ::1] b,
    const double[::1] bn,
    double[:, ::1] bc,
    double[::1] bcn,
):
    """The columns of ``b`` (3, K) and entries of ``bn`` (K,) whose bin is flagged, in
    order, to ``bc`` (3, n) and ``bcn`` (n,), n from :func:`count_near`: what
    ``np.take(b, np.flatnonzero(np.take(near_bin, index)), axis=1)`` gives, in one pass.
    """
    cdef Py_ssize_t nk = index.shape[0], n = bc.shape[1]
    if b.shape[0] != 3 or b.shape[1] != nk or bn.shape[0] != nk or bc.shape[0] != 3:
        raise ValueError("gather_near: index (K,), b (3, K), bn (K,), bc (3, n)")
    if bcn.shape[0] != n or count_near(index, near_bin) != n:
        raise ValueError("gather_near: the outputs do not hold the near vectors")
    if n == 0:
        return
    with nogil:
        pma_gather_near(&index[0], nk, &near_bin[0], &b[0, 0], &b[1, 0], &b[2, 0], &bn[0],
                        &bc[0, 0], &bc[1, 0], &bc[2, 0], &bcn[0])
