"""Which vehicles and pairs a step of the impulse kernel visits: the awake vehicles, the pairs with an awake
member, and (broad phase) those whose static partner is near (kernel docstring)."""
import math

from numba import njit

from .contact import _gap


@njit(cache=True)
def _awake_sets(asleep, nk, awake, pair_i, pair_k):
    """The awake vehicles (ascending) and the pairs (vehicle i, vehicle or barrier k > i) with an awake
    member, in the order of the full double loop over i < k. Returns their counts."""
    nv = asleep.shape[0]
    na, n_pairs = 0, 0
    for i in range(nv):
        if not asleep[i]:
            awake[na] = i
            na += 1
            for k in range(i + 1, nk):
                pair_i[n_pairs], pair_k[n_pairs] = i, k
                n_pairs += 1
        else:
            for k in range(i + 1, nv):
                if not asleep[k]:
                    pair_i[n_pairs], pair_k[n_pairs] = i, k
                    n_pairs += 1
    return na, n_pairs


@njit(cache=True)
def _moved(S, Snew, awake, na, ref, reach):
    """Some awake vehicle is more than `reach` from ref at the start (S) or the end (Snew) of the step."""
    for a in range(na):
        i = awake[a]
        if (math.hypot(S[i, 0] - ref[i, 0], S[i, 1] - ref[i, 1]) > reach
                or math.hypot(Snew[i, 0] - ref[i, 0], Snew[i, 1] - ref[i, 1]) > reach):
            return True
    return False


@njit(cache=True)
def _near_pairs(S, B, radius, asleep, awake, na, pair_i, pair_k, n_pairs, ref, reach, near_i, near_k,
                in_contact, episode, allowed):
    """The listed pairs without those of an awake vehicle and a static partner (a sleeping vehicle or a
    barrier) whose bounding circles are more than 2 reach apart: while no awake vehicle is more than reach
    (plus the curvature of a step) from ref = its position now, those stay apart, so the broad phase
    would skip them and reset their contact state, done here once. Returns the count."""
    nv = S.shape[0]
    for a in range(na):
        ref[awake[a], 0], ref[awake[a], 1] = S[awake[a], 0], S[awake[a], 1]
    n = 0
    for p in range(n_pairs):
        i, k = pair_i[p], pair_k[p]
        if (k >= nv or asleep[k] or asleep[i]) and _gap(S, B, radius, i, k, nv) > 2.0 * reach:
            in_contact[i, k] = False
            episode[i, k] = -1
            allowed[i, k] = 0.0
            continue
        near_i[n], near_k[n] = i, k
        n += 1
    return n
