"""The dynamic-screen front-to-back renderer of Reynolds, Gordon and Chen (sections 3 to 6).

The view is split as the paper's Theorems 1 and 2 say: rotations alpha and beta
keep object rows parallel to scanlines, gamma turns the finished pre-image.
For every scanline the *dynamic screen* holds the sorted list of its unlit
segments, initialised to the projection of the object's bounding box.  Slices
and rows are read front to back (slices and rows change roles when
``|sin alpha| > |cos alpha|``); each object segment is scan-converted as the
projection of its thin parallelepiped (Fig. 8), and on every scanline that
projection is MERGEd with the unlit segments (Fig. 6): only unlit pixels are
painted, lit pixels leave the list and are never looked at again, and a row is
skipped on a scanline that has no unlit pixel left.

Here the parallelepiped's span on each scanline is computed in closed form
(:func:`~voxrender._render.geometry.row_spans`), the exact limit of the paper's
DDA, and each lit pixel takes the depth where its ray enters the segment's box,
so the depth image is the view contract's.

Two implementations: :mod:`.literal.ftb` walks the linked lists case by case
with a geometry of its own (the oracle), and :func:`render_ftb` runs the same
merges for many scanlines at once: every merge of one row into one scanline is
independent of the other scanlines (the paper's section 7), so the merges are
batched by their rank on their scanline (over all the slabs read at once), and
each batch is a few searches and one split of all unlit segments; the MERGE
cases are counted from the searches after the last batch.  Both give the same
depth image and the same statistics, MERGE cases included.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace

import numpy as np

from ..object.segments import ranges
from ..space.view import View
from .btf import back_to_front
from .geometry import box_rows, cross_section_reach, ray_box_entry, row_spans, span_columns

CASES = tuple(range(1, 9))


@dataclass(frozen=True)
class ScreenPlan:
    """What a front-to-back pass needs to know about a view (alpha and beta only)."""

    view: View                # the (alpha, beta, 0) view that is rendered
    shape: tuple
    outer_is_z: bool          # slices are the outer loop (|cos alpha| >= |sin alpha|), else rows are
    outer_order: np.ndarray   # front to back
    inner_order: np.ndarray
    x_ascending: bool         # object rows are read with x ascending (front to back)
    mirror: bool              # the merge walks right to left in the picture: columns are mirrored

    @property
    def matrix(self):
        return self.view.matrix

    @property
    def size(self):
        return self.view.size

    def to_walk(self, first, last):
        """Pixel columns ``[first, last]`` to the walk's coordinates (and back: the map is its own inverse)."""
        if not self.mirror:
            return first, last
        width = self.size[1]
        return width - 1 - last, width - 1 - first

    def column(self, walk_x):
        return self.size[1] - 1 - walk_x if self.mirror else walk_x

    def centres(self, z, y, starts, ends):
        """Image-space box centres ``(Xc, Yc, Zc)`` and half-lengths of runs ``[starts, ends]`` of rows (z, y)."""
        xc, yc, zc = self.view.to_image((starts + ends) / 2, y, z, self.shape)
        return xc, yc, zc, (np.asarray(ends) - starts + 1) / 2

    def scanlines(self, yc, half_y=0.5, half_z=0.5):
        """First and last scanline a box centred at ``Y' = yc`` covers, clipped to the picture."""
        first, last = box_rows(yc, half_y, half_z, self.view)
        return np.maximum(first, 0), np.minimum(last, self.size[0] - 1)

    def scanline_y(self, line):
        return self.view.pixel_centres(0, line)[1]

    def spans(self, line, xc, yc, half_x, half_y=0.5, half_z=0.5):
        """Walk-coordinate span ``[first, last]`` of boxes on scanline ``line`` (empty: first > last)."""
        first, last = row_spans(self.scanline_y(line) - yc, xc, half_x, half_y, half_z, self.view)
        return self.to_walk(first, last)

    def reach(self, line, yc):
        """How far a voxel row's cross-section reaches left and right of its centre line on scanline ``line``
        (:func:`~voxrender._render.geometry.cross_section_reach`), for rows centred at ``Y' = yc``.
        """
        return cross_section_reach(self.scanline_y(line) - yc, 0.5, 0.5, self.view)

    def columns(self, xc, half_x, left, right, empty):
        """Walk-coordinate span ``[first, last]`` of runs centred at ``X' = xc`` whose row reaches ``(left, right,
        empty)`` on the scanline (:meth:`reach`): :meth:`spans` in two halves.
        """
        return self.to_walk(*span_columns(xc, half_x, left, right, empty, self.view))

    def depth(self, line, walk_x, xc, yc, zc, half_x):
        """Depth where the ray of pixel (line, walk_x) enters the box."""
        x, y = self.view.pixel_centres(self.column(walk_x), line)
        _, entry = ray_box_entry(x - xc, y - yc, self.matrix, half_x)
        return zc + entry


