"""Files written atomically: each appears complete under its name, or not at all, so that a failed or interrupted
command never leaves a half-written output; and the checks, made before any work, that an output can be written.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
from pathlib import Path

from ..errors import InputError


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

