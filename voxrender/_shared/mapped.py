"""Reading memory-mapped arrays a block at a time, from their file, so that their pages do not stay resident."""

from __future__ import annotations

import os

import numpy as np


def blocks(array, overlap=0, count=1 << 24):
    """The values of an array a block at a time (:func:`read_mapped`: a file's are read from it, not through its
    mapping), each block with the first ``overlap`` values of the next.
    """
    for read in block_reads(array, overlap, count):
        yield read()


def block_reads(array, overlap=0, count=1 << 22):
    """The blocks of :func:`blocks`, each as a function that reads it: blocks read where they are used, on threads
    (:func:`~voxrender._shared.threads.on_threads`), each thread reading its own.
    """
    if not is_mapped(array) or not array.size:
        return [lambda: np.asarray(array)]
    return [lambda first=first: read_mapped(array, first, first + count + overlap)
            for first in range(0, array.size, count)]


def is_mapped(array):
    """Whether ``array`` is a view of a memory-mapped file."""
    return _mapping(array) is not None


def _mapping(array):
    """The memory map ``array`` is a view of, or ``None``: the last ``np.memmap`` down its bases, the one that holds
    the mapping (a slice of a memmap is a memmap too, but keeps the offset of the one it was cut from).
    """
    found = None
    while array is not None:
        if isinstance(array, np.memmap):
            found = array
        array = getattr(array, "base", None)
    return found


def prefetch(*arrays):
    """Ask the system to read the files behind memory-mapped ``arrays`` into its page cache, in the background
    (``posix_fadvise`` ``WILLNEED``), so that the disk reads them while the caller computes; plain arrays are
    left alone.  Nothing is read into this process's memory.
    """
    if not hasattr(os, "posix_fadvise"):
        return
    for array in arrays:
        mapping = _mapping(array)
        if mapping is None or mapping.filename is None or not array.size:
            continue
        try:
            descriptor = os.open(mapping.filename, os.O_RDONLY)
        except OSError:
            continue
        try:
            os.posix_fadvise(descriptor, _file_offset(array, mapping), array.nbytes, os.POSIX_FADV_WILLNEED)
        except OSError:
            pass                 # only advice: the reads come anyway
        finally:
            os.close(descriptor)


def read_mapped(array, first, last):
    """``array[first:last]`` (of a one-dimensional ``array``) as a plain array.  When ``array`` is a view of a
    memory-mapped file, the values are read from the file, so that its pages, unlike those of the mapping once
    touched, do not stay in the process's memory (a large object's normals are gigabytes).
    """
    first, last = max(first, 0), min(last, len(array))
    mapping = _mapping(array)
    if mapping is None or mapping.filename is None or not array.flags.c_contiguous:
        return np.array(array[first:last])
    return np.fromfile(mapping.filename, array.dtype, count=max(last - first, 0),
                       offset=_file_offset(array, mapping) + first * array.itemsize)


def file_span(array):
    """Where the bytes of a contiguous, memory-mapped ``array`` lie: ``(file name, offset)``; ``None`` for any
    other array.
    """
    mapping = _mapping(array)
    if mapping is None or mapping.filename is None or not array.flags.c_contiguous:
        return None
    return mapping.filename, _file_offset(array, mapping)


def _file_offset(array, mapping):
    """Where ``array``'s first value lies in the file behind ``mapping`` (the memory map it is a view of)."""
    return mapping.offset + array.__array_interface__["data"][0] - mapping.__array_interface__["data"][0]



def search_mapped(array, values, block=1 << 20):
    """``np.searchsorted(array, values)`` of a sorted one-dimensional ``array`` that may be a read-only mapping of a
    file: NumPy's own search copies such an array whole first (gigabytes, for a large object's normals); this one
    finds each value's block among every ``block``-th value, then searches that block alone, read from the file.

    >>> search_mapped(np.arange(0, 100, 2), [-1, 0, 3, 98, 99], block=8).tolist()
    [0, 0, 2, 49, 50]
    >>> search_mapped(np.array([0, 5], np.int32), [-2 ** 40, 5, 2 ** 40]).tolist()
    [0, 1, 2]
    """
    values, below, above = _in_type_of(array, values)
    if not is_mapped(array):
        found = np.asarray(np.searchsorted(array, values))
        found[below], found[above] = 0, len(array)
        return found
    firsts = np.array(array[::block])                     # a value of every block: a page each
    found = np.empty(values.shape, np.int64)
    which = np.maximum(np.searchsorted(firsts, values, "right") - 1, 0)
    for k in np.unique(which):                            # a Python loop over blocks, not values
        here = which == k
        part = read_mapped(array, k * block, (k + 1) * block)
        found[here] = k * block + np.searchsorted(part, values[here])
    found[below], found[above] = 0, len(array)
    return found


def _in_type_of(array, values):
    """``values`` as integers of ``array``'s type, when both are integers: NumPy searches integers of a wider type
    by copying the whole array into it first (the int32 voxel numbers of a level's normals, 227 MB, became 454 MB
    for each search).  Returns them, clipped to that type, and which were below and above its range.
    """
    values = np.asarray(values)
    none = np.zeros(values.shape, bool)
    if array.dtype.kind not in "iu" or values.dtype.kind not in "iu" or values.dtype == array.dtype:
        return values, none, none
    info = np.iinfo(array.dtype)
    below, above = values < info.min, values > info.max
    return np.clip(values, info.min, info.max).astype(array.dtype), below, above
