"""Open an input for reading only if it is a regular file.

A FIFO named as an input would block its reader forever (no writer ever comes), a
character device (``/dev/zero``, ``/dev/urandom``) never ends, and a symlink loop is not
"missing". The file is opened without blocking and checked on the open descriptor, so it
cannot be swapped for a FIFO between the check and the read.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import BinaryIO

_KINDS = (
    (stat.S_ISFIFO, "a named pipe"),
    (stat.S_ISCHR, "a character device"),
    (stat.S_ISBLK, "a block device"),
    (stat.S_ISSOCK, "a socket"),
)


class NotRegularFile(OSError):
    """The path is a FIFO, a device or a socket; ``strerror`` says which."""


def open_regular(path: str | os.PathLike, *, follow_links: bool = True) -> BinaryIO:
    """Open ``path`` for binary reading; raise ``OSError`` unless it is a regular file.

    A folder raises ``IsADirectoryError``, a FIFO, device or socket :class:`NotRegularFile`
    (``strerror`` e.g. ``is a named pipe, not a regular file``); a missing file
    ``FileNotFoundError`` and a symlink loop ``OSError`` with ``ELOOP``, as ``open`` does.
    Without ``follow_links``, a symbolic link raises ``OSError`` (``ELOOP``) too.
    """
    flags = os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0)
    if not follow_links:
        flags |= getattr(os, "O_NOFOLLOW", 0)
    fd = os.open(Path(path), flags)
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(path))
        if not stat.S_ISREG(mode):
            kind = next((name for test, name in _KINDS if test(mode)), "a special file")
            raise NotRegularFile(errno.EINVAL, f"is {kind}, not a regular file", str(path))
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise
