"""Vectorizable ``exp`` and ``log`` for Numba kernels, accurate to about one ulp, and the two
divided differences built on them that closed-form discrete gradients need (:func:`log_ratio`,
:func:`exprel`).

Numba compiles ``math.exp``/``math.log`` to scalar libm calls unless its SVML vector library is
present (it is not in every build), and a loop that calls libm does not vectorize. The functions
here use only arithmetic, comparisons and bit casts, so LLVM inlines them and vectorizes the loop
around them. They handle the whole float64 range: zero, subnormals, infinities, NaN, and
overflow/underflow of ``exp``; ``tests/test_fastmath.py`` bounds their error in ulps against NumPy.

Model code may use them instead of ``math.exp``/``math.log`` (``thermonet.models.hencky`` does)::

    from thermonet.kernels.fastmath import exp, log

Method (textbook range reduction; coefficients are exact Taylor coefficients, no tables):

- ``exp(x)``: k = round(x / ln 2), r = x − k ln 2 in two parts (Cody–Waite), so |r| ≤ ln2/2;
  e^r by its degree-13 Taylor polynomial (truncation < 2⁻⁵⁷); scaled by 2^k built from integer
  arithmetic in two factors, so that results in the subnormal range and overflow come out right.
- ``log(x)``: x = 2^k y with y in [√2/2, √2) read from the bits; with f = y − 1 (exact) and
  s = f / (2 + f), log y = 2 atanh s = f − f²/2 + s (f²/2 + R(s²)), R the atanh series to s²⁰
  (truncation < 2⁻⁵⁸ for |s| ≤ 0.1716); the form keeps the leading f exact, as in fdlibm.
- ``log_ratio(u)`` = ln u / (u − 1) and ``exprel(x)`` = (eˣ − 1)/x, each with its derivative: a
  difference quotient written so that nothing cancels as u → 1 or x → 0 (Kahan's trick for the
  first, ln u / (u − 1) with the rounded u being exact for that u; the Taylor series near 0 for
  the second and for the derivatives). Branch-free selects, so loops over them vectorize too.
"""

from __future__ import annotations

import math

from llvmlite import ir
from numba import njit, types
from numba.extending import intrinsic

__all__ = ["exp", "log", "fma", "log_ratio", "exprel"]


@intrinsic
def _bits(typingctx, x):
    """The IEEE-754 bit pattern of a float64, as int64 (a register bit cast, no memory)."""
    if not isinstance(x, types.Float) or x.bitwidth != 64:
        return None

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return types.int64(types.float64), codegen


@intrinsic
def _from_bits(typingctx, i):
    """The float64 whose IEEE-754 bit pattern is the int64 ``i``."""
    if not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        v = args[0]
        if signature.args[0].bitwidth != 64:
            v = builder.sext(v, ir.IntType(64)) if signature.args[0].signed else builder.zext(v, ir.IntType(64))
        return builder.bitcast(v, ir.DoubleType())

    return types.float64(i), codegen


@intrinsic
def fma(typingctx, a, b, c):
    """a * b + c with a single rounding (the llvm.fma intrinsic; one instruction on x86-64-v3)."""
    if not all(isinstance(t, types.Float) for t in (a, b, c)):
        return None

    def codegen(context, builder, signature, args):
        args = [context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args)]
        return builder.fma(*args)

    return types.float64(types.float64, types.float64, types.float64), codegen


_OPTS = dict(inline="always", error_model="numpy")

# exp ------------------------------------------------------------------------------------------
_INV_LN2 = 1.4426950408889634
# ln 2 = _LN2_HI + _LN2_LO, _LN2_HI with 32 trailing zero bits so that k * _LN2_HI is exact.
_LN2_HI = 0.6931471803691238
_LN2_LO = 1.9082149292705877e-10
# Adding this rounds |t| < 2^51 to an integer held in the low bits of the sum (round to nearest).
_ROUNDER = 6755399441055744.0  # 1.5 * 2^52
_ROUNDER_BITS = 0x4338000000000000
_EXP_MAX = 709.8  # exp overflows above 709.78…
_EXP_MIN = -746.0  # and underflows to 0 below −745.13…

_E2, _E3, _E4, _E5, _E6, _E7 = 1 / 2, 1 / 6, 1 / 24, 1 / 120, 1 / 720, 1 / 5040
_E8, _E9, _E10, _E11, _E12, _E13 = 1 / 40320, 1 / 362880, 1 / 3628800, 1 / 39916800, 1 / 479001600, 1 / 6227020800


@njit(**_OPTS)
def exp(x):
    """e**x for a float64 x (|error| ≲ 1 ulp; inf above 709.78, 0 below −745.13, NaN for NaN)."""
    xc = x if x < _EXP_MAX else _EXP_MAX
    xc = xc if xc > _EXP_MIN else _EXP_MIN
    t = fma(xc, _INV_LN2, _ROUNDER)
    k = _bits(t) - _ROUNDER_BITS
    kf = t - _ROUNDER
    r = fma(-kf, _LN2_LO, fma(-kf, _LN2_HI, xc))
    # Estrin's scheme: the polynomial in a few independent chains instead of one long Horner
    # chain, so consecutive vector iterations are not serialized on FP latency.
    r2 = r * r
    r4 = r2 * r2
    r8 = r4 * r4
    q = fma(fma(fma(_E13, r, _E12), r2, fma(_E11, r, _E10)), r8,
            fma(fma(fma(_E9, r, _E8), r2, fma(_E7, r, _E6)), r4, fma(fma(_E5, r, _E4), r2, fma(_E3, r, _E2))))
    er = 1.0 + fma(r2, q, r)
    # 2^k as two normal factors: k spans about [−1076, 1025], each half stays in range.
    k1 = k >> 1
    k2 = k - k1
    y = er * _from_bits((k1 + 1023) << 52) * _from_bits((k2 + 1023) << 52)
    return y if x == x else x


