"""ASCII text of whole float64 and integer arrays at once, with numpy and no per-value Python.

Text mesh formats (2DM, ASCII DAT, ASCII PLY) need millions of numbers as decimal tokens, and
Python's ``%r`` costs about half a microsecond per float. Here every step works on whole
columns: the digits come from integer numpy arithmetic, four characters at a time from a
table, into one fixed-width uint8 block per field; padding is NUL bytes, dropped when the
rows of a block are joined into one ``bytes`` object.

Floats
------
Every token reads back (Python's ``float()``, C's ``strtod``/``atof`` as MDAL uses, or any
correctly rounded parser) as exactly the same double, the sign of -0.0 included. Tokens use
Python's ``repr`` layout: fixed notation (``351182.162``, ``0.0001``, ``12.0``) for
1e-4 <= |x| < 1e16, which is where the vectorised path works; other values (smaller or larger
magnitudes, subnormals, inf, nan) and the rare ones below 1e-2 that need more than 18 fraction
digits are written by ``repr`` itself, one by one, so they keep repr's exponent notation
(``1e-05``, ``1e+16``), which ``strtod`` reads.

For a finite x with 10**e <= |x| < 10**(e+1), -4 <= e <= 15:

1. ``N = round(|x| * 10**(16 - e))`` is computed exactly (ties to even), N in
   [10**16, 10**17). 10**s is exact in binary64 for s <= 22 (5**22 < 2**53), and Dekker's
   TwoProduct (Veltkamp splitting, no FMA needed) gives the product exactly as ``p + err``
   with ``p = fl(|x| * 10**s)``. Once e is right, 1e16 <= p <= 1e17, so p >= 2**53 is an even
   integer, and ``N = p + rint(err)`` rounds the exact product half to even. e starts from
   ``floor(log10(|x|))`` and is corrected until N has 17 digits.
2. The 17 correctly rounded significant digits always read back as x: the decimal is within
   5 * 10**(e-17) of |x|, less than 2**-54 * |x|, which is at most half the gap between x and
   either neighbouring double (Matula's bound, 10**16 > 2**53).
3. First a 15-digit decimal is tried: ``N15 = rint(fl(|x| * 10**k))``, k = 14 - e. N15 < 2**53
   and 10**k (0 <= k <= 22) are exact doubles and IEEE division is correctly rounded, so
   ``fl(N15 / 10**k) == |x|`` proves that the decimal N15 * 10**-k reads back as x (a
   correctly rounded ``strtod`` returns that same nearest double). When it does, these digits
   are used, trailing zeros stripped, so 351182.162 stays ``351182.162``; otherwise the 17
   digits of step 1 are.
4. If ``repr(x)`` has at most 15 significant digits, the token equals it. repr's decimal D
   (padded to 15 digits, D * 10**-k) is within half an ulp of x, < 1.2e-16 |x|, so
   ``|x| * 10**k`` is within 0.11 of the integer D and fl() moves it by at most 1/16: rint
   gives D, which passes the check. Only one 15-digit decimal can read back as x (their
   spacing, > 1e-15 |x|, exceeds the width of x's rounding interval, < 2.3e-16 |x|), so a
   passing N15 is always the nearest one. Values whose repr needs 16 or 17 digits get 17
   (fewer if they end in zeros), which still read back exactly.
5. A column often has a fixed number of decimals c: a sample of 64 values gives the most
   common c, and then ``D = rint(fl(|x| * 10**c))`` with ``fl(D / 10**c) == |x|`` and
   D < 10**15 (so, as in 4, D is repr's decimal if that has c decimals) but no such decimal
   with c - 1 digits, is repr's text directly, without steps 1-3.

Integers
--------
Plain decimal digits with a leading minus for negative values, as ``str``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Union

import numpy as np


def _quad_table(transform) -> np.ndarray:
    """10,000 four-character entries (one native uint32 each) of ``transform(i)``."""
    text = b"".join(transform(i) for i in range(10_000))
    return np.frombuffer(text, np.uint32).copy()


def _lead(i: int, zero: bytes = b"\0\0\0\0") -> bytes:
    return str(i).encode().rjust(4, b"\0") if i else zero


def _dot(i: int) -> bytes:
    # The top group of 10**count + fraction: its leading 1 becomes the decimal point.
    text = str(i).encode()
    return (b"." + text[1:]).rjust(4, b"\0") if text[0:1] == b"1" else _lead(i)


_FULL = _quad_table(lambda i: b"%04d" % i)
# Index rem + 10_000 * (nothing above): the highest group drops its leading zeros.
_INNER = np.concatenate([_FULL, _quad_table(_lead)])
_UNITS = np.concatenate([_FULL, _quad_table(lambda i: _lead(i, b"\0\0\x000"))])
_FRACTION = np.concatenate([_FULL, _quad_table(_dot)])
_POW10_INT = np.array([10**k for k in range(19)], dtype=np.int64)
_POW10 = np.array([float(10**k) for k in range(23)])  # all exact
_SPLITTER = float(2**27 + 1)
_MIN_EXP, _MAX_EXP = -4, 15  # decimal exponents that repr writes in fixed notation
_MAX_FRACTION_DIGITS = 18  # 10**18 + fraction still fits int64
_BLOCK_BYTES = 2**18  # rows joined at a time: their block stays in the CPU cache
_GUESS_ROWS = 1024  # from this many values on, a sample guesses their number of decimals


class Field:
    """The tokens of one column, written only when the rows are joined: digit runs (int64
    values, each < 10**width, with the table of their units quad), a minus sign where
    ``negative``, and whole tokens (bytes) for the ``fallback`` rows."""

    __slots__ = ("fallback", "negative", "rows", "runs", "tokens")

    def __init__(
        self,
        runs: list[tuple[np.ndarray, int, np.ndarray]],
        negative: np.ndarray | None,
        fallback: np.ndarray,
        tokens: list[bytes],
    ) -> None:
        self.runs = runs
        self.rows = len(runs[0][0])
        self.negative = negative if negative is not None and negative.any() else None
        self.fallback = fallback
        self.tokens = tokens

    def __len__(self) -> int:
        return self.rows


Part = Union[bytes, Field]


def _split(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Veltkamp splitting: a == hi + lo exactly, each with at most 26 significant bits."""
    c = _SPLITTER * a
    hi = c - (c - a)
    return hi, a - hi


