"""Triangular solves with SuperLU's kept factors, split along their elimination tree so that
independent subtrees run on different threads.

A nested-dissection ordering makes the factors' elimination tree a binary tree of separators:
a row of L refers only to rows of its own subtree (forward substitution), a column of U only to
rows of its own subtree (backward substitution), so two sibling subtrees are independent. The
factors are copied once per factorization, relabelled in a postorder of the tree (every subtree
a contiguous range of rows), into blocks of rows that share their columns (a node's three
unknowns: one pass over the shared columns serves the block's rows, each row's values
contiguous so that the pass runs in vector lanes at memory speed), and the tree is cut into
groups (2**TREE_DEPTH leaf subtrees at most and the separators above them). A solve runs the
groups phase by phase, one parallel region per phase and direction: forward the leaves first,
then each level of separators, a phase's groups in thread bins, each group whole on one thread;
the top separator (a phase of one group) spreads its products with the subtrees below over the
threads, block by block forward and one child subtree per thread backward.

Every unknown's sums are taken in one order fixed by the factors and the compiled code
whichever thread takes them, so the solution is the same bit for bit at any thread count (it
differs from SuperLU's own solve in the last bits: another order of the same sums). The forward
products' vector lanes are the compiler's (their sums may be reassociated): the kernel compiled
in a process and the same kernel loaded from Numba's cache were seen to give different last bits
(the steel part's 5 172-unknown factors; with the sums in lanes written out in the source the
two agreed, but the solve took 1.02–1.30× the time on two threads at 47 637 unknowns), so a run that compiled its
kernels and one that loaded them can part in the last bits once they solve on the tree. It is compiled threaded only: on one thread its regions
run on the calling thread, and that compile ran faster than one without ``parallel=True``. Where SuperLU pivoted off
the diagonal or reordered columns, or a group's rows would refer to a sibling's (checked entry
by entry), :func:`tree_factors` returns None and the caller keeps SuperLU's solve.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from numba import njit, prange

from ..kernels.specialize import specialize

#: levels of the tree cut into groups: 2**TREE_DEPTH leaf subtrees at most (8 for two threads:
#: leaves of unequal work still fill both); fixed, so that the groups, hence the order of the
#: sums, do not depend on the thread count
TREE_DEPTH = 3


@dataclass(frozen=True, eq=False)
class TreeFactors:
    """SuperLU's factors A = L U (no pivoting) relabelled in a postorder of their elimination
    tree, in blocks, cut into groups (n unknowns, nnz entries of L below its unit diagonal, on
    whose pattern U's above its diagonal lies too, r runs, q blocks, g groups, b thread bins).

    order (n,) int64: the relabelling, new → old (row k here is row order[k] of A).
    lower_vals, upper_vals (nnz,): L's rows and U's columns, block by block: the |R| columns
        (rows of U) that a block's rows s … e − 1 share, as an (e − s) × |R| array (each row's
        shared values contiguous), then each row's entries inside the block; block q's from
        lower_ptr[s] in lower_vals, from lower_ptr[s] + upper_shift[q] in upper_vals, whose
        blocks lie in the opposite order (the backward substitution's, so that it streams
        through memory forwards as the forward one does).
    upper_shift (q,) int64: where block q's values start in upper_vals less where in lower_vals.
    diagonal (n,): U's diagonal. lower_ptr (n+1,) int64: row i's entries (on the pattern).
    run_ptr (n+1,) int64, run_col (r,) int32, run_off (r+1,) int64: row i's columns in runs of
        consecutive columns, run k starting at column run_col[k] with entry run_off[k];
        run_cut, run_lo (n,) int64: row i's first run in the second child subtree of its group
        and in its group itself (the runs before: the subtrees below).
    block_start (q+1,) int64: block q is rows block_start[q] … block_start[q+1] − 1;
        group_block_lo, group_block_hi (g,): group k's blocks; the groups by phase (leaves first,
        then the separators level by level), each phase's by thread bin.
    separator (g,) bool: whether a group is a separator (its rows refer to subtrees below it).
    bin_start (b+1,) int64: bin k holds groups bin_start[k] … bin_start[k+1] − 1, run in order
        by one thread; phase_bins (p+1,) int64: phase k's bins, phase_bins[k] … phase_bins[k+1] − 1.
    """

    order: np.ndarray
    lower_vals: np.ndarray
    upper_vals: np.ndarray
    diagonal: np.ndarray
    upper_shift: np.ndarray
    lower_ptr: np.ndarray
    run_ptr: np.ndarray
    run_col: np.ndarray
    run_off: np.ndarray
    run_cut: np.ndarray
    run_lo: np.ndarray
    block_start: np.ndarray
    group_block_lo: np.ndarray
    group_block_hi: np.ndarray
    separator: np.ndarray
    bin_start: np.ndarray
    phase_bins: np.ndarray

    @property
    def size(self) -> int:
        return len(self.diagonal)


#: rows padded into blocks (:func:`_amalgamated`): up to a node's three, while the block stores
#: at most this many times its rows' own entries
AMALGAMATION_WIDTH = 3
AMALGAMATION_SLACK = 1.5

_OPTIONS = dict(cache=True, nogil=True, boundscheck=False, error_model="numpy")
#: the forward products' sums may be reassociated: taken in vector lanes, the long rows of the
#: factors (a few hundred shared columns) stream at memory speed instead of waiting on one chain
#: of dependent additions; the order is fixed by the code and the data alone, so a solve is still
#: the same bit for bit at any thread count
_SUMS = {"reassoc", "nsz"}


@njit(**_OPTIONS)
def _parents(n, l_indptr, l_indices, u_indptr, u_indices):
    """(n,) int64: each row's parent in the elimination tree of the pattern of L + Uᵀ (both
    CSC): the first row below the diagonal in its column of L or its row of U (−1 where none)."""
    parent = np.full(n, -1, dtype=np.int64)
    for j in range(n):
        for k in range(l_indptr[j], l_indptr[j + 1]):
            i = l_indices[k]
            if i > j and (parent[j] < 0 or i < parent[j]):
                parent[j] = i
    for i in range(n):  # U's column i: rows j < i
        for k in range(u_indptr[i], u_indptr[i + 1]):
            j = u_indices[k]
            if j < i and (parent[j] < 0 or i < parent[j]):
                parent[j] = i
    return parent


@njit(**_OPTIONS)
def _with_upper(lp, lc, lv, u_indptr, u_indices, order, new):
    """L's rows (``lp``, ``lc``, ``lv``: relabelled, columns ascending) widened to the pattern
    of L + Uᵀ: the entries U holds in its column i where L has none in its row i (SuperLU's
    U may hold a few, values at round-off, where its L holds none) added with the value 0.
    Returns (ptr, cols, vals) of the widened rows (the same arrays where U adds none), and
    whether every added entry stays below the diagonal."""
    n = len(lp) - 1
    stamp = np.full(n, -1, dtype=np.int64)
    extra = np.zeros(n + 1, dtype=np.int64)
    ok = True
    for i in range(n):
        for k in range(lp[i], lp[i + 1]):
            stamp[lc[k]] = i
        c = order[i]
        for k in range(u_indptr[c], u_indptr[c + 1]):
            j = new[u_indices[k]]
            if j != i and stamp[j] != i:
                stamp[j] = i
                extra[i + 1] += 1
                if j > i:
                    ok = False
    if extra.sum() == 0 or not ok:
        return lp, lc, lv, ok
    ptr = lp.copy()
    for i in range(n):
        extra[i + 1] += extra[i]
        ptr[i + 1] += extra[i + 1]
    cols = np.empty(ptr[n], dtype=np.int32)
    vals = np.zeros(ptr[n])
    stamp[:] = -1
    for i in range(n):
        q = ptr[i]
        for k in range(lp[i], lp[i + 1]):
            stamp[lc[k]] = i
            cols[q] = lc[k]
            vals[q] = lv[k]
            q += 1
        c = order[i]
        for k in range(u_indptr[c], u_indptr[c + 1]):
            j = new[u_indices[k]]
            if j != i and stamp[j] != i:
                stamp[j] = i
                cols[q] = j
                q += 1
        if extra[i + 1] > extra[i]:  # (rare) the row's columns in order again: the few added
            for a in range(ptr[i] + 1, ptr[i + 1]):  # ones inserted (no np.argsort: compiling it
                c, v = cols[a], vals[a]  # costs seconds)
                b = a - 1
                while b >= ptr[i] and cols[b] > c:
                    cols[b + 1] = cols[b]
                    vals[b + 1] = vals[b]
                    b -= 1
                cols[b + 1] = c
                vals[b + 1] = v
    return ptr, cols, vals, ok


@njit(**_OPTIONS)
def _postorder(parent):
    """(order (n,), first (n,)): the tree's rows in postorder (new → old, children in their
    own order), and each new row's subtree's first new row (subtrees: [first, row])."""
    n = len(parent)
    head = np.full(n, -1, dtype=np.int64)
    nxt = np.full(n, -1, dtype=np.int64)
    for j in range(n - 1, -1, -1):  # children lists, ascending
        p = parent[j]
        if p >= 0:
            nxt[j] = head[p]
            head[p] = j
    order = np.empty(n, dtype=np.int64)
    first = np.empty(n, dtype=np.int64)
    stack = np.empty(n, dtype=np.int64)
    start = np.empty(n, dtype=np.int64)
    done = 0
    for root in range(n):
        if parent[root] >= 0:
            continue
        top = 0
        stack[0] = root
        start[root] = done
        while top >= 0:
            v = stack[top]
            c = head[v]
            if c >= 0:  # descend into the next child not yet visited
                head[v] = nxt[c]
                top += 1
                stack[top] = c
                start[c] = done
            else:
                order[done] = v
                first[done] = start[v]
                done += 1
                top -= 1
    return order, first


@njit(**_OPTIONS)
def _by_rows(n, indptr, indices, data, lower, order, new):
    """The strict lower (``lower``) or upper triangle of a CSC matrix (n, n), relabelled
    (``order``: new → old, ``new``: old → new), by rows, columns ascending: (ptr (n+1,), cols,
    vals), the diagonal (n,), and whether every entry stays on its side of the diagonal."""
    ptr = np.zeros(n + 1, dtype=np.int64)
    diagonal = np.zeros(n)
    ok = True
    for j in range(n):
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            if i == j:
                diagonal[new[j]] = data[k]
            elif (i > j) == lower:
                ptr[new[i] + 1] += 1
                if (new[i] > new[j]) != lower:
                    ok = False
    for i in range(n):
        ptr[i + 1] += ptr[i]
    cols = np.empty(ptr[n], dtype=np.int32)
    vals = np.empty(ptr[n])
    fill = ptr[:n].copy()
    for jn in range(n):
        j = order[jn]
        for k in range(indptr[j], indptr[j + 1]):
            i = indices[k]
            if i != j and (i > j) == lower:
                q = fill[new[i]]
                cols[q] = jn
                vals[q] = data[k]
                fill[new[i]] = q + 1
    return ptr, cols, vals, diagonal, ok


@njit(**_OPTIONS)
def _amalgamated(lp, lc, lv, group_of, first, width, slack):
    """L's rows (``lp``, ``lc``, ``lv``) padded into blocks of up to ``width`` consecutive rows
    that share their columns below the block (zeros where a row lacks one) and hold every
    column inside it (a dense triangle), where that stores at most ``slack`` times the rows'
    own entries: what :func:`_blocks` then finds as blocks. (A factorization drops the
    entries that come out exactly 0 — a net at rest has such Jacobian entries — and then a
    node's three rows differ by a few columns: each would be a block of its own.) A row joins
    the block of row s only where it is an ancestor of s in the tree, in s's group, and its
    columns below s lie in s's subtree, so that a padded column is solved before every row
    that reads it, on any thread. Returns (ptr, cols, vals), the same arrays where nothing is
    padded."""
    n = len(lp) - 1
    mark = np.full(n, -1, dtype=np.int64)  # mark[c] == s: c is a shared column of block s
    block_of = np.zeros(n, dtype=np.int64)
    shared = np.zeros(n, dtype=np.int64)  # |R| of the block starting at s
    s = 0
    own = 0  # the block's rows' own entries
    padded_any = False
    for j in range(n):
        fits = j > 0 and j - s < width and group_of[j] == group_of[s] and first[j] <= s
        new = 0
        if fits:
            for k in range(lp[j], lp[j + 1]):
                c = lc[k]
                if c < s:
                    if c < first[s]:
                        fits = False
                        break
                    if mark[c] != s:
                        new += 1
        if fits:
            rows = j - s + 1
            total_shared = shared[s] + new
            fits = rows * total_shared + rows * (rows - 1) // 2 <= slack * (own + lp[j + 1] - lp[j])
        if not fits:
            s = j
            own = 0
        block_of[j] = s
        for k in range(lp[j], lp[j + 1]):
            c = lc[k]
            if c < s and mark[c] != s:
                mark[c] = s
                shared[s] += 1
        own += lp[j + 1] - lp[j]
    size = np.zeros(n + 1, dtype=np.int64)
    for j in range(n):
        size[j + 1] = shared[block_of[j]] + j - block_of[j]
        padded_any = padded_any or size[j + 1] != lp[j + 1] - lp[j]
    if not padded_any:
        return lp, lc, lv
    ptr = np.cumsum(size)
    cols = np.empty(ptr[n], dtype=lc.dtype)
    vals = np.zeros(ptr[n], dtype=lv.dtype)
    seen = np.full(n, -1, dtype=np.int64)  # seen[c] == s: c already listed for block s
    j = 0
    while j < n:
        s = j
        e = s + 1
        while e < n and block_of[e] == s:
            e += 1
        # the shared columns in ascending order: the rows' sorted lists merged one by one
        m = 0
        base = ptr[s]
        for r in range(s, e):
            for k in range(lp[r], lp[r + 1]):
                c = lc[k]
                if c < s and seen[c] != s:
                    seen[c] = s
                    cols[base + m] = c
                    m += 1
        merged = cols[base:base + m]
        for a in range(1, m):  # (insertion: the lists are sorted, so it moves little)
            c = merged[a]
            b = a - 1
            while b >= 0 and merged[b] > c:
                merged[b + 1] = merged[b]
                b -= 1
            merged[b + 1] = c
        for a in range(m):  # (mark now: a shared column's place in the block's rows)
            mark[merged[a]] = a
        for r in range(s, e):
            q = ptr[r]
            if r > s:
                cols[q:q + m] = merged
            for t in range(r - s):
                cols[q + m + t] = s + t
            for k in range(lp[r], lp[r + 1]):
                c = lc[k]
                vals[q + (mark[c] if c < s else m + c - s)] = lv[k]
        j = e
    return ptr, cols, vals


@njit(**_OPTIONS)
def _blocks(lp, lc, group_of):
    """(b+1,) int64: where the blocks (supernodes) of rows start, each in one group: a block
    goes on from row j − 1 to row j where row j of L holds the columns row j − 1 holds, and
    j − 1 (row n: the end)."""
    n = len(lp) - 1
    starts = np.zeros(n + 1, dtype=np.bool_)
    starts[0] = True
    starts[n] = True
    for j in range(1, n):
        a, b = lp[j - 1], lp[j]
        m = b - a
        same = group_of[j] == group_of[j - 1] and lp[j + 1] - b == m + 1 and lc[b + m] == j - 1
        t = 0
        while same and t < m:
            same = lc[a + t] == lc[b + t]
            t += 1
        starts[j] = not same
    return np.flatnonzero(starts).astype(np.int64)


@njit(**_OPTIONS)
def _block_place(lp, block_start, q, jn, t):
    """Where entry t of row jn (of block q) goes in the blocked layout: the columns R that the
    block's rows s … e − 1 share, as an (e − s) × |R| array (row jn's value for R[t] at
    [jn − s, t]: each row's shared values contiguous, so that a product streams them), then each
    row's columns in the block, s … jn − 1."""
    s, e = block_start[q], block_start[q + 1]
    shared = lp[s + 1] - lp[s]
    if t < shared:
        return lp[s] + (jn - s) * shared + t
    return lp[s] + shared * (e - s) + (jn - s) * (jn - s - 1) // 2 + (t - shared)


@njit(**_OPTIONS)
def _lower_blocked(lp, lv, block_start):
    """L's values by rows (on ``lp``) in the blocked layout of :func:`_block_place`."""
    out = np.empty_like(lv)
    for q in range(len(block_start) - 1):
        for jn in range(block_start[q], block_start[q + 1]):
            for t in range(lp[jn + 1] - lp[jn]):
                out[_block_place(lp, block_start, q, jn, t)] = lv[lp[jn] + t]
    return out


@njit(**_OPTIONS)
def _upper_blocked(indptr, indices, data, order, new, lp, lc, block_start):
    """U (CSC, n × n) strictly above its diagonal, relabelled, on the pattern of L's rows (U's
    column j on the rows of row j of L, 0 where U has none) in the blocked layout of
    :func:`_block_place`. Returns (vals (nnz_L,), the diagonal (n,), whether U has no entry
    off that pattern)."""
    n = len(lp) - 1
    vals = np.zeros(len(lc))
    diagonal = np.zeros(n)
    place = np.zeros(n, dtype=np.int64)  # place[i]: where row i of the current column goes
    stamp = np.full(n, -1, dtype=np.int64)
    ok = True
    for q in range(len(block_start) - 1):
        for jn in range(block_start[q], block_start[q + 1]):
            for t in range(lp[jn + 1] - lp[jn]):
                i = lc[lp[jn] + t]
                stamp[i] = jn
                place[i] = _block_place(lp, block_start, q, jn, t)
            j = order[jn]
            for k in range(indptr[j], indptr[j + 1]):
                i = indices[k]
                if i == j:
                    diagonal[jn] = data[k]
                elif stamp[new[i]] != jn:
                    ok = False
                else:
                    vals[place[new[i]]] = data[k]
    return vals, diagonal, ok


@njit(inline="always", **_OPTIONS)
def _breaks(cols, k, first, lo, cut):
    """Whether entry k of a row starts a run: the row's first, past a gap, or at a bound."""
    if first:
        return True
    c, p = cols[k], cols[k - 1]
    return c != p + 1 or (p < lo) != (c < lo) or (p < cut) != (c < cut)


@njit(**_OPTIONS)
def _runs(ptr, cols, lo, cut):
    """Each row's columns (ascending) as runs of consecutive columns, broken also where they
    reach cut[i] and lo[i] (cut ≤ lo): (run_ptr (n+1,): row i's runs; run_col (r,) int32: a
    run's first column; run_off (r+1,) int64: where its entries start (run r: run_off[r] …
    run_off[r+1] − 1); run_cut, run_lo (n,): row i's first run at or past cut[i], lo[i])."""
    n = len(ptr) - 1
    run_ptr = np.zeros(n + 1, dtype=np.int64)
    for i in range(n):
        runs = 0
        for k in range(ptr[i], ptr[i + 1]):
            if _breaks(cols, k, k == ptr[i], lo[i], cut[i]):
                runs += 1
        run_ptr[i + 1] = run_ptr[i] + runs
    total = run_ptr[n]
    run_col = np.empty(total, dtype=np.int32)
    run_off = np.empty(total + 1, dtype=np.int64)
    run_off[total] = ptr[n]
    run_cut = np.empty(n, dtype=np.int64)
    run_lo = np.empty(n, dtype=np.int64)
    for i in range(n):
        r = run_ptr[i]
        run_cut[i] = run_ptr[i + 1]
        run_lo[i] = run_ptr[i + 1]
        for k in range(ptr[i], ptr[i + 1]):
            if _breaks(cols, k, k == ptr[i], lo[i], cut[i]):
                run_col[r] = cols[k]
                run_off[r] = k
                if cols[k] >= cut[i] and run_cut[i] == run_ptr[i + 1]:
                    run_cut[i] = r
                if cols[k] >= lo[i] and run_lo[i] == run_ptr[i + 1]:
                    run_lo[i] = r
                r += 1
    return run_ptr, run_col, run_off, run_cut, run_lo


@njit(**_OPTIONS)
def _independent(ptr, cols, group_of, cover_lo):
    """Whether every row i of L (by rows) refers only to its own group and the groups below it
    (columns from its group's cover_lo on)."""
    n = len(ptr) - 1
    for i in range(n):
        for k in range(ptr[i], ptr[i + 1]):
            if cols[k] < cover_lo[group_of[i]]:
                return False
    return True


def _children(v: int, first: np.ndarray) -> list[int]:
    """The children of v in a postordered tree, last first."""
    out = []
    c = v - 1
    while c >= first[v]:
        out.append(c)
        c = first[c] - 1
    return out


def _split(lo: int, hi: int, first: np.ndarray, work: np.ndarray):
    """Cut the rows [lo, hi) (whole subtrees) into two halves of about equal work and the
    separator above them: ((lo, m), (m, s), (s, hi)), or None where they are a chain."""
    roots = []
    r = hi - 1
    while r >= lo:
        roots.append(r)
        r = first[r] - 1
    s = hi
    if len(roots) == 1:  # one tree: its root's chain is the separator, down to a fork
        v = hi - 1
        kids = _children(v, first)
        while len(kids) == 1:
            v = kids[0]
            kids = _children(v, first)
        if not kids:
            return None
        s, roots = v, kids
    roots = roots[::-1]  # ascending: subtrees [first[r], r] in order
    bounds = np.array([first[r] for r in roots] + [roots[-1] + 1])
    cum = work[bounds] - work[bounds[0]]
    m = bounds[1 + int(np.argmin(np.abs(cum[1:-1] - cum[-1] / 2)))]
    return (int(bounds[0]), int(m)), (int(m), int(s)), (int(s), int(hi))


def _groups(n: int, first: np.ndarray, work: np.ndarray, depth: int):
    """The groups of rows: [(lo, hi, phase, separator, cover_lo, mid)], where a group's rows
    may refer to the rows [cover_lo, hi) (its subtree), its two children's being
    [cover_lo, mid) and [mid, lo) (a leaf: cover_lo = mid = lo)."""
    out = []

    def cut(lo, hi, level):
        parts = _split(lo, hi, first, work) if level < depth and hi - lo > 1 else None
        if parts is None:
            out.append((lo, hi, 0, False, lo, lo))
            return 0
        (a, m), (m2, s), (s2, h) = parts
        phase = 1 + max(cut(a, m, level + 1), cut(m2, s, level + 1))
        if s2 < h:
            out.append((s2, h, phase, True, lo, m))
        return phase

    cut(0, n, 0)
    return out


def _bins(groups, work: np.ndarray, threads: int):
    """Each phase's groups spread over at most ``threads`` bins, largest first onto the least
    loaded bin: (group order, bin_start, phase_bins)."""
    order, bin_start, phase_bins = [], [0], [0]
    for phase in range(max(g[2] for g in groups) + 1):
        members = [k for k, g in enumerate(groups) if g[2] == phase]
        cost = {k: float(work[groups[k][1]] - work[groups[k][0]]) for k in members}
        nb = max(1, min(threads, len(members)))
        bins = [[] for _ in range(nb)]
        load = [0.0] * nb
        for k in sorted(members, key=lambda k: (-cost[k], k)):
            b = int(np.argmin(load))
            bins[b].append(k)
            load[b] += cost[k]
        for b in bins:
            order.extend(b)
            bin_start.append(len(order))
        phase_bins.append(len(bin_start) - 1)
    return order, bin_start, phase_bins


@dataclass(frozen=True, eq=False)
class TreeLayout:
    """Where a factorization's entries go in :class:`TreeFactors`, kept for the next
    factorization whose factors have the same pattern (the same matrix pattern and pivots:
    the same L and U index arrays): copying its values is then one gather per array.

    l_indptr, l_indices, u_indptr, u_indices: the CSC index arrays of the L and U it was made
    for. lower_from, upper_from (nnz,), diagonal_from (n,): the entry of L.data,
    U.data, U.data each value comes from (−1: none, the value 0; int32 where the factors hold
    fewer than 2³¹ entries). arrays: the TreeFactors whose structure the copies share (its
    values are placeholders).
    """

    l_indptr: np.ndarray
    l_indices: np.ndarray
    u_indptr: np.ndarray
    u_indices: np.ndarray
    lower_from: np.ndarray
    upper_from: np.ndarray
    diagonal_from: np.ndarray
    arrays: TreeFactors

    def fits(self, L, U) -> bool:
        return (np.array_equal(self.l_indptr, L.indptr) and np.array_equal(self.u_indptr, U.indptr)
                and np.array_equal(self.l_indices, L.indices) and np.array_equal(self.u_indices, U.indices))

    def factors(self, L, U) -> TreeFactors:
        """The TreeFactors of factors L and U (CSC) that this layout :meth:`fits`."""
        return dataclasses.replace(self.arrays, lower_vals=_gather(L.data, self.lower_from),
                                   upper_vals=_gather(U.data, self.upper_from),
                                   diagonal=_gather(U.data, self.diagonal_from))


@njit(**_OPTIONS)
def _gather(data, source):
    """(len(source),) data[source], 0 where source is −1, in data's precision (single factors
    stay single: half the bytes a solve reads)."""
    out = np.empty(len(source), dtype=data.dtype)
    for k in range(len(source)):
        out[k] = data[source[k]] if source[k] >= 0 else 0.0
    return out


def tree_factors(lu, threads: int, layout: TreeLayout | None = None):
    """(TreeFactors, TreeLayout) of SuperLU's factors of ``lu`` (scipy.sparse.linalg.splu) for
    ``threads`` threads, by the given ``layout`` where it fits (no new one made), or
    (None, None) where SuperLU permuted rows or columns or the tree does not split into
    independent groups."""
    n = lu.shape[0]
    ident = np.arange(n)
    if not (np.array_equal(lu.perm_r, ident) and np.array_equal(lu.perm_c, ident)):
        return None, None
    L, U = lu.L, lu.U
    if layout is not None and layout.fits(L, U):
        return layout.factors(L, U), layout
    # the arrays of the entries' numbers + 1 (exact in float64; 0: none): where each came from
    numbered = _tree_arrays(n, _numbered(L), _numbered(U), threads)
    if numbered is None:
        return None, None
    kind = np.int32 if max(L.nnz, U.nnz) < 2**31 - 1 else np.int64
    layout = TreeLayout(L.indptr.copy(), L.indices.copy(), U.indptr.copy(), U.indices.copy(),
                        (numbered.lower_vals - 1).astype(kind), (numbered.upper_vals - 1).astype(kind),
                        (numbered.diagonal - 1).astype(kind), numbered)
    return layout.factors(L, U), layout


@njit(**_OPTIONS)
def _blocks_reversed(vals, starts):
    """(vals with its blocks in the opposite order, (q,) int64 where each block moved by): block q
    spans vals[starts[q] : starts[q + 1]] ((q+1,) ``starts``)."""
    q = len(starts) - 1
    out = np.empty_like(vals)
    shift = np.empty(q, dtype=np.int64)
    at = 0
    for b in range(q - 1, -1, -1):
        size = starts[b + 1] - starts[b]
        out[at:at + size] = vals[starts[b]:starts[b + 1]]
        shift[b] = at - starts[b]
        at += size
    return out, shift


def _numbered(M):
    """M (CSC) with its entries' numbers + 1 as values."""
    return sp.csc_matrix((np.arange(1.0, M.nnz + 1.0), M.indices, M.indptr), shape=M.shape)


def _tree_arrays(n: int, L, U, threads: int) -> TreeFactors | None:
    """TreeFactors of L and U (CSC, no pivoting), or None (see :func:`tree_factors`)."""
    order, first = _postorder(_parents(n, L.indptr, L.indices, U.indptr, U.indices))
    new = np.empty(n, dtype=np.int64)
    new[order] = np.arange(n)
    lp, lc, lv, _, lower_ok = _by_rows(n, L.indptr, L.indices, L.data, True, order, new)
    if not lower_ok:
        return None
    lp, lc, lv, lower_ok = _with_upper(lp, lc, lv, U.indptr, U.indices, order, new)
    if not lower_ok:
        return None
    work = np.zeros(n + 1)
    np.cumsum(2 * np.diff(lp) + 1, out=work[1:])  # (U's columns on L's rows' pattern)
    groups = _groups(n, first, work, TREE_DEPTH)
    ranked, bin_start, phase_bins = _bins(groups, work, max(1, int(threads)))
    lo, hi, _, sep, cover_lo, mid = (np.array([groups[k][c] for k in ranked], dtype=np.int64) for c in range(6))
    group_of = np.empty(n, dtype=np.int64)
    for g in range(len(lo)):
        group_of[lo[g]:hi[g]] = g
    if not _independent(lp, lc, group_of, cover_lo):
        return None
    lp, lc, lv = _amalgamated(lp, lc, lv, group_of, first, AMALGAMATION_WIDTH, AMALGAMATION_SLACK)
    block_start = _blocks(lp, lc, group_of)
    uv, diagonal, upper_ok = _upper_blocked(U.indptr, U.indices, U.data, order, new, lp, lc, block_start)
    del L, U
    if not upper_ok:
        return None
    run_ptr, run_col, run_off, run_cut, run_lo = _runs(lp, lc, lo[group_of], mid[group_of])
    uv, upper_shift = _blocks_reversed(uv, lp[block_start])
    return TreeFactors(order, _lower_blocked(lp, lv, block_start), uv, diagonal, upper_shift, lp, run_ptr, run_col,
                       run_off, run_cut, run_lo, block_start, np.searchsorted(block_start, lo),
                       np.searchsorted(block_start, hi), sep.astype(np.bool_), np.array(bin_start, dtype=np.int64),
                       np.array(phase_bins, dtype=np.int64))


@njit(fastmath=_SUMS, **_OPTIONS)
def _lower_product(x, vals, lp, run_col, run_off, s, e, r0, r1, gathered):
    """x[s + c] −= Σ_k L[s + c, col k] x[col k] for the block's rows s … e − 1 over the shared
    columns in the runs r0 … r1 − 1 of row s: those x first gathered into ``gathered`` (float64,
    at least as long), then each row's sum over its contiguous values in vector lanes (_SUMS; a
    block of three rows, a node's, in one pass)."""
    width = e - s
    shared = lp[s + 1] - lp[s]  # (row c's value for row s's entry k: vals[k + c shared])
    m = 0
    for r in range(r0, r1):
        c0 = np.int64(run_col[r])
        n = run_off[r + 1] - run_off[r]
        source, target = x[c0:c0 + n], gathered[m:m + n]
        for i in range(n):  # (a slice assignment checks the two for overlap: about 10 % of a solve)
            target[i] = source[i]
        m += n
    k0 = run_off[r0] if r1 > r0 else lp[s]
    if width == 3:
        v0 = vals[k0:k0 + m]
        v1 = vals[k0 + shared:k0 + shared + m]
        v2 = vals[k0 + 2 * shared:k0 + 2 * shared + m]
        a0 = a1 = a2 = 0.0
        for i in range(m):
            v = gathered[i]
            a0 += v0[i] * v
            a1 += v1[i] * v
            a2 += v2[i] * v
        x[s] -= a0
        x[s + 1] -= a1
        x[s + 2] -= a2
        return
    for c in range(width):
        row = vals[k0 + c * shared:k0 + c * shared + m]
        acc = 0.0
        for i in range(m):
            acc += row[i] * gathered[i]
        x[s + c] -= acc


@njit(**_OPTIONS)
def _lower_triangle(x, vals, lp, s, e):
    """The block's rows s … e − 1 in turn: x[j] −= Σ_{s ≤ c < j} L[j, c] x[c]."""
    tri = lp[s] + (lp[s + 1] - lp[s]) * (e - s)
    for j in range(s + 1, e):
        base = tri + (j - s) * (j - s - 1) // 2
        acc = 0.0
        for t in range(j - s):
            acc += vals[base + t] * x[s + t]
        x[j] -= acc


@njit(**_OPTIONS)
def _upper_product(x, vals, lp, run_col, run_off, s, e, r0, r1, shift):
    """x[r] −= Σ_c U[r, c] x[c] over a block's columns s … e − 1 and its shared rows r in the
    runs r0 … r1 − 1 of row s (each column's values contiguous: a run's rows update as one
    vector loop); the block's values from lp[s] + ``shift`` in ``vals``."""
    width = e - s
    shared = lp[s + 1] - lp[s]
    if width == 3:
        w0, w1, w2 = x[s], x[s + 1], x[s + 2]
        for r in range(r0, r1):
            k0 = run_off[r] + shift
            n = run_off[r + 1] - run_off[r]
            c0 = np.int64(run_col[r])
            rows = x[c0:c0 + n]
            v0 = vals[k0:k0 + n]
            v1 = vals[k0 + shared:k0 + shared + n]
            v2 = vals[k0 + 2 * shared:k0 + 2 * shared + n]
            for i in range(n):
                rows[i] -= (v0[i] * w0 + v1[i] * w1) + v2[i] * w2
        return
    for r in range(r0, r1):
        rows = run_col[r] - run_off[r]
        for k in range(run_off[r], run_off[r + 1]):
            acc = 0.0
            for c in range(width):
                acc += vals[k + shift + c * shared] * x[s + c]
            x[rows + k] -= acc


@njit(**_OPTIONS)
def _upper_triangle(x, vals, diagonal, lp, s, e, shift):
    """The block's columns e − 1 … s: x[j] ← x[j] / U[j, j], then its column's rows s … j − 1
    (the block's values from lp[s] + ``shift``)."""
    tri = lp[s] + (lp[s + 1] - lp[s]) * (e - s) + shift
    for j in range(e - 1, s - 1, -1):
        w = x[j] / diagonal[j]
        x[j] = w
        base = tri + (j - s) * (j - s - 1) // 2
        for t in range(j - s):
            x[s + t] -= vals[base + t] * w


@njit(**_OPTIONS)
def _widest(lp, block_start, q0, q1):
    """The most shared columns of the blocks q0 … q1 − 1."""
    most = 0
    for q in range(q0, q1):
        s = block_start[q]
        most = max(most, lp[s + 1] - lp[s])
    return most


@njit(**_OPTIONS)
def _forward_group(x, lv, lp, run_ptr, run_col, run_off, run_lo, block_start, q0, q1, below):
    """Forward substitution through a group's blocks q0 … q1 − 1: each block's products (with
    the subtrees below where ``below``, else only with the group's own rows) and its triangle.
    (``below`` is passed as ``np.bool_``: a literal would compile a copy per value.)"""
    gathered = np.empty(_widest(lp, block_start, q0, q1))
    for q in range(q0, q1):
        s, e = block_start[q], block_start[q + 1]
        _lower_product(x, lv, lp, run_col, run_off, s, e, run_ptr[s] if below else run_lo[s], run_ptr[s + 1],
                       gathered)
        _lower_triangle(x, lv, lp, s, e)


@njit(**_OPTIONS)
def _backward_group(x, uv, diagonal, shift, lp, run_ptr, run_col, run_off, run_lo, block_start, q0, q1, below):
    """Backward substitution through a group's blocks q1 − 1 … q0: each block's triangle and its
    products (with the subtrees below where ``below``, else only with the group's own rows)."""
    for q in range(q1 - 1, q0 - 1, -1):
        s, e = block_start[q], block_start[q + 1]
        _upper_triangle(x, uv, diagonal, lp, s, e, shift[q])
        _upper_product(x, uv, lp, run_col, run_off, s, e, run_ptr[s] if below else run_lo[s], run_ptr[s + 1],
                       shift[q])


def _solve(x, lv, uv, diagonal, shift, lp, run_ptr, run_col, run_off, run_cut, run_lo, block_start, gb_lo, gb_hi, sep,
           bin_start, phase_bins):
    """x ← U⁻¹ L⁻¹ x in place (the arrays of :class:`TreeFactors`). One parallel region per
    phase and direction (a region waits for every thread to wake: on a loaded machine that can
    be a scheduler's time slice, so their number counts): a phase of several groups runs its
    thread bins, each group whole on one thread; a phase of one separator (the top) spreads its
    products with the subtrees below over the threads, block by block forward and one child
    subtree per thread backward, and runs its own rows on one. Which phases spread follows from
    the tree alone, so each group's sums are the same at any thread count."""
    phases = len(phase_bins) - 1
    for phase in range(phases):  # forward, by blocks of L's rows: leaves first
        b0, b1 = phase_bins[phase], phase_bins[phase + 1]
        g0 = bin_start[b0]
        spread = bin_start[b1] - g0 == 1 and sep[g0]
        t0, t1 = b0, b1  # (one loop for both kinds of phase: each prange costs its own compile)
        if spread:
            t0, t1 = gb_lo[g0], gb_hi[g0]
        for t in prange(t0, t1):
            if spread:  # block t's products with the subtrees below
                s, e = block_start[t], block_start[t + 1]
                _lower_product(x, lv, lp, run_col, run_off, s, e, run_ptr[s], run_lo[s],
                               np.empty(lp[s + 1] - lp[s]))
            else:
                for g in range(bin_start[t], bin_start[t + 1]):
                    _forward_group(x, lv, lp, run_ptr, run_col, run_off, run_lo, block_start, gb_lo[g], gb_hi[g],
                                   np.bool_(True))
        if spread:
            _forward_group(x, lv, lp, run_ptr, run_col, run_off, run_lo, block_start, gb_lo[g0], gb_hi[g0],
                           np.bool_(False))
    for phase in range(phases - 1, -1, -1):  # backward, by blocks of U's columns: the top first
        b0, b1 = phase_bins[phase], phase_bins[phase + 1]
        g0 = bin_start[b0]
        spread = bin_start[b1] - g0 == 1 and sep[g0]
        if spread:
            _backward_group(x, uv, diagonal, shift, lp, run_ptr, run_col, run_off, run_lo, block_start, gb_lo[g0],
                            gb_hi[g0], np.bool_(False))
        t0, t1 = b0, b1
        if spread:
            t0, t1 = 0, 2
        for t in prange(t0, t1):
            if spread:  # its child subtree t's rows
                for q in range(gb_hi[g0] - 1, gb_lo[g0] - 1, -1):
                    s, e = block_start[q], block_start[q + 1]
                    _upper_product(x, uv, lp, run_col, run_off, s, e, run_ptr[s] if t == 0 else run_cut[s],
                                   run_cut[s] if t == 0 else run_lo[s], shift[q])
            else:
                for g in range(bin_start[t], bin_start[t + 1]):
                    _backward_group(x, uv, diagonal, shift, lp, run_ptr, run_col, run_off, run_lo, block_start,
                                    gb_lo[g], gb_hi[g], np.bool_(True))


# (compiled threaded only: on one thread its regions run on the calling thread, and a compile
# without parallel=True ran slower there: benchmarks/README.md, "Kept factors solved on their
# elimination tree")
_parallel_solve = specialize(_solve, "parallel", {}, parallel=True, **_OPTIONS)


def tree_solve(factors: TreeFactors, rhs: np.ndarray) -> np.ndarray:
    """(n,) the solution of L U x = rhs with :class:`TreeFactors`, on Numba's threads."""
    f = factors
    x = np.asarray(rhs, dtype=np.float64)[f.order]
    _parallel_solve(
        x, f.lower_vals, f.upper_vals, f.diagonal, f.upper_shift, f.lower_ptr, f.run_ptr, f.run_col, f.run_off,
        f.run_cut, f.run_lo, f.block_start, f.group_block_lo, f.group_block_hi, f.separator, f.bin_start, f.phase_bins)
    out = np.empty_like(x)
    out[f.order] = x
    return out
