"""What the readers share: the :class:`Volume` they return, the :class:`Reader` record that describes each, and
the listing of folders, the filling of stacks and the checks they have in common.
"""

from __future__ import annotations

import bz2
import contextlib
import logging
import math
import os
import re
import threading
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from .._shared.memory import free_memory
from .._shared.text import first_line, in_words
from ..errors import InputError

# Files that sit beside slices or volume files without being either.
NOTE_SUFFIXES = {".txt", ".md", ".json", ".csv", ".tsv", ".xml", ".ini", ".py"}
# Pictures a pipeline leaves beside its volume files (TotalSegmentator's preview_total.png).
PICTURE_SUFFIXES = {".png", ".jpg", ".jpeg"}


@dataclass
class Volume:
    """A stack of slices: ``values[z, y, x]`` with voxel ``spacing`` (x, y, z) in mm.

    ``direction`` (3 x 3, or ``None`` when the input does not say) holds in column ``k`` the patient (LPS)
    direction along which voxel axis ``k`` (x, y, z) grows; see :mod:`voxrender.space.orient`.  ``meta["origin"]``, when
    the input says it, is the patient position (LPS, mm) of voxel ``values[0, 0, 0]``; with the direction and the
    spacing it makes :func:`voxrender.space.grids.patient_affine`.

    Examples
    --------
    >>> v = Volume(np.zeros((3, 4, 5), np.int16), (0.5, 0.5, 2.0))
    >>> v.shape
    (3, 4, 5)
    """

    values: np.ndarray
    spacing: tuple[float, float, float] = (1.0, 1.0, 1.0)
    meta: dict = field(default_factory=dict)
    direction: np.ndarray | None = None

    @property
    def shape(self):
        return self.values.shape


@dataclass(frozen=True)
class Reader:
    """One input format: its reading function and how to recognise its files.

    Parameters
    ----------
    function : callable
        ``function(path, progress, **options) -> Volume``.
    suffixes : tuple of str
        File name endings (lower case) that mean this format when ``format="auto"``.
    options : tuple of str
        The keyword options of :func:`~voxrender.io.read_volume` it takes (``"raw"``, ``"series"``, ``"frame"``).
    sniff : callable, optional
        ``sniff(path) -> bool``: whether ``path`` is of this format although no suffix says so, from what a folder
        holds or a file's magic bytes.  ``format="auto"`` asks it after every reader's suffixes.
    sniff_first : bool
        Ask ``sniff`` of a file before any reader's suffixes: for a format whose files bear another's suffix (a
        DICOM SEG is a ``.dcm`` file).
    open : callable, optional
        ``open(path, **options) -> Stack``: the stack unread, its slices read a slab at a time
        (:class:`voxrender.io._stack.Stack`), for stacks larger than memory; ``None`` when the format is read whole.
    """

    function: Callable
    suffixes: tuple = ()
    options: tuple = ()
    sniff: Callable | None = None
    sniff_first: bool = False
    open: Callable | None = None


@dataclass(frozen=True)
class RawLayout:
    """How headerless slices are laid out: ``width`` x ``height`` values of ``dtype`` (with its byte order).

    >>> RawLayout(64, 64, np.dtype("<u2")).slice_bytes
    8192
    """

    width: int
    height: int
    dtype: np.dtype

    def __post_init__(self):
        if int(self.width) < 1 or int(self.height) < 1:
            raise InputError(f"width and height must be positive, not {self.width}x{self.height}", parameter="raw")
        if np.dtype(self.dtype).kind not in "uif":
            raise InputError(f"dtype {np.dtype(self.dtype).name!r} is not numeric", parameter="raw")

    @property
    def slice_bytes(self):
        return int(self.width) * int(self.height) * np.dtype(self.dtype).itemsize


def natural_key(name):
    """Sort key that orders ``quarter.2`` before ``quarter.10``.

    >>> sorted(["s10.png", "s2.png", "s1.png"], key=natural_key)
    ['s1.png', 's2.png', 's10.png']
    """
    return [(0, int(part), "") if part.isdigit() else (1, 0, part.lower())
            for part in re.split(r"(\d+)", str(name)) if part]


def identity_progress(iterable, length=None, label=None):
    return iterable


