"""Reading slice stacks into a :class:`Volume`: one module per format, each with its :class:`Reader` record.

Supported inputs (detected from the path, or named with ``format=``), in the order detection tries them; each is
read by the module of its name (``voxrender.io.dicom`` ...):

========== ==========================================================================
format     what
========== ==========================================================================
seg        a DICOM SEG file (BINARY, FRACTIONAL or LABELMAP): one label map, named by its segments (highdicom)
zarr       a Zarr array or OME-Zarr image folder (NGFF 0.4/0.5), one level of it (``level=``), read a slab of
           chunks at a time
dicom      a folder holding a DICOM series, ordered by ImagePositionPatient
images     a folder of 2-D images (PNG, TIFF, BMP, JPEG), in natural order of names
metaimage  a MetaImage ``.mhd`` (header + raw file) or ``.mha`` (one file), raw or zlib
raw        headerless slices: a folder of files or one file, with ``raw=RawLayout(...)``
npy        a 3-D NumPy ``.npy`` array ``[z, y, x]``
tiff       a multi-page TIFF, one page a slice (spacing from ImageJ or OME metadata)
masks      a folder of binary NIfTI or NRRD masks, one file per structure: one label map, named by the files
nifti      NIfTI-1 or -2, ``.nii`` or ``.nii.gz`` (nibabel), scaled by scl_slope/scl_inter
nrrd       NRRD, ``.nrrd`` or ``.nhdr`` with a detached data file (pynrrd), raw, gzip or bzip2
========== ==========================================================================

An RTSTRUCT holds contours, not a grid: it is read as the labels of its image only, by
:func:`voxrender.io.rtstruct.read_rtstruct` (``--labels-from``), and so has no entry in ``READERS``.

``voxrender.io._shared`` holds what they share: :class:`Volume`, :class:`Reader`, :class:`RawLayout`, the listing
of folders and the filling of stacks.  A folder of NIfTI or NRRD files (a segmentation's one file per organ) is
read as one label map (``masks``); the ``nifti`` and ``nrrd`` formats, named for a folder, refuse it.

Every reader also returns, when its header says it, the volume's *direction* (see :mod:`voxrender.space.orient`);
:func:`read_volume` then brings the volume to the canonical patient frame (LPS) by flips and permutations.
Readers stream: the volume array is allocated once and filled slice by slice.

A reader turns only the errors its library raises for a damaged file into :class:`~voxrender.errors.InputError`;
anything else (a bug, a ``MemoryError``) goes on as it is.  Before it allocates, it compares the sizes its header
promises with what the file holds and with the free memory, and inflates compressed voxels no further than
promised (``_shared.check_holds``, ``check_fits``, ``inflate``): a hostile header is bad input, with both sizes.
Adding a format is one module with its reading function and its ``READER`` record, one line in ``READERS`` and
one test file (see ``docs/design.md``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np  # noqa: F401 (the examples below use it)

from ..errors import InputError
from . import dicom, images, masks, metaimage, nifti, npy, nrrd, raw, seg, tiff, zarr
from ._reading import options_for, placed, read_with
from ._shared import (
    RawLayout,
    Reader,
    Volume,
    check_spacing,
    files_in,
    identity_progress,
    natural_key,
    real_numbers,
    slices_at,
    some_names,
)

__all__ = ["Volume", "RawLayout", "Reader", "READERS", "FORMATS", "read_volume", "open_stack", "detect_format",
           "natural_key", "check_spacing", "slices_at", "real_numbers"]

# The formats by name, in the order ``format="auto"`` tries them: a Zarr store before DICOM (its folders are told by a
# metadata file, where the DICOM sniff would open every chunk), a folder of DICOM files before one of images (an
# export may hold a preview picture beside its slices), folders of slices before folders of volume files.
READERS = {
    "seg": seg.READER,
    "zarr": zarr.READER,
    "dicom": dicom.READER,
    "masks": masks.READER,            # before images: a folder of masks may hold a preview picture
    "images": images.READER,
    "metaimage": metaimage.READER,
    "raw": raw.READER,
    "npy": npy.READER,
    "tiff": tiff.READER,
    "nifti": nifti.READER,
    "nrrd": nrrd.READER,
}
FORMATS = ("auto", *READERS)


def detect_format(path, raw=None):
    """Name the format of ``path``: the first reader in ``READERS`` whose suffixes name the file, else the first
    whose ``sniff`` recognises it (a folder by what it holds, a file by its magic bytes).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> np.save(folder / "v.npy", np.zeros((2, 3, 4), np.int16))
    >>> detect_format(folder / "v.npy")
    'npy'
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"no such file or folder: {path}")
    if not path.is_file() and not path.is_dir():
        raise InputError(f"{path} is neither a file nor a folder (a device or a pipe); give a file or a folder")
    if raw is not None:
        return "raw"
    if path.is_dir() and next(path.iterdir(), None) is None:
        raise InputError(f"{path} is an empty folder; give a folder of slices")
    if path.is_file():
        for format, reader in READERS.items():
            if reader.sniff_first and reader.sniff(path):
                return format
        for format, reader in READERS.items():
            if path.name.lower().endswith(reader.suffixes):
                return format
    for format, reader in READERS.items():
        if reader.sniff is not None and reader.sniff(path):
            return format
    if path.is_file():
        raise InputError(f"cannot tell the format of {path}; give a folder of slices, .mhd/.mha, .nii/.nii.gz, "
                         ".nrrd/.nhdr, .npy, a multi-page .tif, a Zarr or OME-Zarr folder, or the layout of "
                         "headerless slices", parameter="format")
    files = files_in(path)
    raise InputError(f"{path} holds {len(files)} file{'s' * (len(files) > 1)} ({some_names(files)}) but no DICOM "
                     "files, images (PNG, TIFF, BMP, JPEG) or volume files; for headerless slices give their layout",
                     parameter="raw")


