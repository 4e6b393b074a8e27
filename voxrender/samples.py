"""Small synthetic CT-like slice stacks: phantoms for the demo, the tests and for teaching.

Each phantom is a grey-value volume ``[z, y, x]`` of unsigned 16-bit "stored
values": about 0 for air and about 1000 for the object, so a threshold of 500
separates them.  The functions return arrays; ``voxrender samples`` writes each as a
folder of 16-bit PNG slices (:func:`voxrender.outputs.output.write_slices`), the format a user's
own image folder would have.

Beside them the package ships one real CT, VTK's quarter-resolution head (:func:`headsq_path`), which
``voxrender demo`` renders.
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import numpy as np

AIR, OBJECT = 40, 1040
SAMPLE_THRESHOLD = 500

# The 11 voxels (x, y, z) of the linear-octree paper's Fig. 2 (Chandran, Gupta and Patgawkar, Table 2).
STAIRCASE_VOXELS = [(3, 3, 3), (2, 3, 3), (3, 2, 3), (2, 2, 3), (3, 3, 2), (2, 3, 2), (3, 2, 2), (2, 2, 2),
                    (1, 3, 3), (3, 1, 2), (3, 3, 1)]


def _grid(shape):
    nz, ny, nx = shape
    z, y, x = np.mgrid[:nz, :ny, :nx].astype(np.float32)
    return x - (nx - 1) / 2, y - (ny - 1) / 2, z - (nz - 1) / 2


def _ct(inside, noise=0.0, seed=0):
    """Stored values from a bool (or 0..1 soft) object, with optional Gaussian noise."""
    values = AIR + (OBJECT - AIR) * inside.astype(np.float32)
    if noise:
        values += np.random.default_rng(seed).normal(0, noise, values.shape).astype(np.float32)
    return np.clip(np.rint(values), 0, 65535).astype(np.uint16)


def sphere(n=48, radius=None):
    """A ball of ``radius`` (default ``0.4 n``) in an ``n``-cube.

    >>> v = sphere(16)
    >>> v.shape, v.dtype.name, bool(v[8, 8, 8] > 500), bool(v[0, 0, 0] < 500)
    ((16, 16, 16), 'uint16', True, True)
    """
    x, y, z = _grid((n, n, n))
    radius = 0.4 * n if radius is None else radius
    return _ct(x * x + y * y + z * z <= radius * radius)


def torus(n=64, major=None, minor=None):
    """A ring lying in the x-y plane: a convex-hull-defeating object with a hole.

    >>> v = torus(32)
    >>> v.shape, bool(v[8, 16, 16] < 500), bool(v[8, 16, 4] > 500)
    ((16, 32, 32), True, True)
    """
    x, y, z = _grid((n // 2, n, n))
    major = 0.3 * n if major is None else major
    minor = 0.12 * n if minor is None else minor
    ring = np.sqrt(x * x + y * y) - major
    return _ct(ring * ring + z * z <= minor * minor)


def shell(shape=(72, 88, 80), thickness=3.5, noise=60.0, seed=1):
    """A noisy, hollow, skull-like shell: an ellipsoid with a wall, two eye holes and a hole below.

    >>> v = shell((36, 44, 40), thickness=2.0)
    >>> bool(v[18, 22, 20] < 500)
    True
    """
    x, y, z = _grid(shape)
    nz, ny, nx = shape
    radii = np.array([0.42 * nx, 0.42 * ny, 0.42 * nz], np.float32)
    distance = np.sqrt((x / radii[0]) ** 2 + (y / radii[1]) ** 2 + (z / radii[2]) ** 2)
    wall = (distance <= 1) & (distance >= 1 - thickness / radii.min())
    for side in (-1, 1):  # eye sockets: holes through the front (-y) wall
        eye = (x - side * 0.16 * nx) ** 2 + (z + 0.08 * nz) ** 2 <= (0.09 * nx) ** 2
        wall &= ~(eye & (y < 0))
    wall &= ~((x * x + y * y <= (0.12 * nx) ** 2) & (z < 0))  # the large hole at the base
    return _ct(wall, noise=noise, seed=seed)


def staircase():
    """The 4x4x4 staircase of the linear-octree paper's Fig. 2 (11 voxels).

    >>> int((staircase() > 500).sum())
    11
    """
    inside = np.zeros((4, 4, 4), bool)
    for x, y, z in STAIRCASE_VOXELS:
        inside[z, y, x] = True
    return _ct(inside)


def cylinder(n=64, radius=None, axis=(0.25, 0.15, 0.8)):
    """An oblique solid cylinder voxelized by sweeping (the line-voxelization paper's opening example).

    A voxelized disc in the first slice is swept along a 26-connected 3-D line
    (:func:`voxrender.space.lines.line26`): the cylinder is every disc voxel moved by every line voxel.

    >>> v = cylinder(32)
    >>> v.shape, bool(v[0, 7, 7] > 500), bool(v[-1, 7, 7] < 500)
    ((32, 32, 32), True, True)
    """
    from .space.lines import line26

    radius = 0.18 * n if radius is None else radius
    centre = int(round(radius)) + 1
    y, x = np.mgrid[-centre:centre + 1, -centre:centre + 1]
    inside = x * x + y * y <= radius * radius
    disc = np.stack([x[inside] + centre, y[inside] + centre, np.zeros(inside.sum(), int)], axis=1)
    end = np.rint(np.array(axis) / np.array(axis)[2] * (n - 1)).astype(int)
    end = np.minimum(end, n - 1 - 2 * centre)
    end[2] = n - 1
    swept = (disc[:, None, :] + line26((0, 0, 0), end)[None, :, :]).reshape(-1, 3)
    inside = np.zeros((n, n, n), bool)
    inside[swept[:, 2], swept[:, 1], swept[:, 0]] = True
    return _ct(inside)


def headsq_path():
    """The folder of VTK's quarter-resolution head, shipped with voxrender as package data.

    93 headerless slices ``quarter.1`` ... ``quarter.93`` of 64 x 64 little-endian uint16 values, voxels of
    3.2 x 3.2 x 1.5 mm, orientation ``LPI``; its ``README.md`` and VTK's licence lie beside them.

    Returns
    -------
    pathlib.Path
        The folder inside the installed package (inside the checkout for an editable install).

    >>> (headsq_path() / "quarter.93").is_file()
    True
    """
    return Path(resources.files("voxrender").joinpath("data", "headsq"))


SAMPLES = {"sphere": sphere, "torus": torus, "shell": shell, "staircase": staircase, "cylinder": cylinder}


# name and colour of the labels of tissue_labels (3D Slicer's bone and muscle colours, a light blue for air)
TISSUES = {1: ("bone", (241, 214, 145)), 2: ("soft tissue", (192, 104, 88)), 3: ("airway", (110, 170, 230))}


def segment_fields(table):
    """The header fields of a 3D Slicer ``.seg.nrrd`` naming and colouring labels ``{label: (name, (r, g, b))}``
    (for :func:`voxrender.outputs.output.write_nrrd`).
    """
    fields = {}
    for k, (label, (name, colour)) in enumerate(sorted(table.items())):
        fields.update({f"Segment{k}_Name": name, f"Segment{k}_Color": " ".join(f"{c / 255:.4f}" for c in colour),
                       f"Segment{k}_LabelValue": str(label), f"Segment{k}_Layer": "0"})
    return fields


def tissue_labels(hu):
    """A label map of a CT by Hounsfield ranges (names and colours in :data:`TISSUES`): 1 bone (from 300 HU),
    2 soft tissue (-300 to 300 HU), 3 airway (below -300 HU and enclosed by the body: air not connected to the
    volume's border).

    A stand-in for a segmentation tool's output, made from the CT itself, for tests and examples.

    >>> hu = np.full((5, 5, 5), -1000); hu[1:4, 1:4, 1:4] = 40; hu[2, 2, 2] = -900; hu[1, 1, 1] = 700
    >>> np.bincount(tissue_labels(hu).ravel()).tolist()
    [98, 1, 25, 1]
    """
    from scipy import ndimage

    hu = np.asarray(hu)
    labels = np.zeros(hu.shape, np.uint8)
    labels[(hu >= -300) & (hu < 300)] = 2
    labels[hu >= 300] = 1
    air, count = ndimage.label(hu < -300)
    border = np.unique(np.concatenate([air[[0, -1]].ravel(), air[:, [0, -1]].ravel(), air[:, :, [0, -1]].ravel()]))
    labels[(air > 0) & ~np.isin(air, border)] = 3
    return labels
