"""The multipliers of one vehicle's constraints (docs/physics.md §7): (D M^-1 D^T) lam = b, solved by a
block-sparse Cholesky over the joints.

Rows come in joint blocks (rows jst[a]..jst[a+1]-1 belong to joint a, between bodies JB[a]); the Schur
matrix S = D M^-1 D^T has a non-zero block (a, b) only where joints a and b share a body. With the joints
ordered leaves first (equations.rhs: the knuckle-wheel joints before the chassis-knuckle joints) the factor
has no fill-in: eliminating a knuckle-wheel block touches only its chassis-knuckle block, and the four
chassis-knuckle blocks are coupled through the chassis anyway. The symbolic pattern (`block_pattern`)
still adds any fill-in, so any joint order gives the exact factor; only zero blocks are skipped, i.e. the
same arithmetic as the dense Cholesky without its zero products (Clio, 44 rows: ~2,100 instead of ~14,000
multiply-adds, and the assembly touches only the non-zero blocks).
"""
import math

from numba import njit


@njit(cache=True)
def block_pattern(JB, nj, NZ):
    """NZ[a, b] (b <= a): block (a, b) of S or of its Cholesky factor can be non-zero (joints sharing a
    body, plus the fill-in of the elimination in joint order)."""
    for a in range(nj):
        ia, ja = JB[a, 0], JB[a, 1]
        for b in range(a + 1):
            ib, jb = JB[b, 0], JB[b, 1]
            NZ[a, b] = ia == ib or ia == jb or ja == ib or ja == jb
    for k in range(nj):
        for a in range(k + 1, nj):
            if NZ[a, k]:
                for b in range(k + 1, a + 1):
                    if NZ[b, k]:
                        NZ[a, b] = True


@njit(cache=True)
def assemble(D, MD, jst, JB, nj, NZ, S):
    """S = D M^-1 D^T on the non-zero blocks (lower triangle; fill-in blocks zeroed); MD = D M^-1 per row."""
    for a in range(nj):
        ia, ja = JB[a, 0], JB[a, 1]
        for b in range(a + 1):
            if not NZ[a, b]:
                continue
            ib, jb = JB[b, 0], JB[b, 1]
            # which ends of the two joints are the same body: (row side, column side) offsets into D
            s00, s01, s10, s11 = ia == ib, ia == jb, ja == ib, ja == jb
            for r in range(jst[a], jst[a + 1]):
                cend = jst[b + 1] if b < a else r + 1
                for c in range(jst[b], cend):
                    acc = 0.0
                    if s00:
                        for k in range(6):
                            acc += MD[r, k] * D[c, k]
                    if s01:
                        for k in range(6):
                            acc += MD[r, k] * D[c, 6 + k]
                    if s10:
                        for k in range(6):
                            acc += MD[r, 6 + k] * D[c, k]
                    if s11:
                        for k in range(6):
                            acc += MD[r, 6 + k] * D[c, 6 + k]
                    S[r, c] = acc


@njit(cache=True)
def dense_tail(nj, NZ):
    """The first block of the dense tail: every pair of blocks from it on is non-zero (the chassis-knuckle
    joints, all coupled through the chassis)."""
    t = nj
    while t > 0:
        for b in range(t - 1, nj):
            if not NZ[b, t - 1]:
                return t
        t -= 1
    return 0


@njit(cache=True)
def _dense_cholesky(S, lo, hi):
    """Cholesky in place of the dense diagonal block S[lo:hi, lo:hi] (lower triangle)."""
    for j in range(lo, hi):
        d = S[j, j]
        for p in range(lo, j):
            d -= S[j, p] * S[j, p]
        d = math.sqrt(max(d, 1e-300))
        S[j, j] = d
        for i in range(j + 1, hi):
            acc = S[i, j]
            for p in range(lo, j):
                acc -= S[i, p] * S[j, p]
            S[i, j] = acc / d


@njit(cache=True)
def factor(S, jst, nj, NZ):
    """Cholesky S = L L^T in place (lower triangle), visiting only the blocks NZ marks: the blocks before the
    dense tail right-looking (factor the diagonal block, solve the blocks below it, update the trailing
    blocks), then the dense tail as one dense matrix (long inner loops)."""
    kt = dense_tail(nj, NZ)
    for K in range(kt):
        k0, k1 = jst[K], jst[K + 1]
        _dense_cholesky(S, k0, k1)
        for A in range(K + 1, nj):
            if not NZ[A, K]:
                continue
            for i in range(jst[A], jst[A + 1]):
                for j in range(k0, k1):
                    acc = S[i, j]
                    for p in range(k0, j):
                        acc -= S[i, p] * S[j, p]
                    S[i, j] = acc / S[j, j]
        for A in range(K + 1, nj):
            if not NZ[A, K]:
                continue
            for B in range(K + 1, A + 1):
                if not NZ[B, K]:
                    continue
                for i in range(jst[A], jst[A + 1]):
                    cend = jst[B + 1] if B < A else i + 1
                    for c in range(jst[B], cend):
                        acc = 0.0
                        for p in range(k0, k1):
                            acc += S[i, p] * S[c, p]
                        S[i, c] -= acc
    _dense_cholesky(S, jst[kt], jst[nj])  # the dense tail


@njit(cache=True)
def solve(S, jst, nj, NZ, x):
    """x <- (L L^T)^-1 x with the factor of `factor`."""
    for A in range(nj):
        for i in range(jst[A], jst[A + 1]):
            acc = x[i]
            for P in range(A):
                if NZ[A, P]:
                    for k in range(jst[P], jst[P + 1]):
                        acc -= S[i, k] * x[k]
            for k in range(jst[A], i):
                acc -= S[i, k] * x[k]
            x[i] = acc / S[i, i]
    for A in range(nj - 1, -1, -1):
        for i in range(jst[A + 1] - 1, jst[A] - 1, -1):
            acc = x[i]
            for k in range(i + 1, jst[A + 1]):
                acc -= S[k, i] * x[k]
            for P in range(A + 1, nj):
                if NZ[P, A]:
                    for k in range(jst[P], jst[P + 1]):
                        acc -= S[k, i] * x[k]
            x[i] = acc / S[i, i]
