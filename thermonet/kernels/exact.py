"""Exactly rounded sums of float64 terms, independent of the order the terms come in.

A float sum's last bits depend on the order of its additions, so a sum split among threads or
processes would change with their number. Here each term is added without rounding into an
*accumulator*: a fixed-point integer over the whole float64 range, kept as ``CHUNKS`` signed
int64 digits of ``DIGIT`` bits (digit i weighs 2^(DIGIT·i − 1074)), plus three counters of
+inf, −inf and NaN terms. Integer additions are exact and commute, so accumulators of any parts
of the terms, in any order, add up (:func:`combine`) to the same integers; :func:`value` then
rounds that exact sum once, to the nearest float64 (ties to even). The result is what
``math.fsum`` gives for the same terms: the correctly rounded sum.

Special values, as IEEE sums of the same terms in any order give them: a NaN term, or +inf and
−inf together, make the sum NaN; otherwise an infinite term makes it that infinity. An exact
sum of zero is +0.0 (as a float sum started from 0.0, and ``math.fsum``), even of −0.0 terms.
Finite terms whose exact sum lies beyond the float64 range give ±inf (the IEEE rounding of the
overflow; ``math.fsum`` raises instead).

Capacity: an addition (:func:`add_bits`) adds less than 2^33 to each of the three digits it
touches, so one accumulator takes up to 2^30 of them before a digit can overflow; :func:`normalize` carries the
digits back into [0, 2^DIGIT) (the top one signed), after which accumulators of up to 2^30
terms each can be combined by the 2^30.

Blocks of terms (:func:`add_terms`, what the reductions use) go faster than term by term: the
block's terms are split exactly on a grid fitted to its largest magnitude (``q = (σ + x) − σ``,
``x − q``, with σ a power of two above the block's sum: Rump, Ogita and Oishi's extraction), the
grid parts summed in float64 without rounding and their sum added to the accumulator, and the
same done for the remainders on grids 2^43 times finer each until none is left: a few vectorized
passes over a block of BLOCK terms (two, where the block's magnitudes span less than 2^33).
The terms of blocks the grids do not take (largest magnitude below 2^-900 or above 2^1000, inf,
NaN) and whatever is left after LEVELS passes are added term by term (:func:`add_bits`: a few
integer operations and three additions to the digits). A block of n terms thus makes at most
n + LEVELS additions to the accumulator: capacity counts these.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .blocks import BLOCK

#: bits per digit of an accumulator
DIGIT = 32
#: digits covering the float64 range: a term's 53-bit significand starts at bit (biased
#: exponent − 1) ≤ 2045 and spans at most three digits from there
CHUNKS = 66
#: positions of the +inf, −inf and NaN counters after the digits
POS_INF, NEG_INF, NAN = CHUNKS, CHUNKS + 1, CHUNKS + 2
#: int64 entries of one accumulator
WIDTH = CHUNKS + 3

_MASK = np.uint64(0xFFFFFFFF)
_SIGNIFICAND = np.uint64((1 << 52) - 1)
_HIDDEN = np.uint64(1 << 52)


def new(k: int = 0) -> np.ndarray:
    """A zeroed accumulator (WIDTH,) int64, or (k, WIDTH) for k sums when ``k``."""
    return np.zeros((k, WIDTH) if k else WIDTH, dtype=np.int64)


@njit(inline="always", error_model="numpy", boundscheck=False)
def add_bits(acc, u):
    """Add the float64 whose bit pattern is ``u`` (uint64) to ``acc`` (WIDTH,) int64, exactly."""
    biased = (u >> np.uint64(52)) & np.uint64(0x7FF)
    significand = u & _SIGNIFICAND
    if biased == np.uint64(0x7FF):  # inf or NaN: counted
        if significand != np.uint64(0):
            acc[NAN] += 1
        elif u >> np.uint64(63):
            acc[NEG_INF] += 1
        else:
            acc[POS_INF] += 1
        return
    if biased == np.uint64(0):  # subnormal (or zero): no hidden bit, the exponent of biased 1
        biased = np.uint64(1)
    else:
        significand |= _HIDDEN
    at = biased - np.uint64(1)  # the significand's lowest bit weighs 2^(at − 1074)
    digit = np.int64(at >> np.uint64(5))
    shift = at & np.uint64(31)
    low = (significand & _MASK) << shift  # < 2^63
    high = (significand >> np.uint64(32)) << shift  # < 2^52
    d0 = np.int64(low & _MASK)
    d1 = np.int64((low >> np.uint64(32)) + (high & _MASK))
    d2 = np.int64(high >> np.uint64(32))
    sign = np.int64(1) - (np.int64(u >> np.uint64(63)) << np.int64(1))  # (a multiplier: signs are not predictable)
    acc[digit] += sign * d0
    acc[digit + 1] += sign * d1
    acc[digit + 2] += sign * d2


@njit(inline="always", error_model="numpy", boundscheck=False)
def normalize(acc):
    """Carry ``acc``'s digits into [0, 2^DIGIT), the top digit keeping the sign (same value)."""
    carry = np.int64(0)
    for i in range(CHUNKS - 1):
        v = acc[i] + carry
        acc[i] = v & np.int64(0xFFFFFFFF)
        carry = v >> np.int64(32)  # (arithmetic: floor)
    acc[CHUNKS - 1] += carry