def check_spacing(spacing, source=None):
    """``spacing`` as three positive floats (x, y, z) in mm; ``source`` names the file it came from, if any.

    >>> check_spacing([1, 1, 2.5])
    (1.0, 1.0, 2.5)
    """
    where = f"{source}: " if source else ""
    try:
        values = tuple(float(s) for s in spacing)
    except (TypeError, ValueError):
        values = ()
    if len(values) != 3 or not all(np.isfinite(v) and v > 0 for v in values):
        raise InputError(f"{where}spacing must be three positive numbers x, y, z in mm, not {spacing}",
                         parameter=None if source else "spacing")
    return values


def listed(folder):
    """The files in ``folder`` (hidden ones left out), in natural order of names."""
    return sorted((p for p in folder.iterdir() if p.is_file() and not p.name.startswith(".")),
                  key=lambda p: natural_key(p.name))


def files_in(folder):
    """The files in ``folder``, for a reader: an empty folder is bad input."""
    files = listed(folder)
    if not files:
        raise InputError(f"{folder} is an empty folder; give a folder of slices")
    return files


def some_names(files, count=3):
    """The first few names of ``files``, for a message.

    >>> from pathlib import Path
    >>> some_names([Path("a.nii.gz"), Path("b.nii.gz"), Path("c.nii.gz"), Path("d.nii.gz")])
    'a.nii.gz, b.nii.gz, c.nii.gz, ...'
    """
    return ", ".join([f.name for f in files[:count]] + ["..."] * (len(files) > count))


def volume_files(folder, suffixes):
    """The files of ``folder`` whose names end in ``suffixes`` when, besides notes and fewer pictures than them
    (:func:`files_beside`), they are all it holds: a folder of volume files, such as a segmentation's one file per
    organ with TotalSegmentator's ``preview_total.png`` and ``statistics.json``; otherwise an empty list.

    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> for name in ("liver.nii.gz", "spleen.nii.gz", "preview_total.png", "statistics.json"):
    ...     _ = (folder / name).write_bytes(b"")
    >>> [f.name for f in volume_files(folder, (".nii.gz",))], [f.name for f in files_beside(folder, (".nii.gz",))]
    (['liver.nii.gz', 'spleen.nii.gz'], ['preview_total.png', 'statistics.json'])
    """
    files = listed(folder)
    found = [f for f in files if f.name.lower().endswith(suffixes)]
    beside = files_beside(folder, suffixes)
    return found if len(found) + len(beside) == len(files) else []


def files_beside(folder, suffixes):
    """The files beside a folder's volume files (named with ``suffixes``) that a pipeline writes with them and a
    reader passes over: notes (JSON, CSV, text) and pictures (a preview PNG or JPEG), when fewer pictures than volume
    files (a folder of many pictures is a stack of slices).
    """
    files = listed(folder)
    volumes = sum(f.name.lower().endswith(suffixes) for f in files)
    pictures = [f for f in files if f.suffix.lower() in PICTURE_SUFFIXES and not f.name.lower().endswith(suffixes)]
    notes = [f for f in files if f.suffix.lower() in NOTE_SUFFIXES]
    return sorted(notes + (pictures if len(pictures) < volumes else []), key=lambda p: natural_key(p.name))


def folder_of_volumes(folder, kind, suffixes):
    """The error for a folder given where one ``kind`` volume file (named with ``suffixes``) was wanted."""
    files = [f for f in files_in(folder) if f.name.lower().endswith(suffixes)]
    if not files:
        return InputError(f"{folder} is a folder without {kind} files; give a {kind} file")
    masks = ", or the folder as one label map of masks (format masks)" if kind in ("NIfTI", "NRRD") else ""
    return InputError(f"{folder} holds {len(files)} {kind} volume file{'s' * (len(files) > 1)} ({some_names(files)}), "
                      f"not slices; give one of them{masks}")


class _Kept(logging.Handler):
    """Takes a quieted library's log in place of its own handlers: each record goes to the innermost list of the
    thread that logged it (readers run on threads: the masks of a folder, two at a time).
    """

    def __init__(self):
        super().__init__(logging.WARNING)
        self.lists, self.depth, self.saved = {}, 0, None

    def emit(self, record):
        lists = self.lists.get(record.thread)
        if lists:
            lists[-1].append(record.getMessage())


_QUIET_LOCK = threading.Lock()
_QUIETED = {}


