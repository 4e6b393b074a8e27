"""One call from a scan (a path or an array) to a shaded picture, for notebooks and scripts."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ._render import DEFAULT_METHOD
from .errors import InputError
from .io import Volume, check_spacing, real_numbers
from .object.pipeline import AUTO, PrepOptions, ReadOptions, encode_volume, load_segments
from .object.prep import LabelSelection
from .pictures import RenderOptions, picture
from .space.view import PRESETS, View


def snapshot(source, *, threshold=None, view="anterior", labels=None, spacing=None, size=(512, 512), scale=None,
             method=DEFAULT_METHOD, **options):
    """Render the object in ``source`` and shade it: the whole command line's ``render`` in one call.

    Parameters
    ----------
    source : str, Path, ndarray or Volume
        What ``voxrender render`` reads (a folder of slices or DICOM files, a volume file, a ``.vxs``), or the
        grey values ``[z, y, x]`` themselves (a bool array is the object).  An array or ``Volume`` is taken in its
        stored order, as the canonical patient frame (x toward the patient's left, y toward the back, z up).
    threshold : float, Interval or callable, optional
        The grey values of the object: ``value >= threshold``, a :class:`~voxrender.object.prep.Interval`, or a function
        of the values (default: Otsu's threshold, :func:`~voxrender.object.prep.otsu_threshold`).  With ``labels`` it
        applies only when given.
    view : str, (alpha, beta, gamma) or View
        A named view (``"anterior"``, ``"left"``, ... see :data:`voxrender.space.view.PRESETS`), the rotation angles
        in degrees, or a :class:`~voxrender.space.view.View` (its size and scale then hold).
    labels : True, sequence of int, str, Path, ndarray or Volume, optional
        ``True``: ``source`` is a label map, each label drawn in its colour; a sequence of labels: only those;
        a path, array or ``Volume``: a label map on ``source``'s grid, drawn in colour (a CT and its
        segmentation).
    spacing : 3 floats, optional
        Voxel spacing (x, y, z) in mm: of an array (default 1 mm), or instead of what a file's header says.
    size : (H, W)
        Picture size in pixels.
    scale : float, optional
        Pixels per voxel (default: the object fills the picture).
    method : str
        A renderer of :data:`voxrender.METHODS`.
    **options
        Further fields of :class:`~voxrender.pictures._picture.RenderOptions` (``shading``, ``colour``, ``legend``,
        ``clip``, ``orientation_marks`` ...).

    Returns
    -------
    ndarray of uint8, (H, W, 3)
        The picture, RGB.

    Examples
    --------
    >>> zz, yy, xx = np.mgrid[:24, :24, :24]
    >>> ball = (xx - 11.5) ** 2 + (yy - 11.5) ** 2 + (zz - 11.5) ** 2 <= 81
    >>> rgb = snapshot(ball, size=(64, 64))
    >>> rgb.shape, rgb.dtype, bool(rgb[32, 32].any()), bool(rgb[0, 0].any())
    ((64, 64, 3), dtype('uint8'), True, False)
    """
    alpha, beta, gamma, size, scale = _view(view, size, scale)
    render_options = RenderOptions(method=method, size=size, scale=scale, **options)
    selection = _labels(labels, spacing)
    if threshold is None:                             # a mask is its ones; else PrepOptions decides (Otsu's)
        threshold = 1 if selection is None and getattr(source, "dtype", None) == np.bool_ else AUTO
    prepare = PrepOptions(threshold=threshold, labels=selection)
    if isinstance(source, (str, Path)):
        read = ReadOptions(spacing=None if spacing is None else check_spacing(spacing))
        segments = load_segments(source, read, prepare).segments
    else:
        segments = encode_volume(_volume(source, spacing, "source"), prepare)
    return picture(segments, render_options.view(alpha, beta, gamma), render_options).rgb


def _view(view, size, scale):
    """The angles, size and scale of a named view, three angles or a :class:`View`."""
    if isinstance(view, View):
        return view.alpha, view.beta, view.gamma, view.size, view.scale
    if isinstance(view, str):
        if view not in PRESETS:
            raise InputError(f"unknown view {view!r}; choose one of {', '.join(PRESETS)}", parameter="view")
        return (*PRESETS[view], tuple(size), scale)
    angles = tuple(float(a) for a in np.ravel(view))
    if len(angles) != 3:
        raise InputError(f"{view!r}: give a named view or three angles (alpha, beta, gamma)", parameter="view")
    return (*angles, tuple(size), scale)


def _volume(values, spacing, parameter):
    """A :class:`Volume` of an array (a bool mask becomes 0 and 1), or the ``Volume`` given."""
    if isinstance(values, Volume):
        return values
    values = np.asarray(values)
    if values.ndim != 3:
        raise InputError(f"an array of shape {values.shape}: give a 3-D array [z, y, x]", parameter=parameter)
    values = real_numbers(values, f"the {parameter} array")
    return Volume(values, check_spacing(spacing) if spacing is not None else (1.0, 1.0, 1.0),
                  {"source": f"an array {values.shape[::-1]} (x, y, z)"})


def _labels(labels, spacing):
    """The :class:`LabelSelection` that ``snapshot``'s ``labels`` means."""
    if labels is None or labels is False:
        return None
    if labels is True:
        return LabelSelection()
    if isinstance(labels, (str, Path)):
        return LabelSelection(source=Path(labels))
    if isinstance(labels, Volume) or np.ndim(labels) == 3:
        return LabelSelection(source=_volume(labels, spacing, "labels"))
    return LabelSelection(tuple(int(v) for v in np.ravel(labels)))
