"""Time functions of baths, sources and loads: values and rates, compiled against plain Python."""

import math

import numpy as np
import pytest

from thermonet.errors import InputError
from thermonet.timefunctions import (TimeFunction, bounds, evaluate, evaluate_py, evaluate_rate, evaluate_rate_py,
                                     pack, time_function)


FUNCTIONS = [
    TimeFunction.constant(3.0),
    TimeFunction.linear(0.5, start=1.0),
    TimeFunction.ramp(900.0, 2.0, start=300.0),
    TimeFunction.sine(0.1, 3.0, phase=0.3, offset=1.0),
    TimeFunction.table([[0.0, 1.0], [1.0, 3.0], [1.5, -1.0]]),
]


def test_values_and_rates_match_their_definitions():
    t = 1.25
    assert FUNCTIONS[0](t) == 3.0 and FUNCTIONS[0].rate(t) == 0.0
    assert FUNCTIONS[1](t) == pytest.approx(1.625) and FUNCTIONS[1].rate(t) == 0.5
    assert FUNCTIONS[2](t) == pytest.approx(300 + 600 * t / 2) and FUNCTIONS[2].rate(t) == pytest.approx(300)
    assert FUNCTIONS[2](5.0) == 900.0 and FUNCTIONS[2].rate(5.0) == 0.0
    w = 2 * math.pi * 3.0
    assert FUNCTIONS[3](t) == pytest.approx(1.0 + 0.1 * math.sin(w * t + 0.3))
    assert FUNCTIONS[3].rate(t) == pytest.approx(0.1 * w * math.cos(w * t + 0.3))
    table = FUNCTIONS[4]
    assert table(-1.0) == 1.0 and table(0.5) == pytest.approx(2.0) and table(1.25) == pytest.approx(1.0)
    assert table(9.0) == -1.0 and table.rate(1.25) == pytest.approx(-8.0) and table.rate(9.0) == 0.0


def test_rates_are_derivatives():
    for f in FUNCTIONS:
        for t in (0.3, 0.77, 1.31):
            d = 1e-6
            assert f.rate(t) == pytest.approx((f(t + d) - f(t - d)) / (2 * d), rel=1e-5, abs=1e-7), f


def test_compiled_equals_python():
    packed = pack(FUNCTIONS)
    for i in range(len(FUNCTIONS)):
        for t in np.linspace(-0.5, 3.0, 29):
            assert evaluate(*packed, i, t) == evaluate_py(*packed, i, t)
            assert evaluate_rate(*packed, i, t) == evaluate_rate_py(*packed, i, t)


def test_scene_forms():
    assert time_function(2, "x")(5.0) == 2.0
    assert time_function({"start": 1.0, "end": 2.0, "duration": 1.0}, "x")(0.5) == 1.5
    assert time_function({"rate": 2.0}, "x")(0.5) == 1.0
    assert time_function({"amplitude": 1.0, "frequency": 0.25}, "x")(1.0) == pytest.approx(1.0)
    assert time_function({"table": [[0, 0], [2, 4]]}, "x")(1.0) == 2.0
    assert bounds(FUNCTIONS[4], 10.0) == (-1.0, 3.0)
    assert bounds(FUNCTIONS[3], 10.0) == pytest.approx((0.9, 1.1))


@pytest.mark.parametrize("value, message", [
    ({"table": [[0, 1], [0, 2]]}, "times must increase strictly; point 1"),
    ({"table": [[0, 1], [1, float("nan")]]}, "non-finite"),
    ({"end": 1.0, "duration": 0.0}, "duration: must be > 0"),
    ({"end": 1.0, "duration": 1.0, "speed": 2}, "unknown key"),
    ({"frequency": 2}, "is not a time function"),
    ("hot", "expected a number or a time function"),
    (True, "expected a number"),
])
def test_bad_time_functions_name_the_key(value, message):
    with pytest.raises(InputError, match=message) as info:
        time_function(value, "baths.hot.temperature")
    assert "baths.hot.temperature" in str(info.value)
