"""rrrobot_gym.numerics: the transcendentals written from exactly rounded operations alone, so that a
float, an array and the compiled copy give the same bits on any CPU. Judged against 40-digit values
(mpmath), not against libm or numpy, whose kernels are what they replace."""

import math

import mpmath
import numpy as np
import pytest

from rrrobot_gym import compiled, numerics


def _ulps(got, true):
    return float(abs(mpmath.mpf(float(got)) - true) / math.ulp(float(true))) if true != 0 else abs(float(got)) / 5e-324


@pytest.mark.parametrize("scale, bound", [(4.0, 1.5), (1e4, 1.5), (1e6, 2.0)])
def test_sincos_is_within_two_ulp_of_the_true_values(scale, bound, rng):
    mpmath.mp.dps = 40
    worst = 0.0
    for x in np.concatenate([rng.uniform(-scale, scale, 1500), np.arange(-8, 9) * (np.pi / 4)]):
        s, c = numerics.sincos(float(x))
        worst = max(worst, _ulps(s, mpmath.sin(mpmath.mpf(float(x)))), _ulps(c, mpmath.cos(mpmath.mpf(float(x)))))
    assert worst <= bound


def test_sincos_of_inf_or_nan_is_nan_and_zero_is_exact():
    for bad in (np.inf, -np.inf, np.nan):
        assert all(np.isnan(v) for v in numerics.sincos(bad))
    assert numerics.sincos(0.0) == (0.0, 1.0)


def test_arctan2_is_within_five_ulp_of_the_true_angle_in_every_octant(rng):
    mpmath.mp.dps = 40
    n = 3000
    magnitude = 10.0 ** rng.uniform(-8, 3, (2, n))
    y, x = rng.normal(size=(2, n)) * magnitude
    worst = 0.0
    for yi, xi in zip(np.concatenate([y, [0.0, 1.0, -1.0, 1.0, 1e-300]]), np.concatenate([x, [-1.0, 0.0, -1.0, 1.0, -1.0]])):
        worst = max(worst, _ulps(numerics.arctan2(float(yi), float(xi)), mpmath.atan2(mpmath.mpf(float(yi)), mpmath.mpf(float(xi)))))
    assert worst <= 5.0


def test_arctan2_keeps_the_sign_of_y_and_is_zero_at_the_origin():
    assert numerics.arctan2(0.0, 0.0) == 0.0 and numerics.arctan2(0.0, -2.0) == math.pi
    assert numerics.arctan2(-0.0, -2.0) == -math.pi and numerics.arctan2(-3.0, 0.0) == -0.5 * math.pi
    assert np.isnan(numerics.arctan2(np.nan, 1.0)) and np.isnan(numerics.arctan2(1.0, np.nan))


def test_floats_and_arrays_give_the_same_bits(rng):
    x = rng.uniform(-50.0, 50.0, 500)
    y = rng.normal(size=500) * 10.0 ** rng.uniform(-6, 2, 500)
    s, c = numerics.sincos(x)
    angle = numerics.arctan2(y, x)
    for i in range(len(x)):
        assert numerics.sincos(float(x[i])) == (s[i], c[i])
        assert numerics.arctan2(float(y[i]), float(x[i])) == angle[i]


@pytest.mark.skipif(not compiled.available(), reason="numba is not installed")
def test_the_compiled_copies_give_the_same_bits(rng):
    import numba

    scalar = {name: numba.njit(fn) for name, fn in numerics.SCALAR.items()}
    copies = compiled._copies(numerics.KERNELS, numba.njit, {**vars(numerics), **scalar})
    x = rng.uniform(-50.0, 50.0, 300)
    y = rng.normal(size=300) * 10.0 ** rng.uniform(-6, 2, 300)
    for xi, yi in zip(x.tolist(), y.tolist()):
        assert copies["sincos"](xi) == numerics.sincos(xi)
        assert copies["arctan2"](yi, xi) == numerics.arctan2(yi, xi)
    # numerics' select on an array is numpy's where; its compiled form a conditional on floats
    assert numerics.select(np.array([True, False]), 1.0, 2.0).tolist() == [1.0, 2.0]
    assert scalar["select"](False, 1.0, 2.0) == 2.0
