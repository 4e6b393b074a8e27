"""The memory this machine has: what a reader checks a header's promise against, and a worker's budget."""

from __future__ import annotations

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

