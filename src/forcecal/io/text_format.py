"""Numbers to CSV text, compiled: C's ``%.{P}g`` for a block of rows at once.

Formatting floats one by one in Python makes text the slowest part of writing a long table
(the result files of METHOD.md section 3, step 6). :func:`format_rows` writes a whole
(n_rows, n_columns) block into one byte buffer in compiled code (Numba, cached on disk), each
column with its own number of significant digits P (1..17), exactly as ``'%.{P}g' % value``
spells it: fixed notation for decimal exponents -4 <= X < P, else d.ddde+XX, trailing zeros
dropped. P = 0 asks for the value that reads back exactly in few digits: 15 when they do (time
stamps k / fs mostly), else 17.

The decimal digits are the value times 10^k rounded to an integer, the product formed in
double-double arithmetic (10^k to 106 bits, Dekker's exact product), so that the rounding is
the correct one except for a value within 2^-100 (relative) of a tie, where it may go either
way. P = 17 therefore writes every float64 so that it reads back exactly.
"""

from __future__ import annotations

import math
from fractions import Fraction

import numba
import numpy as np

__all__: list[str] = []

_LOW, _HIGH = -360, 360
"""Range of the tabulated powers of ten."""


def _powers() -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """10^k for k in [_LOW, _HIGH]: as hi + lo (0 where out of range), and as (hi + lo) 2^E
    with hi + lo in [1, 2), both to 106 bits."""
    size = _HIGH - _LOW + 1
    hi, lo, m_hi, m_lo = (np.zeros(size) for _ in range(4))
    exp = np.zeros(size, dtype=np.int64)
    for j, k in enumerate(range(_LOW, _HIGH + 1)):
        exact = Fraction(10) ** k
        if -_DIRECT <= k <= _DIRECT:
            hi[j] = float(exact)
            lo[j] = float(exact - Fraction(hi[j]))
        e = exact.numerator.bit_length() - exact.denominator.bit_length()
        if Fraction(2) ** e > exact:
            e -= 1
        m = exact / Fraction(2) ** e
        m_hi[j] = float(m)
        m_lo[j] = float(m - Fraction(m_hi[j]))
        exp[j] = e
    return hi, lo, m_hi, m_lo, exp


_DIRECT = 250
"""10^k times a value of up to 10^250 in size is formed directly; beyond, both are first
brought to [0.5, 2) by powers of two (exact, slower)."""
_P10_HI, _P10_LO, _P2_HI, _P2_LO, _P2_EXP = _powers()       # constants of the compiled code
_POW10 = np.array([10**k for k in range(18)], dtype=np.uint64)


@numba.njit(cache=True, nogil=True)
def _two_product(a, b):                                             # pragma: no cover
    """(p, e) with p + e = a b exactly (Dekker; no fused multiply-add assumed)."""
    p = a * b
    c = 134217729.0 * a
    ah = c - (c - a)
    al = a - ah
    c = 134217729.0 * b
    bh = c - (c - b)
    bl = b - bh
    e = ((ah * bh - p) + ah * bl + al * bh) + al * bl
    return p, e


@numba.njit(cache=True, nogil=True)
def _scaled(a, k):                                              # pragma: no cover
    """a 10^k as a double-double (hi, lo), a > 0, for a result of moderate size."""
    j = k - _LOW
    if -_DIRECT <= k <= _DIRECT and 1e-250 < a < 1e250:
        p, e = _two_product(a, _P10_HI[j])
        e += a * _P10_LO[j]
        hi = p + e
        return hi, e - (hi - p)
    m, ea = math.frexp(a)                                  # exact: m in [0.5, 1)
    p, e = _two_product(m, _P2_HI[j])
    e += m * _P2_LO[j]
    hi = p + e
    lo = e - (hi - p)
    scale = ea + _P2_EXP[j]
    return math.ldexp(hi, scale), math.ldexp(lo, scale)


@numba.njit(cache=True, nogil=True)
def _digits(a, k):                                              # pragma: no cover
    """round(a 10^k) to the nearest integer, ties to even (a 10^k below 2^62)."""
    hi, lo = _scaled(a, k)
    f = np.uint64(hi)                                      # floor: hi >= 0
    t = (hi - np.float64(f)) + lo
    g = np.floor(t)
    n = np.uint64(np.int64(f) + np.int64(g))
    frac = t - g
    if frac > 0.5 or (frac == 0.5 and n & np.uint64(1)):
        n += np.uint64(1)
    return n


@numba.njit(cache=True, nogil=True)
def _decimal(a, prec):                                               # pragma: no cover
    """(n, x): a = n 10^(x - prec + 1) rounded, 10^(prec-1) <= n < 10^prec, a > 0."""
    top = _POW10[prec]
    x = int(np.floor(np.log10(a)))
    n = _digits(a, prec - 1 - x)
    if n >= top:                                                     # log10 fell short
        x += 1
        n = _digits(a, prec - 1 - x)
    elif n < top // np.uint64(10):                                   # or overshot
        x -= 1
        n = _digits(a, prec - 1 - x)
        if n >= top:
            x += 1
            n = top // np.uint64(10)
    return n, x


