"""The one exception type for bad input.

Library functions raise :class:`InputError` when the user's data or options
are wrong; the CLI prints its message as one line and exits with status 2.
Any other exception is a bug in voxrender (exit status 1).
"""


class InputError(ValueError):
    """Bad input: a message that says what is wrong and how to fix it."""
