"""Work on threads: NumPy calls let go of Python's lock, so independent array passes run on all cores."""

from __future__ import annotations

import os
import threading


def on_threads(work, items, states=None):
    """``[work(item) for item in items]``, the items on threads, the results in order.

    Each thread takes the next item when done with its last (their work may differ much), so a progress bar over
    ``items`` follows the work done.  Without ``states``, as many threads as this machine has cores (or as there
    are items, when fewer).  With ``states``, one thread for each, and each call is ``work(item, state)`` with its
    thread's state (an output or buffers of its own, used by no other thread meanwhile).

    >>> on_threads(lambda n: n * n, range(5))
    [0, 1, 4, 9, 16]
    >>> totals = [[0], [0]]
    >>> _ = on_threads(lambda n, total: total.__setitem__(0, total[0] + n), range(10), totals)
    >>> totals[0][0] + totals[1][0]
    45
    """
    from concurrent.futures import ThreadPoolExecutor

    if states is None:
        items = list(items)
        threads = [None] * min(len(items), os.cpu_count() or 1)
    else:
        threads = list(states)
    numbered, lock, results = enumerate(items), threading.Lock(), {}

    def drain(state):
        while True:
            with lock:
                taken = next(numbered, None)
            if taken is None:
                return
            k, item = taken
            results[k] = work(item) if states is None else work(item, state)

    if len(threads) == 1:
        drain(threads[0])
    elif threads:
        with ThreadPoolExecutor(len(threads)) as pool:
            list(pool.map(drain, threads))
    return [results[k] for k in range(len(results))]
