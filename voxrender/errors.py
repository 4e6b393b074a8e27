"""The one exception type for bad input.

Library functions raise :class:`InputError` when the user's data or options
are wrong, naming the parameter at fault; the CLI maps that parameter to its
flag, prints the message as one line and exits with status 2.  Any other
exception is a bug in voxrender (exit status 1).
"""


class InputError(ValueError):
    """Bad input: a message that says what is wrong and how to fix it.

    Parameters
    ----------
    message : str
        What is wrong and how to fix it.
    parameter : str, optional
        The library parameter at fault (``"scale"``, ``"threshold"`` ...), when one is; the command line shows
        it as its flag.

    Examples
    --------
    >>> str(InputError("must be positive, not -1", parameter="scale"))
    'scale: must be positive, not -1'
    """

    def __init__(self, message, parameter=None):
        super().__init__(message)
        self.message = message
        self.parameter = parameter

    def __str__(self):
        return f"{self.parameter}: {self.message}" if self.parameter else self.message

    def __reduce__(self):  # survives pickling between batch workers
        return type(self), (self.message, self.parameter)