# terms per block of add_terms: the reductions' blocks (the grids' bound below needs at most 2^9)
assert BLOCK <= 512
#: grid passes per block before the rest goes term by term
LEVELS = 6
_ABS = np.uint64(0x7FFFFFFFFFFFFFFF)
#: the grids work for blocks whose largest magnitude lies strictly between these (bit patterns)
_HUGE = np.uint64(np.float64(2.0 ** 1000).view(np.uint64))
_TINY = np.uint64(np.float64(2.0 ** -900).view(np.uint64))
#: the finest σ a grid pass takes (its grid, σ/2^53, still a normal number)
_FINEST = 2.0 ** -960


@njit(inline="always", error_model="numpy", boundscheck=False)
def _largest(u):
    """The largest magnitude's bit pattern among the float64s whose bits are ``u`` (a NaN's
    pattern exceeds inf's)."""
    big = np.uint64(0)
    for i in range(u.shape[0]):
        big = max(big, u[np.uint64(i)] & _ABS)
    return big


@njit(inline="always", error_model="numpy", boundscheck=False)
def _any(u):
    """Whether any of the float64s whose bits are ``u`` is not zero."""
    seen = np.uint64(0)
    for i in range(u.shape[0]):
        seen |= u[np.uint64(i)] & _ABS
    return seen != np.uint64(0)


@njit(inline="always", error_model="numpy", boundscheck=False)
def add_terms(acc, x, n, one):
    """Add x[0 … n−1] to ``acc`` (WIDTH,) int64, exactly. x: (BLOCK,) float64 scratch holding
    the terms (overwritten: x[n:] zeroed, then the remainders); one: (1,) float64 scratch."""
    for i in range(n, BLOCK):
        x[np.uint64(i)] = 0.0
    u = x.view(np.uint64)
    grid_sum = one.view(np.uint64)
    big = _largest(u)
    if big == np.uint64(0):
        return
    if big < _HUGE and big > _TINY:
        # σ = 2^(e + 10) with every |x| < 2^e: each grid part is at most 2^e = σ/2^10 and a multiple
        # of σ/2^53, so with BLOCK ≤ 2^9 terms every partial sum is below σ/2 on that grid: exact.
        # The remainders are at most σ/2^53: the next grid is 2^43 times finer.
        sigma = math.ldexp(1.0, np.int64(big >> np.uint64(52)) - 1022 + 10)
        for _ in range(LEVELS):
            s0 = 0.0
            s1 = 0.0
            s2 = 0.0
            s3 = 0.0
            for k in range(BLOCK // 4):
                j = np.uint64(4 * k)
                q0 = (sigma + x[j]) - sigma
                q1 = (sigma + x[j + np.uint64(1)]) - sigma
                q2 = (sigma + x[j + np.uint64(2)]) - sigma
                q3 = (sigma + x[j + np.uint64(3)]) - sigma
                x[j] -= q0
                x[j + np.uint64(1)] -= q1
                x[j + np.uint64(2)] -= q2
                x[j + np.uint64(3)] -= q3
                s0 += q0
                s1 += q1
                s2 += q2
                s3 += q3
            one[0] = (s0 + s1) + (s2 + s3)
            add_bits(acc, grid_sum[0])
            if not _any(u):
                return
            sigma *= 2.0 ** -43
            if sigma < _FINEST:  # (grids in the normal range only)
                break
    for i in range(BLOCK):  # what the grids did not take
        if u[np.uint64(i)] & _ABS:
            add_bits(acc, u[np.uint64(i)])


@njit(cache=True, error_model="numpy", boundscheck=False)
def add_array(acc, values):
    """Add every entry of ``values`` (k,) float64 to ``acc`` (WIDTH,) int64 (normalized after)."""
    x = np.empty(BLOCK)
    one = np.empty(1)
    k = values.shape[0]
    for lo in range(0, k, BLOCK):
        n = min(BLOCK, k - lo)
        for i in range(n):
            x[np.uint64(i)] = values[np.uint64(lo + i)]
        add_terms(acc, x, n, one)
    normalize(acc)


def combine(accumulators) -> np.ndarray:
    """The accumulator of all the terms of several normalized accumulators (each (..., WIDTH))."""
    return np.sum(np.asarray(accumulators, dtype=np.int64), axis=0)


def value(acc) -> float:
    """The exact sum held by ``acc`` (WIDTH,), rounded once to the nearest float64."""
    acc = np.asarray(acc)
    if acc[NAN] or (acc[POS_INF] and acc[NEG_INF]):
        return math.nan
    if acc[POS_INF]:
        return math.inf
    if acc[NEG_INF]:
        return -math.inf
    total = 0
    for i in range(CHUNKS - 1, -1, -1):
        total = (total << DIGIT) + int(acc[i])
    try:
        return total / (1 << 1074)  # (Python's int division rounds correctly, subnormals too)
    except OverflowError:
        return math.inf if total > 0 else -math.inf


def exact_sum(values) -> float:
    """The correctly rounded sum of ``values`` (any shape, float64; at most 2^30 of them)."""
    acc = new()
    add_array(acc, np.ascontiguousarray(values, dtype=np.float64).ravel())
    return value(acc)
