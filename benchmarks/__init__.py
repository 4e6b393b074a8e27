"""voxrender's benchmarks: ``make benchmark`` (:mod:`benchmarks.bench`) and ``make bench-compare``."""

import compileall
import statistics
import time
from pathlib import Path


def compile_bytecode(tree):
    """Compile the ``voxrender`` package of the checkout ``tree`` to bytecode, as pip does when it installs one.

    A fresh process of an uncompiled checkout compiles every module it imports, each time, where bytecode is not
    written (``PYTHONDONTWRITEBYTECODE``, as on the project's machine): about 0.2 s of a command's start-up here
    that no installed package pays, and that its peers (VTK, installed by pip) do not pay either.
    """
    if not compileall.compile_dir(str(Path(tree) / "voxrender"), quiet=1):
        raise SystemExit(f"error: cannot compile {Path(tree) / 'voxrender'} to bytecode")


def median_seconds(work, repeat):
    """Median wall time of ``repeat`` calls of ``work()``, and the last result."""
    times, result = [], None
    for _ in range(repeat):
        started = time.perf_counter()
        result = work()
        times.append(time.perf_counter() - started)
    return statistics.median(times), result
