"""Agreement with a reference beside DeepMind's ``surface-distance`` on the same masks, on vhf_head's grid, in two
cases: its three tissues (bone, soft tissue, airway by Hounsfield ranges) as the reference and a damaged copy (the
bone eroded, the soft tissue moved by a voxel, the airway cut in half) as the test; and 40 organ-sized ellipsoids,
each moved by a voxel or eroded in the test, as a multi-organ segmentation is.  :func:`bench_agreement` is called
by ``benchmarks/bench.py``.

    python -m benchmarks.agreement [--repeat 3]

Both compute Dice, HD95, the average surface distances and the surface Dice at 2 mm of each structure; the
numbers are checked equal before the times are compared.  ``surface-distance`` is given each structure's mask of
the whole grid, as its users call it; voxrender takes the label maps.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from benchmarks import median_seconds


def damaged_labels(reference):
    """The test segmentation: the reference's bone eroded, its soft tissue moved one voxel along x, its airway
    cut in half along z."""
    from scipy import ndimage

    test = np.zeros_like(reference)
    test[ndimage.binary_erosion(reference == 1)] = 1
    test[np.roll(reference == 2, 1, axis=2) & (test == 0)] = 2
    airway = reference == 3
    airway[: reference.shape[0] // 2] = False
    test[airway & (test == 0)] = 3
    return test


def organs(shape, count=40, seed=2026):
    """A label map of ``count`` ellipsoids of 2 to 40 mL-sized radii (in voxels) spread over ``shape``, apart."""
    rng = np.random.default_rng(seed)
    labels = np.zeros(shape, np.uint8)
    zz, yy, xx = (np.arange(n) for n in shape)
    for label in range(1, count + 1):
        radii = np.minimum(rng.uniform(4, 14, 3), np.array(shape) / 4)      # a small grid: smaller ones
        centre = [rng.uniform(r + 1, n - r - 1) for r, n in zip(radii, shape, strict=True)]
        box = tuple(slice(max(int(c - r) - 1, 0), min(int(c + r) + 2, n))
                    for c, r, n in zip(centre, radii, shape, strict=True))
        inside = sum(((axis[b][tuple(slice(None) if k == j else None for k in range(3))] - c) / r) ** 2
                     for j, (axis, b, c, r) in enumerate(zip((zz, yy, xx), box, centre, radii, strict=True))) <= 1
        view = labels[box]
        view[inside & (view == 0)] = label
    return labels


def damaged_organs(reference):
    """Odd organs moved one voxel along x, even ones eroded (when something is left of them)."""
    from scipy import ndimage

    test = np.zeros_like(reference)
    for label, box in enumerate(ndimage.find_objects(reference), start=1):
        if box is None:
            continue
        grown = tuple(slice(max(b.start - 2, 0), b.stop + 2) for b in box)
        own = reference[grown] == label
        eroded = ndimage.binary_erosion(own)
        # surface-distance fails on an empty mask under NumPy 2 (its np.Inf): a small organ is moved, not eroded away
        own = np.roll(own, 1, axis=2) if label % 2 or not eroded.any() else eroded
        test[grown][own & (test[grown] == 0)] = label
    return test


def bench_agreement(path, repeat):
    """Median seconds of voxrender's agreement and of ``surface-distance`` on the same structures, and their ratio,
    of each case.

    Returns
    -------
    dict
        ``grid_xyz`` and ``cases``: of each, ``structures``, ``voxrender_s``, ``surface_distance_s``, ``speedup``
        (theirs / ours) and ``largest_difference`` (of any metric, between the two); or ``skipped`` with why.
    """
    from voxrender import io
    from voxrender.samples import TISSUES, tissue_labels

    try:
        import surface_distance  # noqa: F401
    except ImportError:
        return {"skipped": "surface-distance is not installed (pip install surface-distance)"}
    volume = io.read_volume(path)
    tissues = tissue_labels(volume.values)
    table = {str(k): {"name": name} for k, (name, _) in TISSUES.items()}
    many = organs(volume.shape)
    cases = {"3 tissues filling the head": (damaged_labels(tissues), tissues, table),
             "40 organ-sized structures": (damaged_organs(many), many, {})}
    return {"grid_xyz": list(volume.shape[::-1]),
            "cases": {name: _case(volume, *case, repeat) for name, case in cases.items()}}


def _case(volume, test, reference, table, repeat):
    """One case: both timed on the same label maps, their numbers compared."""
    import surface_distance

    from voxrender import io
    from voxrender.review.agreement import Comparison

    sides = [io.Volume(values, volume.spacing, {"label_table": table}) for values in (test, reference)]
    ours_s, rows = median_seconds(lambda: Comparison(volume, *sides).metrics(2.0), repeat)
    spacing = tuple(volume.spacing)[::-1]
    labels = [int(k) for k in np.unique(reference) if k]

    def theirs():                                  # each structure's masks of the whole grid, as its users call it
        found = {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for label in labels:
                gt, pred = reference == label, test == label
                distances = surface_distance.compute_surface_distances(gt, pred, spacing)
                found[label] = (surface_distance.compute_dice_coefficient(gt, pred),
                                surface_distance.compute_robust_hausdorff(distances, 95),
                                surface_distance.compute_surface_dice_at_tolerance(distances, 2.0))
        return found

    theirs_s, found = median_seconds(theirs, repeat)
    largest = max(abs(a - b) for row in rows for a, b in zip((row["dice"], row["hd95_mm"], row["nsd"]),
                                                             found[row["reference_label"]], strict=True))
    return {"structures": len(rows), "voxrender_s": ours_s, "surface_distance_s": theirs_s,
            "speedup": theirs_s / ours_s, "largest_difference": float(largest)}


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[1].parent / "shared" / "data"))
    args = parser.parse_args()
    print(bench_agreement(Path(args.data) / "vhf_head", args.repeat))
