"""sin, cos, atan2, tanh and exp as straight-line polynomial code that LLVM vectorises: a loop over
a batch of schemes (one scheme per SIMD lane) that calls these runs as packed instructions.

Why: numba leaves ``math.sin`` and the like to the C library, one call per value, and LLVM
vectorises a loop holding such a call only through a vector math library. PyPI's llvmlite has no
SVML, and its LLVM maps glibc's libmvec for sin, cos, tan, exp, log and pow only (not atan2, not
tanh; docs/lanes.md). So the transcendental functions a batched kernel needs are written here
(the batched right-hand side binds them: walk.py, batched.py), each as the
classic algorithm of fdlibm (Sun's freely distributable libm, the source of most C libraries' own)
or Cephes, with every branch on a value written as ``pick`` (a select, which the vectoriser turns
into a blend) and every test of two conditions as ``&`` or ``|`` (``and`` and ``or`` branch).

Accuracy, measured against the C library by test/test_vmath.py and charted by
``python -m benchmarks lanes``:

    sincos(x)    fdlibm's __kernel_sin/__kernel_cos after a three-part Cody-Waite reduction by
                 pi/2 (151 bits of pi/2); within 1 ulp for |x| <= REDUCTION_LIMIT (about 1.6e6 rad),
                 NaN beyond (the reduction would need more bits of pi/2 than it carries)
    atan2(y, x)  fdlibm's atan polynomial on min(|x|, |y|) / max(|x|, |y|) reduced to [0, 7/16),
                 then the octant in one rounding; within 2 ulp, and the C library's value at zeros
                 and infinities
    exp(x)       fdlibm's exp (Remez rational on [-ln2/2, ln2/2]), 2^k from a table; within 1 ulp,
                 0 below EXP_MIN (-745.13) and inf above EXP_MAX (709.78)
    tanh(x)      Cephes: x + x^3 P(x^2)/Q(x^2) for |x| < 0.625, 1 - 2 / (exp(2|x|) + 1) above;
                 within 2 ulp

NaN in gives NaN out. Each has a loop over lanes (``*_lanes``, compiled by ``jit.lanes``), which
the tests and the benchmark read: its assembly holds packed instructions and no call. These are
not the C library's values to the last bit, so a kernel that uses them is not bit-identical to the
readable reference (which uses ``math``): the scalar kernel keeps ``math``.
"""
from __future__ import annotations

import math

import numpy as np

from ...jit import inlined, jitable, lanes

@jitable
def pick(condition, if_true, if_false):
    """``if_true if condition else if_false``, as a function: LLVM inlines it as a select, which the
    vectoriser turns into a blend. Written inline instead, the if-expression is a branch in numba's
    IR, and inlining such a function twice into one caller trips numba issue 9489 (on Python 3.11:
    NumbaIRAssumptionWarning, a variable not in scope)."""
    return if_true if condition else if_false


# -- sin and cos: fdlibm s_sin.c, k_sin.c, k_cos.c, e_rem_pio2.c -----------------------------------

S1, S2, S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
S4, S5, S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
C1, C2, C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
C4, C5, C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
INV_PIO2 = 6.36619772367581382433e-01
#: pi/2 in three parts of 33 bits and their tails (fdlibm's pio2_1, pio2_1t, ... pio2_3t)
PIO2_1, PIO2_1T = 1.57079632673412561417e+00, 6.07710050650619224932e-11
PIO2_2, PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21
PIO2_3, PIO2_3T = 2.02226624871116645580e-21, 8.47842766036889956997e-32
#: |x| up to which n (pi/2) is exact in the reduction (n below 2^20, as fdlibm's medium case)
REDUCTION_LIMIT = 2.0 ** 20 * PIO2_1


