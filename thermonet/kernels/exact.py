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

Capacity: a term adds less than 2^33 to each of the three digits it touches, so one
accumulator takes up to 2^30 terms before a digit can overflow; :func:`normalize` carries the
digits back into [0, 2^DIGIT) (the top one signed), after which accumulators of up to 2^30
terms each can be combined by the 2^30.

Cost: a few integer operations and three additions to a small array (in L1) per term, no
division or branch on the data but for the special values; not vectorized (the digit a term
lands in depends on its exponent).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

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


@njit(cache=True, error_model="numpy", boundscheck=False)
def add_array(acc, values):
    """Add every entry of ``values`` (k,) float64 to ``acc`` (WIDTH,) int64 (normalized after)."""
    bits = values.view(np.uint64)
    for i in range(bits.shape[0]):
        add_bits(acc, bits[i])
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
