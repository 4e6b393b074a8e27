"""Back-to-front display voxel by voxel, as the paper describes it: the oracle of :mod:`voxrender._render.btf`.

Each voxel's cube is painted over what is behind it with the literal geometry (:mod:`.geometry`), one pixel
at a time.  Where a ray only touches two cubes the voxel painted last keeps the pixel, as in the fast painter
(see the ties in :mod:`voxrender._render.btf`).
"""

from __future__ import annotations

import numpy as np

from . import geometry


def render_btf_literal(segments, view, clip=None):
    """Back-to-front rendering one voxel at a time, as the paper describes it (the test oracle).

    Slices, rows within a slice and voxels within a row are visited from the farthest to the nearest;
    each voxel overwrites the pixels its cube covers (:func:`.geometry.box_pixels`).
    """
    r = geometry.rotation(view.alpha, view.beta, view.gamma)
    size = tuple(view.size)
    nz, ny, nx = segments.shape
    centre = ((nx - 1) / 2, (ny - 1) / 2, (nz - 1) / 2)
    image = np.full(size, np.inf)
    stats = {"slices": 0, "rows": 0, "voxels_projected": 0, "pixel_writes": 0}

    def farthest_first(n, component):          # the viewer looks along +Z': high indices are far when it grows
        return list(range(n - 1, -1, -1)) if component > 0 else list(range(n))

    for z in farthest_first(nz, r[2][2]):
        slice_has_voxels = False
        for y in farthest_first(ny, r[2][1]):
            runs = [kept for start, end in zip(*segments.row(z, y), strict=True)
                    if (kept := geometry.clip_run(clip, r, z, y, start, end, centre))]
            if not runs:
                continue
            slice_has_voxels = True
            stats["rows"] += 1
            voxels = [x for start, end in runs for x in range(int(start), int(end) + 1)]
            for x in (voxels[::-1] if r[2][0] > 0 else voxels):
                stats["voxels_projected"] += 1
                for row, column, depth in geometry.box_pixels(r, (x, y, z), (0.5, 0.5, 0.5), centre, size,
                                                              view.scale, tuple(view.centre)):
                    image[row, column] = depth                # painted over what is behind
                    stats["pixel_writes"] += 1
        stats["slices"] += slice_has_voxels
    return image.astype(np.float32), stats
