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

Capacity: an addition (:func:`add_bits`, :func:`add_scaled`) adds less than 2^33 to each of the
three digits it touches, so one accumulator takes up to 2^30 of them before a digit can
overflow; :func:`normalize` carries the digits back into [0, 2^DIGIT) (the top one signed), after
which accumulators of up to 2^30 additions each can be combined by the 2^30.

Blocks of terms (:func:`add_terms`, what the reductions use) go faster than term by term: each
term is cut exactly into its integer multiples of two grids fitted to the block's largest
magnitude (2^53 and 2^106 times finer than it) and a remainder; the block's multiples are summed
as int64 (exact, in any order: the loop vectorizes) and the two sums added to the accumulator.
One pass over the block after the one finding its largest magnitude. The remainders are zero
unless the block's magnitudes span more than 2^53; those, and blocks the grids do not take
(largest magnitude below 2^-900 or above 2^1000, inf, NaN), are added term by term. A block of n
terms thus makes at most n + 2 additions to the accumulator: capacity counts these.
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
def _add_magnitude(acc, magnitude, at, sign):
    """Add sign·magnitude·2^(at − 1074) to ``acc``: magnitude uint64 below 2^63, at uint64 (its
    lowest bit's position on the accumulator's grid), sign int64 ±1; less than 2^33 added to
    each of the three digits it touches."""
    digit = np.int64(at >> np.uint64(5))
    shift = at & np.uint64(31)
    low = (magnitude & _MASK) << shift  # < 2^63
    high = (magnitude >> np.uint64(32)) << shift  # < 2^62
    d0 = np.int64(low & _MASK)
    d1 = np.int64((low >> np.uint64(32)) + (high & _MASK))
    d2 = np.int64(high >> np.uint64(32))
    acc[digit] += sign * d0
    acc[digit + 1] += sign * d1
    acc[digit + 2] += sign * d2


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
    sign = np.int64(1) - (np.int64(u >> np.uint64(63)) << np.int64(1))  # (a multiplier: signs are not predictable)
    # the significand's lowest bit weighs 2^(biased − 1 − 1074)
    _add_magnitude(acc, significand, biased - np.uint64(1), sign)


@njit(inline="always", error_model="numpy", boundscheck=False)
def normalize(acc):
    """Carry ``acc``'s digits into [0, 2^DIGIT), the top digit keeping the sign (same value)."""
    carry = np.int64(0)
    for i in range(CHUNKS - 1):
        v = acc[i] + carry
        acc[i] = v & np.int64(0xFFFFFFFF)
        carry = v >> np.int64(32)  # (arithmetic: floor)
    acc[CHUNKS - 1] += carry


@njit(inline="always", error_model="numpy", boundscheck=False)
def add_scaled(acc, s, g):
    """Add s·2^g to ``acc`` (WIDTH,) int64, exactly: s int64 with |s| < 2^63, −1074 ≤ g ≤ 1074."""
    negative = s < 0
    _add_magnitude(acc, np.uint64(-s) if negative else np.uint64(s), np.uint64(g + 1074),
                   np.int64(-1) if negative else np.int64(1))


# terms per block of add_terms: the reductions' blocks (the grids' integer sums below need at most 2^9)
assert BLOCK <= 512
_ABS = np.uint64(0x7FFFFFFFFFFFFFFF)
#: the grids work for blocks whose largest magnitude lies strictly between these (bit patterns)
_HUGE = np.uint64(np.float64(2.0 ** 1000).view(np.uint64))
_TINY = np.uint64(np.float64(2.0 ** -900).view(np.uint64))


@njit(inline="always", error_model="numpy", boundscheck=False)
def add_terms(acc, terms, n, rest):
    """Add terms[0 … n−1] to ``acc`` (WIDTH,) int64, exactly. terms: (≥ n,) float64, read only;
    rest: (BLOCK,) float64 scratch."""
    u = terms.view(np.uint64)
    big = np.uint64(0)
    for i in range(n):
        big = max(big, u[np.uint64(i)] & _ABS)
    if big == np.uint64(0):
        return
    if big < _HUGE and big > _TINY:
        # Every |x| < 2^top. On the grid 2^g1, g1 = top − 53, each term's truncation q1 is an
        # integer below 2^53 in magnitude and its remainder r = x − q1·2^g1 (exact) is below 2^g1;
        # on the grid g2 = g1 − 53 likewise. n ≤ 2^9 integers below 2^53 add up in int64 without
        # overflow, in any order (so the loop vectorizes). Scalings by powers of two in the normal
        # range are exact, and a product that underflows was below 1 anyway (q = 0).
        top = np.int64(big >> np.uint64(52)) - 1022
        g1 = top - 53
        g2 = g1 - 53
        to1 = math.ldexp(1.0, -g1)
        grid1 = math.ldexp(1.0, g1)
        to2 = math.ldexp(1.0, -g2)
        grid2 = math.ldexp(1.0, g2)
        s1 = np.int64(0)
        s2 = np.int64(0)
        left = np.int64(0)
        for i in range(n):
            x = terms[np.uint64(i)]
            q1 = np.int64(x * to1)
            r = x - np.float64(q1) * grid1
            q2 = np.int64(r * to2)
            s1 += q1
            s2 += q2
            left += (r - np.float64(q2) * grid2) != 0.0
        add_scaled(acc, s1, g1)
        add_scaled(acc, s2, g2)
        if left == 0:
            return
        # terms more than 2^53 below the block's largest keep bits below both grids: the rest
        # term by term (rare: only blocks whose magnitudes span that much)
        for i in range(n):
            x = terms[np.uint64(i)]
            r = x - np.float64(np.int64(x * to1)) * grid1
            rest[np.uint64(i)] = r - np.float64(np.int64(r * to2)) * grid2
        u = rest.view(np.uint64)
    for i in range(n):  # (also blocks the grids do not take: an inf, a NaN, magnitudes beyond them)
        if u[np.uint64(i)] & _ABS:
            add_bits(acc, u[np.uint64(i)])


