"""Writing files, atomically: pictures, depth arrays, JSON reports and slice folders.

Every writer goes through :func:`atomic_output`: the file appears complete under its name, or not
at all, so a failed or interrupted command never leaves a half-written output.
"""

from __future__ import annotations

import contextlib
import json
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import InputError


def check_writable(path):
    """Raise :class:`InputError` now if ``path`` could not be written later.

    >>> check_writable("/no/such/folder/out.png")
    Traceback (most recent call last):
    ...
    voxrender.errors.InputError: cannot write /no/such/folder/out.png: folder /no/such/folder does not exist
    """
    path = Path(path)
    folder = path.parent
    if not folder.is_dir():
        raise InputError(f"cannot write {path}: folder {folder} does not exist")
    refused = _write_refused(folder)
    if refused:
        raise InputError(f"cannot write {path}: folder {folder} is not writable ({refused})")
    if path.is_dir():
        raise InputError(f"cannot write {path}: it is a folder; give a file name")


def check_folder_writable(folder):
    """Raise :class:`InputError` now if no file can be made in ``folder``, by making one and removing it.

    A real write tells what :func:`os.access` cannot: a read-only file system, a full disk, or (when running as
    root, whom permissions do not stop) that the folder is writable after all.
    """
    refused = _write_refused(folder)
    if refused:
        raise InputError(f"cannot write in {folder}: {refused}")


def _write_refused(folder):
    """Why no file can be made in ``folder`` (the system's words), found by making one and removing it; ``None``
    when one can.
    """
    try:
        fd, probe = tempfile.mkstemp(prefix=".voxrender-probe-", dir=folder)
    except OSError as exc:
        return exc.strerror or str(exc)
    os.close(fd)
    os.unlink(probe)
    return None


# The temporaries of atomic_output are named .{name}{PARTIAL}XXXXXXXX{suffix}: only a process killed while writing
# leaves one behind, and remove_partials finds it by this name.
PARTIAL = ".partial-"


@contextlib.contextmanager
def atomic_output(path):
    """Yield a temporary path beside ``path``, in the same folder; rename it to ``path`` only on success.

    A failure leaves neither a partial file nor the temporary behind (a killed process leaves its temporary, which
    :func:`remove_partials` clears).
    """
    path = Path(path)
    check_writable(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}{PARTIAL}", suffix=path.suffix, dir=path.parent)
    os.close(fd)
    try:
        yield Path(tmp)
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the usual permissions
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


def remove_partials(folder):
    """Remove the temporaries that processes killed while writing left in ``folder``; the number removed.

    Only for a folder no running process writes in (a batch holds its folder's lock).
    """
    removed = 0
    for leftover in Path(folder).glob(f".*{PARTIAL}*"):
        if leftover.is_file():
            leftover.unlink()
            removed += 1
    return removed


def _umask():
    mask = os.umask(0)
    os.umask(mask)
    return mask


# zlib level 3: on a 512 x 512 picture of the head, 1.6 ms for an 8-bit grey PNG against 2.2 ms at level 6, for
# files within 10 % of the same size (level 1 is no faster on grey pictures).
PNG_LEVEL = 3


def write_png(path, image, level=PNG_LEVEL):
    """Write an 8-bit or 16-bit grey or RGB image to ``path`` as PNG, atomically; an RGB picture without colour
    (its three channels equal) is written as 8-bit grey, a third of the work and of the file.

    The PNG is put together here (signature, IHDR, one zlib IDAT of "Up"-filtered rows, IEND): a fresh process
    then pays no image library's import and plugin start-up, 30 ms against the 3 ms of the write itself.

    >>> import tempfile, imageio.v3 as iio
    >>> path = Path(tempfile.mkdtemp()) / "grey.png"
    >>> write_png(path, np.full((2, 3, 3), 7, np.uint8))
    >>> iio.imread(path).tolist()
    [[7, 7, 7], [7, 7, 7]]
    """
    import struct
    import zlib

    image = np.asarray(image)
    if image.ndim == 3 and image.shape[2] == 3 and image.dtype == np.uint8 and \
            (image[..., 0] == image[..., 1]).all() and (image[..., 0] == image[..., 2]).all():
        image = image[..., 0]
    if image.dtype not in (np.uint8, np.uint16) or image.ndim not in (2, 3) or \
            (image.ndim == 3 and image.shape[2] != 3):
        raise ValueError(f"a PNG holds 8- or 16-bit grey or RGB pixels, not {image.dtype} {image.shape}")
    height, width = image.shape[:2]
    rows = np.ascontiguousarray(image, dtype=">u2" if image.dtype == np.uint16 else np.uint8)
    rows = rows.reshape(height, -1).view(np.uint8)
    # filter "Up" (2): each byte minus the byte above it, which flattens a picture's smooth areas for zlib
    filtered = np.empty((height, rows.shape[1] + 1), np.uint8)
    filtered[:, 0] = 2
    filtered[0, 1:] = rows[0]
    np.subtract(rows[1:], rows[:-1], out=filtered[1:, 1:])

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))

    colour = 2 if image.ndim == 3 else 0
    header = struct.pack(">IIBBBBB", width, height, 16 if image.dtype == np.uint16 else 8, colour, 0, 0, 0)
    data = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(filtered.tobytes(), level)) + \
        chunk(b"IEND", b"")
    with atomic_output(path) as tmp:
        tmp.write_bytes(data)


