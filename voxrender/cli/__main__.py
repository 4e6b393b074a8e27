"""``python -m voxrender.cli``: the command line, as the ``voxrender`` command runs it."""

from . import main

main()
