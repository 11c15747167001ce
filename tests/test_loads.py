"""Load laws: switching functions and values per mode."""
from __future__ import annotations

import numpy as np

from csim.load_laws import LoadLaw, LoadSet


def test_windowed_law_switching_functions_are_positive_where_conditions_hold():
    law = LoadLaw("F", 2.0, (-1.0, 1.0), "negative")
    assert law.switching(0.0, -3.0) == [1.0, 1.0, 3.0]
    assert len(law.switch_labels) == 3


def test_constant_law_has_no_switches():
    ls = LoadSet([LoadLaw("torque", 5.0)])
    assert ls.n_switches == 0
    np.testing.assert_array_equal(ls.values(np.zeros(0, bool)), [5.0])


def test_values_follow_the_mode():
    ls = LoadSet([LoadLaw("torque", 5.0), LoadLaw("F", 2.0, (-1.0, 1.0), "negative")])
    inside_moving_back = ls.mode(ls.switching(np.array([0.0, 0.5]), np.array([1.0, -1.0])))
    np.testing.assert_array_equal(ls.values(inside_moving_back), [5.0, 2.0])
    outside = ls.mode(ls.switching(np.array([0.0, 1.5]), np.array([1.0, -1.0])))
    np.testing.assert_array_equal(ls.values(outside), [5.0, 0.0])
    moving_forward = ls.mode(ls.switching(np.array([0.0, 0.5]), np.array([1.0, 1.0])))
    np.testing.assert_array_equal(ls.values(moving_forward), [5.0, 0.0])


def test_infinite_window_bounds_add_no_switches():
    law = LoadLaw("F", 1.0, (-np.inf, 2.0), "positive")
    assert len(law.switching(0.0, 1.0)) == 2
