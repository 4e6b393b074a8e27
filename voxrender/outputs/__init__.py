"""Outputs: files written atomically (``output``), the kinds of output a picture step writes (``output_kinds``,
the ``OUTPUTS`` record), where a picture goes and its writing (``picture_outputs``) and DICOM Secondary Capture
pictures (``secondary_capture``).
"""

from .._shared.face import face

_FACE = {
    "write_png": "output",
    "write_json": "output",
    "write_npy": "output",
    "OUTPUTS": "output_kinds",
    "Outputs": "picture_outputs",
    "Composite": "picture_outputs",
    "write_outputs": "picture_outputs",
    "about": "picture_outputs",
    "write_secondary_capture": "secondary_capture",
    "dicom_study": "secondary_capture",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
