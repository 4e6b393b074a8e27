"""Segmentation review: how two segmentations of one image agree (``agreement.agreement``, structure by structure,
on the measures of ``surfaces``: Dice, surface distances, normalised surface Dice, pieces; ``voxrender.agreement``)
and what in a cohort looks unlike the rest (``flags``: ``voxrender.cohort_flags``).
"""

from .._shared.face import face

_FACE = {
    "Comparison": "agreement",
    "cohort_flags": "flags",
    "surface_distances": "surfaces",
    "SurfaceDistances": "surfaces",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
