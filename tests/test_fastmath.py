"""thermonet.kernels.fastmath's exp and log against NumPy (libm), in ulps, over the whole float64
range and densely over what the models reach: stretches l/l0 in 1e-3..1e3, temperature ratios
θ/θ0 in 1e-3..1e3 (exp arguments within ±ln 1e3), and the special values; its divided
differences log_ratio and exprel (and their derivatives) against 80-digit arithmetic."""

import math

import numpy as np
import pytest
from numba import njit

from thermonet.kernels.fastmath import exp, exprel, fma, log, log_ratio

MAX_ULPS = 1


@njit(error_model="numpy")
def _exp_all(x, out):
    for i in range(x.shape[0]):
        out[i] = exp(x[i])


@njit(error_model="numpy")
def _log_all(x, out):
    for i in range(x.shape[0]):
        out[i] = log(x[i])


def fast_exp(x):
    out = np.empty_like(x)
    _exp_all(x, out)
    return out


def fast_log(x):
    out = np.empty_like(x)
    _log_all(x, out)
    return out


def ulp_distance(a, b):
    """Number of float64 values between a and b (0 when equal, both NaN, or equal infinities)."""
    ia, ib = (np.asarray(v, dtype=np.float64).view(np.int64) for v in (a, b))
    # map the sign-magnitude bit patterns onto a monotone integer line
    ia = np.where(ia < 0, np.int64(-(2**63)) - ia, ia)
    ib = np.where(ib < 0, np.int64(-(2**63)) - ib, ib)
    d = np.abs(ia.astype(object) - ib.astype(object)).astype(float)
    both_nan = np.isnan(a) & np.isnan(b)
    return np.where(both_nan, 0.0, d)


def assert_within_ulps(actual, expected, x, what):
    d = ulp_distance(actual, expected)
    worst = int(np.argmax(d))
    assert d.max() <= MAX_ULPS, f"{what}({x[worst]!r}) = {actual[worst]!r}, NumPy {expected[worst]!r}: {d.max():.0f} ulps"


RNG = np.random.default_rng(20260101)


def test_exp_over_its_whole_range():
    x = np.concatenate([
        RNG.uniform(-745.2, 709.79, 200_000),                        # every binade of the result
        RNG.uniform(-745.2, -708.0, 20_000),                          # subnormal results
        RNG.uniform(-math.log(1e3), math.log(1e3), 200_000),          # θ/θ0 in 1e-3..1e3
        RNG.uniform(-1e-6, 1e-6, 20_000),                             # near 0
        np.ldexp(RNG.uniform(-1, 1, 20_000), RNG.integers(-1074, -20, 20_000)),
    ])
    assert_within_ulps(fast_exp(x), np.exp(x), x, "exp")


def test_exp_special_values():
    x = np.array([0.0, -0.0, 709.78, 709.7827128933839, 709.79, 710.0, 1e300, np.inf,
                  -745.13, -745.14, -746.0, -1e300, -np.inf, np.nan, 5e-324, -5e-324])
    with np.errstate(over="ignore", under="ignore"):
        expected = np.exp(x)
    got = fast_exp(x)
    assert_within_ulps(got, expected, x, "exp")
    assert np.isnan(got[x != x]).all() and (got[x == np.inf] == np.inf).all() and (got[x == -np.inf] == 0).all()


def test_log_over_every_positive_float():
    bits = RNG.integers(1, 0x7FF0000000000000, 400_000, dtype=np.int64)  # subnormals included
    x = np.concatenate([
        bits.view(np.float64),
        10.0 ** RNG.uniform(-3, 3, 200_000),                          # stretches and θ/θ0 in 1e-3..1e3
        1.0 + RNG.uniform(-1e-3, 1e-3, 50_000),                       # near 1, where log is small
        1.0 + RNG.uniform(-1e-12, 1e-12, 10_000),
        RNG.uniform(math.sqrt(0.5) * 0.999, math.sqrt(2.0) * 1.001, 50_000),  # the reduction's edges
    ])
    assert_within_ulps(fast_log(x), np.log(x), x, "log")


def test_log_special_values():
    x = np.array([1.0, 2.0, 0.5, 5e-324, 2.2250738585072014e-308, 2.225073858507201e-308,
                  1.7976931348623157e308, np.inf, 0.0, -0.0, -1.0, -np.inf, np.nan])
    with np.errstate(divide="ignore", invalid="ignore"):
        expected = np.log(x)
    got = fast_log(x)
    assert_within_ulps(got, expected, x, "log")
    assert got[0] == 0.0 and got[-6] == np.inf and got[-5] == -np.inf and got[-4] == -np.inf
    assert np.isnan(got[-3:]).all()


