"""NIfTI-1 or -2, ``.nii`` or ``.nii.gz`` (nibabel), scaled by scl_slope and scl_inter, oriented by its sform or qform.

A 4-D file gives the volume chosen by ``frame``.  A folder of NIfTI files (a segmentation's one file per organ) is
recognised, and refused with what it holds.  :func:`open_nifti` gives the volume unread, a slab at a time.
"""

from __future__ import annotations

import warnings
import zlib

import numpy as np

from .._shared.text import first_line
from ..errors import InputError
from ..space import orient
from ._shared import (
    Reader,
    Volume,
    check_fits,
    check_frame,
    check_holds,
    check_spacing,
    folder_of_volumes,
    inflated_size,
    open_voxels,
    promised_bytes,
    quiet_log,
    read_voxels,
    real_numbers,
    volume_files,
)
from ._stack import Stack

SUFFIXES = (".nii", ".nii.gz")


def read_nifti(path, progress, frame=None):
    """Read a NIfTI volume (of a 4-D file, the one ``frame`` names)."""
    image, frame, placement = _described(path, frame)
    shape = image.shape
    if str(path).lower().endswith(".gz") and image.dataobj.slope == 1 and image.dataobj.inter == 0:
        values = _inflated_voxels(path, image, shape, frame)
    else:
        _check_sizes(path, image, shape)
        try:                                                 # of a 4-D file, nibabel reads only the frame
            values = np.asanyarray(image.dataobj[..., frame] if len(shape) == 4 else image.dataobj)
        except _damaged() as exc:                            # a truncated or corrupt file
            raise InputError(f"cannot read the voxels of {path}: {first_line(exc)}; the file is truncated or "
                             "damaged") from None
        values = np.transpose(values, (2, 1, 0))              # NIfTI stores [i, j, k], i fastest: our x, y, z
    return Volume(values, *placement)


def open_nifti(path, frame=None):
    """A NIfTI volume (of a 4-D file, the one ``frame`` names) as a :class:`~voxrender.io._stack.Stack`: a
    ``.nii``'s slices read at their offset (i fastest: a slice k is contiguous), a ``.nii.gz``'s inflated by one
    stream read forward; scaled by scl_slope and scl_inter as :func:`read_nifti` scales them.
    """
    image, frame, (spacing, meta, direction) = _described(path, frame)
    dtype, offset = image.header.get_data_dtype(), int(image.dataobj.offset)
    volume = tuple(int(n) for n in image.shape[:3][::-1])                 # i fastest: C order [k, j, i]
    frames = image.shape[3] if len(image.shape) == 4 else 1
    compressed = str(path).lower().endswith(".gz")
    read, stored_bytes = open_voxels(path, 0 if compressed else offset, (frames * volume[0],) + volume[1:], dtype,
                                     "gzip" if compressed else None, skip=offset if compressed else 0, longer=True,
                                     first=(frame or 0) * volume[0], count=volume[0])
    scale = _scaling(image.dataobj)
    scaled_dtype = real_numbers(scale(np.empty((0,), dtype.newbyteorder("="))), path).dtype

    def read_slices(z0, z1):
        return real_numbers(scale(read(z0, z1)), path)

    return Stack(volume, scaled_dtype, read_slices, spacing, direction, meta, stored_bytes, sequential=compressed)


def _damaged():
    """What nibabel raises for a damaged file, with gzip's for a ``.nii.gz`` and numpy's memory map's for sizes
    that leave it a negative length.
    """
    from nibabel.filebasedimages import ImageFileError
    from nibabel.spatialimages import HeaderDataError

    return ImageFileError, HeaderDataError, OSError, EOFError, ValueError, zlib.error, OverflowError


