"""Space: how voxels, views and lines sit in patient space, the geometry every layer above shares.

``orient`` (directions, the canonical frame), ``grids`` (a voxel grid's affine, pairing two grids), ``view``
(the view contract: angles, presets, framing), ``lines`` (the 3-D digital lines of the ray-casting paper).
"""

from .._shared.face import face

_FACE = {
    "View": "view",
    "PRESETS": "view",
    "rotation_matrix": "view",
    "angles_from_matrix": "view",
    "angles_from_vpn": "view",
    "frame_together": "view",
    "fit_scale": "view",
    "patient_affine": "grids",
    "voxel_affine": "grids",
    "pair": "grids",
    "relate": "grids",
    "to_canonical": "orient",
    "in_patient_frame": "orient",
}
__all__ = list(_FACE)
__getattr__, __dir__ = face(__name__, _FACE)