def _plan_screen(segments, view):
    """The front-to-back plan for ``view`` (its gamma is ignored: it turns the pre-image afterwards)."""
    flat = replace(view, gamma=0.0)
    matrix = flat.matrix
    nz, ny, _ = segments.shape
    direction = matrix[2]
    outer_is_z = abs(matrix[1, 1]) >= abs(matrix[1, 2])
    z_order = back_to_front(nz, direction[2])[::-1]
    y_order = back_to_front(ny, direction[1])[::-1]
    x_ascending = direction[0] >= 0
    return ScreenPlan(flat, tuple(segments.shape), outer_is_z, z_order if outer_is_z else y_order,
                      y_order if outer_is_z else z_order, x_ascending, bool(x_ascending != (matrix[0, 0] >= 0)))


def _object_box(segments, clip=None):
    """``((x0, x1), (y0, y1), (z0, z1))`` inclusive: the bounding box of the object inside the clip limits."""
    (z0, z1), (y0, y1), (x0, x1) = segments.bounding_box()
    box = [[x0, x1], [y0, y1], [z0, z1]]
    if clip is not None:
        for bounds, limits in zip((clip.x, clip.y, clip.z), box, strict=True):
            if bounds is not None:
                if bounds[0] is not None:
                    limits[0] = max(limits[0], bounds[0])
                if bounds[1] is not None:
                    limits[1] = min(limits[1], bounds[1] - 1)
    return tuple(tuple(limits) for limits in box)


def _initial_unlit(plan, box):
    """The dynamic screen at the start: per scanline, the span of the bounding box's projection.

    Returns ``(lines, first, last)`` in walk coordinates, one unlit segment per scanline that has one.
    """
    (x0, x1), (y0, y1), (z0, z1) = box
    if x0 > x1 or y0 > y1 or z0 > z1:
        return (np.zeros(0, np.int64),) * 3
    half = np.array([(x1 - x0 + 1) / 2, (y1 - y0 + 1) / 2, (z1 - z0 + 1) / 2])
    xc, yc, _, _ = plan.centres(np.array((z0 + z1) / 2), np.array((y0 + y1) / 2), np.array(x0), np.array(x1))
    first_line, last_line = plan.scanlines(yc, half[1], half[2])
    lines = np.arange(int(first_line), int(last_line) + 1)
    first, last = plan.spans(lines, xc, yc, half[0], half[1], half[2])
    keep = first <= last
    return lines[keep], first[keep].astype(np.int64), last[keep].astype(np.int64)


def new_stats():
    return {"slices_read": 0, "rows_read": 0, "segments_read": 0, "merge_calls": 0, "segments_merged": 0,
            "cases": {str(c): 0 for c in CASES}, "pixels_lit": 0, "unlit_segments_start": 0,
            "unlit_segments_peak": 0, "unlit_segments_end": 0, "scanlines_skipped_full": 0, "rows_skipped_full": 0}


# ------------------------------------------------------------------ the vectorised renderer

def _distinct_count(ordered):
    """How many distinct values an array holds whose equal values are together."""
    return int(len(ordered) > 0) + int(np.count_nonzero(ordered[1:] != ordered[:-1]))


