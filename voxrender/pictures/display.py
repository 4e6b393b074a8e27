"""Grey values on a screen: the display window (level and width) that maps stored values to 8-bit grey.

Slices and projections show grey values, not surfaces; a reader sees them through a window, as on a PACS
viewer: values below ``level - width / 2`` are black, above ``level + width / 2`` white, linear between.
:data:`CT_WINDOWS` holds the windows radiologists use for CT, in Hounsfield units.

References
----------
.. [1] Radiopaedia, "Windowing (CT)", https://radiopaedia.org/articles/windowing-ct: brain W 80 L 40, soft
   tissue W 350-400 L 20-60, bone W 1800 L 400, lung W 1500 L -600.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class DisplayWindow:
    """A display window: ``level`` (its centre) and ``width``, in stored units (HU for CT).

    >>> DisplayWindow(40, 80).to_uint8(np.array([-100.0, 20.0, 40.0, 80.0, np.nan])).tolist()
    [0, 64, 128, 255, 0]
    """

    level: float
    width: float

    def __post_init__(self):
        if not (math.isfinite(self.level) and math.isfinite(self.width)):
            raise InputError(f"{self} must be two finite numbers, LEVEL/WIDTH (e.g. 40/400)", parameter="window")
        if self.width <= 0:
            raise InputError(f"{self}: the width must be above 0 (e.g. 40/400: level 40, width 400)",
                             parameter="window")

    def to_uint8(self, values):
        """``values`` through the window as 8-bit grey; NaN is black."""
        low = self.level - self.width / 2
        grey = (np.asarray(values, np.float32) - np.float32(low)) * np.float32(255 / self.width)
        return np.nan_to_num(np.clip(np.rint(grey), 0, 255), nan=0.0).astype(np.uint8)

    def __str__(self):
        return f"{self.level:g}/{self.width:g}"


# The CT windows of [1], in HU; soft tissue at the middle of its ranges.
CT_WINDOWS = {
    "brain": DisplayWindow(40, 80),
    "soft-tissue": DisplayWindow(50, 400),
    "bone": DisplayWindow(400, 1800),
    "lung": DisplayWindow(-600, 1500),
}


def auto_window(values):
    """A window over the 1st to 99th percentile of the finite ``values`` (a sample of at most about a million),
    for images without a standard window.

    >>> auto_window(np.arange(101.0))
    DisplayWindow(level=50.0, width=98.0)
    """
    values = np.asarray(values)
    sample = values.ravel()[::max(1, values.size // (1 << 20))]
    sample = sample[np.isfinite(sample)] if sample.dtype.kind in "fc" else sample
    if not sample.size:
        return DisplayWindow(0.0, 1.0)
    low, high = (float(v) for v in np.percentile(sample, [1, 99]))
    return DisplayWindow((low + high) / 2, max(high - low, 1e-6))