def write_npy(path, array):
    """Write ``array`` to ``path`` as ``.npy``, atomically."""
    with atomic_output(path) as tmp, open(tmp, "wb") as f:
        np.save(f, array)


def write_json(path, data):
    """Write ``data`` to ``path`` as indented JSON (NumPy numbers as floats), atomically."""
    with atomic_output(path) as tmp:
        tmp.write_text(json.dumps(data, indent=2, default=float))


def write_slices(values, folder):
    """Write ``values[z, y, x]`` (uint16) as 16-bit PNG slices ``slice_000.png`` ... into ``folder``.

    >>> import tempfile
    >>> folder = write_slices(np.zeros((2, 3, 4), np.uint16), Path(tempfile.mkdtemp()) / "stack")
    >>> sorted(p.name for p in folder.iterdir())
    ['slice_000.png', 'slice_001.png']
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    for z, plane in enumerate(values):
        write_png(folder / f"slice_{z:03d}.png", plane)
    return folder


def write_nifti(path, values, spacing=(1.0, 1.0, 1.0), origin=(0.0, 0.0, 0.0)):
    """Write ``values[z, y, x]``, in the canonical frame (x toward L, y toward P, z toward S), as NIfTI (gzipped
    when ``path`` ends in ``.gz``) with its sform, atomically; ``origin`` is the patient position (LPS, mm) of
    ``values[0, 0, 0]`` (a volume's ``meta["origin"]``), so that a label map written of an image pairs with it.

    >>> import tempfile
    >>> path = write_nifti(Path(tempfile.mkdtemp()) / "v.nii.gz", np.zeros((2, 3, 4), np.int16), (1, 1, 2))
    >>> from voxrender.io import read_volume
    >>> read_volume(path).shape, read_volume(path).spacing
    ((2, 3, 4), (1.0, 1.0, 2.0))
    """
    import gzip

    import nibabel

    affine = np.diag([-float(spacing[0]), -float(spacing[1]), float(spacing[2]), 1.0])   # LPS voxels, RAS world
    affine[:3, 3] = np.asarray(origin, float) * [-1, -1, 1]
    data = nibabel.Nifti1Image(np.transpose(values, (2, 1, 0)), affine).to_bytes()
    with atomic_output(path) as tmp:
        tmp.write_bytes(gzip.compress(data, 6) if str(path).endswith(".gz") else data)
    return Path(path)


def write_nrrd(path, values, spacing=(1.0, 1.0, 1.0), fields=None, origin=(0.0, 0.0, 0.0)):
    """Write ``values[z, y, x]``, in the canonical frame, as a gzip-encoded NRRD in LPS space, atomically;
    ``fields`` adds header fields (e.g. a ``.seg.nrrd``'s ``Segment0_Name``), ``origin`` is as for
    :func:`write_nifti`.
    """
    import nrrd

    header = {"space": "left-posterior-superior", "space directions": np.diag([float(v) for v in spacing]),
              "space origin": [float(v) for v in origin], "encoding": "gzip", **(fields or {})}
    with atomic_output(path) as tmp:
        nrrd.write(str(tmp), np.ascontiguousarray(values), header, index_order="C")
    return Path(path)