@inlined
def reduce_pio2(x):
    """(n mod 4, r, r's tail) with x = n pi/2 + r + tail, |r| <= pi/4 (to 151 bits of pi/2)."""
    fn = np.floor(x * INV_PIO2 + 0.5)  # a float, as Python's math.floor is not: inf and NaN pass
    r = x - fn * PIO2_1
    t = r  # second and third rounds, always: each only adds bits
    w = fn * PIO2_2
    r = t - w
    w = fn * PIO2_2T - ((t - r) - w)
    t = r
    w = fn * PIO2_3
    r = t - w
    w = fn * PIO2_3T - ((t - r) - w)
    head = r - w
    tail = (r - head) - w
    fn = pick(math.isfinite(fn), fn, 0.0)
    return int(fn - 4.0 * np.floor(0.25 * fn)), head, tail


@inlined
def sincos(x):
    """(sin x, cos x), within 1 ulp for |x| <= REDUCTION_LIMIT, NaN beyond (module docstring)."""
    q, r, tail = reduce_pio2(x)
    z = r * r
    v = z * r
    p = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))
    s = r - ((z * (0.5 * tail - v * p) - tail) - v * S1)
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz) + (z * (z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))) - r * tail))
    odd = (q & 1) != 0
    sin_x = pick(odd, c, s)
    cos_x = pick(odd, s, c)
    sin_x = pick((q & 2) != 0, -sin_x, sin_x)
    cos_x = pick(((q + 1) & 2) != 0, -cos_x, cos_x)
    reduced = abs(x) <= REDUCTION_LIMIT  # False for inf and NaN too
    return pick(reduced, sin_x, math.nan), pick(reduced, cos_x, math.nan)


# -- atan2: fdlibm s_atan.c, e_atan2.c ------------------------------------------------------------

AT0, AT1, AT2 = 3.33333333333329318027e-01, -1.99999999998764832476e-01, 1.42857142725034663711e-01
AT3, AT4, AT5 = -1.11111104054623557880e-01, 9.09088713343650656196e-02, -7.69187620504482999495e-02
AT6, AT7, AT8 = 6.66107313738753120669e-02, -5.83357013379057348645e-02, 4.97687799461593236017e-02
AT9, AT10 = -3.65315727442169155270e-02, 1.62858201153657823623e-02
#: atan(1/2) and atan(1), each as a head and a tail (fdlibm's atanhi, atanlo)
ATAN_HALF_HI, ATAN_HALF_LO = 4.63647609000806093515e-01, 2.26987774529616870924e-17
ATAN_ONE_HI, ATAN_ONE_LO = 7.85398163397448278999e-01, 3.06161699786838301793e-17
PI_HI, PI_LO = 3.1415926535897931160e+00, 1.2246467991473531772e-16
PIO2_HI, PIO2_LO = 1.5707963267948965580e+00, 6.1232339957367658e-17


@inlined
def atan_unit(t):
    """atan t for 0 <= t <= 1 (NaN stays NaN): fdlibm's reduction to |t'| < 7/16 about 0, 1/2 or 1."""
    middle = (t >= 0.4375) & (t < 0.6875)
    upper = t >= 0.6875
    num = pick(middle, 2.0 * t - 1.0, pick(upper, t - 1.0, t))
    den = pick(middle, 2.0 + t, pick(upper, t + 1.0, 1.0))
    u = num / den
    z = u * u
    w = z * z
    s1 = z * (AT0 + w * (AT2 + w * (AT4 + w * (AT6 + w * (AT8 + w * AT10)))))
    s2 = w * (AT1 + w * (AT3 + w * (AT5 + w * (AT7 + w * AT9))))
    hi = pick(middle, ATAN_HALF_HI, ATAN_ONE_HI)
    lo = pick(middle, ATAN_HALF_LO, ATAN_ONE_LO)
    reduced = hi - ((u * (s1 + s2) - lo) - u)
    return pick(middle | upper, reduced, u - u * (s1 + s2))


