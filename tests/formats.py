"""One asymmetric phantom, stored in any orientation, written with each format's own library (for reader tests)."""

import warnings

import nibabel
import nrrd
import numpy as np
from dicom_files import write_series

from voxrender.errors import InputError
from voxrender.space import orient

SPACING = (0.8, 1.0, 1.25)      # canonical x, y, z in mm


def random_stack(shape=(5, 6, 7), seed=0):
    """Random ``uint16`` slices ``[z, y, x]`` (0 to 2999), for readers that keep the stored values."""
    return np.random.default_rng(seed).integers(0, 3000, size=shape).astype(np.uint16)


def refused_cuts(path, read, count=40):
    """Cut ``path`` off at ``count`` lengths from nothing to nearly whole, ``read()`` each, and count the cut files
    it refused with an InputError; any other exception goes on (a cut file is bad input, never a bug).  ``path`` is
    whole again after."""
    whole = path.read_bytes()
    refused = 0
    try:
        for size in range(0, len(whole), max(1, len(whole) // count)):
            path.write_bytes(whole[:size])
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", UserWarning)      # the libraries' notes on what they mend
                    read()
            except InputError:
                refused += 1
    finally:
        path.write_bytes(whole)
    return refused


def phantom():
    """``values[z, y, x]`` in the canonical frame (x toward L, y toward P, z toward S), 0 air, 1000 object:
    a head with a nose in front (low y), an ear on its left (high x) and a knob on top (high z)."""
    z, y, x = np.mgrid[:18, :22, :20].astype(float)
    head = ((x - 9.5) / 6) ** 2 + ((y - 11) / 7) ** 2 + ((z - 8) / 6) ** 2 <= 1
    nose = (np.abs(x - 9.5) <= 1.5) & (y >= 2) & (y < 5) & (np.abs(z - 9) <= 1.5)
    ear = (x >= 15) & (x < 18) & (np.abs(y - 11) <= 2) & (np.abs(z - 8) <= 2)
    knob = (np.abs(x - 9.5) <= 1) & (np.abs(y - 13) <= 1) & (z >= 13) & (z < 17)
    return ((head | nose | ear | knob) * 1000).astype(np.int16)


def stored(canonical, code, spacing=SPACING):
    """The array, spacing and direction of ``canonical`` stored in orientation ``code``."""
    direction = orient.direction_of(code)
    axis, sign, _ = orient.nearest_axes(direction)
    values = np.transpose(canonical, [2 - axis[2 - i] for i in range(3)])
    for i in range(3):
        if sign[2 - i] < 0:
            values = np.flip(values, axis=i)
    return np.ascontiguousarray(values), tuple(spacing[axis[k]] for k in range(3)), direction


def write_nifti(path, values, spacing, direction):
    affine = np.eye(4)
    affine[:3, :3] = orient.ras_to_lps(direction) * np.asarray(spacing)
    nibabel.save(nibabel.Nifti1Image(np.transpose(values, (2, 1, 0)), affine), str(path))
    return path


def write_nrrd(path, values, spacing, direction, space="left-posterior-superior", **header):
    matrix = direction if space == "left-posterior-superior" else orient.ras_to_lps(direction)
    nrrd.write(str(path), values, {"space": space, "space directions": (matrix * np.asarray(spacing)).T,
                                   "space origin": [0.0, 0.0, 0.0], **header},
               index_order="C", detached_header=str(path).endswith(".nhdr"))
    return path


def write_metaimage(path, values, spacing, direction):
    """MetaImage has no library here: its header is text, written as ITK writes it (TransformMatrix row k is
    the direction of axis k)."""
    header = (f"ObjectType = Image\nNDims = 3\nDimSize = {values.shape[2]} {values.shape[1]} {values.shape[0]}\n"
              f"ElementSpacing = {spacing[0]} {spacing[1]} {spacing[2]}\n"
              f"TransformMatrix = {' '.join(str(v) for v in direction.T.ravel())}\nOffset = 0 0 0\n"
              "ElementType = MET_SHORT\nElementByteOrderMSB = False\nElementDataFile = LOCAL\n")
    path.write_bytes(header.encode() + values.astype("<i2").tobytes())
    return path


def write_dicom(folder, values, spacing, direction):
    """A classic series: x along the rows' direction, y along the columns', slices along their normal."""
    return write_series(folder, values, spacing, intercept=0, direction=direction)