@numba.njit(cache=True, nogil=True)
def _format(buf, pos, v, prec):                              # pragma: no cover
    """Write '%.{prec}g' % v at buf[pos:] (prec 0: the shorter of 15 and 17 digits that
    reads back exactly); return the new end."""
    if v != v:                                                       # 'nan'
        buf[pos], buf[pos + 1], buf[pos + 2] = 110, 97, 110
        return pos + 3
    if v < 0 or (v == 0 and math.copysign(1.0, v) < 0):
        buf[pos] = 45                                                # '-'
        pos += 1
    a = abs(v)
    if a == math.inf:                                                # 'inf'
        buf[pos], buf[pos + 1], buf[pos + 2] = 105, 110, 102
        return pos + 3
    if a == 0:
        buf[pos] = 48
        return pos + 1
    if prec == 0:
        prec = 15
        n, x = _decimal(a, prec)
        k = prec - 1 - x                 # n and 10^|k| exact: one rounding gives a back
        back = -1.0
        if 0 <= k <= 22:
            back = np.float64(n) / _P10_HI[k - _LOW]
        elif -22 <= k < 0:
            back = np.float64(n) * _P10_HI[-k - _LOW]
        if back != a:
            prec = 17
            n, x = _decimal(a, prec)
    else:
        n, x = _decimal(a, prec)
    if -4 <= x < prec:                                               # fixed notation
        if x < 0:                                                    # 0.000ddd
            buf[pos] = 48
            buf[pos + 1] = 46
            for j in range(pos + 2, pos + 1 - x):
                buf[j] = 48
            end = pos + 1 - x + prec                                 # past the last digit
            _put_digits(buf, end, n, prec)
            return _trim(buf, end, pos + 1)
        end = pos + prec + 1                                         # ddd.ddd
        point = pos + x + 1
        n = _put_digits(buf, end, n, prec - 1 - x)
        buf[point] = 46
        _put_digits(buf, point, n, x + 1)
        if point + 1 == end:
            return point
        return _trim(buf, end, point)
    end = pos + prec + 1                                             # d.ddde+XX
    n = _put_digits(buf, end, n, prec - 1)
    buf[pos] = 48 + np.uint8(n)
    buf[pos + 1] = 46
    end = _trim(buf, end, pos + 1)
    buf[end] = 101
    buf[end + 1] = 45 if x < 0 else 43
    end += 2
    e = abs(x)
    if e >= 100:
        buf[end] = 48 + e // 100
        end += 1
    buf[end] = 48 + (e // 10) % 10
    buf[end + 1] = 48 + e % 10
    return end + 2


@numba.njit(cache=True, nogil=True)
def _put_digits(buf, end, n, count):                                 # pragma: no cover
    """Write the last ``count`` decimal digits of n before buf[end]; return the rest of n."""
    ten = np.uint64(10)
    for j in range(end - 1, end - 1 - count, -1):
        q = n // ten
        buf[j] = 48 + np.uint8(n - q * ten)
        n = q
    return n


@numba.njit(cache=True, nogil=True)
def _trim(buf, end, point):                                          # pragma: no cover
    """The end of the text at buf[:end] without trailing zeros after the decimal point at
    buf[point] (nor the point itself when nothing follows it)."""
    while end > point + 1 and buf[end - 1] == 48:
        end -= 1
    return point if end == point + 1 else end


@numba.njit(cache=True, nogil=True)
def _rows(values, precision, buf):                 # pragma: no cover
    pos = 0
    n_rows, n_cols = values.shape
    for r in range(n_rows):
        for j in range(n_cols):
            if j:
                buf[pos] = 44                                        # ','
                pos += 1
            pos = _format(buf, pos, values[r, j], precision[j])
        buf[pos] = 10                                                # '\n'
        pos += 1
    return pos


def format_rows(values: np.ndarray, precision: np.ndarray | list[int]) -> bytes:
    """CSV lines of a block: every row's values joined by commas, each line ended by a newline.

    Parameters
    ----------
    values : (n_rows, n_columns) array_like of float
        The block.
    precision : (n_columns,) sequence of int
        Significant digits P of each column, 1..17 (17: every value reads back exactly), or 0
        for the shorter of 15 and 17 digits that reads back exactly.

    Returns
    -------
    bytes
        ASCII text, each value as ``'%.{P}g' % value`` would write it.

    Raises
    ------
    ValueError
        A precision outside 0..17 or of the wrong length.
    """
    block = np.ascontiguousarray(values, dtype=float)
    if block.ndim != 2:
        block = block.reshape(len(block), -1)
    prec = np.asarray(precision, dtype=np.int64)
    if prec.shape != (block.shape[1],) or np.any((prec < 0) | (prec > 17)):
        raise ValueError(f"format_rows: precision {prec.tolist()} for {block.shape[1]} columns; "
                         "expected one value from 0 to 17 per column")
    buf = np.empty(block.size * 26 + block.shape[0], dtype=np.uint8)
    end = _rows(block, prec, buf)
    return buf[:end].tobytes()
