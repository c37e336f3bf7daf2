"""One compiled pass over a CSV batch: line bounds, field counts, UTF-8 and number hints, times.

:func:`scan_chunk` walks the bytes of a batch once (numba, no GIL) and returns per line:

* ``starts``/``ends``: byte bounds (``ends`` before ``\\r\\n``/``\\n``);
* ``fields``: separators + 1 (the field-count check);
* ``high``: a byte >= 0x80 occurs (only those lines need a UTF-8 check);
* ``clean``: every byte of the numeric fields is one a number can be written with
  (digits, ``.+-eE`` and the letters of ``nan``/``inf``/``infinity``). Only when all
  kept lines are clean may polars parse the numbers as floats directly: its CSV float
  parser trims blanks that the string cast of the string path rejects;
* ``naive_us``/``ts_ok``: the first field read as a naive local time, for the one
  strict shape ``YYYY-MM-DD[ T]HH:MM:SS[.f{1,6}]`` with a plausible calendar date
  (years 1900-2199, seconds 0-59). ``ts_ok`` is false for everything else (other shapes,
  offsets, leap seconds, more than 6 fractional digits): those rows go through the polars
  formats of :mod:`.local_time`, which give the same value for every row accepted here.
"""

from __future__ import annotations

import threading

import numpy as np
from numba import njit

__all__ = ["NUMBER_BYTES", "count_newlines", "scan_chunk", "warm_up_in_background"]


def _number_bytes() -> np.ndarray:
    table = np.zeros(256, np.bool_)
    for char in "0123456789.+-eEnNaAiIfFtTyY":
        table[ord(char)] = True
    return table


#: Bytes a float field may hold for the direct (typed) polars parse.
NUMBER_BYTES = _number_bytes()


@njit(cache=True, nogil=True)
def _days_from_civil(year: int, month: int, day: int) -> int:
    y = year - 1 if month <= 2 else year
    era = y // 400
    yoe = y - era * 400
    shifted = month - 3 if month > 2 else month + 9
    doy = (153 * shifted + 2) // 5 + day - 1
    doe = yoe * 365 + yoe // 4 - yoe // 100 + doy
    return era * 146097 + doe - 719468


@njit(cache=True, nogil=True)
def _digits(buf: np.ndarray, pos: int, count: int) -> int:
    value = 0
    for k in range(count):
        d = buf[pos + k] - 48
        if d < 0 or d > 9:
            return -1
        value = value * 10 + d
    return value


@njit(cache=True, nogil=True)
def _timestamp(buf: np.ndarray, start: int, end: int, sep: int) -> tuple[int, bool]:
    if end - start < 19:
        return 0, False
    p = start
    if buf[p + 4] != 45 or buf[p + 7] != 45 or buf[p + 13] != 58 or buf[p + 16] != 58:
        return 0, False
    if buf[p + 10] != 32 and buf[p + 10] != 84:  # ' ' or 'T'
        return 0, False
    year = _digits(buf, p, 4)
    month = _digits(buf, p + 5, 2)
    day = _digits(buf, p + 8, 2)
    hour = _digits(buf, p + 11, 2)
    minute = _digits(buf, p + 14, 2)
    second = _digits(buf, p + 17, 2)
    if year < 1900 or year > 2199 or month < 1 or month > 12 or day < 1:
        return 0, False
    if hour < 0 or hour > 23 or minute < 0 or minute > 59 or second < 0 or second > 59:
        return 0, False
    if month == 2:
        leap = (year % 4 == 0 and year % 100 != 0) or year % 400 == 0
        month_days = 29 if leap else 28
    elif month == 4 or month == 6 or month == 9 or month == 11:
        month_days = 30
    else:
        month_days = 31
    if day > month_days:
        return 0, False
    q = p + 19
    micros = 0
    if q < end and buf[q] != sep:
        if buf[q] != 46:  # '.'
            return 0, False
        q += 1
        count = 0
        while q < end and buf[q] != sep:
            d = buf[q] - 48
            if d < 0 or d > 9 or count == 6:
                return 0, False
            micros = micros * 10 + d
            count += 1
            q += 1
        if count == 0:
            return 0, False
        for _ in range(6 - count):
            micros *= 10
    seconds = ((_days_from_civil(year, month, day) * 24 + hour) * 60 + minute) * 60 + second
    return seconds * 1_000_000 + micros, True


@njit(cache=True, nogil=True)
def count_newlines(buf: np.ndarray) -> int:
    """Newline bytes in ``buf``."""
    count = 0
    for i in range(buf.size):
        count += buf[i] == 10
    return count


@njit(cache=True, nogil=True)
def scan_chunk(buf: np.ndarray, n_lines: int, sep: int, numeric: np.ndarray, number_bytes):
    """Per-line facts of a batch ending with a newline (see the module docstring)."""
    starts = np.empty(n_lines, np.int64)
    ends = np.empty(n_lines, np.int64)
    fields = np.empty(n_lines, np.int64)
    high = np.zeros(n_lines, np.bool_)
    clean = np.ones(n_lines, np.bool_)
    naive_us = np.zeros(n_lines, np.int64)
    ts_ok = np.zeros(n_lines, np.bool_)
    # byte classes: 0 number byte, 1 newline, 2 separator, 3 anything else
    kind = np.where(number_bytes, 0, 3).astype(np.uint8)
    kind[10] = 1
    kind[sep] = 2
    size = buf.size
    n_numeric = numeric.size
    line = 0
    start = 0
    field = 0
    for i in range(size):
        b = buf[i]
        c = kind[b]
        if c == 0:
            continue
        if c == 1:
            if line == n_lines:
                break
            end = i
            if end > start and buf[end - 1] == 13:
                end -= 1
            starts[line] = start
            ends[line] = end
            fields[line] = field + 1
            value, ok = _timestamp(buf, start, end, sep)
            naive_us[line] = value
            ts_ok[line] = ok
            line += 1
            start = i + 1
            field = 0
        elif c == 2:
            field += 1
        elif line < n_lines:
            if b >= 128:
                high[line] = True
            if field < n_numeric and numeric[field]:
                if not (b == 13 and i + 1 < size and buf[i + 1] == 10):
                    clean[line] = False
    return starts, ends, fields, high, clean, naive_us, ts_ok


_warm_up: threading.Thread | None = None


def _warm() -> None:
    # the same argument types as a real batch (read-only bytes), so the cached machine
    # code that later calls use is the one loaded here
    data = np.frombuffer(b"t,1\n", np.uint8)
    scan_chunk(data, count_newlines(data), 44, np.ones(2, np.bool_), NUMBER_BYTES)


def warm_up_in_background() -> None:
    """Load the compiled scan (numba cache, ~0.5 s) on a thread, once per process.

    Called before hashing a CSV file (hashlib releases the GIL), so the load overlaps
    the hash instead of delaying the first batch. A batch that comes first simply
    waits for numba's compiler lock.
    """
    global _warm_up
    if _warm_up is None:
        _warm_up = threading.Thread(target=_warm, name="ropeload-scan-warm-up", daemon=True)
        _warm_up.start()