# log ------------------------------------------------------------------------------------------
_MANT = (1 << 52) - 1
_SQRT_HALF_BITS = 0x3FE6A09E667F3BCD  # √2/2
_ONE_BITS = 0x3FF0000000000000
_TWO54 = 18014398509481984.0
_MIN_NORMAL = 2.2250738585072014e-308
_INF = float("inf")

_L1, _L2, _L3, _L4, _L5 = 2 / 3, 2 / 5, 2 / 7, 2 / 9, 2 / 11
_L6, _L7, _L8, _L9, _L10 = 2 / 13, 2 / 15, 2 / 17, 2 / 19, 2 / 21


@njit(**_OPTS)
def log(x):
    """Natural logarithm of a float64 x (|error| ≲ 1 ulp; −inf at 0, NaN below 0, inf at inf)."""
    sub = x < _MIN_NORMAL
    xs = x * _TWO54 if sub else x
    # Shift the bits so that the exponent field counts from √2/2: y = 2^-k xs lands in [√2/2, √2).
    ix = _bits(xs) - _SQRT_HALF_BITS
    k = (ix >> 52) - (54 if sub else 0)
    y = _from_bits((ix & _MANT) + _SQRT_HALF_BITS)
    f = y - 1.0
    s = f / (2.0 + f)
    z = s * s
    z2 = z * z
    z4 = z2 * z2
    z8 = z4 * z4
    R = z * fma(fma(_L10, z, _L9), z8, fma(fma(fma(_L8, z, _L7), z2, fma(_L6, z, _L5)), z4,
                                           fma(fma(_L4, z, _L3), z2, fma(_L2, z, _L1))))
    hfsq = 0.5 * f * f
    kf = float(k)
    v = fma(kf, _LN2_HI, (f - hfsq) + fma(s, hfsq + R, kf * _LN2_LO))
    if x > 0.0:
        if x == _INF:
            v = _INF
    elif x == 0.0:
        v = -_INF
    else:
        v = x if x != x else _INF - _INF
    return v


# divided differences -----------------------------------------------------------------------------
#: |s| = |u − 1|/(u + 1) below which log_ratio's derivative is the series in s (u in 0.54…1.86;
#: s¹⁶ terms, truncation < 1e-17)
_LOG_RATIO_SERIES = 0.3
#: |x| below which exprel and its derivative are their Taylor series (degree 16: truncation < 1e-20)
_EXPREL_SERIES = 0.5


@njit(**_OPTS)
def _poly16(t, c):
    """c[0] + c[1] t + … + c[16] t¹⁶ (c a tuple of 17 coefficients; Estrin's scheme)."""
    t2 = t * t
    t4 = t2 * t2
    t8 = t4 * t4
    low = fma(fma(fma(c[7], t, c[6]), t2, fma(c[5], t, c[4])), t4, fma(fma(c[3], t, c[2]), t2, fma(c[1], t, c[0])))
    high = fma(fma(fma(c[15], t, c[14]), t2, fma(c[13], t, c[12])), t4,
               fma(fma(c[11], t, c[10]), t2, fma(c[9], t, c[8])))
    return fma(c[16] * t8, t8, fma(high, t8, low))


_A = tuple(1.0 / (2 * k + 1) for k in range(17))              # atanh(s)/s = Σ z^k/(2k+1), z = s²
_DA = tuple(2.0 * (k + 1) / (2 * k + 3) for k in range(17))    # its derivative over s, in z


@njit(**_OPTS)
def log_ratio(u):
    """(G, dG/du) for G(u) = ln u / (u − 1), u > 0 (G(1) = 1, G'(1) = −1/2): the divided
    difference of ln between 1 and u, with no cancellation as u → 1. G is ln u over the exact
    u − 1 of the rounded u (Kahan), within a few ulps. G' = (1/u − G)/(u − 1) loses digits as
    u → 1; for |s| < 0.3, s = (u − 1)/(u + 1), it is the series form: with ln u = 2 s A(s),
    A = atanh(s)/s = Σ s^2k/(2k+1), G = 2A/(u + 1) and G' = (4 A'(s) − 2 A (u + 1)) / (u + 1)³."""
    t = u - 1.0
    g = log(u) / t
    g = g if t != 0.0 else 1.0
    w = u + 1.0
    s = t / w
    z = s * s
    A = _poly16(z, _A)
    dA = s * _poly16(z, _DA)
    series = (4.0 * dA - 2.0 * A * w) / (w * w * w)
    return g, (series if abs(s) < _LOG_RATIO_SERIES else (1.0 / u - g) / t)


_X = tuple(1.0 / math.factorial(k + 1) for k in range(17))          # (e^x − 1)/x = Σ x^k/(k+1)!
_DX = tuple((k + 1) / math.factorial(k + 2) for k in range(17))     # its derivative = Σ (k+1) x^k/(k+2)!


@njit(**_OPTS)
def exprel(x):
    """(φ, dφ/dx) for φ(x) = (eˣ − 1)/x (φ(0) = 1, φ'(0) = 1/2), with no cancellation as x → 0:
    their Taylor series (degree 16) for |x| < 0.5, (eˣ − 1)/x and (eˣ (x − 1) + 1)/x² beyond."""
    ex = exp(x)
    f = (ex - 1.0) / x
    df = fma(ex, x - 1.0, 1.0) / (x * x)
    small = abs(x) < _EXPREL_SERIES
    fs = _poly16(x, _X)
    dfs = _poly16(x, _DX)
    return (fs if small else f), (dfs if small else df)
