"""exact_sign.exact_sum against rational arithmetic, on sums that cancel to the last bit."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from conftest import examples
from csm_assets.cones.exact_sign import exact_sum

heights = st.one_of(st.floats(0, 1), st.sampled_from([0.0, 1.0, 0.5, 5e-324, 1e-310, 2.0 ** -1022]))
coefficients = st.one_of(st.integers(-8, 8), st.integers(-(2 ** 51), 2 ** 51))


@examples(1.0)
@given(st.lists(st.tuples(coefficients, heights), min_size=1, max_size=8))
def test_sign_and_value_are_exact(terms):
    c = np.array([float(k) for k, _ in terms])
    z = np.array([v for _, v in terms])
    exact = sum(Fraction(int(k)) * Fraction(v) for k, v in terms)
    sign, value = exact_sum(c, z)
    assert sign == (exact > 0) - (exact < 0)
    if exact:
        assert abs(Fraction(value) - exact) <= abs(exact) * Fraction(1, 2 ** 48) + Fraction(2.0 ** -1074)


def test_cancellation_to_the_last_bit():
    """0.1 + 0.2 - 0.3 is 2^-54 in float64 and 2^-55 exactly (the doubles as they are):
    exact_sum gives the exact one, and a sum that is zero exactly as zero."""
    z = np.array([0.1, 0.2, 0.3])
    exact = Fraction(0.1) + Fraction(0.2) - Fraction(0.3)
    sign, value = exact_sum(np.array([1.0, 1.0, -1.0]), z)
    assert exact == Fraction(2.0 ** -55) and sign == 1 and Fraction(value) == exact
    assert exact_sum(np.array([2.0, -1.0, -1.0]), np.array([0.5, 0.25, 0.75])) == (0, 0.0)
    lo = np.nextafter(0.5, 0)
    assert exact_sum(np.array([1.0, 1.0, -2.0]), np.array([lo, np.nextafter(0.5, 1), 0.5]))[0] == 1
    assert exact_sum(np.array([3.0, -3.0]), np.array([5e-324, 5e-324])) == (0, 0.0)
