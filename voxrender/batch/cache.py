"""The cache of encoded objects a batch keeps (``OUT/.voxrender-cache``): keyed by the input's content and the options
that shape the object, each entry checked by its checksum before it is used.
"""

from __future__ import annotations

import functools
import hashlib
import json
from dataclasses import asdict
from pathlib import Path

from .. import __version__
from ..errors import InputError
from ..object.pipeline import load_segments


def _content_files(path):
    """The files an input is made of: a folder's (a series, a mask folder), or the file and the data files a
    detached header names.
    """
    if path.is_dir():
        return sorted(p for p in path.rglob("*") if p.is_file())
    files = [path]
    if path.suffix.lower() == ".mhd":
        files += [p for p in path.parent.iterdir() if p.suffix.lower() in (".raw", ".zraw")]
    if path.suffix.lower() == ".nhdr":                      # a detached NRRD header names its data file
        files += [p for p in path.parent.iterdir() if p.name.startswith(path.stem + ".") and p != path]
    return files



def cache_key(path, read, prepare):
    """Hex digest of the input's content (every file's name and bytes) and the options that shape the object."""
    digest = hashlib.sha256()
    path = Path(path)
    if not path.exists():            # a manifest's row may name anything
        raise InputError(f"no such file or folder: {path}", parameter="inputs")
    files = _content_files(path)
    if prepare.labels is not None and prepare.labels.source is not None:      # the paired label map shapes it too
        if not Path(prepare.labels.source).exists():
            raise InputError(f"no such file or folder: {prepare.labels.source}", parameter="labels_from")
        files += _content_files(Path(prepare.labels.source))
    for file in files:
        digest.update(str(file.relative_to(path) if file.is_relative_to(path) else file.name).encode())
        _add_bytes(digest, file)
    digest.update(json.dumps([asdict(read), asdict(prepare), __version__], sort_keys=True, default=_stable).encode())
    return digest.hexdigest()[:32]



def _stable(value):
    """A text for ``value`` that is the same in every process (a function's name, not its address)."""
    return getattr(value, "__qualname__", None) or str(value)



def study_files(target):
    """The grey values and the record a cache entry keeps beside the object when its pictures draw them (the labels
    and codes too, when it has them).
    """
    from ..qc.study import saved_files

    grey, _, record, _ = saved_files(target.with_suffix(""))
    return [grey, record]



def record_of(entry):
    """The record beside a cache entry: its size and checksum, written once the entry is whole."""
    return entry.with_name(entry.name + ".json")



def _add_bytes(digest, path):
    """Feed the bytes of the file at ``path`` to ``digest``, a block at a time."""
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            digest.update(block)



def checksum(path):
    """The size and SHA-256 of the file at ``path``."""
    digest = hashlib.sha256()
    _add_bytes(digest, path)
    return {"bytes": Path(path).stat().st_size, "sha256": digest.hexdigest()}



def is_intact(entry):
    """Whether the cache entry exists and its bytes are those its record says were written."""
    try:
        record = json.loads(record_of(entry).read_text())
        return record["bytes"] == entry.stat().st_size and record == checksum(entry)
    except (OSError, ValueError, KeyError, TypeError):   # no entry, no record, or a damaged record
        return False



@functools.lru_cache(maxsize=2)
def load_encoded(path, stamp):
    """The object at ``path`` (``stamp``: its size and time, so a remade file is read again), kept between the
    tasks of a worker with its octree (read from a ``.vxo``, or built once per object, not once per picture).
    """
    return load_segments(path)



@functools.lru_cache(maxsize=2)
def load_study_files(path, stamp):
    """The grey values kept beside the object at ``path`` (memory-mapped), with the object, kept as
    :func:`load_encoded`.
    """
    from ..qc.study import load_saved

    return load_saved(Path(path).with_suffix(""), load_encoded(path, stamp))
