"""Batches: many inputs, many views, one command, on one machine or a Dask cluster (``run``); ``parse`` turns
the text of a manifest or a command line into the library's values.
"""

from .._shared.face import face

_FACE = {
    "run_batch": "run",
    "items_from": "run",
    "read_manifest": "run",
    "parse_views": "run",
    "turntable": "run",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
