"""Text for messages: the first line of a library's error, a size in words."""

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

