"""Preprocessing (the paper's section 7): subregioning, interpolation to cubic voxels, thresholding.

:func:`binarize` runs the three steps slice by slice, so that only the binary
mask (one byte a voxel) and two interpolated slices are held besides the input.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._shared import label_sets
from ..errors import InputError
from .slabs import blocks, kept_parts, kept_range, resample_slices, resampled_shape


@dataclass(frozen=True)
class Interval:
    """An interval of values (a CT tissue's HU window): the object is ``lo <= value <= hi``; ``None`` leaves a side
    open. What a picture's grey values are shown through is :class:`voxrender.pictures.display.DisplayWindow`.

    >>> Interval(-100, 300).select(np.array([-200, 0, 300, 400])).tolist()
    [False, True, True, False]
    """

    lo: float | None = None
    hi: float | None = None

    def __post_init__(self):
        for bound in (self.lo, self.hi):
            if bound is not None and not math.isfinite(bound):
                raise InputError(f"{bound} must be a finite number (in stored units, HU for CT)",
                                 parameter="threshold")
        if self.lo is None and self.hi is None:
            raise InputError("a window needs at least one bound, as in 300: or :1000 or 300:1000",
                             parameter="threshold")
        if None not in (self.lo, self.hi) and self.lo > self.hi:
            raise InputError(f"window {self.lo:g}:{self.hi:g} is empty: lo is above hi; give lo:hi with lo <= hi",
                             parameter="threshold")

    def select(self, values, out=None):
        """``lo <= values <= hi`` as a bool array (into ``out`` when given)."""
        inside = np.ones(np.shape(values), bool) if out is None else out
        lo, hi = self._bounds_for(np.asarray(values).dtype)
        if lo is not None:
            np.greater_equal(values, lo, out=inside)
        else:
            inside[...] = True
        if hi is not None:
            inside &= np.less_equal(values, hi)
        return inside

    def _bounds_for(self, dtype):
        """The bounds, for values of ``dtype``: integers are compared with whole bounds of their own type (the
        same answer, without a float copy of every value), a bound beyond the type's range dropped or made one
        that no value passes.
        """
        if dtype.kind not in "iu":
            return self.lo, self.hi
        info = np.iinfo(dtype)
        lo = None if self.lo is None or self.lo <= info.min else math.ceil(self.lo)
        hi = None if self.hi is None or self.hi >= info.max else math.floor(self.hi)
        if (lo is not None and lo > info.max) or (hi is not None and hi < info.min):
            return dtype.type(info.max), dtype.type(info.min)            # lo above hi: none
        return (None if lo is None else dtype.type(lo)), (None if hi is None else dtype.type(hi))

    def __str__(self):
        return f"{'' if self.lo is None else f'{self.lo:g}'}:{'' if self.hi is None else f'{self.hi:g}'}"

    def words(self):
        """The window in words, for messages.

        >>> Interval(300).words(), Interval(-100, 300).words(), Interval(None, 0).words()
        ('300 and above', '-100 to 300', '0 and below')
        """
        if self.hi is None:
            return f"{self.lo:g} and above"
        return f"{self.hi:g} and below" if self.lo is None else f"{self.lo:g} to {self.hi:g}"


def crop(values, region=None):
    """The subregion ``values[region]`` (a view, no copy), after checking that it lies in the volume.

    Parameters
    ----------
    values : ndarray ``[z, y, x]``
    region : tuple of 3 slices, optional
        ``(z, y, x)`` ranges in voxel indices, end excluded; ``slice(None)`` keeps an axis whole.

    Examples
    --------
    >>> crop(np.zeros((4, 5, 6)), (slice(None), slice(None), slice(1, 3))).shape
    (4, 5, 2)
    """
    if region is None:
        return values
    if len(region) != 3 or not all(isinstance(r, slice) and r.step in (None, 1) for r in region):
        raise InputError(f"{region!r} must be three slices (z, y, x) without steps", parameter="crop")
    for axis, part, n in zip("zyx", region, values.shape, strict=True):
        lo = 0 if part.start is None else part.start
        hi = n if part.stop is None else part.stop
        if not 0 <= lo < hi <= n:
            raise InputError(f"{axis} range {lo}:{hi} is outside the volume's {axis} range 0:{n}", parameter="crop")
    return values[tuple(region)]


def resample(values, spacing, voxel):
    """``values`` resampled to cubic voxels of ``voxel`` mm, as one float32 array.

    >>> resample(np.arange(8.0).reshape(2, 2, 2), (1, 1, 2), 1).shape
    (3, 2, 2)
    """
    return np.stack(list(resample_slices(values, spacing, voxel)))


def otsu_threshold(values, padding=None):
    """Otsu's threshold of ``values`` (from a 1024-bin histogram, so large volumes stay fast).

    NaN and inf voxels are left out, and so is ``padding``: the value a CT stores outside its scan circle
    (see :func:`padding_value`), which would otherwise be the threshold's lower class.

    >>> float(otsu_threshold(np.array([0, 0, 0, 10, 10, 10]))) > 0
    True
    >>> float(otsu_threshold(np.array([-3024, -3024, -1000, -1000, 40, 40]), padding=-3024)) > -1000
    True
    """
    values = np.asarray(values)
    low, high, whole = kept_range(values, padding)
    check_range(low, high, padding)
    edges = otsu_bins(low, high, values.dtype)
    if whole:                                   # every value counts: one histogram, no copy
        counts = np.histogram(values, bins=edges)[0]
    else:
        counts = sum(np.histogram(part, bins=edges)[0] for part in kept_parts(values, padding))
    return otsu_of_histogram(counts, edges)


def otsu_bins(low, high, dtype):
    """The edges of the 1024 bins :func:`otsu_threshold` counts values of ``dtype`` in, from the lowest to the
    highest: of the type NumPy would give them for such values (float32 for float32 values), so that values
    counted a slab at a time fall in the same bins.
    """
    return np.histogram_bin_edges(np.zeros(0, dtype), bins=1024, range=(low, high))


def otsu_of_histogram(counts, edges):
    """Otsu's threshold of the values counted in bins (:func:`otsu_bins`): :func:`otsu_threshold` of values that
    were counted a slab at a time.

    >>> otsu_of_histogram(np.array([3, 0, 0, 3]), np.array([0.0, 2.5, 5.0, 7.5, 10.0]))
    5.0
    """
    from skimage.filters import threshold_otsu

    centres = (edges[:-1] + edges[1:]) / 2
    threshold = float(threshold_otsu(hist=(counts, centres)))
    # Between two separated classes every empty bin splits them equally well; take the middle of the gap.
    occupied = centres[counts > 0]
    below, above = occupied[occupied <= threshold], occupied[occupied > threshold]
    return float((below[-1] + above[0]) / 2) if len(below) and len(above) else threshold


def check_range(low, high, padding=None):
    """Refuse values between ``low`` and ``high`` (:func:`value_range`) that hold no threshold to find."""
    besides = "" if padding is None else f" (besides the padding, {padding:g})"
    if low is None:
        raise InputError(f"every value is NaN or infinite{besides}, so there is nothing to threshold")
    if low == high:
        raise InputError(f"every value is {low:g}{besides}, so there is no threshold to find; give one at or below "
                         f"{low:g} to keep every voxel")


def value_range(values, padding=None):
    """The lowest and highest of ``values`` leaving out NaN, inf and ``padding``; ``(None, None)`` when none is left.

    >>> value_range(np.array([np.nan, -3024, -1000, 40, np.inf]), padding=-3024)
    (-1000.0, 40.0)
    """
    return kept_range(np.asarray(values), padding)[:2]


def non_finite_counts(values):
    """How many voxels are NaN and how many infinite: ``{"nan": n, "inf": m}``, empty when there are none.

    >>> non_finite_counts(np.array([1.0, np.nan, np.inf, -np.inf]))
    {'nan': 1, 'inf': 2}
    """
    values = np.asarray(values)
    if values.dtype.kind not in "fc" or kept_range(values, None)[2]:
        return {}
    nan = sum(int(np.count_nonzero(np.isnan(part))) for part in blocks(values))
    inf = sum(int(np.count_nonzero(np.isinf(part))) for part in blocks(values))
    return {key: count for key, count in (("nan", nan), ("inf", inf)) if count}


def padding_value(volume):
    """The value a CT stores outside its scan circle, to leave out of thresholds found from the values; ``None``
    when there is none.

    The DICOM PixelPaddingValue when the reader found one (``meta["padding_value"]``, in the volume's units);
    else, for a CT in HU, its lowest value when that is at or below -1024 HU, fills the corners of the slices
    outside the scan circle and is rare inside it (air clipped at -1024 HU is everywhere around the patient).

    >>> from voxrender.io import Volume
    >>> yy, xx = np.mgrid[:32, :32]
    >>> slice_ = np.where(np.hypot(yy - 15.5, xx - 15.5) < 16, -1000, -3024)
    >>> padding_value(Volume(np.stack([slice_] * 4), meta={"units": "HU"}))
    -3024.0
    """
    known = volume.meta.get("padding_value")
    if known is not None:
        return float(known)
    if volume.meta.get("units") != "HU" or volume.values.ndim != 3 or min(volume.shape[1:]) < 8:
        return None
    nz, ny, nx = volume.shape
    sample = np.asarray(volume.values[::max(1, nz // 8)])            # a few slices tell
    low = float(np.min(sample))
    if not low <= -1024:
        return None
    yy, xx = np.ogrid[:ny, :nx]
    radius = np.hypot((yy - (ny - 1) / 2) / (ny / 2), (xx - (nx - 1) / 2) / (nx / 2))  # 1 on the inscribed circle
    outside, inside = sample[:, radius > 1.02], sample[:, radius < 0.9]
    fills_outside = outside.size and np.all(outside == low)
    return low if fills_outside and np.mean(inside == low) < 0.05 else None


def _nothing_selected(volume, values, what, parameter):
    """The error for a selection (``what``, in words) that holds no voxel: with the range the values do hold, so
    that the fix is in sight, or, when none is a number, the input's fault and nothing a selection could mend.
    """
    low, high = value_range(values)
    source = volume.meta.get("source", "the volume")
    if low is None:
        return InputError(f"{source}: every voxel is NaN or infinite, so no threshold or window selects an object")
    return InputError(f"{what} holds no voxel of {source}, whose values range from {low:g} to {high:g}; choose a "
                      "threshold or window in that range", parameter=parameter)


def bin_slices(values, n):
    """The mean of every ``n`` x ``n`` x ``n`` block of ``values`` ``[z, y, x]`` (float32), one binned slice at a
    time, so that a slab binned alone gives the slices the whole volume would (a remainder of fewer than ``n``
    voxels along an axis is dropped).

    >>> bin_slices(np.arange(16.0).reshape(2, 2, 4), 2).tolist()
    [[[6.5, 8.5]]]
    """
    nz, ny, nx = (size // n for size in values.shape)
    out = np.empty((nz, ny, nx), np.float32)
    for k in range(nz):
        block = np.asarray(values[k * n:(k + 1) * n, :ny * n, :nx * n])
        wide = np.int64 if block.dtype.kind in "uib" else np.float64       # integers sum exactly
        out[k] = block.reshape(n, ny, n, nx, n).sum(axis=(0, 2, 4), dtype=wide) / n ** 3
    return out


def binned(volume, n, region=None):
    """The ``volume`` cropped to ``region`` and binned by ``n`` (:func:`bin_slices`), with its spacing scaled: a
    preview of a stack too large to render at its own resolution.

    >>> from voxrender.io import Volume
    >>> v = binned(Volume(np.ones((4, 6, 8), np.uint16), (0.5, 0.5, 1.0)), 2)
    >>> v.shape, v.spacing
    ((2, 3, 4), (1.0, 1.0, 2.0))
    """
    from dataclasses import replace

    check_bin(n, crop(volume.values, region).shape)
    values = bin_slices(crop(volume.values, region), n)
    return replace(volume, values=values, spacing=tuple(float(s) * n for s in volume.spacing),
                   meta={**volume.meta, "binned": n})


def check_bin(n, shape):
    """Refuse a binning factor that is not a whole number from 1, or that leaves no voxel of ``shape``."""
    if not (isinstance(n, (int, np.integer)) and n >= 1):
        raise InputError(f"{n!r} must be a whole number of voxels, 1 or more", parameter="bin")
    if min(shape) < n:
        raise InputError(f"binning by {n} leaves no voxel of a volume {' x '.join(map(str, shape[::-1]))} voxels "
                         "(x, y, z) large; bin by less", parameter="bin")


_crop = crop  # binarize's parameter of the same name hides the function


def binarize(volume, threshold=otsu_threshold, *, crop=None, voxel=None, resample=True, min_object=0, progress=None):
    """Crop, resample to cubic voxels, and threshold a :class:`~voxrender.io.Volume`.

    Parameters
    ----------
    volume : Volume
    threshold : float, Interval or callable
        Voxels with value ``>= threshold`` (stored units) belong to the object, or those inside a
        :class:`Interval`; a callable is given the (cropped) values and returns the threshold, like the
        default :func:`otsu_threshold` (which also leaves out a CT's padding, :func:`padding_value`).
        NaN and inf voxels never belong to the object.
    crop : tuple of 3 slices, optional
        The ``(z, y, x)`` subregion in input voxel indices (see :func:`crop`).
    voxel : float, optional
        Size of the cubic voxels in mm (default: the smallest spacing).
    resample : bool
        ``False`` keeps the input grid (voxels are then treated as cubes).
    min_object : int
        Connected (26-neighbour) pieces with fewer voxels are dropped.

    Returns
    -------
    mask : ndarray of bool, ``[z, y, x]``
    info : dict
        ``threshold`` (the number used, or the window as text), ``voxel`` (mm), ``spacing`` of the mask.

    Examples
    --------
    >>> from voxrender.io import Volume
    >>> values = np.zeros((5, 4, 4)); values[1:4, 1:3, 1:3] = 100
    >>> mask, info = binarize(Volume(values, (1, 1, 2)), 50)
    >>> mask.shape, int(mask.sum()), info["voxel"]
    ((9, 4, 4), 28, 1.0)
    """
    values = _crop(volume.values, crop)
    if threshold is otsu_threshold:
        try:
            threshold = otsu_threshold(values, padding_value(volume))
        except InputError as exc:                      # a constant or all-NaN input: name it
            raise InputError(f"{volume.meta.get('source', 'the volume')}: {exc.message}", exc.parameter) from None
    elif callable(threshold):
        threshold = threshold(values)
    window = threshold if isinstance(threshold, Interval) else Interval(float(threshold))
    mask, voxel, spacing = _windowed(values, volume.spacing, [window], voxel, resample, progress)
    mask = mask.view(bool)                                  # one window: 0 and 1
    if min_object > 1:
        from skimage.morphology import remove_small_objects

        mask = remove_small_objects(mask, max_size=int(min_object) - 1, connectivity=3)
    if not mask.any():
        raise _nothing_selected(volume, values, f"the window {window.words()}" if isinstance(threshold, Interval)
                                else f"the threshold {window.lo:g}", "threshold")
    return mask, {"threshold": str(threshold) if isinstance(threshold, Interval) else window.lo, "voxel": voxel,
                  "spacing": spacing}


def classify(volume, windows, *, crop=None, voxel=None, resample=True, progress=None):
    """Label each voxel by the value windows that hold it: the number (1, 2, ...) of the last of ``windows`` that
    does, 0 for none; cropped and resampled as :func:`binarize` does.  Several tissues of one CT in one object
    (skin and bone: bone, given last, wins where both windows hold a voxel).

    Returns
    -------
    labels : ndarray of uint8, ``[z, y, x]``
    info : dict
        ``threshold`` (the windows as text), ``voxel`` (mm), ``spacing``.

    Examples
    --------
    >>> from voxrender.io import Volume
    >>> labels, info = classify(Volume(np.array([[[-1000, 0, 500]]]), (1, 1, 1)), [Interval(-300), Interval(300)])
    >>> labels.tolist(), info["threshold"]
    ([[[0, 1, 2]]], '-300:, 300:')
    """
    values = _crop(volume.values, crop)
    labels, voxel, spacing = _windowed(values, volume.spacing, windows, voxel, resample, progress)
    if not labels.any():
        raise _nothing_selected(volume, values, "none of the windows " + ", ".join(w.words() for w in windows),
                                "preset")
    return labels, {"threshold": ", ".join(str(w) for w in windows), "voxel": voxel, "spacing": spacing}


def _windowed(values, spacing, windows, voxel, resample, progress):
    """The number (1, 2, ...) of the last of ``windows`` holding each voxel, 0 for none (uint8), on the grid the
    object is made on, slice by slice: resampled to cubic voxels, or the input's own.  Returns it with the voxel
    size and the spacing of that grid.
    """
    voxel, out_shape = cubic_grid(values.shape, spacing, voxel, resample)
    planes = resample_slices(values, spacing, voxel, progress) if out_shape is not None else values
    labels = np.empty(out_shape or values.shape, np.uint8)
    every_value_finite = values.dtype.kind not in "fc" or kept_range(values, None)[2]
    for layer, plane in zip(labels, planes, strict=True):
        select_layer(plane, windows, layer, every_value_finite)
    return labels, voxel, (voxel,) * 3 if out_shape is not None else tuple(float(s) for s in spacing)


def select_layer(plane, windows, layer, every_value_finite=False):
    """Write into ``layer`` (uint8) the number (1, 2, ...) of the last of ``windows`` holding each value of
    ``plane``, 0 for none: one slice of the object's grid.
    """
    windows[0].select(plane, out=layer.view(bool))     # writes 0 and 1
    for number, window in enumerate(windows[1:], 2):
        layer[window.select(plane)] = number
    # NaN is in no window, but inf is in an open one (and resampling spreads both): such voxels are outside
    if not every_value_finite and plane.dtype.kind in "fc":
        layer[~np.isfinite(plane)] = 0


def cubic_grid(shape, spacing, voxel, resample):
    """The cubic voxel size (mm) and the shape of the resampled grid (``None`` when the input grid is kept)."""
    if voxel is not None and not (voxel > 0 and math.isfinite(voxel)):
        raise InputError(f"{voxel} must be a positive size in mm", parameter="voxel")
    voxel = float(voxel or min(spacing))
    if not resample or all(math.isclose(s, voxel) for s in spacing):
        return voxel, None
    counts = [(n - 1) * s / voxel + 1 for n, s in zip(shape, spacing[::-1], strict=True)]  # floats: no overflow
    if not all(math.isfinite(c) for c in counts) or math.prod(counts) > 4e9:
        raise InputError(f"the voxel spacing {tuple(spacing)} mm, resampled to cubic {voxel:g} mm voxels, would give "
                         f"{' x '.join(f'{c:.3g}' for c in counts[::-1])} voxels; check the spacing, or choose a "
                         "larger voxel or crop a subregion", parameter="voxel")
    return voxel, resampled_shape(shape, spacing, voxel)


@dataclass(frozen=True)
class LabelSelection:
    """Which labels of a label map make the object.

    Parameters
    ----------
    chosen : tuple of int, optional
        The labels to keep (default: every non-zero label).
    separate : bool
        Each label an object of its own (a multi-label picture), or all chosen labels one object.
    source : path, optional
        A label map paired with the input (a CT and its segmentation); default: the input is the label map.
    envelopes : bool
        When every label is drawn (``chosen`` None), draw the patient's outline too: an RTSTRUCT ROI of type
        EXTERNAL, or a structure named BODY or External (:func:`voxrender._shared.label_sets.envelopes`).  It is
        left out by default, since its surface hides every structure inside it; it stays in slices and counts.
    """

    chosen: tuple | None = None
    separate: bool = True
    source: object = None
    envelopes: bool = False

    def __post_init__(self):
        if self.chosen is not None:
            if not self.chosen or not all(isinstance(v, (int, np.integer)) and 0 < v < 65536 for v in self.chosen):
                raise InputError(f"{self.chosen!r}: labels are whole numbers from 1 to 65535", parameter="label")


def label_map(volume, selection=None, *, crop=None, voxel=None, resample=True):
    """The chosen labels of a label map, cropped and resampled (nearest neighbour) to cubic voxels.

    Parameters
    ----------
    volume : Volume
        Integer labels, 0 for the background; where structures share voxels, the codes of
        ``meta["label_sets"]`` (:mod:`voxrender._shared.label_sets`): a shared voxel takes the most specific of
        the chosen structures it is in, and each structure's voxels are its own.
    selection : LabelSelection, optional
    crop, voxel, resample
        As for :func:`binarize`, so that a label map and its CT give the same grid.

    Returns
    -------
    labels : ndarray of uint16, ``[z, y, x]``
        The chosen labels; 0 elsewhere (and everywhere, with ``separate=False``, the object is ``labels > 0``).
    info : dict
        ``labels`` (the chosen labels present), ``voxels`` (``{label: count}`` of the chosen labels, and of those
        set aside, in the cropped map, before resampling), ``voxel`` (mm), ``spacing``, ``set_aside`` (the labels of
        the patient's outline left out of the object, still counted; see ``LabelSelection.envelopes``).

    Examples
    --------
    >>> from voxrender.io import Volume
    >>> values = np.zeros((2, 3, 3), np.int16); values[:, 1, 1] = 7; values[:, 2, 2] = 9
    >>> labels, info = label_map(Volume(values, (1, 1, 1)), LabelSelection(chosen=(9,)))
    >>> int(labels.sum()), info["labels"]
    (18, [9])
    """
    selection = selection or LabelSelection()
    values = _crop(volume.values, crop)
    source = volume.meta.get("source", "the label map")
    check_labels(values, source)
    sets = volume.meta.get("label_sets") or {}                            # structures that share voxels
    counts = label_counts(values, sets)                                   # each structure's own voxels
    chosen = chosen_labels(counts, selection.chosen, source, crop is not None)
    aside = []
    if selection.chosen is None and not selection.envelopes:
        aside = [label for label in label_sets.envelopes(volume.meta) if label in counts]
        if len(aside) < len(chosen):                    # an outline alone is still drawn
            chosen = np.setdiff1d(chosen, aside)
        else:
            aside = []
    voxel, out_shape = cubic_grid(values.shape, volume.spacing, voxel, resample)
    spacing = tuple(float(s) for s in volume.spacing)
    if out_shape is not None:
        # the input voxel nearest each grid point (labels cannot be interpolated)
        nearest = [np.minimum(np.rint(np.arange(n) * voxel / s).astype(np.int64), m - 1)
                   for n, s, m in zip(out_shape, spacing[::-1], values.shape, strict=True)]
        values = np.asarray(values)[np.ix_(*nearest)]
        spacing = (voxel, voxel, voxel)
    labels = label_sets.resolve(values, sets, chosen.tolist())
    if not labels.any():
        raise InputError("the chosen labels vanish at this voxel size; choose a smaller one", parameter="voxel")
    counted = sorted([*chosen.tolist(), *aside])
    return labels, {"labels": [int(v) for v in chosen], "voxels": {int(v): counts[int(v)] for v in counted},
                    "voxel": voxel, "spacing": spacing, "set_aside": aside}


def chosen_labels(counts, chosen, source="the label map", cropped=False):
    """The labels chosen of a label map that holds ``counts`` (``{label: voxels}``, :func:`label_counts`), all of
    them when ``chosen`` is ``None``, as a sorted array; an :class:`InputError` when it holds none, or not one of
    those chosen.

    >>> chosen_labels({3: 10, 7: 2}, None).tolist(), chosen_labels({3: 10, 7: 2}, (7,)).tolist()
    ([3, 7], [7])
    """
    present = np.asarray(sorted(counts), np.int64)
    if not len(present):
        raise InputError(f"{source} holds no label: every voxel is 0 (background)"
                         + (" in the crop" if cropped else ""))
    chosen = present if chosen is None else np.asarray(sorted(set(chosen)))
    missing = np.setdiff1d(chosen, present)
    if len(missing):
        shown = ", ".join(str(v) for v in present[:30]) + (" ..." if len(present) > 30 else "")
        raise InputError(f"label {', '.join(str(v) for v in missing)} is not in {source}"
                         + (" within the crop" if cropped else "") + f"; it holds {shown}", parameter="label")
    return chosen


def label_counts(values, sets=None):
    """The voxels of each label of a label map, ``{label: count}`` for the labels above 0 that it holds; a few
    slices at a time, so that a whole-body map is counted without an int64 copy of it.  With ``sets`` (a reader's
    ``meta["label_sets"]``: structures that share voxels), each structure's own voxels.

    >>> label_counts(np.array([[[0, 3, 3], [7, 0, 3]]], np.uint8))
    {3: 3, 7: 1}
    >>> label_counts(np.array([[[0, 3, 3], [7, 0, 3]]], np.uint8), {"7": [2, 3]})
    {2: 1, 3: 4}
    """
    counts = label_sets.code_counts(values)
    return label_sets.structure_counts(values, sets, counts) if sets else counts


def check_labels(values, source="the label map"):
    """Refuse values that are not a label map (non-integers, negatives, labels above 65535), naming ``source``: the
    file is at fault, not a label the user chose.
    """
    values = np.asarray(values)
    if values.dtype.kind == "f":
        fractional = values[~(values == np.round(values))]           # NaN and inf too
        if fractional.size:
            raise InputError(f"{source} is not a label map: it holds non-integer values such as "
                             f"{fractional.flat[0]:g}; give a label map (whole numbers), or select grey values by a "
                             "threshold")
    elif values.dtype.kind not in "uib":
        raise InputError(f"{source} is not a label map: a label map holds whole numbers, not {values.dtype}")
    if values.size and (np.min(values) < 0 or np.max(values) > 65535):
        raise InputError(f"{source} is not a label map: labels lie in 0..65535, but its values run from "
                         f"{np.min(values):g} to {np.max(values):g}; if it is an image, select by a threshold, or "
                         "pair it with its label map")
