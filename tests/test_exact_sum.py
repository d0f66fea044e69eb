"""The exactly rounded sums of the diagnostics rows (thermonet.kernels.exact): the sum of any
split or reordering of the terms has the same bits, and they are math.fsum's."""

import math

import numpy as np
import pytest

from thermonet.kernels import exact


def terms(seed: int) -> np.ndarray:
    """A few hundred terms over the whole float64 range, both signs, subnormals and
    cancellations among them."""
    rng = np.random.default_rng(seed)
    n = 300
    wide = rng.normal(size=n) * 10.0 ** rng.integers(-300, 300, n)
    tiny = rng.normal(size=n) * 1e-310
    big = rng.normal(size=n) * 1e300
    return np.concatenate([wide, tiny, big, -big, rng.normal(size=n), [5e-324, -0.0, 0.0]])


@pytest.mark.parametrize("seed", range(4))
def test_the_sum_of_any_split_and_order_is_fsum_bit_for_bit(seed):
    v = terms(seed)
    want = math.fsum(v)
    assert exact.exact_sum(v) == want
    rng = np.random.default_rng(100 + seed)
    for parts in (2, 3, 7):  # shuffled, cut into uneven parts, each reduced apart, then combined
        shuffled = rng.permutation(v)
        cuts = np.sort(rng.integers(0, len(v) + 1, parts - 1))
        accumulators = []
        for part in np.split(shuffled, cuts):
            acc = exact.new()
            exact.add_array(acc, np.ascontiguousarray(part))
            accumulators.append(acc)
        assert exact.value(exact.combine(accumulators)).hex() == want.hex()


def test_special_values_are_those_of_an_ieee_sum_in_any_order():
    assert math.copysign(1.0, exact.exact_sum([-0.0, -0.0])) == 1.0  # +0.0, as math.fsum gives
    assert exact.exact_sum([]) == 0.0
    assert exact.exact_sum([1.0, math.inf, -5.0]) == math.inf
    assert math.isnan(exact.exact_sum([math.inf, 1.0, -math.inf]))
    assert math.isnan(exact.exact_sum([2.0, math.nan]))
    assert exact.exact_sum([1.7e308, 1.7e308]) == math.inf  # beyond the range: the IEEE rounding
    assert exact.exact_sum([-1.7e308, -1.7e308, 1e-300]) == -math.inf
    assert exact.exact_sum([1.7e308, 1.7e308, -1.7e308]) == 1.7e308  # exact: no overflow inside
    assert exact.exact_sum([5e-324, 5e-324, 5e-324]) == 1.5e-323  # subnormals exactly


def test_halfway_sums_round_to_even_and_any_bit_below_breaks_the_tie():
    """Sums exactly halfway between two floats (at every scale, the subnormals' included) round
    to the even one; a bit far below the halfway point, or above it, decides; the largest float
    plus half its spacing is +inf. As math.fsum rounds them."""
    rng = np.random.default_rng(5)
    cases = [[2.0 ** 1023 * (2 - 2.0 ** -52), 2.0 ** 970]]  # (beyond the range)
    for e in list(rng.integers(-1074, 970, 300)) + [-1074, -1073, -1023, -1022, -1021, -1000, 0, 969]:
        e = int(e)
        for odd in (0, 1):
            base = math.ldexp(float((1 << 52) + 2 * int(rng.integers(0, 1 << 50)) + odd), e)
            half = math.ldexp(1.0, e - 1)  # half the spacing at base (the subnormals' smallest: 0)
            below = [math.ldexp(1.0, max(e - 1 - k, -1074)) for k in (1, 60, 500)]
            cases += [[base, half], [-base, -half], [base, half, below[0]], [base, half, -below[1]],
                      [base, half, below[2], -below[2]], [half, base, -half, -half]]
    for c in cases:
        c = [x for x in c if x != 0.0]
        got = exact.exact_sum(c)
        try:
            want = math.fsum(c)
        except OverflowError:
            want = math.inf
        assert got.hex() == want.hex(), (c, got, want)


def test_a_normalized_accumulator_keeps_its_digits_in_range():
    acc = exact.new()
    exact.add_array(acc, -np.abs(terms(9)))
    digits = acc[:exact.CHUNKS]
    assert (digits[:-1] >= 0).all() and (digits[:-1] < 2 ** exact.DIGIT).all() and digits[-1] < 0


@pytest.mark.parametrize("span", [0, 20, 52, 53, 54, 60, 106, 107, 200])
def test_blocks_whose_magnitudes_span_up_to_and_beyond_both_grids(span):
    """Blocks of terms whose magnitudes spread over ``span`` binary orders: below 2^53 the two
    grids take every bit, beyond it the remainders go term by term; either way fsum's bits."""
    rng = np.random.default_rng(span)
    v = rng.normal(size=3000) * 2.0 ** rng.integers(-span, 1, 3000) * 1e5
    v[::7] = -v[::7]
    assert exact.exact_sum(v).hex() == math.fsum(v).hex()
