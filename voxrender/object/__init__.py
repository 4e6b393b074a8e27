"""The object: a volume thresholded (``prep``), encoded as run-length segments (``segments``), kept in a
``.vxs`` file (``vxs``), with its region octree (``octree``) and surface normals (``normals``); ``pipeline``
runs those steps for one input, ``stream`` for a stack larger than memory.
"""

from .._shared.face import face

_FACE = {
    "Segments": "segments",
    "encode": "segments",
    "encode_labels": "segments",
    "save": "vxs",
    "load": "vxs",
    "binarize": "prep",
    "Interval": "prep",
    "LabelSelection": "prep",
    "otsu_threshold": "prep",
    "load_segments": "pipeline",
    "encode_volume": "pipeline",
    "PrepOptions": "pipeline",
    "ReadOptions": "pipeline",
    "Encoded": "pipeline",
    "SurfaceNormals": "normals",
    "encode_file": "stream",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
