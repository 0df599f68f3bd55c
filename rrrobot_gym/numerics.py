"""Arithmetic that gives the same bits on every CPU: on Python floats, on numpy arrays and compiled.

IEEE 754 rounds +, -, *, / and sqrt exactly, on any CPU and at any SIMD width, and so do
comparisons, min, max, abs and copysign. A library's transcendental functions do not: numpy
runs sin, cos, arccos or arctan2 on arrays through SIMD kernels chosen by the CPU (AVX-512's
differ from AVX2's), and those may differ by an ulp from each other and from libm, which
``math`` and numba's compiled code call. The few transcendentals that the task layer and the
leg trigonometry need are written here from exact operations alone, with :func:`select` for
branches, so that a float, an array and the compiled copy give the same bits on any machine.

The functions take floats or numpy arrays of any shape (elementwise). ``rrrobot_gym.compiled``
compiles copies of :data:`KERNELS` whose :func:`select` is a plain conditional on floats
(:data:`SCALAR`), as it compiles the equations of motion.
"""

from __future__ import annotations

import numpy as np


def select(condition, if_true, if_false):
    """``if_true`` where ``condition`` holds, else ``if_false``: a conditional on floats, ``np.where``
    on arrays. Both branches are computed before the choice, so each must be finite-safe (no
    division by a zero the condition excludes: divide by ``select(c, x, 1.0)`` instead)."""
    if isinstance(condition, np.ndarray):
        return np.where(condition, if_true, if_false)
    return if_true if condition else if_false


def anywhere(condition) -> bool:
    """True if ``condition`` holds for any robot: a batch's arrays take a branch if one robot needs it
    (and :func:`select` keeps the others' values), one robot's float condition is itself."""
    return bool(np.any(condition))


def _select_scalar(condition, if_true, if_false):
    """:func:`select` on floats, the form the compiled copies take (numba types no ``np.where`` on floats)."""
    return if_true if condition else if_false


def _anywhere_scalar(condition):
    """:func:`anywhere` of one robot's condition, the compiled copies' form."""
    return condition


# sincos's constants: pi/2 in three parts, the first two of 33 significant bits, so that k times
# either is exact for |k| < 2^20 (Cody and Waite's reduction); the minimax polynomials of fdlibm's
# __kernel_sin and __kernel_cos on [-pi/4, pi/4] (degree 13 and 14, errors below 2^-58).
_ROUNDER = 6755399441055744.0  # 1.5 * 2^52: (v + it) - it is v rounded to an integer, |v| < 2^51
_TWO_OVER_PI = 0.6366197723675814
_HALF_PI_1, _HALF_PI_2, _HALF_PI_3 = 1.5707963267341256, 6.077100506303966e-11, 2.0222662487959506e-21
_SIN_1, _SIN_2, _SIN_3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
_SIN_4, _SIN_5, _SIN_6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
_COS_1, _COS_2, _COS_3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
_COS_4, _COS_5, _COS_6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


def sincos(x):
    """(sin x, cos x) by arithmetic alone, within 1.4 ulp for |x| <= 1e4 rad and 2 ulp to 1e6
    (libm: 0.5); NaN for inf or NaN. No call or branch that data could not share, so the
    compiled stepper takes it on several robots in one SIMD instruction."""
    k = (x * _TWO_OVER_PI + _ROUNDER) - _ROUNDER  # the nearest multiple of pi/2
    r = ((x - k * _HALF_PI_1) - k * _HALF_PI_2) - k * _HALF_PI_3  # in [-pi/4, pi/4]
    z = r * r
    s = r + r * z * (_SIN_1 + z * (_SIN_2 + z * (_SIN_3 + z * (_SIN_4 + z * (_SIN_5 + z * _SIN_6)))))
    c = 1.0 + z * (-0.5 + z * (_COS_1 + z * (_COS_2 + z * (_COS_3 + z * (_COS_4 + z * (_COS_5 + z * _COS_6))))))
    q = k - 4.0 * ((k * 0.25 + _ROUNDER) - _ROUNDER)  # the quadrant, k mod 4, in {-2, -1, 0, 1, 2}
    odd = np.abs(q) == 1.0
    sin_x = select(odd, c, s)
    cos_x = select(odd, s, c)
    sin_x = select((q < 0.0) | (q > 1.5), -sin_x, sin_x)  # q in {-2, -1, 2}
    cos_x = select((q > 0.5) | (q < -1.5), -cos_x, cos_x)  # q in {-2, 1, 2}
    return sin_x, cos_x


# arctan2's constants: (-1)^k / (2k + 1), the Taylor series of atan(u) = u (1 - u^2/3 + ...) to u^19,
# taken where |u| <= tan(pi/32) < 0.0985 (the next term, u^21/21, is below 2e-23 there).
_ATAN = (-1.0 / 3.0, 1.0 / 5.0, -1.0 / 7.0, 1.0 / 9.0, -1.0 / 11.0, 1.0 / 13.0, -1.0 / 15.0, 1.0 / 17.0, -1.0 / 19.0)
_PI = 3.141592653589793
_HALF_PI = 1.5707963267948966


def arctan2(y, x):
    """The angle of the point (x, y) from the +x axis, in [-pi, pi] (the sign of y's), by
    arithmetic alone, within about 3 ulp of the exact angle; 0 at the origin, NaN for NaN.

    The ratio t = min/max of |x| and |y| (in [0, 1]) is halved in angle three times,
    t -> t / (1 + sqrt(1 + t^2)), so atan(t) = 8 atan(t'''), t''' <= tan(pi/32), where a short
    Taylor series is exact to rounding; then the octant is restored."""
    ax, ay = np.abs(x), np.abs(y)
    big, small = np.maximum(ax, ay), np.minimum(ax, ay)
    t = small / select(big > 0.0, big, 1.0)  # (0 at the origin)
    for _ in range(3):
        t = t / (1.0 + np.sqrt(1.0 + t * t))
    z = t * t
    c1, c2, c3, c4, c5, c6, c7, c8, c9 = _ATAN
    series = t + t * z * (c1 + z * (c2 + z * (c3 + z * (c4 + z * (c5 + z * (c6 + z * (c7 + z * (c8 + z * c9))))))))
    angle = 8.0 * series
    angle = select(ay > ax, _HALF_PI - angle, angle)
    angle = select(x < 0.0, _PI - angle, angle)
    return np.copysign(angle, y)


KERNELS = (sincos, arctan2)
"""The functions :mod:`rrrobot_gym.compiled` compiles (with :data:`SCALAR`'s :func:`select`)."""
SCALAR = {"select": _select_scalar, "anywhere": _anywhere_scalar}
"""The names a compiled copy of a kernel (of this module, or one that uses :func:`select` or
:func:`anywhere`) takes instead, each a function on floats."""