@njit(cache=True, error_model="numpy", boundscheck=False)
def add_block(acc, terms, n, rest):
    """:func:`add_terms`, called rather than inlined: for kernels that add whole blocks at a few
    places, where a copy inlined at each would cost compile time and save nothing."""
    add_terms(acc, terms, n, rest)


@njit(cache=True, error_model="numpy", boundscheck=False)
def add_array(acc, values):
    """Add every entry of ``values`` (k,) float64 to ``acc`` (WIDTH,) int64 (normalized after)."""
    rest = np.empty(BLOCK)
    k = values.shape[0]
    for lo in range(0, k, BLOCK):
        add_terms(acc, values[lo:], min(BLOCK, k - lo), rest)
    normalize(acc)


def combine(accumulators) -> np.ndarray:
    """The accumulator of all the terms of several normalized accumulators (each (..., WIDTH))."""
    return np.sum(np.asarray(accumulators, dtype=np.int64), axis=0)


@njit(cache=True, error_model="numpy", boundscheck=False)
def _round(acc) -> float:
    """The exact sum of the digits of ``acc`` (WIDTH,) int64, none of its special counters set,
    rounded once to the nearest float64 (ties to even; ±inf beyond the range)."""
    d = acc[:CHUNKS].copy()
    normalize(d)  # (digits in [0, 2^32), the top one signed)
    negative = d[CHUNKS - 1] < 0
    if negative:  # the magnitude: every digit negated, carried again
        for i in range(CHUNKS):
            d[i] = -d[i]
        normalize(d)
    t = CHUNKS - 1
    while t >= 0 and d[t] == 0:
        t -= 1
    if t < 0:
        return 0.0
    # the top four digits as one 128-bit number H:L whose lowest bit is digit t − 3's (digits
    # below 0 are zero); H ≥ 2^32, so H:L holds at least 96 significant bits
    d3 = np.uint64(d[t - 3]) if t >= 3 else np.uint64(0)
    d2 = np.uint64(d[t - 2]) if t >= 2 else np.uint64(0)
    d1 = np.uint64(d[t - 1]) if t >= 1 else np.uint64(0)
    high = (np.uint64(d[t]) << np.uint64(32)) | d1
    low = (d2 << np.uint64(32)) | d3
    sticky = False
    for i in range(t - 3):
        if d[i] != 0:
            sticky = True
            break
    bits = 0  # the bit length of high (33 to 64)
    probe = high
    while probe:
        probe >>= np.uint64(1)
        bits += 1
    base = DIGIT * (t - 3) - 1074  # the weight of H:L's lowest bit is 2^base
    if base + 64 + bits <= -1074 + 53:  # below 2^53 units of 2^-1074 (so t ≤ 1, low = 0): exact
        r = np.ldexp(np.float64(high), np.int32(base + 64))
        return -r if negative else r
    # keep the top 53 bits of H:L (on the subnormal grid where the sum lies below 2^-1022)
    shift = bits + 64 - 53
    if base + shift < -1074:
        shift = -1074 - base
    if shift >= 64:
        s = np.uint64(shift - 64)
        mantissa = high >> s
        below = high & ((np.uint64(1) << s) - np.uint64(1)) if s > 0 else np.uint64(0)
        half = np.uint64(1) << (s - np.uint64(1)) if s > 0 else np.uint64(0)
        if s == 0:  # the round bit is low's top bit
            round_bit = (low >> np.uint64(63)) != 0
            sticky = sticky or (low << np.uint64(1)) != 0
        else:
            round_bit = (below & half) != 0
            sticky = sticky or (below & (half - np.uint64(1))) != 0 or low != 0
    else:
        s = np.uint64(shift)
        mantissa = (high << (np.uint64(64) - s)) | (low >> s)
        below = low & ((np.uint64(1) << s) - np.uint64(1))
        half = np.uint64(1) << (s - np.uint64(1))
        round_bit = (below & half) != 0
        sticky = sticky or (below & (half - np.uint64(1))) != 0
    if round_bit and (sticky or (mantissa & np.uint64(1)) != 0):
        mantissa += np.uint64(1)  # (2^53 at most: still exact as a float64)
    r = np.ldexp(np.float64(mantissa), np.int32(base + shift))
    return -r if negative else r


@njit(cache=True, error_model="numpy", boundscheck=False)
def _value(acc) -> float:
    if acc[NAN] or (acc[POS_INF] and acc[NEG_INF]):
        return np.nan
    if acc[POS_INF]:
        return np.inf
    if acc[NEG_INF]:
        return -np.inf
    return _round(acc)


@njit(cache=True, error_model="numpy", boundscheck=False)
def _values(accs, out):
    for i in range(accs.shape[0]):
        out[i] = _value(accs[i])


def value(acc) -> float:
    """The exact sum held by ``acc`` (WIDTH,), rounded once to the nearest float64."""
    return float(_value(np.ascontiguousarray(acc, dtype=np.int64)))


def values(accs) -> np.ndarray:
    """(k,) float64: :func:`value` of each accumulator of ``accs`` (k, WIDTH), in one call."""
    accs = np.ascontiguousarray(accs, dtype=np.int64)
    out = np.empty(accs.shape[0])
    _values(accs, out)
    return out


def exact_sum(values) -> float:
    """The correctly rounded sum of ``values`` (any shape, float64; at most 2^30 of them)."""
    acc = new()
    add_array(acc, np.ascontiguousarray(values, dtype=np.float64).ravel())
    return value(acc)
