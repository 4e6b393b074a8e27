"""Agreement with a reference beside DeepMind's ``surface-distance`` on the same masks: vhf_head's tissues (bone,
soft tissue, airway by Hounsfield ranges) as the reference, and a damaged copy (the bone eroded, the soft tissue
moved by a voxel, the airway cut in half) as the test; :func:`bench_agreement` is called by ``benchmarks/bench.py``.

    python -m benchmarks.agreement [--repeat 3]

Both compute Dice, HD95, the average surface distances and the surface Dice at 2 mm of each structure; the
numbers are checked equal before the times are compared.  ``surface-distance`` is given each structure's mask of
the whole grid, as its users call it; voxrender takes the label maps.
"""

from __future__ import annotations

import statistics
import time
import warnings
from pathlib import Path

import numpy as np


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


def _median(work, repeat):
    times, result = [], None
    for _ in range(repeat):
        started = time.perf_counter()
        result = work()
        times.append(time.perf_counter() - started)
    return statistics.median(times), result


def bench_agreement(path, repeat):
    """Median seconds of voxrender's agreement and of ``surface-distance`` on the same structures, and their ratio.

    Returns
    -------
    dict
        ``grid_xyz``, ``structures``, ``voxrender_s``, ``surface_distance_s``, ``speedup`` (theirs / ours),
        ``largest_difference`` (of any metric, between the two), or ``skipped`` with why.
    """
    from voxrender import io
    from voxrender.review.agreement import Comparison
    from voxrender.samples import TISSUES, tissue_labels

    try:
        import surface_distance
    except ImportError:
        return {"skipped": "surface-distance is not installed (pip install surface-distance)"}
    volume = io.read_volume(path)
    reference = tissue_labels(volume.values)
    test = damaged_labels(reference)
    table = {str(k): {"name": name, "colour": list(colour)} for k, (name, colour) in TISSUES.items()}
    sides = [io.Volume(values, volume.spacing, {"label_table": table}) for values in (test, reference)]
    ours_s, rows = _median(lambda: Comparison(volume, *sides).metrics(2.0), repeat)
    spacing = tuple(volume.spacing)[::-1]

    def theirs():
        found = {}
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for label, (name, _) in TISSUES.items():
                distances = surface_distance.compute_surface_distances(reference == label, test == label, spacing)
                found[name] = (surface_distance.compute_dice_coefficient(reference == label, test == label),
                               surface_distance.compute_robust_hausdorff(distances, 95),
                               surface_distance.compute_surface_dice_at_tolerance(distances, 2.0))
        return found

    theirs_s, found = _median(theirs, repeat)
    largest = max(abs(a - b) for row in rows for a, b in zip((row["dice"], row["hd95_mm"], row["nsd"]),
                                                             found[row["name"]], strict=True))
    return {"grid_xyz": list(volume.shape[::-1]), "structures": len(rows), "voxrender_s": ours_s,
            "surface_distance_s": theirs_s, "speedup": theirs_s / ours_s, "largest_difference": float(largest)}


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--data", default=str(Path(__file__).resolve().parents[1].parent / "shared" / "data"))
    args = parser.parse_args()
    print(bench_agreement(Path(args.data) / "vhf_head", args.repeat))