@inlined
def atan2(y, x):
    """atan2(y, x) in [-pi, pi], within 2 ulp; at zeros and infinities the C library's values."""
    a, b = abs(y), abs(x)
    big = a > b
    hi = pick(big, a, b)
    lo = pick(big, b, a)
    t = pick(math.isinf(a) & math.isinf(b), 1.0, lo / pick(hi > 0.0, hi, 1.0))  # 0 / 0: 0
    z = atan_unit(t)
    left = math.copysign(1.0, x) < 0.0  # x < 0 or x = -0 (NaN: the select below)
    # the angle as base + (+-z + base's tail), one rounding: pi/2 -+ z above the diagonal,
    # pi - z left of it, z right of it
    base = pick(big, PIO2_HI, pick(left, PI_HI, 0.0))
    tail = pick(big, PIO2_LO, pick(left, PI_LO, 0.0))
    z = base + (pick(big != left, -z, z) + tail)
    z = pick(math.isnan(x) | math.isnan(y), math.nan, z)
    return math.copysign(z, y)


# -- exp: fdlibm e_exp.c ------------------------------------------------------------------------------

LN2_HI, LN2_LO = 6.93147180369123816490e-01, 1.90821492927058770002e-10
INV_LN2 = 1.44269504088896338700e+00
P1, P2, P3 = 1.66666666666666019037e-01, -2.77777777770155933842e-03, 6.61375632143793436117e-05
P4, P5 = -1.65339022054652515390e-06, 4.13813679705723846039e-08
EXP_MAX, EXP_MIN = 7.09782712893383973096e+02, -7.45133219101941108420e+02
#: 2^j for j = -540 .. 540: 2^k = 2^(k // 2) 2^(k - k // 2) for any k exp meets, each factor normal
POW2_HALF = 540
POW2 = np.ldexp(1.0, np.arange(-POW2_HALF, POW2_HALF + 1))


@inlined
def exp(x):
    """e^x within 1 ulp (module docstring)."""
    inside = (x >= EXP_MIN) & (x <= EXP_MAX)
    xr = pick(inside, x, 0.0)
    k = np.floor(xr * INV_LN2 + 0.5)
    hi = xr - k * LN2_HI
    lo = k * LN2_LO
    r = hi - lo
    t = r * r
    c = r - t * (P1 + t * (P2 + t * (P3 + t * (P4 + t * P5))))
    y = 1.0 - ((lo - (r * c) / (2.0 - c)) - hi)
    ki = int(k)
    half = ki // 2
    y = (y * POW2[POW2_HALF + half]) * POW2[POW2_HALF + ki - half]
    outside = pick(x > EXP_MAX, math.inf, pick(x < EXP_MIN, 0.0, x))  # NaN stays NaN
    return pick(inside, y, outside)


# -- tanh: Cephes tanh.c ---------------------------------------------------------------------------

TP0, TP1, TP2 = -9.64399179425052238628e-1, -9.92877231001918586564e1, -1.61468768441708447952e3
TQ0, TQ1, TQ2 = 1.12811678491632931402e2, 2.23548839060100448583e3, 4.84406305325125486048e3


@inlined
def tanh(x):
    """tanh x within 2 ulp (module docstring); +-1 beyond |x| = 22, where it rounds to 1."""
    z = abs(x)
    z2 = z * z
    small = z + z * z2 * ((TP0 * z2 + TP1) * z2 + TP2) / (((z2 + TQ0) * z2 + TQ1) * z2 + TQ2)
    s = exp(2.0 * pick(z > 22.0, 22.0, z))  # NaN stays NaN
    large = 1.0 - 2.0 / (s + 1.0)
    return math.copysign(pick(z < 0.625, small, large), x)  # odd, and -0 stays -0


# -- loops over lanes: what the tests and ``python -m benchmarks lanes`` compile and read ----------

@lanes
def sincos_lanes(x, sin_out, cos_out):
    """sin_out[j], cos_out[j] = sincos(x[j]) for every lane j."""
    for j in range(x.shape[0]):
        sin_out[j], cos_out[j] = sincos(x[j])


@lanes
def atan2_lanes(y, x, out):
    """out[j] = atan2(y[j], x[j])."""
    for j in range(x.shape[0]):
        out[j] = atan2(y[j], x[j])


@lanes
def exp_lanes(x, out):
    """out[j] = exp(x[j])."""
    for j in range(x.shape[0]):
        out[j] = exp(x[j])


@lanes
def tanh_lanes(x, out):
    """out[j] = tanh(x[j])."""
    for j in range(x.shape[0]):
        out[j] = tanh(x[j])