@contextlib.contextmanager
def quiet_log(name):
    """Keep the log of library ``name`` quiet while it reads: it logs what it mends or skips in a damaged file,
    which the reader's one error line (or the volume) says well enough.  Yields the list of what it logged (its
    warnings and errors) in this thread, for a reader that must know what was skipped.
    """
    logger, logged, thread = logging.getLogger(name), [], threading.get_ident()
    with _QUIET_LOCK:
        kept = _QUIETED.setdefault(name, _Kept())
        if not kept.depth:                        # the first reader in: the library's own handlers step aside
            kept.saved = (logger.handlers[:], logger.propagate)
            logger.handlers[:] = [kept]
            logger.propagate = False
        kept.depth += 1
        kept.lists.setdefault(thread, []).append(logged)
    try:
        yield logged
    finally:
        with _QUIET_LOCK:
            kept.lists[thread].pop()
            if not kept.lists[thread]:
                del kept.lists[thread]
            kept.depth -= 1
            if not kept.depth:                    # the last one out: they come back
                logger.handlers[:], logger.propagate = kept.saved

def to_grey(image, name):
    """A 2-D slice from an image file; colour images become luminance in their own units."""
    if image.ndim == 3 and image.shape[-1] in (3, 4):
        rgb = image[..., :3]
        if np.all(rgb == rgb[..., :1]):
            return rgb[..., 0]
        return (rgb @ np.array([0.2125, 0.7154, 0.0721])).astype(np.float32)
    if image.ndim != 2:
        raise InputError(f"{name} is not a 2-D image (shape {image.shape}); slices must be single images")
    return image


def fill_stack(items, read_slice, label, progress, source):
    """Allocate the volume from the first slice (if the free memory holds it), then fill it slice by slice;
    ``source`` names the folder in messages.
    """
    volume = None
    for z, item in enumerate(progress(items, len(items), label)):
        data, name = read_slice(item)
        if volume is None:
            check_fits((len(items),) + data.shape, data.dtype, source)
            volume = np.empty((len(items),) + data.shape, dtype=data.dtype)
            first = name
        if data.shape != volume.shape[1:]:
            raise InputError(f"slice {name} is {data.shape[1]}x{data.shape[0]} but {first} is "
                             f"{volume.shape[2]}x{volume.shape[1]}; all slices must have the same size")
        if np.can_cast(data.dtype, volume.dtype, "safe"):
            volume[z] = data
        else:  # a later slice needs a wider type: widen once, keep going
            check_fits(volume.shape, np.result_type(volume.dtype, data.dtype), source)
            volume = volume.astype(np.result_type(volume.dtype, data.dtype))
            volume[z] = data
    return volume


def slices_at(path, offset, shape, dtype, z0, z1):
    """Slices ``z0 .. z1 - 1`` of a C-ordered ``shape`` array of ``dtype`` stored at byte ``offset`` of ``path``,
    read by one call (no memory map, whose touched pages would stay resident), in native byte order.  A slice is
    what follows the first axis (of a 4-D array, a slice of every frame).
    """
    dtype = np.dtype(dtype)
    plane = math.prod(int(n) for n in shape[1:])
    values = np.fromfile(path, dtype, count=(z1 - z0) * plane, offset=offset + z0 * plane * dtype.itemsize)
    if values.size != (z1 - z0) * plane:
        raise InputError(f"{path} ends within slice {z0 + values.size // max(plane, 1)}; the file is truncated")
    return values.reshape(z1 - z0, *shape[1:]).astype(dtype.newbyteorder("="), copy=False)


def real_numbers(values, source):
    """The voxels as integers or floats the renderers take, whatever type ``source`` stores: booleans become 0 and
    1 (a view, no copy), 16-bit floats 32-bit ones; complex (or other) values are refused.

    >>> real_numbers(np.array([True, False]), "mask.npy")
    array([1, 0], dtype=uint8)
    """
    if values.dtype.kind == "b":
        return values.view(np.uint8)
    if values.dtype == np.float16:
        check_fits(values.shape, np.float32, source)
        return values.astype(np.float32)
    if values.dtype.kind not in "uif":
        raise InputError(f"{source} holds {values.dtype.name} values; voxrender needs real numbers (integers or "
                         "floats)")
    return values


def stack_type(dtype, source):
    """The type :func:`~voxrender.io.read_volume` gives slices stored as ``dtype`` (booleans as ``uint8``, 16-bit
    floats as 32-bit ones, in native byte order), for a :class:`~voxrender.io._stack.Stack` of them; other than
    real numbers is refused, naming ``source``.
    """
    return real_numbers(np.empty(0, dtype), source).dtype.newbyteorder("=")