_POW10_HI, _POW10_LO = _split(_POW10)


def _quads(width: int) -> int:
    return max(-(-width // 4), 1)


def _write_run(out: np.ndarray, values: np.ndarray, units: np.ndarray, low: int) -> None:
    """Digits of non-negative int64 ``values`` (none below ``low``) into the uint32 columns
    ``out`` (four characters each), right-aligned, NUL instead of leading zeros (0 itself is
    "0"). With ``units=_FRACTION`` the leading 1 of each value becomes a decimal point."""
    groups = out.shape[1]
    inner = units if units is _FRACTION else _INNER
    rest = values
    for group in range(groups - 1, 0, -1):
        high = rest // 10_000
        index = rest - high * 10_000
        if low < 10 ** (4 * (groups - group)):  # the highest quad of some values
            index += (high == 0) * 10_000
        out[:, group] = (units if group == groups - 1 else inner)[index]
        rest = high
    out[:, 0] = (units if groups == 1 else inner)[rest + 10_000]


def int_field(values: np.ndarray) -> Field:
    """Decimal tokens of integers (bool or any integer dtype), as ``str`` writes them."""
    original = np.asarray(values).ravel()
    if original.dtype.kind not in "biu":
        raise TypeError(f"int_field needs integers, not {original.dtype}")
    values = original.astype(np.int64, copy=False)
    low, high = (int(values.min()), int(values.max())) if len(values) else (0, 0)
    fallback = np.zeros(0, np.intp)
    if original.dtype == np.uint64 and int(original.max(initial=0)) >= 2**63:
        fallback = np.flatnonzero(original >= np.uint64(2**63))
    elif low == np.iinfo(np.int64).min:
        fallback = np.flatnonzero(values == low)  # |v| is no int64
    if len(fallback) or low < 0:
        values = values.copy()
        values[fallback] = 0
        negative = values < 0
        magnitudes = np.abs(values)
        high = int(magnitudes.max())
    else:
        negative, magnitudes = None, values
    tokens = [str(int(v)).encode() for v in original[fallback].tolist()]
    return Field([(magnitudes, len(str(high)), _UNITS)], negative, fallback, tokens)


def _bounds(values: np.ndarray | int) -> tuple[int, int]:
    if isinstance(values, int):
        return values, values
    return int(values.min()), int(values.max())


def _scale(e: np.ndarray | int, offset: int) -> np.ndarray | int:
    """``offset - e``, as one int where every e is the same (the usual case for a column of
    coordinates), so that table look-ups and products take a scalar."""
    low, high = _bounds(e)
    return offset - low if low == high else offset - e


def _round_17(a: np.ndarray, s: np.ndarray | int) -> np.ndarray:
    """``round(a * 10**s)`` half to even, exactly; needs 0 <= s <= 22 and
    1e16 <= fl(a * 10**s) <= 1e17."""
    p = a * _POW10[s]
    a_hi, a_lo = _split(a)
    p_hi, p_lo = _POW10_HI[s], _POW10_LO[s]
    # Dekker's TwoProduct: a * 10**s == p + err exactly (no overflow or underflow here).
    err = ((a_hi * p_hi - p) + a_hi * p_lo + a_lo * p_hi) + a_lo * p_lo
    # p >= 2**53 is an even integer, so rounding err half to even rounds p + err the same way.
    return p.astype(np.int64) + np.rint(err).astype(np.int64)


def _decimal_17(a: np.ndarray) -> tuple[np.ndarray, np.ndarray | int, np.ndarray | None]:
    """For a in [1e-4, 1e16): (N, e, ok), N in [10**16, 10**17) the exact
    round(a * 10**(16 - e)), 10**e <= a < 10**(e + 1) (one int if it is the same for all);
    ok (None: all) is False where that failed."""
    low, high = float(a.min()), float(a.max())
    e = math.floor(math.log10(low))
    # fl() is monotonic, so every fl(a * 10**s) lies between these two products; 64 is more
    # than the rounding of p (8 at most) and of p + err to N.
    if (
        e == math.floor(math.log10(high))
        and low * _POW10[16 - e] >= 1e16 + 64
        and high * _POW10[16 - e] <= 1e17 - 64
    ):
        return _round_17(a, 16 - e), e, None
    # log10 is good to an ulp or so: e may be one off next to powers of ten, fixed below.
    e = np.floor(np.log10(a)).astype(np.int64)
    p = a * _POW10[_scale(e, 16)]
    off = np.flatnonzero((p < 1e16) | (p > 1e17))
    ok = None
    for _ in range(3):
        if not len(off):
            break
        p_off = a[off] * _POW10[16 - e[off]]
        e[off] += (p_off > 1e17).astype(np.int64) - (p_off < 1e16)
        np.clip(e, -6, 16, out=e)
        p_off = a[off] * _POW10[16 - e[off]]
        off = off[(p_off < 1e16) | (p_off > 1e17)]
    if len(off):
        ok = np.ones(len(a), bool)
        ok[off] = False
        e[off] = 0
        a = np.where(ok, a, 1.0)
    n = _round_17(a, _scale(e, 16))
    for _ in range(3):
        # fl(a * 10**s) == 1e16 can still round below 10**16 (e one too high) and 1e17 above.
        off = np.flatnonzero((n < 10**16) | (n >= 10**17))
        if ok is not None:
            off = off[ok[off]]
        if not len(off):
            break
        top = off[n[off] == 10**17]  # rounded up to a power of ten: same decimal, e + 1
        n[top] = 10**16
        e[top] += 1
        off = off[n[off] != 10**16]
        e[off] += (n[off] > 10**17).astype(np.int64) - (n[off] < 10**16)
        np.clip(e, -6, 16, out=e)
        n[off] = _round_17(a[off], 16 - e[off])
    off = np.flatnonzero((n < 10**16) | (n >= 10**17))
    if len(off):
        ok = np.ones(len(a), bool) if ok is None else ok
        ok[off] = False
    return n, e, ok


def _strip_zeros(fraction: np.ndarray, count: np.ndarray) -> None:
    """Drop the trailing zeros of ``fraction`` (``count`` digits, zero-padded), in place."""
    last_zero = fraction - fraction // 10 * 10 == 0
    if int(count.min()) <= 0:
        last_zero &= count > 0
    hits = np.count_nonzero(last_zero)
    if not hits:
        return
    index = np.flatnonzero(last_zero) if hits < len(fraction) // 2 else slice(None)
    f, c = fraction[index], count[index]
    for k in (16, 8, 4, 2, 1):  # binary search on the number of zeros
        if c.max() < k:
            continue
        unit = 10**k
        shorter = f // unit
        strip = (shorter * unit == f) & (c >= k)
        f -= strip * (f - shorter)
        c -= strip * k
    fraction[index], count[index] = f, c


def _fixed_parts(a: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Fixed notation of a in [1e-4, 1e16): (integer part, 10**count + fraction digits, ok),
    the fraction's ``count`` >= 1 digits without trailing zeros but one. ok (None: all) is
    False where the value needs ``repr``."""
    rows = len(a)
    n17, e, ok = _decimal_17(a)
    # The 15-digit decimal: if the nearest one reads back, rint(fl(a * 10**k)) is it (see
    # _fixed_decimals), the division proves it, and no other 15-digit decimal reads back.
    k = _scale(e, 14)
    low_k = k if isinstance(k, int) else int(k.min())
    unit15 = _POW10[max(k, 0) if isinstance(k, int) else np.maximum(k, 0)]
    n15 = np.rint(a * unit15)
    short = n15 / unit15 == a
    if low_k < 0:  # e = 15: 10**k is no exact double, these take 17 digits
        short &= k >= 0
    top = np.zeros(0, np.intp)
    if n15.max() >= 1e15:  # rounded up to a power of ten: the same decimal with e + 1
        top = np.flatnonzero(short & (n15 >= 1e15))
        n15[top] = 1e14
        k = np.full(rows, k) if isinstance(k, int) else k.copy()
        k[top] -= 1
    s17 = _scale(e, 16)
    if short.all():
        digits, scale = n15.astype(np.int64), k
    elif not short.any():
        digits, scale = n17, s17
    else:
        digits = n17 - short * (n17 - n15.astype(np.int64))
        scale = s17 - short * (s17 - k)
    low_e, high_e = _bounds(e)
    if low_e < _MIN_EXP or high_e + (len(top) > 0) > _MAX_EXP:  # repr writes an exponent
        exponent = np.full(rows, e) if isinstance(e, int) else e.copy()
        exponent[top] += 1
        wrong = (exponent < _MIN_EXP) | (exponent > _MAX_EXP)
        ok = ~wrong if ok is None else ok & ~wrong
    # Integer part: floor(a) or one more, where the decimal rounds up to the next integer
    # (rounding a * 10**s >= floor(a) * 10**s cannot go below floor(a)).
    whole = np.floor(a).astype(np.int64)
    uniform = isinstance(scale, int)
    low_scale = scale if uniform else int(scale.min())
    # digits < 10**17: capping the unit at 10**18 is exact
    unit = _POW10_INT[min(max(scale, 0), 18) if uniform else np.clip(scale, 0, 18)]
    fraction = digits - whole * unit
    carry = np.flatnonzero(fraction >= unit)
    whole[carry] += 1
    fraction[carry] -= unit if uniform else unit[carry]
    count = np.full(rows, scale) if uniform else scale
    if low_scale <= 0:  # only e = 15 with 15 digits: 10 * n15
        integral = np.flatnonzero(count <= 0)
        whole[integral] = digits[integral] * _POW10_INT[-count[integral]]
        fraction[integral] = 0
        count = np.maximum(count, 0)
    _strip_zeros(fraction, count)
    if int(count.min()) < 1:
        count = np.maximum(count, 1)
    if int(count.max()) > _MAX_FRACTION_DIGITS:
        long = count > _MAX_FRACTION_DIGITS
        ok = ~long if ok is None else ok & ~long
    if ok is not None:
        count[~ok] = 1
    return whole, _POW10_INT[count] + fraction, ok


def _fixed_decimals(a: np.ndarray, decimals: int) -> tuple[np.ndarray, ...]:
    """The rows of positive a whose shortest decimal has exactly ``decimals`` fraction digits
    (and at most 15 significant digits): (good, integer part, 10**count + fraction digits).

    If a reads back from a decimal D * 10**-c with D < 10**15, then D = rint(fl(a * 10**c)):
    |a * 10**c - D| < 0.11 and fl adds at most 1/16. ``fl(D / 10**c) == a`` proves it reads
    back (exact operands, correctly rounded division), and no shorter decimal does when the
    same test fails with c - 1 digits; D is then what repr writes, and ends in no zero."""
    unit = _POW10[decimals]
    digits = np.rint(a * unit)
    good = (digits / unit == a) & (digits < 1e15)
    if decimals:
        shorter = _POW10[decimals - 1]
        good &= np.rint(a * shorter) / shorter != a
    whole = np.floor(a)
    fraction = digits - whole * unit
    good &= fraction < unit
    top = _POW10_INT[max(decimals, 1)]
    return good, whole.astype(np.int64), fraction.astype(np.int64) + top


def _guess_decimals(a: np.ndarray) -> int | None:
    """The number of fraction digits most of a sample of a >= 0 has, if at least half of the
    sample has that many and at most 15 significant digits; else None."""
    if len(a) < _GUESS_ROWS:
        return None
    sample = a[:: len(a) // 64][:64]
    sample = sample[(sample >= 1e-4) & (sample < 1e16)]
    if len(sample) < 32:
        return None
    _, sample_fraction, sample_ok = _fixed_parts(sample)
    if sample_ok is not None:
        sample_fraction = sample_fraction[sample_ok]
    counts = np.searchsorted(_POW10_INT, sample_fraction, side="right") - 1
    decimals = int(np.bincount(counts, minlength=19).argmax())
    if np.count_nonzero(_fixed_decimals(sample, decimals)[0]) < 32:
        return None
    return decimals


def _positive_parts(
    a: np.ndarray, decimals: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """``_fixed_parts`` of a, trying ``decimals`` fraction digits first (columns often have a
    fixed number of decimals), which is several times cheaper."""
    if decimals is None:
        return _fixed_parts(a)
    good, whole, fraction = _fixed_decimals(a, decimals)
    rest = np.flatnonzero(~good)
    if not len(rest):
        return whole, fraction, None
    whole[rest], fraction[rest], rest_ok = _fixed_parts(a[rest])
    if rest_ok is None:
        return whole, fraction, None
    ok = np.ones(len(a), bool)
    ok[rest] = rest_ok
    return whole, fraction, ok


def float_field(values: np.ndarray) -> Field:
    """Tokens of float64 values that read back bit for bit (see the module docstring)."""
    x = np.asarray(values, dtype=np.float64).ravel()
    magnitude = np.abs(x)
    decimals = _guess_decimals(magnitude)
    candidate = (magnitude >= 1e-4) & (magnitude < 1e16)
    if len(x) and candidate.all():
        whole, fraction, ok = _positive_parts(magnitude, decimals)
        ok = np.ones(len(x), bool) if ok is None else ok
    else:
        whole = np.zeros(len(x), np.int64)
        fraction = np.full(len(x), 10, np.int64)  # ".0", as for zeros
        ok = magnitude == 0
        index = np.flatnonzero(candidate)
        if len(index):
            whole[index], fraction[index], part_ok = _positive_parts(magnitude[index], decimals)
            ok[index] = True if part_ok is None else part_ok
    fallback = np.flatnonzero(~ok)
    whole[fallback] = 0
    fraction[fallback] = 10
    runs = [
        (whole, len(str(int(whole.max(initial=0)))), _UNITS),
        (fraction, len(str(int(fraction.max(initial=10)))), _FRACTION),
    ]
    tokens = [repr(v).encode() for v in x[fallback].tolist()]
    return Field(runs, np.signbit(x) & ok, fallback, tokens)


def join_rows(parts: Sequence[Part]) -> bytes:
    """Rows made of ``parts`` (bytes repeated on every row, or fields of one length), joined
    into one bytes object."""
    return b"".join(text_pieces(parts))


def text_pieces(parts: Sequence[Part]) -> list[bytes]:
    """The text of ``join_rows`` as a list of pieces (a few thousand rows each), to write
    without joining them first.

    Every field takes whole uint32 quads of a (rows, quads) block, its digits right-aligned;
    the literal text before it (and its sign) goes into leading NUL bytes of its first quad
    where they are free, and all NUL bytes are dropped at the end. The literal text after the
    last field is moved to the front of the row and moved back as a whole at the end, so it
    costs no quad of its own."""
    fields = [part for part in parts if isinstance(part, Field)]
    if not fields:
        raise ValueError("join_rows needs at least one field")
    rows = len(fields[0])
    if any(len(field) != rows for field in fields):
        raise ValueError("fields of different lengths")
    if not rows:
        return []
    plan = []
    pending = b""
    for part in parts:
        if isinstance(part, Field):
            plan.append((part, pending))
            pending = b""
        else:
            pending += part
    trailing = pending
    plan[0] = (plan[0][0], trailing + plan[0][1])
    layout = []
    total = 0
    for field, prefix in plan:
        run_quads = [_quads(width) for _, width, _ in field.runs]
        lead = len(prefix) + (field.negative is not None)
        slack = 4 * run_quads[0] - field.runs[0][1]
        extra = max(-(-(lead - slack) // 4), 0)
        longest = max((len(token) for token in field.tokens), default=0)
        extra = max(extra, -(-(len(prefix) + longest) // 4) - sum(run_quads))
        lows = [int(values.min()) for values, _, _ in field.runs]
        prefix_chars = np.frombuffer(prefix, np.uint8)
        layout.append((field, prefix_chars, total, extra, run_quads, lows))
        total += extra + sum(run_quads)
    pieces = []
    step = max(_BLOCK_BYTES // (4 * total), 256)
    for begin in range(0, rows, step):
        end = min(begin + step, rows)
        pieces.append(_join_block(layout, total, begin, end).translate(None, b"\0"))
    if trailing:
        pieces[0] = pieces[0][len(trailing) :]
        pieces.append(trailing)
    return pieces


def _join_block(layout: list, total: int, begin: int, end: int) -> bytes:
    """Rows ``begin:end`` of the planned layout as one bytes object, NUL padding included."""
    block = np.empty((end - begin, total), np.uint32)
    text = block.view(np.uint8)
    for field, prefix, start, extra, run_quads, lows in layout:
        if extra:
            block[:, start : start + extra] = 0
        column = start + extra
        for (values, _, units), quads, low in zip(field.runs, run_quads, lows):
            _write_run(block[:, column : column + quads], values[begin:end], units, low)
            column += quads
        first = 4 * start
        if len(prefix):
            text[:, first : first + len(prefix)] = prefix
        if field.negative is not None:
            text[:, first + len(prefix)] = field.negative[begin:end] * ord("-")
        if field.tokens:
            first_token, last_token = np.searchsorted(field.fallback, [begin, end])
            if first_token == last_token:
                continue
            tokens = field.tokens[first_token:last_token]
            width = 4 * (column - start) - len(prefix)
            padded = np.frombuffer(b"".join(t.ljust(width, b"\0") for t in tokens), np.uint8)
            region = text[:, first + len(prefix) : 4 * column]
            region[field.fallback[first_token:last_token] - begin] = padded.reshape(-1, width)
    return block.tobytes()


def float_tokens(values: np.ndarray) -> list[str]:
    """The tokens of ``float_field`` as strings (for tests and small arrays)."""
    if np.size(values) == 0:
        return []
    return join_rows([float_field(values), b"\n"]).decode("ascii").splitlines()


def int_tokens(values: np.ndarray) -> list[str]:
    """The tokens of ``int_field`` as strings (for tests and small arrays)."""
    if np.size(values) == 0:
        return []
    return join_rows([int_field(values), b"\n"]).decode("ascii").splitlines()
