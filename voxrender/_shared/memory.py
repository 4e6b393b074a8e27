"""The memory this machine has: what a reader checks a header's promise against, and a worker's budget."""

from __future__ import annotations

import contextlib
import os


def free_memory():
    """The bytes this process can still allocate: the memory the system has available, within the process's
    address-space limit (``RLIMIT_AS``) when it has one.
    """
    import resource

    free = None
    try:
        with open("/proc/meminfo") as f:
            free = next(int(line.split()[1]) * 1024 for line in f if line.startswith("MemAvailable:"))
    except (OSError, StopIteration, ValueError, IndexError):
        try:
            free = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
        except (ValueError, OSError, AttributeError):
            free = None
    limit = resource.getrlimit(resource.RLIMIT_AS)[0]
    if limit not in (resource.RLIM_INFINITY, -1):
        try:
            with open("/proc/self/statm") as f:
                used = int(f.read().split()[0]) * os.sysconf("SC_PAGE_SIZE")
        except (OSError, ValueError, IndexError):
            used = 0
        free = min(free if free is not None else limit, max(limit - used, 0))
    return free if free is not None else 1 << 62


# glibc's mallopt parameters, and their defaults (malloc.h)
_M_TRIM_THRESHOLD, _M_MMAP_MAX = -1, -4
_DEFAULT_TRIM_THRESHOLD, _DEFAULT_MMAP_MAX = 128 * 1024, 65536


@contextlib.contextmanager
def memory_reused():
    """Within it, memory freed stays with the process for the next arrays (glibc), and is given back at its end.

    Memory a process touches for the first time is slow on a virtual machine (about 3.5 ms for each 2 MB on the
    benchmark's), and glibc gives each array of more than 32 MB fresh pages of its own and returns them when it is
    freed: a stack encoded a slab at a time would touch new memory for every slab's arrays, a tenth of its time.
    With large arrays taken from the heap and the heap not trimmed, each slab reuses the pages the last one
    touched.  Elsewhere than glibc, nothing changes.
    """
    libc = keep_freed_memory()
    try:
        yield
    finally:
        if libc is not None:
            libc.mallopt(_M_MMAP_MAX, _DEFAULT_MMAP_MAX)
            libc.mallopt(_M_TRIM_THRESHOLD, _DEFAULT_TRIM_THRESHOLD)
            libc.malloc_trim(0)


def keep_freed_memory():
    """From now on, memory this process frees stays with it for the next arrays (:func:`memory_reused`): for a
    worker process, which ends with its work.  Returns the C library's functions, ``None`` where it is not glibc.
    """
    libc = _glibc()
    if libc is not None:
        libc.mallopt(_M_MMAP_MAX, 0)
        libc.mallopt(_M_TRIM_THRESHOLD, 1 << 30)
    return libc


def _glibc():
    """The C library's functions, when it is glibc."""
    import ctypes

    try:
        if not os.confstr("CS_GNU_LIBC_VERSION").startswith("glibc"):
            return None
        return ctypes.CDLL(None)
    except (ValueError, OSError, AttributeError):
        return None
