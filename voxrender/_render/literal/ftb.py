"""The dynamic screen as the paper writes it: linked lists and MERGE case by case (the test oracle).

``YCHAIN[L]`` points to the linked list of unlit segments of scanline ``L``
(Fig. 5).  Slices and rows are read front to back (Fig. 9); for each row and
each scanline its parallelepipeds reach, MERGE (Fig. 6) walks the row's
projected segments and the unlit segments together and takes one of eight
actions each step.  Slow on purpose: it is what :func:`~voxrender._render.ftb.render_ftb`
is checked against, depth image and statistics alike.

It shares no geometry with the vectorised version: every parallelepiped is scan-converted
by :mod:`.geometry` (its projected edges crossed with each scanline) and every lit pixel's
depth is its slab test, one pixel at a time.
"""

from __future__ import annotations

import numpy as np

from . import geometry


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
    """Front-to-back rendering with linked lists, one segment and one MERGE case at a time.

    The view's gamma is ignored (it turns the pre-image afterwards); the statistics are those of
    :func:`~voxrender._render.ftb.render_ftb`.
    """
    r = geometry.rotation(view.alpha, view.beta)
    size, scale, middle = tuple(view.size), view.scale, tuple(view.centre)
    height, width = size
    nz, ny, nx = segments.shape
    centre = ((nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2)
    direction = r[2]

    def front_to_back(n, component):           # the viewer looks along +Z': low indices first when it grows
        return list(range(n)) if component > 0 else list(range(n - 1, -1, -1))

    outer_is_z = abs(r[1][1]) >= abs(r[1][2])   # "roles interchanged" when rows cross scanlines faster
    z_order, y_order = front_to_back(nz, direction[2]), front_to_back(ny, direction[1])
    x_ascending = direction[0] >= 0
    mirror = x_ascending != (r[0][0] >= 0)      # the walk meets the row's segments right to left

    def walk(first, last):
        return (width - 1 - last, width - 1 - first) if mirror else (first, last)

    stats = {"slices_read": 0, "rows_read": 0, "segments_read": 0, "merge_calls": 0, "segments_merged": 0,
             "cases": {}, "pixels_lit": 0, "unlit_segments_start": 0, "unlit_segments_peak": 0,
             "unlit_segments_end": 0, "scanlines_skipped_full": 0, "rows_skipped_full": 0}
    cases = {c: 0 for c in range(1, 9)}
    image = np.full((height, width), np.inf)
    chains = [None] * height

    # The dynamic screen starts as the projection of the object's bounding box (within the clip limits).
    (z0, z1), (y0, y1), (x0, x1) = segments.bounding_box()
    limits = [[x0, x1], [y0, y1], [z0, z1]]
    for bounds, pair in zip((clip.x, clip.y, clip.z) if clip is not None else (None,) * 3, limits, strict=True):
        if bounds is not None:
            pair[0] = pair[0] if bounds[0] is None else max(pair[0], bounds[0])
            pair[1] = pair[1] if bounds[1] is None else min(pair[1], bounds[1] - 1)
    if all(lo <= hi for lo, hi in limits):
        box_centre = tuple((lo + hi) / 2 for lo, hi in limits)
        half = tuple((hi - lo + 1) / 2 for lo, hi in limits)
        first, last = geometry.box_scanlines(r, box_centre, half, centre, size, scale, middle)
        for line in range(max(first, 0), min(last, height - 1) + 1):
            y = geometry.pixel_centre(0, line, size, scale, middle)[1]
            span = geometry.box_scanline_span(r, box_centre, half, centre, y, size, scale, middle)
            if span is not None:
                chains[line] = Unlit(*walk(*span))
    stats["unlit_segments_start"] = stats["unlit_segments_peak"] = _count(chains)

    def paint(i, j, box):
        line, box_centre, half = box
        y = geometry.pixel_centre(0, line, size, scale, middle)[1]
        for walk_x in range(i, j + 1):
            column = width - 1 - walk_x if mirror else walk_x
            x = geometry.pixel_centre(column, line, size, scale, middle)[0]
            image[line, column] = geometry.ray_entry(r, x, y, box_centre, half, centre)
            stats["pixels_lit"] += 1

    for outer in (z_order if outer_is_z else y_order):
        slice_read = False
        for inner in (y_order if outer_is_z else z_order):
            z, y = (outer, inner) if outer_is_z else (inner, outer)
            runs = list(zip(*segments.row(z, y), strict=True))
            if not x_ascending:
                runs = runs[::-1]
            runs = [kept for start, end in runs if (kept := geometry.clip_run(clip, r, z, y, start, end, centre))]
            if not runs:
                continue
            slice_read = True
            stats["rows_read"] += 1
            stats["segments_read"] += len(runs)
            boxes = [(((start + end) / 2, y, z), ((end - start + 1) / 2, 0.5, 0.5)) for start, end in runs]
            first, last = geometry.box_scanlines(r, *boxes[0], centre, size, scale, middle)   # Y' does not vary along x
            calls = full = 0
            for line in range(max(first, 0), min(last, height - 1) + 1):
                scan_y = geometry.pixel_centre(0, line, size, scale, middle)[1]
                spans = []
                for box_centre, half in boxes:
                    span = geometry.box_scanline_span(r, box_centre, half, centre, scan_y, size, scale, middle)
                    if span is not None:
                        spans.append((*walk(*span), (line, box_centre, half)))
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
