"""Text for messages and tables: the first line of a library's error, a size in words, a spreadsheet's cell."""

from __future__ import annotations

import math


def first_line(exc):
    """The first line of an exception's message (a library's messages can run to many lines), for ours."""
    text = str(exc).strip().splitlines()
    return (text[0] if text else type(exc).__name__)[:200]


def in_words(nbytes):
    """A size for a message.

    >>> in_words(54000000000000), in_words(64), in_words(1500000)
    ('54 TB', '64 bytes', '1.5 MB')
    """
    if nbytes < 1000:
        return f"{nbytes} bytes"
    power = min(int(math.log10(nbytes) // 3), 6)
    return f"{nbytes / 1000 ** power:.3g} {'kMGTPE'[power - 1]}B"


FORMULA_STARTS = ("=", "+", "-", "@", "\t", "\r")     # what a spreadsheet runs as a formula (OWASP's CSV injection)


def spreadsheet_cell(value):
    """``value`` as a CSV cell a spreadsheet shows and does not run: text that begins like a formula is prefixed with
    a quote, as OWASP advises; numbers, negative ones too, are left as they are.  :func:`from_spreadsheet_cell`
    undoes it.

    >>> spreadsheet_cell("=1+2"), spreadsheet_cell("@SUM(A1)"), spreadsheet_cell("-0.5000"), spreadsheet_cell("liver")
    ("'=1+2", "'@SUM(A1)", '-0.5000', 'liver')
    """
    if not isinstance(value, str) or not value.startswith(FORMULA_STARTS):
        return value
    try:
        float(value)
        return value
    except ValueError:
        return "'" + value


def from_spreadsheet_cell(value):
    """A cell :func:`spreadsheet_cell` wrote, as it was."""
    return value[1:] if isinstance(value, str) and value[:1] == "'" and value[1:2] in FORMULA_STARTS else value