def _described(path, frame):
    """The NIfTI image of ``path`` (its header read, its voxels not), checked, with the ``frame`` to read (of a 4-D
    file) and the volume's spacing, meta and direction: what :func:`read_nifti` and :func:`open_nifti` share.
    """
    import nibabel

    if path.is_dir():
        raise folder_of_volumes(path, "NIfTI", SUFFIXES)
    try:
        with quiet_log("nibabel.global"):                    # nibabel logs the header repairs it makes
            image = nibabel.load(str(path))
        header = image.header
        shape = image.shape
    except _damaged() as exc:
        raise InputError(f"cannot read {path} as NIfTI: {first_line(exc)}") from None
    _check_a_volume(path, image)
    if min(shape, default=0) < 1:
        raise InputError(f"{path}: its sizes (dim) {list(shape)} must be positive; the header is damaged")
    with nibabel.openers.ImageOpener(str(path)) as opener:     # as stored: loading mends a zero pixdim to 1
        stored = type(header).from_fileobj(opener, check=False)
    pixdim = [float(v) for v in stored["pixdim"][1:4]]
    if not all(np.isfinite(v) and v > 0 for v in pixdim):
        raise InputError(f"{path}: its voxel sizes (pixdim) {pixdim} must be positive; the header is damaged")
    if len(shape) == 4:
        frame = check_frame(path, frame, shape[3])
    else:
        check_frame(path, frame)
        if len(shape) != 3:
            raise InputError(f"{path} holds a {len(shape)}-D image; voxrender needs a 3-D volume")
    return image, frame, _placement(path, header, pixdim, image.dataobj.slope, image.dataobj.inter)


def _placement(path, header, pixdim, slope, inter):
    """The spacing, meta and direction of a NIfTI volume, from its sform, else its qform, else ``pixdim`` (and
    in ``meta``, its scaling by ``slope`` and ``inter``, when it is scaled).
    """
    affine, code = header.get_sform(coded=True)
    source = "NIfTI sform"
    if not code:
        affine, code = header.get_qform(coded=True)
        source = "NIfTI qform"
    meta = {"spacing_from": "NIfTI pixdim"}
    if code:
        matrix = np.asarray(affine, dtype=float)[:3, :3]
        sizes = np.linalg.norm(matrix, axis=0)
        if not np.all(sizes > 0):
            raise InputError(f"{path}: its {source} has a zero column; the header is damaged")
        direction = orient.ras_to_lps(matrix / sizes)
        spacing = tuple(float(v) for v in sizes)
        meta.update(spacing_from=source, orientation_from=source,
                    origin=orient.ras_to_lps(np.asarray(affine, dtype=float)[:3, 3]).tolist())
    else:
        warnings.warn(f"{path} has neither sform nor qform; its orientation is unknown (give it with an "
                      "orientation code if the presets should hold)", stacklevel=4)
        direction, spacing = None, tuple(pixdim)
        meta["orientation_from"] = "unknown: NIfTI without sform or qform"
    if (slope, inter) != (1, 0):         # nibabel's (the loaded header's scl_slope and scl_inter are NaN)
        meta["scaled"] = f"scl_slope {float(slope):g}, scl_inter {float(inter):g}"
    table = _label_table(path, header)
    if table:
        meta["label_table"] = table
    return check_spacing(spacing, path), meta, direction


def _scaling(proxy):
    """The function that scales stored voxels as nibabel's array proxy ``proxy`` scales them when it reads them
    (``ArrayProxy._get_scaled``): the same type, the same values, whatever part of the volume it is given.
    """
    from nibabel.volumeutils import apply_read_scaling

    slope, inter = np.asanyarray(proxy.slope), np.asanyarray(proxy.inter)
    if np.can_cast(inter, slope.dtype):
        inter = inter.astype(slope.dtype)

    def scale(values):
        return apply_read_scaling(values, slope, inter)

    return scale


CARET = 30        # the extension code of a Connectome Workbench label table, whose colours are the user's