def test_fma_is_fused():
    @njit
    def f(a, b, c):
        return fma(a, b, c)

    a = 1.0 + 2.0**-30
    # a² − (1 + 2⁻²⁹) is 2⁻⁶⁰ exactly; an unfused multiply-add rounds it away
    assert f(a, a, -(1.0 + 2.0**-29)) == 2.0**-60


@pytest.mark.parametrize("function", [exp, log])
def test_a_loop_over_them_vectorizes(function):
    """The point of the module: no libm call, so LLVM vectorizes loops that use them."""

    @njit(error_model="numpy")
    def loop(x, out):
        for i in range(x.shape[0]):
            out[i] = function(x[i])

    x = np.linspace(0.5, 2.0, 64)
    loop(x, np.empty_like(x))
    assert "vector.body" in loop.inspect_llvm(loop.signatures[0])


@njit(error_model="numpy")
def _pairs(function, x, out):
    for i in range(x.shape[0]):
        out[0, i], out[1, i] = function(x[i])


def _relative_error_in_eps(got, exact):
    exact = np.asarray(exact, dtype=float)
    return np.abs(got - exact) / np.abs(exact) / np.finfo(float).eps


def test_log_ratio_and_its_derivative_without_cancellation():
    """G(u) = ln u/(u − 1) and G'(u) within a few ulps from u = 1 (and one ulp away) to u far
    from 1, across the switch of G' between its series and the quotient (|s| = 0.3)."""
    import mpmath as mp

    mp.mp.dps = 80
    u = np.concatenate([[1.0, 1.0 + 2.0**-52, 1.0 - 2.0**-53, 1.0 / 0.7 * (1 + 1e-15), 1.3 / 0.7, 0.7 / 1.3],
                        1.0 + np.ldexp(RNG.uniform(-1, 1, 3000), RNG.integers(-60, 0, 3000)),
                        np.exp(RNG.uniform(-7, 7, 1000))])
    out = np.empty((2, u.size))
    _pairs(log_ratio, u, out)

    def exact(v):
        v = mp.mpf(v)
        if v == 1:
            return 1.0, -0.5
        with mp.workdps(80 + 2 * max(0, int(-mp.log10(abs(v - 1))))):  # 1/v − G cancels to (1 − v)/2
            g = mp.log(v) / (v - 1)
            return float(g), float((1 / v - g) / (v - 1))

    ref = np.array([exact(v) for v in u]).T
    # measured: 1.2 and 2.9 ulps
    assert _relative_error_in_eps(out[0], ref[0]).max() <= 4
    assert _relative_error_in_eps(out[1], ref[1]).max() <= 8


def test_exprel_and_its_derivative_without_cancellation():
    """φ(x) = (eˣ − 1)/x and φ'(x) within a few ulps from x = 0 through tiny x to |x| of tens,
    across their switch between series and quotient (|x| = 0.5)."""
    import mpmath as mp

    mp.mp.dps = 80
    x = np.concatenate([[0.0, 2.0**-1074, -1e-300, 0.5, -0.5, np.nextafter(0.5, 0.0), np.nextafter(-0.5, 0.0)],
                        np.ldexp(RNG.uniform(-1, 1, 3000), RNG.integers(-60, 2, 3000)), RNG.uniform(-40, 40, 1000)])
    out = np.empty((2, x.size))
    _pairs(exprel, x, out)

    def exact(v):
        v = mp.mpf(v)
        if v == 0:
            return 1.0, 0.5
        with mp.workdps(80 + 2 * max(0, int(-mp.log10(abs(v))))):  # e^v (v − 1) + 1 cancels to v²/2
            return float(mp.expm1(v) / v), float((mp.exp(v) * (v - 1) + 1) / v**2)

    ref = np.array([exact(v) for v in x]).T
    # measured: 2.0 and 3.7 ulps
    assert _relative_error_in_eps(out[0], ref[0]).max() <= 4
    assert _relative_error_in_eps(out[1], ref[1]).max() <= 8


@pytest.mark.parametrize("function", [log_ratio, exprel])
def test_a_loop_over_the_divided_differences_vectorizes(function):
    @njit(error_model="numpy")
    def loop(x, out):
        for i in range(x.shape[0]):
            g, dg = function(x[i])
            out[i] = g + dg

    x = np.linspace(0.5, 2.0, 64)
    loop(x, np.empty_like(x))
    assert "vector.body" in loop.inspect_llvm(loop.signatures[0])
