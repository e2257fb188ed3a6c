"""numtext.fmt_col: the column formatter gives exactly Python's ``"{:.Nf}".format`` text
(negative zero dropped, '+' with ``plus``), the whole list compared as strings."""
import numpy as np
import pytest

from tsplcam.numtext import fmt_col


def reference(values, decimals: int, plus: bool = False) -> list:
    """One ``format`` call per number: the text every CL and program file was written with."""
    out = []
    for v in np.asarray(values, float).tolist():
        t = f"{v:.{decimals}f}"
        if t.startswith("-") and t.strip("-0.") == "":
            t = t[1:]                       # "-0.000" -> "0.000"
        if plus and not t.startswith("-"):
            t = "+" + t
        out.append(t)
    return out


def _with_neighbours(x: np.ndarray) -> np.ndarray:
    """The values and the floats either side of each."""
    return np.concatenate([x, np.nextafter(x, np.inf), np.nextafter(x, -np.inf)])


def _cases(decimals: int) -> np.ndarray:
    """Many magnitudes and both signs, values that round to -0, exact and near ties at
    ``decimals`` (some just inside, some just outside the margin fmt_col leaves to Python's
    format), integers, signed zeros, large and non-finite values."""
    rng = np.random.default_rng(decimals)
    mag = 10.0 ** rng.uniform(-9, 6, 2000) * rng.choice([-1.0, 1.0], 2000)
    q = 10.0 ** -decimals
    k = rng.integers(-10 ** 6, 10 ** 6, 1000)
    ties = (k + 0.5) * q                                  # nearest doubles to the halves
    exact_ties = np.array([0.5, 1.5, 2.5, -0.5, -2.5, 0.125, -0.375, 1.0625, 2 ** -20,
                           -3 * 2 ** -12, 1234.5, 0.03125])   # exact in binary
    odd = 2 * rng.integers(-10 ** 6, 10 ** 6, 500) + 1
    binary_ties = odd / 2.0 ** (decimals + 1)             # exactly d + 1 decimals, last 5
    near_ties = np.concatenate([ties * (1 + e) for e in (2.0 ** -49, -2.0 ** -49, 2.0 ** -46,
                                                          -2.0 ** -46, 2.0 ** -40)])
    to_negzero = -rng.uniform(0, 0.5, 200) * q
    ints = rng.integers(-10 ** 9, 10 ** 9, 200).astype(float)
    big = np.array([9999.4999, 9999.5, 10000.0, 99999999.4, 1e8, 1e8 - 0.5, 1e11 + 0.3,
                    2.0 ** 50 / 10 ** decimals, 2.0 ** 53, 1e16, -1e20, 1e300, -1.7e308])
    special = np.array([0.0, -0.0, 5e-324, -5e-324, np.inf, -np.inf, np.nan])
    coords = rng.uniform(-50, 50, 2000)
    return np.concatenate([mag, _with_neighbours(np.concatenate(
        [ties, near_ties, binary_ties, exact_ties, exact_ties * q, to_negzero, ints, big, special])), coords])


@pytest.mark.parametrize("decimals", range(0, 10))
@pytest.mark.parametrize("plus", [False, True])
def test_fmt_col_is_python_format(decimals, plus):
    x = _cases(decimals)
    assert fmt_col(x, decimals, plus) == reference(x, decimals, plus)


@pytest.mark.parametrize("decimals", [4, 7])
def test_fmt_col_unit_vectors_and_columns_of_a_matrix(decimals):
    """Strided columns (a matrix's), unit vector components, small columns, lists."""
    rng = np.random.default_rng(7)
    v = rng.standard_normal((3000, 3))
    v /= np.linalg.norm(v, axis=1)[:, None]
    for c in range(3):
        assert fmt_col(v[:, c], decimals) == reference(v[:, c], decimals)
    assert fmt_col([1.23456789, -0.00000001], decimals, True) == \
        reference([1.23456789, -0.00000001], decimals, True)
    assert fmt_col(np.array([]), decimals) == []
    assert fmt_col(np.array([-0.0]), decimals) == [reference([0.0], decimals)[0]]