def _stable_order(*keys):
    """The stable order of the rows by ``keys`` (most significant first), as :func:`numpy.lexsort` of them
    reversed, from one sort of the keys packed into one integer (a quarter of lexsort's time).
    """
    packed = np.zeros(len(keys[0]), np.int64)
    room = 1
    for key in keys:
        key = np.asarray(key, np.int64)
        low, high = (int(key.min()), int(key.max())) if len(key) else (0, 0)
        room *= high - low + 1
        if room >= 2 ** 63:
            return np.lexsort(keys[::-1])
        packed = packed * (high - low + 1) + (key - low)
    return np.argsort(packed, kind="stable")


def _front_to_back_runs(segments, plan, clip, outer=slice(None)):
    """Every run of the slabs ``plan.outer_order[outer]``, in the order the paper reads them: slabs, rows, then x
    front to back.

    Returns arrays per run: slab position, row position (front to back within these slabs), z, y, start, end.
    """
    nz, ny, _ = segments.shape
    outer_order = plan.outer_order[outer]
    outer, inner = np.meshgrid(outer_order, plan.inner_order, indexing="ij")
    z, y = (outer, inner) if plan.outer_is_z else (inner, outer)
    slab = np.broadcast_to(np.arange(len(outer_order))[:, None], outer.shape).ravel()
    rows = (z * ny + y).ravel()
    offsets = np.asarray(segments.offsets)
    counts = offsets[rows + 1] - offsets[rows]
    present = counts > 0
    rows, slab, counts = rows[present], slab[present], counts[present]
    rank, owner = ranges(np.zeros(len(rows), np.int64), counts, owners=True)
    if not plan.x_ascending:
        rank = counts[owner] - 1 - rank
    index = offsets[rows][owner] + rank
    starts = np.asarray(segments.starts[index], np.int64)        # only these runs are read from a mapped file
    ends = np.asarray(segments.ends[index], np.int64)
    run_z, run_y = (rows // ny)[owner], (rows % ny)[owner]      # (divided once a row, not once a run)
    if clip is not None and clip.active:
        keep, starts, ends = clip.apply_runs(run_z, run_y, starts, ends, plan.view, segments.shape)
        owner, run_z, run_y, starts, ends = owner[keep], run_z[keep], run_y[keep], starts[keep], ends[keep]
    return slab[owner], owner, run_z, run_y, starts, ends


_SPANS_AT_ONCE = 1 << 21      # about this many (run, scanline) spans are merged from one read of the runs


def _slab_groups(segments, plan):
    """The slabs (positions in ``plan.outer_order``) cut into groups of consecutive slabs of about
    :data:`_SPANS_AT_ONCE` spans each (at least one slab), so that the runs read at once, and the arrays of their
    spans, are bounded by that and not by the object.  Returns the bounds ``[b0, b1, ...]`` of the groups.
    """
    nz, ny, _ = segments.shape
    per_row = np.diff(np.asarray(segments.offsets)).reshape(nz, ny)
    runs = per_row.sum(axis=1 if plan.outer_is_z else 0)[plan.outer_order]
    matrix = plan.matrix
    lines_per_run = (abs(matrix[1, 1]) + abs(matrix[1, 2])) * plan.view.scale + 2     # scanlines a run's box spans
    spans = np.cumsum(runs * lines_per_run)
    cuts = np.searchsorted(spans, np.arange(1, int(spans[-1] // _SPANS_AT_ONCE) + 1) * _SPANS_AT_ONCE)
    return np.unique(np.concatenate([[0], cuts + 1, [len(runs)]]).clip(0, len(runs)))


def _small(keys):
    """``keys`` (whole numbers from 0) as int16 when they fit, which NumPy sorts stably by radix, in linear time."""
    return keys.astype(np.int16) if len(keys) and 0 <= keys.min() and keys.max() < 1 << 15 else keys


def _merge_order(line, counts):
    """The order of the MERGE calls' spans: the calls are ``(row, scanline)``, given in reading order (the rows
    as they are read, a row's scanlines rising) by their scanline ``line`` and how many spans each holds
    (``counts``, each above 0), their spans given one call's after another.

    Returns per span, in merge order: its place among the spans given, its scanline, its call (numbered by
    scanline, then in reading order) and the call's rank, how many rows reached its scanline before it.  The
    merges of one scanline depend on each other only, in the order the rows are read, so the calls of one
    rank (distinct scanlines, of any slab) run together: as many batches as the busiest scanline has calls.
    The spans leave in (rank, scanline) order, a call's in the order they came.  The order is found for the
    calls, not the spans: a row's runs make one call on each scanline they cross.
    """
    if not len(line):
        return (np.zeros(0, np.int64),) * 4
    by_line = np.argsort(_small(line), kind="stable")            # the calls in (scanline, reading) order
    line_of_call = line[by_line]
    starts = np.flatnonzero(np.concatenate([[True], line_of_call[1:] != line_of_call[:-1]]))
    rank = np.arange(len(line)) - np.repeat(starts, np.diff(np.append(starts, len(line))))
    merged = np.argsort(_small(rank), kind="stable")             # calls by number, in (rank, scanline) order
    spans = counts[by_line][merged]
    first = np.cumsum(counts) - counts
    return (ranges(first[by_line][merged], spans), np.repeat(line_of_call[merged], spans),
            np.repeat(merged, spans), np.repeat(rank[merged], spans))


def _in_walk_order(span_first, call):
    """Whether every call's spans, in run order, start in walk order: a row's runs are read in walk order, so
    their spans on a scanline come sorted, unless rounding puts a span a column before the one read before it
    (a view with ``R00`` next to nothing).
    """
    return not np.any((span_first[1:] < span_first[:-1]) & (call[1:] == call[:-1]))


def _merge_layout(line, rank, key_first, key_last, stride):
    """What the batches of :func:`_merge_all` search with: the bounds of the batches, each span's call (numbered
    in merge order), ``M`` and the first key it may paint, whether it paints past ``M``, and the keys searched
    for in the unlit starts ``lo``: its first key and the key after its last.

    The spans are in merge order; a batch is one rank.  Within a call (one scanline of one batch) ``M``, the
    largest end of the call's earlier spans (its scanline's start before the first), depends on the spans
    only, and so does what is searched for.
    """
    base = line * stride
    step_start = np.concatenate([[True], rank[1:] != rank[:-1]])
    first = step_start | np.concatenate([[True], line[1:] != line[:-1]])       # a call's first span
    call = np.cumsum(first) - 1
    lift = call * (int(key_last.max()) + 1)                # a running maximum per call, from one over all spans
    # (below zero at a call's first span, whose M is its scanline's start; arithmetic rather than np.where, whose
    # pick by a mask costs here ten times a sum)
    before = np.maximum(base, np.concatenate([[0], np.maximum.accumulate(key_last + lift)[:-1]]) - lift)
    paint_lo = np.maximum(key_first, before + 1)
    keys = np.stack([key_first, key_last + 1])
    call_base = base[first]                                # a call's scanline, searched once for all its spans
    return (np.flatnonzero(np.concatenate([step_start, [True]])), call, before, paint_lo, paint_lo <= key_last, keys,
            call_base)


def _merge_all(lo, hi, line, rank, key_first, key_last, stride):
    """MERGE, rank by rank, every call's spans with the unlit segments of its scanline.

    ``lo, hi`` are the unlit segments of all scanlines as sorted keys ``line * stride + x + 1`` (two segments
    are at least one key apart); ``line, key_first, key_last`` are the object spans (as keys) in merge order
    (:func:`_merge_order`), one batch per ``rank``: within a batch, sorted by scanline and then in walk order,
    each scanline's spans being one MERGE call.  Returns the counts of cases 1 to 8 (index 0 unused), how many
    unlit segments each span's scanline held before its call (none: a full scanline, no MERGE), the painted
    pieces ``(span, key_lo, key_hi)`` and the unlit segments left.

    A batch only searches the unlit segments and paints: with ``M`` the largest end of the earlier spans of
    the same call, span ``i`` paints its part after ``M`` on the unlit segments that reach it, and the painted
    pieces split the segments they lie in (each segment's starts and ends, sorted with the pieces' ends and
    starts, pair up, empty pairs dropped).  The two-pointer walk of Fig. 6 is then counted from the searches
    in closed form, for all batches at once: span ``i`` starts at the first unlit segment that ends after
    ``M``, passes (case 8) those that end before its start, covers (case 6, or 7 for the first when it starts
    inside it) those that end before its end, and finishes (cases 1 to 5) on the next one; a SPLIT (case 3)
    leaves one extra case 8 for the following span.
    """
    if not len(line):
        return np.zeros(9, np.int64), np.zeros(0, np.int64), None, lo, hi
    bounds, call, before, paint_lo, paints, keys, call_base = _merge_layout(line, rank, key_first, key_last, stride)
    # (counts of segments: int32 holds them, at half the memory of a group's many spans)
    found_lo, found_hi = np.empty((3, len(line)), np.int32), np.empty((4, len(line)), np.int32)
    pointer = np.empty(len(line), np.int32)
    spans, pieces_lo, pieces_hi = [], [], []
    for s in range(len(bounds) - 1):
        a, b = bounds[s], bounds[s + 1]
        on_lo, on_hi = _batch_searches(lo, hi, keys[:, a:b], paints[a:b], call[a:b], call_base, stride)
        # the first unlit segment ending after M: the one after M's own, or the scanline's first
        np.maximum(on_hi[3], np.concatenate([[0], np.maximum.accumulate(on_hi[2])[:-1]]), out=pointer[a:b])
        paint_from = np.maximum(on_hi[0], pointer[a:b])
        count = np.maximum(on_lo[0] - paint_from, 0)              # unlit segments the span paints on
        found_lo[:, a:b], found_hi[:, a:b] = on_lo, on_hi
        ends = np.cumsum(count)
        if not ends[-1]:
            continue
        span = np.repeat(np.arange(a, b), count)
        k = np.repeat(paint_from - ends + count, count) + np.arange(ends[-1])
        piece_lo, piece_hi = np.maximum(lo[k], paint_lo[span]), np.minimum(hi[k], key_last[span])
        lo = np.sort(np.concatenate([lo, piece_hi + 1]), kind="stable")
        hi = np.sort(np.concatenate([hi, piece_lo - 1]), kind="stable")
        left = lo <= hi
        lo, hi = lo[left], hi[left]
        spans.append(span)
        pieces_lo.append(piece_lo)
        pieces_hi.append(piece_hi)

    del keys
    # Per span, how many unlit segments (as its batch found them) start: at most at its end (at most at its
    # scanline's start when M covers it), before its first key, before the next scanline; and end: before its
    # first key, before its last, at most at its last, before its scanline.
    reach, starts_before, scan_end = found_lo
    first_reaching, last_reaching, last_or_before, scan_start = found_hi
    # (none passed or covered on a scanline it does not walk: pointer >= scan_end)
    walked = pointer < scan_end
    passed_to = np.minimum(np.maximum(first_reaching, pointer), scan_end)
    passed = np.maximum(passed_to - pointer, 0)
    finish = np.maximum(pointer, last_reaching)
    covered = np.minimum(finish, scan_end) - passed_to
    after_m = key_first > before + 1
    case7 = (covered > 0) & (passed_to < starts_before) & after_m     # it starts inside the first it covers
    # on the segment it finishes on: ends before it (1), or starts inside it (+1), ends at its end (+2)
    inside = after_m & (finish < starts_before)
    ends_at = finish < last_or_before
    case = 1 + ((key_last > before) & (finish < reach)) * (1 + inside + 2 * ends_at)
    case *= finish < scan_end                     # it finishes on a segment of its scanline (and so walks it)
    counts = np.bincount(case, minlength=9)
    split_before = np.concatenate([[False], (case[:-1] == 3) & (call[1:] == call[:-1])]) & walked
    counts[8] += int(passed.sum() + split_before.sum())
    counts[7] += int(case7.sum())
    counts[6] += int(covered.sum() - case7.sum())
    painted = (np.concatenate(spans), np.concatenate(pieces_lo), np.concatenate(pieces_hi)) if spans else None
    return counts, scan_end - scan_start, painted, lo, hi


def _batch_searches(lo, hi, keys, paints, call, call_base, stride):
    """Where a batch's spans fall among the unlit starts ``lo`` and ends ``hi``: in ``lo``, each span's reach (the
    key after its last when it ``paints``, else its scanline's start), its first key and its scanline's end; in
    ``hi``, its first and last keys, the key after the last and its scanline's start.

    Only ``lo`` is searched, for the ``keys`` (each span's first key and the key after its last) and, once per
    call, its scanline's bounds.  The places in ``hi`` follow: the unlit segments are at least one key apart,
    so of those that start before a key all but the last end before it too.
    """
    on_lo, on_hi = np.empty((3, len(call)), np.int64), np.empty((4, len(call)), np.int64)
    first_in, last_in = np.searchsorted(lo, keys)          # starts before the first key; at most at the last
    own = call - call[0]                                   # the batch's calls are numbered one after another
    bases = call_base[call[0]:call[-1] + 1]
    on_lo[2] = np.searchsorted(lo, bases + stride)[own]
    on_hi[3] = np.searchsorted(hi, bases)[own]
    on_lo[0] = np.where(paints, last_in, on_hi[3])         # (no segment starts on a scanline before its start)
    on_lo[1] = first_in
    if not len(hi):
        on_hi[:3] = 0
        return on_lo, on_hi
    key_first, after = keys
    on_hi[0] = first_in - ((first_in > 0) & (hi[first_in - 1] >= key_first))
    end = hi[last_in - 1]                                  # (at 0, hi[-1]: not counted)
    on_hi[1] = last_in - ((last_in > 0) & (end >= after - 1))
    on_hi[2] = last_in - ((last_in > 0) & (end >= after))
    return on_lo, on_hi


def _count_peak(stats, start, lo, call, line, span_slab, unlit_before, stride):
    """Raise ``stats["unlit_segments_peak"]`` to the most unlit segments the screen held after any slab.

    The merges ran by rank, not slab by slab, so the counts after each slab are summed from the calls: a call
    changes its scanline's count from what the scanline held before it to what it held before its next call
    (the scanline's count at the end after its last), and the screen held ``start`` segments before these slabs.
    """
    if not len(call):
        return
    calls = int(call.max()) + 1
    before = np.zeros(calls, np.int64)
    before[call] = unlit_before
    call_line = np.zeros(calls, np.int64)
    call_line[call] = line
    call_slab = np.zeros(calls, np.int64)
    call_slab[call] = span_slab
    # calls are numbered by scanline and then in reading order
    last_of_line = np.concatenate([call_line[1:] != call_line[:-1], [True]])
    after = np.concatenate([before[1:], [0]])
    ends = call_line[last_of_line]
    after[last_of_line] = np.searchsorted(lo, (ends + 1) * stride) - np.searchsorted(lo, ends * stride)
    change = np.zeros(int(call_slab.max()) + 1, np.int64)
    np.add.at(change, call_slab, after - before)
    stats["unlit_segments_peak"] = max(stats["unlit_segments_peak"], start + int(np.cumsum(change).max()))


def render_ftb(segments, view, progress=None, clip=None, items=False):
    """Front-to-back rendering with the dynamic screen, vectorised over scanlines.

    Parameters
    ----------
    segments : Segments
    view : View
        With ``scale`` set; ``gamma`` is ignored (see :func:`voxrender._render.render_preimage`).
    progress : callable, optional
    clip : Clip, optional
    items : bool
        Also return the item buffer ``(owner, boxes)``: for each pixel the index of the box
        (run) that lit it, ``-1`` for none, and per box its centre x, y, z and half-length
        in object coordinates.  :func:`voxrender._render.preimage.render_preimage` uses it to
        turn the pre-image by gamma exactly.

    Returns
    -------
    depth : ndarray of float32, (H, W)
    stats : dict
        Slices, rows and segments read; MERGE calls, segments merged and the count of each
        MERGE case; pixels lit; unlit segments at the start, at their peak (after a slice)
        and at the end; scanline merges and rows skipped because the scanline was full.

    Examples
    --------
    >>> from voxrender.object.segments import encode
    >>> from voxrender.space.view import View
    >>> depth, stats = render_ftb(encode(np.ones((2, 2, 2), bool)), View(size=(4, 4), scale=1.0))
    >>> depth[1:3, 1:3].tolist(), stats["pixels_lit"], stats["cases"]["4"]
    ([[-1.0, -1.0], [-1.0, -1.0]], 4, 2)
    """
    plan = _plan_screen(segments, view)
    height, width = view.size
    stride = width + 2
    stats = new_stats()
    depth = np.full(height * width, np.inf)
    owner_image = np.full(height * width, -1, np.int64)
    lines, first, last = _initial_unlit(plan, _object_box(segments, clip))
    screen = (lines * stride + first + 1, lines * stride + last + 1)
    stats["unlit_segments_start"] = stats["unlit_segments_peak"] = len(screen[0])
    cases = np.zeros(9, np.int64)
    boxes, boxes_before = [], 0
    # The slabs a group at a time, front to back: the dynamic screen goes on from one group to the next, so the
    # picture and the counts are those of one pass, while only one group's runs and spans are in memory.
    # The spans of a group do not depend on the screen: the next group's are found on a thread while this
    # group's are merged (NumPy lets go of Python's lock in its passes).
    bounds = _slab_groups(segments, plan)
    last_slabs = set((bounds[1:] - 1).tolist())
    groups = [slice(low, high) for low, high in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True)]
    found = _spans_ahead(segments, plan, clip, groups, stride)
    positions = range(len(plan.outer_order))
    for position in (progress(positions, len(positions), "ftb") if progress else positions):
        if position in last_slabs:
            screen, lit = _merge_slabs(next(found), plan, screen, stats, cases, depth, owner_image, boxes_before)
            boxes.append(lit)
            boxes_before += len(lit)
    stats["unlit_segments_end"] = len(screen[0])
    stats["cases"] = {str(c): int(cases[c]) for c in CASES}
    depth = depth.reshape(height, width).astype(np.float32)
    if items:
        return depth, stats, (owner_image.reshape(height, width),
                              np.concatenate(boxes) if boxes else np.zeros((0, 4)))
    return depth, stats


@dataclass
class _Spans:
    """The runs of a group of slabs and their spans on the scanlines, in merge order (:func:`_merge_order`)."""

    slab: np.ndarray          # per run: slab and row position, z, y, start and end, box centre and half-length
    row: np.ndarray
    z: np.ndarray
    y: np.ndarray
    starts: np.ndarray
    ends: np.ndarray
    xc: np.ndarray
    yc: np.ndarray
    zc: np.ndarray
    half_x: np.ndarray
    line: np.ndarray          # per span: scanline, run, MERGE call and rank, first and last key
    run: np.ndarray
    call: np.ndarray
    rank: np.ndarray
    key_first: np.ndarray
    key_last: np.ndarray


def _spans_ahead(segments, plan, clip, groups, stride):
    """The :class:`_Spans` of each group of slabs in turn, the next found on a thread while the caller merges
    this one (one group alone is found here: a thread would cost more than it saves).
    """
    if len(groups) == 1:
        yield _slab_spans(segments, plan, clip, groups[0], stride)
        return
    with ThreadPoolExecutor(1) as ahead:
        coming = ahead.submit(_slab_spans, segments, plan, clip, groups[0], stride)
        for following in groups[1:]:
            spans = coming.result()
            coming = ahead.submit(_slab_spans, segments, plan, clip, following, stride)
            yield spans
        yield coming.result()


def _slab_spans(segments, plan, clip, outer, stride):
    """The :class:`_Spans` of the slabs ``plan.outer_order[outer]``: what merging them needs that does not depend
    on the dynamic screen.
    """
    slab, row, z, y, starts, ends = _front_to_back_runs(segments, plan, clip, outer)
    xc, yc, zc, half_x = plan.centres(z, y, starts, ends)
    # A row's runs share their Y' (the view turns by alpha and beta alone): the scanlines they cross, and how far
    # their cross-section reaches on each, are found once per row.
    row_first = np.flatnonzero(np.concatenate([[True], row[1:] != row[:-1]])) if len(row) else row
    line_first, line_last = plan.scanlines(yc[row_first])
    lines = np.maximum(line_last - line_first + 1, 0)
    row_line, row_of = ranges(line_first, lines, owners=True)     # the calls (row, scanline), in reading order
    left, right, empty = plan.reach(row_line, yc[row_first][row_of])
    runs_of_row = np.diff(np.append(row_first, len(row)))
    # the spans call by call: a row's runs on each of its scanlines in turn
    run, call = ranges(row_first[row_of], runs_of_row[row_of], owners=True)
    span_first, span_last = plan.columns(xc[run], half_x[run], left[call], right[call], empty[call])
    keep = span_first <= span_last
    run, call, span_first, span_last = run[keep], call[keep], span_first[keep], span_last[keep]
    counts = np.bincount(call, minlength=len(row_line))
    made = counts > 0                                    # a call whose spans all miss the pixels is not made
    order, line, call, rank = _merge_order(row_line[made], counts[made])
    run, span_first, span_last = run[order], span_first[order], span_last[order]
    if not _in_walk_order(span_first, call):
        order = _stable_order(rank, line, span_first)
        line, run, call, rank, span_first, span_last = (a[order] for a in (line, run, call, rank, span_first,
                                                                            span_last))
    key_first, key_last = line * stride + span_first + 1, line * stride + span_last + 1
    return _Spans(slab, row, z, y, starts, ends, xc, yc, zc, half_x, line, run, call, rank, key_first, key_last)


def _merge_slabs(spans, plan, screen, stats, cases, depth, owner_image, boxes_before):
    """Merge the runs of a group of slabs (their :class:`_Spans`) into the dynamic screen ``(lo, hi)``, front to
    back, painting ``depth`` and ``owner_image`` and adding to ``stats`` and ``cases``.  Returns the screen left
    and the boxes (centre x, y, z and half-length) of the runs that lit pixels, numbered in ``owner_image`` from
    ``boxes_before`` on.
    """
    lo, hi = screen
    width = plan.size[1]
    stride = width + 2
    slab, row, z, y, starts, ends = spans.slab, spans.row, spans.z, spans.y, spans.starts, spans.ends
    xc, yc, zc, half_x = spans.xc, spans.yc, spans.zc, spans.half_x
    line, run, call, rank = spans.line, spans.run, spans.call, spans.rank
    key_first, key_last = spans.key_first, spans.key_last
    stats["slices_read"] += _distinct_count(slab)          # both come in order: count their changes
    stats["rows_read"] += _distinct_count(row)
    stats["segments_read"] += len(starts)
    unlit_start = len(lo)
    counts, unlit_before, painted, lo, hi = _merge_all(lo, hi, line, rank, key_first, key_last, stride)
    cases += counts
    span_full = unlit_before == 0
    _count_peak(stats, unlit_start, lo, call, line, slab[run], unlit_before, stride)

    # Every lit pixel was painted once; its depth is where its ray enters the box of the span that lit it.
    lit_runs = np.zeros(0, np.int64)
    if painted is not None:
        painted_spans, piece_lo, piece_hi = painted
        keys, piece = ranges(piece_lo, piece_hi - piece_lo + 1, owners=True)
        owner = painted_spans[piece]
        pixel_line, r = line[owner], run[owner]
        walk_x = keys - pixel_line * stride - 1
        pixels = pixel_line * width + plan.column(walk_x)
        depth[pixels] = plan.depth(pixel_line, walk_x, xc[r], yc[r], zc[r], half_x[r])
        lit_runs, numbers = np.unique(r, return_inverse=True)      # the item buffer keeps only the runs that lit
        owner_image[pixels] = boxes_before + numbers
        stats["pixels_lit"] += len(keys)

    # A call is merged unless its scanline was full; a row is skipped when all its calls were.
    merged = ~span_full
    stats["segments_merged"] += int(merged.sum())
    call_full = np.zeros(int(call.max()) + 1 if len(call) else 0, bool)
    call_full[call[span_full]] = True
    call_row = np.zeros(len(call_full), np.int64)
    call_row[call] = row[run]
    stats["merge_calls"] += len(call_full) - int(call_full.sum())
    stats["scanlines_skipped_full"] += int(call_full.sum())
    calls_per_row = np.bincount(call_row)
    full_per_row = np.bincount(call_row[call_full], minlength=len(calls_per_row))
    stats["rows_skipped_full"] += int(((calls_per_row > 0) & (full_per_row == calls_per_row)).sum())
    boxes = np.stack([(starts[lit_runs] + ends[lit_runs]) / 2, y[lit_runs], z[lit_runs], half_x[lit_runs]], axis=1)
    return (lo, hi), boxes.astype(float)
