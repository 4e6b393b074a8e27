"""Reading a folder of binary masks (TotalSegmentator's 117 structures of a whole-body CT) against reading the
same labels as one NIfTI file; :func:`bench_mask_folder` is called by ``benchmarks/bench.py``.

    python -m benchmarks.masks [--repeat 3] [--shape 600 512 512] [--count 117]
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from benchmarks import median_seconds

WHOLE_BODY = (600, 512, 512)          # [z, y, x]: a whole-body CT at about 0.8 x 0.8 x 1.5 mm
TOTALSEGMENTATOR_MASKS = 117          # the structures of TotalSegmentator's "total" task


def bench_mask_folder(repeat, shape=WHOLE_BODY, count=TOTALSEGMENTATOR_MASKS, seed=2026):
    """Median seconds of ``read_volume`` of a folder of ``count`` uint8 ``.nii.gz`` masks on a grid of ``shape``,
    and of the same labels as one ``.nii.gz``, over ``repeat`` runs each.

    The masks are random ellipsoids and slabs, a few overlapping, written by nibabel as TotalSegmentator writes
    them (uint8, gzip, an RAS affine); most are small beside the body, as organs are.

    Returns
    -------
    dict
        ``masks``, ``grid_xyz``, ``mask_folder_s``, ``one_file_s``, ``ratio`` (folder / one file), ``folder_mb``
        and ``one_file_mb`` (compressed sizes).
    """
    from voxrender import io

    with tempfile.TemporaryDirectory() as scratch:
        folder, one_file = write_mask_folder(Path(scratch), shape, count, seed)
        folder_s = median_seconds(lambda: io.read_volume(folder), repeat)[0]
        one_file_s = median_seconds(lambda: io.read_volume(one_file), repeat)[0]
        folder_mb = sum(f.stat().st_size for f in folder.iterdir()) / 1e6
        one_file_mb = one_file.stat().st_size / 1e6
    return {"masks": count, "grid_xyz": list(shape[::-1]), "mask_folder_s": folder_s, "one_file_s": one_file_s,
            "ratio": folder_s / one_file_s, "folder_mb": folder_mb, "one_file_mb": one_file_mb}


def write_mask_folder(scratch, shape, count, seed=2026):
    """A folder ``segmentations/`` of ``count`` masks named ``structure_001`` ... and the label map they make,
    ``labels.nii.gz`` (a voxel in two masks goes to the one numbered first, as the reader numbers them).
    """
    import nibabel

    rng = np.random.default_rng(seed)
    affine = np.diag([-0.8, -0.8, 1.5, 1.0])                  # RAS, stored LPS as a DICOM-made NIfTI often is
    folder = scratch / "segmentations"
    folder.mkdir()
    labels = np.zeros(shape, np.uint8 if count <= 255 else np.uint16)
    for k in range(1, count + 1):
        mask = np.zeros(shape, np.uint8)
        box, inside = _blob(rng, shape)
        mask[box] = inside
        free = labels[box]
        free[(free == 0) & inside] = k
        nibabel.save(nibabel.Nifti1Image(mask.transpose(2, 1, 0), affine), str(folder / f"structure_{k:03d}.nii.gz"))
        del mask
    one_file = scratch / "labels.nii.gz"
    nibabel.save(nibabel.Nifti1Image(labels.transpose(2, 1, 0), affine), str(one_file))
    return folder, one_file


def _blob(rng, shape):
    """A random structure: an ellipsoid (most) or a slab, within a box a tenth to a third of the grid a side."""
    sizes = [int(rng.integers(max(n // 10, 1), max(n // 3, 2))) for n in shape]
    starts = [int(rng.integers(0, n - s + 1)) for n, s in zip(shape, sizes, strict=True)]
    box = tuple(slice(a, a + s) for a, s in zip(starts, sizes, strict=True))
    if rng.random() < 0.2:
        return box, np.ones(sizes, bool)
    grid = np.ogrid[tuple(slice(0, s) for s in sizes)]
    inside = sum(((g - (s - 1) / 2) / (s / 2)) ** 2 for g, s in zip(grid, sizes, strict=True)) <= 1
    return box, inside


if __name__ == "__main__":
    import argparse
    import json

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--shape", type=int, nargs=3, default=WHOLE_BODY, metavar=("Z", "Y", "X"))
    parser.add_argument("--count", type=int, default=TOTALSEGMENTATOR_MASKS)
    arguments = parser.parse_args()
    print(json.dumps(bench_mask_folder(arguments.repeat, tuple(arguments.shape), arguments.count), indent=2))