def check_frame(path, frame, count=None):
    """The ``frame`` to read of a 4-D file of ``count`` volumes (``None``: a 3-D file, which takes none), checked;
    a 4-D file of one volume gives it without being asked.
    """
    if count is None:
        if frame is not None:
            raise InputError(f"{path} holds one volume; a frame number applies to 4-D files", parameter="frame")
    elif count == 1 and frame is None:
        return 0
    elif frame is None:
        raise InputError(f"{path} holds {count} volumes (4-D); choose one with a frame number 0 to {count - 1}",
                         parameter="frame")
    elif not 0 <= frame < count:
        raise InputError(f"{frame} is not a volume of {path}, which holds {count} (0 to {count - 1})",
                         parameter="frame")
    return frame


# ---------------------------------------------------------------- sizes, checked before allocating
# A header can promise any size: what it promises is compared with what the file holds, and with the memory this
# machine has free, before the voxels are allocated; compressed voxels are inflated no further than promised.

CHUNK = 1 << 22          # bytes read or inflated at a time


def promised_bytes(shape, dtype):
    """The bytes of an array of ``shape`` and ``dtype``, in Python integers (no overflow, whatever a header says).

    >>> promised_bytes((30000, 30000, 30000), np.int16)
    54000000000000
    """
    return math.prod(int(n) for n in shape) * np.dtype(dtype).itemsize


def check_fits(shape, dtype, source, held=None):
    """Refuse, before allocating it, a volume of ``shape`` and ``dtype`` that this machine's free memory cannot hold.

    ``held(limit)`` (optional) counts the bytes a compressed file holds (up to ``limit`` + 1): it is asked only
    when the volume is too big, so that a file holding less than its header promises is named as such.

    Examples
    --------
    >>> check_fits((2, 3, 4), np.int16, "v.nii")
    48
    """
    nbytes = promised_bytes(shape, dtype)
    free = free_memory()
    if nbytes > free:
        if held is not None:
            check_holds(source, nbytes, held(nbytes))
        raise InputError(f"{source}: its {'x'.join(str(int(n)) for n in shape)} {np.dtype(dtype).name} voxels take "
                         f"{in_words(nbytes)}, more than the {in_words(free)} of memory free here, and this reads a "
                         "volume whole: encode it into a .vxs first, which reads it a slab at a time (and can bin "
                         "it), or cut it down to a subregion")
    return nbytes


def check_holds(source, promised, held, what="voxels", exact=False):
    """Refuse a file that holds fewer bytes of ``what`` than its header promises (or, ``exact``, other than it
    promises), with both numbers.
    """
    held = max(held, 0)
    words = (in_words(held), in_words(promised))
    if words[0] == words[1]:                      # "15.8 kB of the 15.8 kB" would say nothing: the bytes, then
        words = (f"{held} bytes", f"{promised} bytes")
    if held < promised:
        raise InputError(f"{source} holds {words[0]} of {what}, of the {words[1]} its header promises; the file is "
                         "cut short or its header is damaged")
    if exact and held > promised:
        raise InputError(f"{source} holds {words[0]} of {what}, more than the {words[1]} its header promises; the "
                         "header is damaged")


def inflate(stream, codec, promised, source, longer=False):
    """Exactly ``promised`` bytes inflated from the rest of ``stream`` (a binary file) in ``codec`` (``"gzip"``,
    ``"bzip2"``, or ``"zlib"``: zlib or gzip), inflating no more than that; a stream that ends short, or runs long
    (unless ``longer``: the voxels are the first part of it, a frame of several), is refused with both numbers.

    Examples
    --------
    >>> import io
    >>> len(inflate(io.BytesIO(zlib.compress(bytes(10))), "zlib", 10, "v.mha"))
    10
    """
    data = bytearray()
    try:
        for chunk in _inflated_chunks(stream, codec, promised + 1):
            data += chunk
    except (zlib.error, OSError, EOFError) as exc:          # what zlib and bz2 raise for a garbled stream
        raise _damaged_stream(codec, source, len(data), exc) from None
    if len(data) > promised and longer:
        del data[promised:]
    if len(data) > promised:
        raise _longer_stream(codec, source, promised)
    check_holds(f"the {codec} stream of {source}", promised, len(data))
    return data


def _damaged_stream(codec, source, inflated, exc):
    return InputError(f"the {codec} stream of {source} is damaged after {inflated:,} bytes: {first_line(exc)}")