def read_volume(path, *, format="auto", raw=None, spacing=None, series=None, frame=None, level=None,
                orientation=None, reorient=True, progress=None, run=None):
    """Read a slice stack into a :class:`Volume`, in the canonical patient frame.

    Parameters
    ----------
    path : str or Path
        A folder of slices or a volume file.
    format : str
        ``"auto"`` (detect it) or a name in ``READERS``.
    raw : RawLayout, optional
        The layout of headerless slices (implies ``format="raw"``).
    spacing : sequence of 3 floats, optional
        Voxel spacing (x, y, z) in mm; overrides what the files say.
    series : str, optional
        SeriesInstanceUID to read when a DICOM folder holds several series.
    frame : int, optional
        The volume to read from a 4-D file (NIfTI, NRRD).
    level : int, optional
        The level of a multiscale image (OME-Zarr) to read: 0 the finest (default: the finest level).
    run : int, optional
        Of a DICOM series whose slice steps are uneven (split into regular runs), the run to read, from 1 in the
        order of the slice positions (default: the longest).
    orientation : str, optional
        An orientation code (``"RAS"``, ``"LPI"`` ...) for inputs whose header says none, or to override it.
    reorient : bool
        Bring the volume to the canonical patient frame (x toward L, y toward P, z toward S) by flips and
        permutations, when its orientation is known.  ``False`` keeps the stored order.
    progress : callable, optional
        ``progress(iterable, length, label)`` wraps the slice loop (a progress bar).

    Returns
    -------
    Volume
        ``meta`` tells the format, where the spacing and orientation came from, and what reorienting did.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> np.save(folder / "v.npy", np.arange(24, dtype=np.int16).reshape(2, 3, 4))
    >>> read_volume(folder / "v.npy").shape
    (2, 3, 4)
    >>> read_volume(folder / "v.npy", orientation="RAS").meta["reoriented"]
    'RAS -> LPS: flipped x, y'
    """
    path = Path(path)
    progress = progress or identity_progress
    if format != "auto" and format not in READERS:
        raise InputError(f"unknown format {format!r}; choose one of auto, {', '.join(READERS)}", parameter="format")
    if format == "auto":
        format = detect_format(path, raw)
    elif not path.exists():
        raise InputError(f"no such file or folder: {path}")
    return read_with(READERS[format], path, format, progress, {"raw": raw, "series": series, "frame": frame,
                     "level": level, "run": run}, orientation, reorient, spacing)


def open_stack(path, *, format="auto", raw=None, spacing=None, series=None, frame=None, level=None,
               orientation=None, reorient=True, run=None):
    """A slice stack in the canonical patient frame, unread: :func:`read_volume`'s stack, read slab by slab.

    Takes :func:`read_volume`'s parameters but ``progress`` (the reading happens later).  Returns a
    :class:`~voxrender.io._stack.Canonical`, whose ``read_slices(z0, z1)`` reads the canonical slices ``z0`` to
    ``z1 - 1``; the whole of it equals ``read_volume(...).values``, and its ``spacing``, ``direction`` and ``meta``
    are the volume's.  A format whose reader cannot read slabs (a DICOM SEG, a folder of masks) is refused.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> np.save(folder / "v.npy", np.arange(24, dtype=np.int16).reshape(2, 3, 4))
    >>> stack = open_stack(folder / "v.npy", orientation="LPI")
    >>> stack.how, stack.read_slices(0, 1)[0, 0].tolist()
    ('from the far end', [12, 13, 14, 15])
    """
    from ._stack import canonical

    path = Path(path)
    if format != "auto" and format not in READERS:
        raise InputError(f"unknown format {format!r}; choose one of auto, {', '.join(READERS)}", parameter="format")
    format = detect_format(path, raw) if format == "auto" else format
    if not path.exists():
        raise InputError(f"no such file or folder: {path}")
    reader = READERS[format]
    if reader.open is None:
        raise InputError(f"{format} input is read whole, not slab by slab; read it with read_volume",
                         parameter="format")
    stack = reader.open(path, **options_for(reader, format, {"raw": raw, "series": series, "frame": frame,
                                                              "level": level, "run": run}))
    if len(stack.shape) != 3 or min(stack.shape) < 1:
        raise InputError(f"{path} does not hold a 3-D stack (shape {stack.shape})")
    oriented = placed(stack, path, format, orientation, reorient)
    stack = canonical(stack, oriented)
    if spacing is not None:
        stack.spacing = check_spacing(spacing)
        stack.meta["spacing_from"] = "given"
    return stack
