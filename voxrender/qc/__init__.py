"""Quality control: what an input holds (``description``), a study (image and labels, ``study``), its slices with the
labels over them (``slices``), a sheet of pictures (``sheet``), the QC sheet of all three (``qc``) and the index page
of a batch (``index_page``).
"""

from .._shared.face import face

_FACE = {
    "load_study": "study",
    "Study": "study",
    "SliceOptions": "qc",
    "slice_pictures": "qc",
    "qc_sheet": "qc",
    "slice_picture": "slices",
    "SlicePoint": "slices",
    "describe": "description",
    "write_index": "index_page",
    "read_index": "index_page",
    "StudyRow": "index_page",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