def _longer_stream(codec, source, promised):
    return InputError(f"the {codec} stream of {source} holds more than the {in_words(promised)} of voxels its "
                      "header promises; the header is damaged")


def read_voxels(stream, shape, dtype, source, codec=None, skip=0, exact=False, longer=False):
    """The voxels ``[z, y, x]`` of ``shape`` and ``dtype`` in the rest of the binary file ``stream``: raw
    (``codec=None``), or inflated by ``codec`` (``"gzip"``, ``"bzip2"`` or ``"zlib"``) past its first ``skip``
    inflated bytes.  Before anything is allocated, what the header promises is compared with what the file holds
    (``exact``: no more either, for raw voxels; ``longer``: a compressed stream may hold more, as a 4-D file's
    frame does) and with the memory free.

    Examples
    --------
    >>> import io
    >>> read_voxels(io.BytesIO(zlib.compress(bytes(8))), (2, 2, 2), np.uint8, "v.mha", "zlib").shape
    (2, 2, 2)
    """
    nbytes = promised_bytes(shape, dtype)
    if codec is None:
        check_holds(source, nbytes, os.fstat(stream.fileno()).st_size - stream.tell(), exact=exact)
        check_fits(shape, dtype, source)
        return np.fromfile(stream, dtype, count=math.prod(shape)).reshape(shape)
    start = stream.tell()
    check_fits(shape, dtype, source, held=lambda limit: inflated_size(stream, codec, skip + limit) - skip)
    stream.seek(start)
    return np.frombuffer(inflate(stream, codec, skip + nbytes, source, longer), dtype, offset=skip).reshape(shape)


def inflated_size(stream, codec, limit):
    """How many bytes the rest of ``stream`` inflates to, counted without keeping them, up to ``limit`` + 1."""
    size = 0
    try:
        for chunk in _inflated_chunks(stream, codec, limit + 1):
            size += len(chunk)
    except (zlib.error, OSError, EOFError):
        pass
    return size


def _inflated_chunks(stream, codec, limit):
    """The bytes inflated from ``stream`` in ``codec``, in chunks, until its compressed stream ends or ``limit``
    bytes have come.
    """
    if codec == "bzip2":
        decompressor = bz2.BZ2Decompressor()
    else:                                    # gzip, or zlib's own format (or gzip: 32 tells them apart)
        decompressor = zlib.decompressobj(zlib.MAX_WBITS | (16 if codec == "gzip" else 32))
    pending, size = b"", 0
    while not decompressor.eof and size < limit:
        if not pending and getattr(decompressor, "needs_input", True):   # zlib hands back what it did not take
            pending = stream.read(CHUNK)
            if not pending:
                return                                   # the file ends before the stream does: cut short
        chunk = decompressor.decompress(pending, min(CHUNK, limit - size))
        pending = getattr(decompressor, "unconsumed_tail", b"")
        size += len(chunk)
        yield chunk


# ---------------------------------------------------------------- slabs, for stacks larger than memory
# A Stack's slices are read when asked for: raw ones at their offset, by one read; compressed ones from a stream
# inflated forward by one decompressor kept between reads (so slabs read in order cost one pass), with the same
# checks of what the header promises as above, made as the stream is read.


