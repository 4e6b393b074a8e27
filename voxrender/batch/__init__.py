"""Batches: many inputs, many views, one command, on one machine or a Dask cluster (``run``): what a batch is
(``spec``: items, views, patterns, manifests), the cache of encoded objects (``cache``), the tasks its workers run
(``tasks``); ``parse`` turns the text of a manifest or a command line into the library's values.
"""

from .._shared.face import face

_FACE = {
    "run_batch": "run",
    "items_from": "spec",
    "read_manifest": "spec",
    "parse_views": "spec",
    "turntable": "spec",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
