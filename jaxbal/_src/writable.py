"""Whether a path can be written, checked before the work whose result goes there (a
sweep's store, ``jaxbal plot --out``, ``jaxbal balance --out``), so that a read-only
folder, a parent that is a file or a location nobody may write is refused at once
instead of after the computation (the CLI says ``error: cannot write PATH: REASON``,
:func:`~jaxbal._src.cli_errors.cannot_write`).
"""

from __future__ import annotations

import errno
import os
import tempfile
from pathlib import Path

__all__ = ["check_writable"]


def check_writable(path) -> None:
    """Raise the :class:`OSError` that writing a new file or folder at ``path`` would
    raise: its nearest existing ancestor is a file (``NotADirectoryError``), or no file
    can be created in that folder (read-only file system, permissions, ``/proc``). The
    probe creates and deletes a hidden temporary file there; missing folders in between
    are left to the writer (which creates them).

    Raises:
        OSError: with the reason (``strerror``) and the path at fault (``filename``).
    """
    path = Path(path).absolute()
    if path.is_dir():
        raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
    folder = path.parent
    while not folder.exists() and folder != folder.parent:
        folder = folder.parent
    if not folder.is_dir():
        raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(folder))
    try:
        handle, probe = tempfile.mkstemp(dir=folder, prefix=".jaxbal-probe-")
    except OSError as error:  # named by the folder, not the probe's random name
        raise type(error)(error.errno, error.strerror, str(folder)) from None
    os.close(handle)
    os.unlink(probe)
