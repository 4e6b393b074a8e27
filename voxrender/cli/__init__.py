"""The ``voxrender`` command line, a module per command (as pip's ``commands/`` and nibabel's ``cmdline/``): each
parses its flags, calls the library and reports.

Bad input ends with one line on stderr and exit status 2; a bug in voxrender ends with one line and exit status 1
(``VOXRENDER_DEBUG=1`` shows the traceback).  ``_main`` holds the group and the reporting, ``_options`` the flags the
commands share and the library values they parse into.
"""

from . import batch, compare, demo, encode, info, lines, render, slices  # noqa: F401 (each adds its commands)
from ._main import flag, main, progress

__all__ = ["main", "flag", "progress"]
