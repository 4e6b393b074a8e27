"""The dynamic screen as the paper writes it: linked lists and MERGE case by case (the test oracle).

``YCHAIN[L]`` points to the linked list of unlit segments of scanline ``L``
(Fig. 5).  Slices and rows are read front to back (Fig. 9); for each row and
each scanline its parallelepipeds reach, MERGE (Fig. 6) walks the row's
projected segments and the unlit segments together and takes one of eight
actions each step.  Slow on purpose: it is what :func:`~voxrender.render.ftb.render_ftb`
is checked against, depth image and statistics alike.
"""

from __future__ import annotations

import numpy as np

from .ftb import initial_unlit, new_stats, object_box, plan_screen

__all__ = ["render_ftb_literal", "Unlit"]


class Unlit:
    """One list element: an unlit segment ``MIN..MAX`` of a scanline and the LINK to the next."""

    __slots__ = ("MIN", "MAX", "LINK")

    def __init__(self, lo, hi, link=None):
        self.MIN, self.MAX, self.LINK = lo, hi, link


def _count(chains):
    total = 0
    for head in chains:
        while head is not None:
            total += 1
            head = head.LINK
    return total


def merge(chains, line, spans, paint, cases):
    """Fig. 6: merge the projected object segments ``spans`` [(I, J, box), ...] into ``YCHAIN[line]``.

    ``paint(I, J, box)`` lights pixels I..J; ``cases`` counts the actions taken.
    """
    previous, k = None, chains[line]
    o = 0
    while o < len(spans) and k is not None:
        i, j, box = spans[o]
        if j < k.MIN:                                   # 1: the object segment precedes
            cases[1] += 1
            o += 1
        elif i <= k.MIN and j < k.MAX:                  # 2: covers the left end
            cases[2] += 1
            paint(k.MIN, j, box)
            k.MIN = j + 1                               # CHANGE
            o += 1
        elif i > k.MIN and j < k.MAX:                   # 3: falls strictly inside
            cases[3] += 1
            paint(i, j, box)
            k.LINK = Unlit(j + 1, k.MAX, k.LINK)        # SPLIT
            k.MAX = i - 1
            o += 1
        elif i <= k.MIN and j == k.MAX:                 # 4: covers it exactly to its end
            cases[4] += 1
            paint(k.MIN, k.MAX, box)
            k = _delete(chains, line, previous, k)
            o += 1
        elif i > k.MIN and j == k.MAX:                  # 5: covers the right end, ends with it
            cases[5] += 1
            paint(i, j, box)
            k.MAX = i - 1                               # CHANGE
            previous, k = k, k.LINK
            o += 1
        elif i <= k.MIN:                                # 6: covers it and goes on
            cases[6] += 1
            paint(k.MIN, k.MAX, box)
            k = _delete(chains, line, previous, k)
        elif i <= k.MAX:                                # 7: covers the right end and goes on
            cases[7] += 1
            paint(i, k.MAX, box)
            k.MAX = i - 1                               # CHANGE
            previous, k = k, k.LINK
        else:                                           # 8: the unlit segment precedes
            cases[8] += 1
            previous, k = k, k.LINK


def _delete(chains, line, previous, k):
    """DELETE: unlink ``k``; return the next element."""
    if previous is None:
        chains[line] = k.LINK
    else:
        previous.LINK = k.LINK
    return k.LINK


def render_ftb_literal(segments, view, clip=None):
    """Front-to-back rendering with linked lists, one segment and one MERGE case at a time."""
    plan = plan_screen(segments, view)
    height, width = view.size
    nz, ny, _ = segments.shape
    stats = new_stats()
    cases = {c: 0 for c in range(1, 9)}
    image = np.full((height, width), np.inf)
    chains = [None] * height
    for line, lo, hi in zip(*initial_unlit(plan, object_box(segments, clip))):
        chains[int(line)] = Unlit(int(lo), int(hi))
    stats["unlit_segments_start"] = stats["unlit_segments_peak"] = _count(chains)

    def paint(i, j, box):
        line, xc, yc, zc, half_x = box
        for walk_x in range(i, j + 1):
            image[line, plan.column(walk_x)] = plan.depth(line, walk_x, xc, yc, zc, half_x)
            stats["pixels_lit"] += 1

    for outer in plan.outer_order:
        slice_read = False
        for inner in plan.inner_order:
            z, y = (outer, inner) if plan.outer_is_z else (inner, outer)
            starts, ends = segments.row(int(z), int(y))
            if not plan.x_ascending:
                starts, ends = starts[::-1], ends[::-1]
            if clip is not None and clip.active:
                keep, starts, ends = clip.apply_runs(z, y, starts, ends, plan.view, segments.shape)
                starts, ends = starts[keep], ends[keep]
            if not len(starts):
                continue
            slice_read = True
            stats["rows_read"] += 1
            stats["segments_read"] += len(starts)
            xc, yc, zc, half_x = plan.centres(z, y, starts, ends)
            first_line, last_line = plan.scanlines(yc[0])
            calls = full = 0
            for line in range(int(first_line), int(last_line) + 1):
                lows, highs = plan.spans(np.full(len(xc), line), xc, yc, half_x)
                spans = [(int(a), int(b), (line, xc[k], yc[k], zc[k], half_x[k]))
                         for k, (a, b) in enumerate(zip(lows, highs)) if a <= b]
                spans.sort(key=lambda span: span[0])  # walk order; stable, so ties keep front-to-back order
                if not spans:
                    continue
                calls += 1
                if chains[line] is None:                # no unlit pixel left on this scanline
                    full += 1
                    continue
                stats["merge_calls"] += 1
                stats["segments_merged"] += len(spans)
                merge(chains, line, spans, paint, cases)
            stats["scanlines_skipped_full"] += full
            stats["rows_skipped_full"] += bool(calls) and full == calls
        if slice_read:
            stats["slices_read"] += 1
            stats["unlit_segments_peak"] = max(stats["unlit_segments_peak"], _count(chains))
    stats["unlit_segments_end"] = _count(chains)
    stats["cases"] = {str(c): n for c, n in cases.items()}
    return image.astype(np.float32), stats
