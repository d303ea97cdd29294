"""Writing a file so readers see the old one or the new one, never half of it.

One writer for everything the package leaves on disk: the report's pages, tables and
manifest, the replay database's entries and the case pictures. A neutral module (it
imports nothing of the package) so the simulator's drawing code and the database can use it
without importing the report.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

__all__ = ["atomic_write_bytes", "atomic_write_text", "fsync_dir"]


def fsync_dir(directory: str | os.PathLike) -> None:
    """Make a rename in ``directory`` durable; not possible (nor needed) on every platform."""
    try:
        fd = os.open(directory, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_bytes(path: str | os.PathLike, data: bytes, durable: bool = True) -> None:
    """Write ``data`` to ``path`` so readers see the old file or the new one, never half.

    Writes a temporary file in the same directory (a hidden ``.<name>.<random>.tmp``, which
    no reader's file pattern matches), fsyncs it, then ``os.replace``s it over the target
    (atomic on POSIX and Windows within one file system). ``durable=False`` skips the two
    fsyncs (the file and the directory; ~10 ms per file on a busy disk): still whole or
    absent after a killed process, but a power cut may lose it — for the many per-case files
    of a report (cards, case pictures), which are held to the error table's rows' standard
    (flushed, not fsynced). Errors are ``OSError`` s; the temporary file is removed.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        # mkstemp makes the file private (0600); reports and a shared database are read by
        # CI artifact servers, caches and colleagues: give it the mode a plain open() would
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            if durable:
                os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    if durable:
        fsync_dir(path.parent)


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8",
                      durable: bool = True) -> None:
    """:func:`atomic_write_bytes` for text."""
    atomic_write_bytes(path, text.encode(encoding), durable=durable)
