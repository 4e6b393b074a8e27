"""Comparing two pictures, for golden-image tests (``voxrender compare``, and this project's own tests)."""

from __future__ import annotations

import numpy as np

from ..errors import InputError


def read_picture(path):
    """An image file as an array, or one clean error."""
    import imageio.v3 as iio

    try:
        return iio.imread(path)
    except Exception as exc:  # imageio raises many types for a missing or damaged file
        raise InputError(f"cannot read the picture {path}: {str(exc).splitlines()[0] if str(exc) else exc}") from None


def compare(picture, golden, tolerance=1, share=0.001):
    """How two pictures of one size differ.

    Parameters
    ----------
    picture, golden : ndarray (H, W) or (H, W, C)
    tolerance : int
        Grey levels a pixel may be off (in its most different channel) and still count as equal.
    share : float
        The share of pixels that may be off by more than ``tolerance``.

    Returns
    -------
    dict
        ``mean_difference`` (mean absolute difference over all values), ``largest`` (grey levels),
        ``share_off`` (pixels off by more than ``tolerance``) and ``same`` (``share_off <= share``).

    Examples
    --------
    >>> a = np.zeros((10, 10), np.uint8); b = a.copy(); b[0, 0] = 5
    >>> result = compare(b, a, tolerance=1, share=0.001)
    >>> result["largest"], result["share_off"], result["same"]
    (5, 0.01, False)
    """
    picture, golden = np.asarray(picture), np.asarray(golden)
    if picture.shape != golden.shape:
        raise InputError(f"the pictures differ in size: {picture.shape} against {golden.shape}")
    difference = np.abs(picture.astype(np.int64) - golden.astype(np.int64))
    per_pixel = difference.reshape(difference.shape[0], difference.shape[1], -1).max(axis=2)
    off = float((per_pixel > tolerance).mean())
    return {"mean_difference": float(difference.mean()), "largest": int(difference.max(initial=0)),
            "share_off": off, "same": off <= share}