def _label_table(path, header):
    """The label names a NIfTI file keeps in a header extension: the Caret XML ``LabelTable`` that
    TotalSegmentator's multi-label output (``--ml``) appends with extension code 0, and Connectome Workbench's
    label volumes with code 30.  ``{"5": {"name": "liver", "colour": None}}``: TotalSegmentator's colours only
    cycle through twelve values, so only Workbench's (code 30) are kept.  A table that does not parse is left out,
    with a warning: the voxels are still good.

    References
    ----------
    TotalSegmentator, ``totalsegmentator/nifti_ext_header.py`` (``add_label_map_to_nifti``,
    ``load_multilabel_nifti``), https://github.com/wasserth/TotalSegmentator
    """
    import xml.etree.ElementTree as ElementTree

    for extension in getattr(header, "extensions", ()):
        content = extension.content          # raw bytes whatever the code (get_content unmangles, not for all)
        if not isinstance(content, bytes) or b"<LabelTable" not in content:
            continue
        try:
            root = ElementTree.fromstring(content.rstrip(b"\0").decode("utf-8", errors="replace"))
            table = {}
            for label in root.iter("Label"):
                key, name = int(label.get("Key")), (label.text or "").strip()
                colour = [float(label.get(c, "nan")) for c in ("Red", "Green", "Blue")]
                colour = [round(255 * c) for c in colour] if all(0 <= c <= 1 for c in colour) else None
                if key > 0 and name:
                    table[str(key)] = {"name": name, "colour": colour if extension.get_code() == CARET else None}
            return table
        except (ElementTree.ParseError, TypeError, ValueError, OverflowError) as exc:
            warnings.warn(f"{path}: its label table (a header extension) is damaged ({first_line(exc)}); the labels "
                          "are shown by number", stacklevel=3)
    return {}


# Intents of a NIfTI file that holds no spatial volume, and the CIFTI-2 range (values on brainordinates)
NOT_VOLUMES = {1008: "a point set (a surface's vertices)", 1009: "triangles (a surface)"}
CIFTI_INTENTS = range(3000, 3100)


def _check_a_volume(path, image):
    """Refuse a NIfTI file that holds something other than a spatial volume (CIFTI-2, a surface), naming it."""
    import nibabel

    header = image.header if isinstance(image, nibabel.Nifti1Image) else getattr(image, "nifti_header", None)
    code = int(header["intent_code"]) if header is not None else 0
    if not isinstance(image, nibabel.Nifti1Image) or code in CIFTI_INTENTS:
        name = header.get_intent()[0] if code in CIFTI_INTENTS else type(image).__name__
        raise InputError(f"{path} is a CIFTI-2 file ({name}: a matrix of values on brain surfaces and structures), "
                         "not a spatial volume")
    if code in NOT_VOLUMES:
        raise InputError(f"{path} holds {NOT_VOLUMES[code]}, not a spatial volume")


def _check_sizes(path, image, shape):
    """Refuse, before reading them, voxels that the file does not hold or this machine cannot: an uncompressed
    file must hold what its header promises, and a volume that nibabel reads into memory (one frame of a 4-D
    file; compressed or scaled voxels: unscaled ones of a ``.nii`` are memory-mapped) must fit there.
    """
    dtype, offset = image.header.get_data_dtype(), int(image.dataobj.offset)   # where nibabel reads the voxels
    compressed = str(path).lower().endswith(".gz")
    if not compressed:
        check_holds(path, promised_bytes(shape, dtype), path.stat().st_size - offset)
        if image.dataobj.slope == 1 and image.dataobj.inter == 0:
            return

    def held(limit):                                         # what the .nii.gz inflates to, past its header
        with open(path, "rb") as f:
            return inflated_size(f, "gzip", offset + limit) - offset

    check_fits(shape[:3], dtype, path, held if compressed else None)


def _inflated_voxels(path, image, shape, frame):
    """The unscaled voxels ``[z, y, x]`` of a ``.nii.gz`` (of a 4-D file, frame ``frame``), inflated in large
    blocks by one bounded zlib stream (``_shared.read_voxels``): gzip's file object inflates in small reads that
    hold Python's lock between them, so a folder of masks read on two threads took as long as on one.
    """
    dtype, offset = image.header.get_data_dtype(), int(image.dataobj.offset)
    volume = tuple(int(n) for n in shape[:3][::-1])                       # i fastest: C order [k, j, i]
    skip = offset + (frame or 0) * promised_bytes(volume, dtype)
    with open(path, "rb") as f:
        return read_voxels(f, volume, dtype, path, codec="gzip", skip=skip, longer=True)


def holds_nifti(path):
    """A folder of NIfTI files (besides notes)."""
    return path.is_dir() and bool(volume_files(path, SUFFIXES))


READER = Reader(read_nifti, SUFFIXES, options=("frame",), sniff=holds_nifti, open=open_nifti)