class InflatedStream:
    """The bytes the compressed stream of ``path`` (from byte ``offset``, in ``codec``) inflates to, read forward a
    piece at a time by one decompressor kept between reads: pieces read in increasing order inflate the stream
    once; a piece before the current position starts it again (correct, slow).

    The stream must hold ``promised`` bytes: one that ends before a piece does, or is damaged, is refused when that
    piece is read; one holding more (unless ``longer``: the piece is the first part of it) when its last piece is.
    Between reads the file stays open, in the generator that inflates it: it is closed when the last piece has been
    read, when the stream starts again, or when the stream is dropped.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "v.z"
    >>> _ = path.write_bytes(zlib.compress(bytes(range(10))))
    >>> stream = InflatedStream(path, 0, "zlib", 10)
    >>> stream.read(2, 3).tolist(), stream.read(8, 2).tolist(), stream.read(0, 1).tolist()
    ([2, 3, 4], [8, 9], [0])
    """

    def __init__(self, path, offset, codec, promised, longer=False):
        self.path, self.offset, self.codec, self.promised, self.longer = path, offset, codec, promised, longer
        self.position = 0                    # inflated bytes handed out or passed over
        self._chunks = None                  # the inflated chunks still to come, or None before the first read
        self._held = memoryview(b"")         # the rest of the last chunk, from ``position``

    def read(self, start, count):
        """The inflated bytes ``start .. start + count - 1`` as a ``uint8`` array."""
        if not 0 <= start <= start + count <= self.promised:
            raise IndexError(f"bytes {start}:{start + count} of {self.promised}")
        if self._chunks is None or start < self.position:
            self._restart()
        out = np.empty(count, np.uint8)
        try:
            self._take(start - self.position, None)
            self._take(count, out)
            if start + count == self.promised and not self.longer and self._more():
                raise _longer_stream(self.codec, self.path, self.promised)
        except InputError:
            self._close()                    # the next read starts again: no half-consumed state kept
            raise
        if start + count == self.promised:   # nothing further to read: the file need not stay open
            self._close()
        return out

    def _restart(self):
        self._close()
        self._chunks = self._inflated()
        self.position, self._held = 0, memoryview(b"")

    def _close(self):
        if self._chunks is not None:
            self._chunks.close()
        self._chunks = None

    def _inflated(self):
        with open(self.path, "rb") as f:
            f.seek(self.offset)
            yield from _inflated_chunks(f, self.codec, self.promised + (not self.longer))

    def _next_chunk(self):
        """The next inflated chunk, or ``None`` where the stream ends."""
        try:
            return next(self._chunks, None)
        except (zlib.error, OSError, EOFError) as exc:          # what zlib and bz2 raise for a garbled stream
            raise _damaged_stream(self.codec, self.path, self.position, exc) from None

    def _take(self, count, out):
        """Hand out the next ``count`` inflated bytes into ``out`` (or pass over them: ``None``)."""
        done = 0
        while done < count:
            if not len(self._held):
                chunk = self._next_chunk()
                if chunk is None:            # the stream ends before the header's promise
                    check_holds(f"the {self.codec} stream of {self.path}", self.promised, self.position)
                self._held = memoryview(chunk)
                continue
            size = min(count - done, len(self._held))
            if out is not None:
                out[done:done + size] = np.frombuffer(self._held[:size], np.uint8)
            self._held, self.position, done = self._held[size:], self.position + size, done + size

    def _more(self):
        """Whether the stream holds bytes past the current position (it is inflated at most one further)."""
        while not len(self._held):
            chunk = self._next_chunk()
            if chunk is None:
                return False
            self._held = memoryview(chunk)
        return True


def open_voxels(source, offset, shape, dtype, codec=None, skip=0, exact=False, longer=False, first=0, count=None):
    """What a :class:`~voxrender.io._stack.Stack` needs to read the slices of a C-ordered array ``shape`` of
    ``dtype`` (a slice is what follows its first axis) stored in the file ``source``: raw at byte ``offset``, or
    compressed by ``codec`` (``"gzip"``, ``"bzip2"`` or ``"zlib"``) from byte ``offset`` on, past its first
    ``skip`` inflated bytes.  The stack is the slices ``first .. first + count - 1`` (a frame of a 4-D file).

    What the header promises is checked as :func:`read_voxels` checks it, but not against the free memory: raw
    voxels now (``exact``: no more either), a compressed stream as it is read (:class:`InflatedStream`).

    Returns
    -------
    read_slices : callable
        ``read_slices(z0, z1)``: the stack's slices ``z0 .. z1 - 1`` in native byte order.
    stored_bytes : int
        The bytes of ``source`` read for the whole stack (of a compressed stream, those up to the stack's end).
    """
    dtype = np.dtype(dtype)
    count = int(shape[0]) - first if count is None else count
    plane = promised_bytes(shape[1:], dtype)
    nbytes = promised_bytes(shape, dtype)
    if codec is None:
        check_holds(source, nbytes, os.stat(source).st_size - offset, exact=exact)

        def read_slices(z0, z1):
            return slices_at(source, offset, shape, dtype, first + z0, first + z1)

        return read_slices, count * plane
    stream = InflatedStream(source, offset, codec, skip + nbytes, longer)

    def read_slices(z0, z1):
        data = stream.read(skip + (first + z0) * plane, (z1 - z0) * plane)
        return data.view(dtype).reshape(z1 - z0, *shape[1:]).astype(dtype.newbyteorder("="), copy=False)

    end = skip + (first + count) * plane                 # the stream's compressed bytes are spread evenly, roughly
    return read_slices, max(1, (os.stat(source).st_size - offset) * end // max(skip + nbytes, 1))
