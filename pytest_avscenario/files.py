"""Every file the package writes, reads back or deletes: atomically, and never through a link.

One opener for everything the package leaves on disk: the report's pages, tables, manifest
and lock, the replay database's entries and the case pictures. A neutral module (it imports
nothing of the package) so the simulator's drawing code and the database can use it without
importing the report.

Two guarantees, whatever somebody else put at a path:

* **Nothing is written, read or deleted through a symbolic link below a confined folder.** A
  folder the package owns (the report folder) is *confined* (:func:`confine`): a path below
  it is reached from the folder's own descriptor one component at a time, each directory
  opened with ``O_DIRECTORY | O_NOFOLLOW`` and the file itself with ``O_NOFOLLOW``, so a
  ``cases`` that is a link to an archive, or an ``errors.jsonl`` that is a dangling link,
  stops the operation with :class:`UnsafePath` naming the path instead of writing, or
  deleting, elsewhere. The confined folder itself, and the folders above it, may be links
  (``--avs-report`` pointing at a bigger disk is the user's choice). Outside a confined folder
  the file's own name is still never followed.
* **Only regular files are read or replaced, and no open blocks.** Every open carries
  ``O_NONBLOCK`` and is checked with ``fstat`` before a byte is read or written: a FIFO,
  device or socket at one of our names is refused with :class:`UnsafePath` ("is a FIFO, not
  a regular file") instead of waiting forever for a writer that never comes. A replacing
  write does not replace a link or a special file either: the user's link or FIFO stays.

Where the platform has no ``dir_fd`` / ``O_NOFOLLOW`` (Windows), paths are checked with
``lstat`` before use instead.
"""

from __future__ import annotations

import errno
import os
import secrets
import stat
from pathlib import Path
from typing import IO, Any

__all__ = ["UnsafePath", "confine", "atomic_write_bytes", "atomic_write_text", "fsync_dir",
           "open_regular", "read_regular", "unlink_file", "remove_dir", "make_dirs", "move_file"]

_NOFOLLOW = getattr(os, "O_NOFOLLOW", 0)
_DIRECTORY = getattr(os, "O_DIRECTORY", 0)
_NONBLOCK = getattr(os, "O_NONBLOCK", 0)
_CLOEXEC = getattr(os, "O_CLOEXEC", 0)
_BINARY = getattr(os, "O_BINARY", 0)
#: open relative to a directory's descriptor: the walk below a confined folder
_DIR_FD = bool(_NOFOLLOW and _DIRECTORY) and {os.open, os.mkdir, os.unlink, os.rmdir, os.stat,
                                              os.rename}.issubset(os.supports_dir_fd)

#: the folders the package owns, as absolute paths (links in them are never followed)
_CONFINED: set[str] = set()


class UnsafePath(OSError):
    """A path the package will not write, read or delete through: a symbolic link, or not a
    regular file (a FIFO would block, a device is not ours). ``strerror`` is a whole sentence
    naming the path."""


def confine(root: str | os.PathLike) -> None:
    """Never follow a link below ``root`` (a folder the package owns) from now on."""
    _CONFINED.add(os.path.abspath(root))


def _kind(mode: int) -> str:
    return ("a symbolic link" if stat.S_ISLNK(mode) else "a FIFO" if stat.S_ISFIFO(mode)
            else "a directory" if stat.S_ISDIR(mode) else "a socket" if stat.S_ISSOCK(mode)
            else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "not a regular file")


def _unsafe(path: str, mode: int | None, what: str = "a regular file") -> UnsafePath:
    if mode is None or stat.S_ISLNK(mode):
        return UnsafePath(errno.ELOOP, f"{path} is a symbolic link; pytest-avscenario writes, reads "
                          "and deletes through none", path)
    return UnsafePath(errno.EINVAL, f"{path} is {_kind(mode)}, not {what}; pytest-avscenario "
                      "leaves it as it is", path)


def _why(dfd: int, name: str, shown: str, what: str = "a regular file") -> UnsafePath:
    try:
        mode = os.stat(name, dir_fd=dfd, follow_symlinks=False).st_mode
    except OSError:
        mode = None
    return _unsafe(shown, mode, what)


def _root_of(path: str) -> str | None:
    best = None
    for root in _CONFINED:
        if path.startswith(root.rstrip(os.sep) + os.sep) and (best is None or len(root) > len(best)):
            best = root
    return best


def _parent(path: str | os.PathLike, create: bool) -> tuple[int, str, str]:
    """``(descriptor of the directory holding path, the file's name, path as shown)``; below
    a confined folder every directory on the way is opened without following links (and made
    when ``create``). The caller closes the descriptor."""
    shown = os.fspath(path)
    full = os.path.abspath(shown)
    parent, name = os.path.split(full)
    if not name:
        raise IsADirectoryError(errno.EISDIR, "is a directory", shown)
    root = _root_of(full)
    if root is None:
        if create:
            os.makedirs(parent, exist_ok=True)
        return os.open(parent, os.O_RDONLY | _DIRECTORY | _CLOEXEC), name, shown
    if create:
        os.makedirs(root, exist_ok=True)  # the folder itself is the user's choice, links and all
    dfd = os.open(root, os.O_RDONLY | _DIRECTORY | _CLOEXEC)
    walked = root
    try:
        for part in os.path.relpath(parent, root).split(os.sep) if parent != root else ():
            walked = os.path.join(walked, part)
            try:
                nfd = os.open(part, os.O_RDONLY | _DIRECTORY | _NOFOLLOW | _CLOEXEC, dir_fd=dfd)
            except FileNotFoundError:
                if not create:
                    raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), walked) from None
                try:
                    os.mkdir(part, dir_fd=dfd)
                except FileExistsError:
                    pass
                nfd = os.open(part, os.O_RDONLY | _DIRECTORY | _NOFOLLOW | _CLOEXEC, dir_fd=dfd)
            except OSError as exc:
                if exc.errno in (errno.ELOOP, errno.ENOTDIR, errno.EMLINK):
                    raise _why(dfd, part, walked, "a directory") from None
                raise
            os.close(dfd)
            dfd = nfd
    except BaseException:
        os.close(dfd)
        raise
    return dfd, name, shown


def _checked_path(path: str | os.PathLike, create: bool) -> str:
    """Without ``dir_fd``: the path, once no component below a confined folder is a link."""
    full = os.path.abspath(path)
    root = _root_of(full)
    parent = os.path.dirname(full)
    if create:
        os.makedirs(parent, exist_ok=True)
    if root is not None:
        walked = root
        for part in os.path.relpath(full, root).split(os.sep):
            walked = os.path.join(walked, part)
            try:
                mode = os.lstat(walked).st_mode
            except FileNotFoundError:
                break
            if stat.S_ISLNK(mode):
                raise _unsafe(walked, mode)
    return full


def _open_fd(path: str | os.PathLike, flags: int, create: bool, follow: bool = False) -> int:
    """A descriptor of the regular file ``path`` opened with ``flags`` (plus no-follow,
    non-blocking, close-on-exec); UnsafePath for anything else, checked before use."""
    flags |= _NONBLOCK | _CLOEXEC | _BINARY | (0 if follow else _NOFOLLOW)
    shown = os.fspath(path)
    if _DIR_FD:
        dfd, name, shown = _parent(path, create)
        try:
            try:
                fd = os.open(name, flags, 0o666, dir_fd=dfd)
            except OSError as exc:
                if exc.errno in (errno.ELOOP, errno.EMLINK, errno.ENXIO, errno.EISDIR):
                    raise _why(dfd, name, shown) from None
                raise
        finally:
            os.close(dfd)
    else:
        fd = os.open(_checked_path(path, create), flags, 0o666)
    try:
        mode = os.fstat(fd).st_mode
        if not stat.S_ISREG(mode):
            raise _unsafe(shown, mode)
    except BaseException:
        os.close(fd)
        raise
    return fd


_MODES = {"r": os.O_RDONLY, "w": os.O_WRONLY | os.O_CREAT, "a": os.O_WRONLY | os.O_CREAT | os.O_APPEND,
          "r+": os.O_RDWR, "a+": os.O_RDWR | os.O_CREAT | os.O_APPEND}


def open_regular(path: str | os.PathLike, mode: str = "r", encoding: str | None = "utf-8",
                 newline: str | None = None) -> IO[Any]:
    """``open(path, mode)`` for a regular file only, never through a link (see the module):
    ``mode`` is one of r, w, a, r+, a+ (add ``b`` for bytes); ``w`` truncates after the
    check, so a file that is refused is not emptied either."""
    binary = "b" in mode
    base = mode.replace("b", "")
    fd = _open_fd(path, _MODES[base], create=base != "r" and base != "r+")
    try:
        if base == "w":
            os.ftruncate(fd, 0)
        if binary:
            return os.fdopen(fd, mode)
        return os.fdopen(fd, mode, encoding=encoding, newline=newline)
    except BaseException:
        os.close(fd)
        raise


def read_regular(path: str | os.PathLike, max_bytes: int, follow: bool = False) -> bytes:
    """At most ``max_bytes + 1`` bytes of the regular file ``path`` (more than ``max_bytes``
    means it is too large for the caller). ``follow=True`` for a file the user named (a
    baseline may be a link); it must still be a regular file."""
    fd = _open_fd(path, os.O_RDONLY, create=False, follow=follow)
    with os.fdopen(fd, "rb") as fh:
        return fh.read(max_bytes + 1)


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


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def atomic_write_bytes(path: str | os.PathLike, data: bytes, durable: bool = True) -> None:
    """Write ``data`` to ``path`` so readers see the old file or the new one, never half.

    Writes a temporary file in the same directory (a hidden ``.<name>.<random>.tmp``, which
    no reader's file pattern matches, with the mode a plain ``open()`` would give: reports and
    a shared database are read by CI artifact servers, caches and colleagues), fsyncs it, then
    renames it over the target (atomic on POSIX and Windows within one file system). Refused
    (:class:`UnsafePath`, nothing written) when the target is a link or not a regular file, or
    a folder on the way below a confined folder is a link. ``durable=False`` skips the two
    fsyncs (the file and the directory; ~10 ms per file on a busy disk): still whole or absent
    after a killed process, but a power cut may lose it — for the many per-case files of a
    report (cards, case pictures), which are held to the error table's rows' standard
    (flushed, not fsynced). Errors are ``OSError`` s; the temporary file is removed.
    """
    if not _DIR_FD:
        _atomic_write_by_path(path, data, durable)
        return
    dfd, name, shown = _parent(path, create=True)
    try:
        _regular_or_absent(dfd, name, shown)
        tmp = f".{name}.{secrets.token_hex(4)}.tmp"
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW | _CLOEXEC, 0o666, dir_fd=dfd)
        try:
            try:
                _write_all(fd, data)
                if durable:
                    os.fsync(fd)
            finally:
                os.close(fd)
            os.rename(tmp, name, src_dir_fd=dfd, dst_dir_fd=dfd)
        except BaseException:
            try:
                os.unlink(tmp, dir_fd=dfd)
            except OSError:
                pass
            raise
        if durable:
            try:
                os.fsync(dfd)
            except OSError:
                pass
    finally:
        os.close(dfd)


def _atomic_write_by_path(path: str | os.PathLike, data: bytes, durable: bool) -> None:
    import tempfile

    full = _checked_path(path, create=True)
    if os.path.lexists(full) and not stat.S_ISREG(os.lstat(full).st_mode):
        raise _unsafe(os.fspath(path), os.lstat(full).st_mode)
    parent, name = os.path.split(full)
    mask = os.umask(0)
    os.umask(mask)
    fd, tmp = tempfile.mkstemp(prefix=f".{name}.", suffix=".tmp", dir=parent)
    try:
        os.chmod(tmp, 0o666 & ~mask)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            if durable:
                os.fsync(fh.fileno())
        os.replace(tmp, full)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    if durable:
        fsync_dir(parent)


def atomic_write_text(path: str | os.PathLike, text: str, encoding: str = "utf-8",
                      durable: bool = True) -> None:
    """:func:`atomic_write_bytes` for text."""
    atomic_write_bytes(path, text.encode(encoding), durable=durable)


def unlink_file(path: str | os.PathLike) -> None:
    """Delete the regular file ``path``: never a link, a special file, or anything reached
    through a link below a confined folder (:class:`UnsafePath`); FileNotFoundError when it
    is not there."""
    if not _DIR_FD:
        full = _checked_path(path, create=False)
        mode = os.lstat(full).st_mode
        if not stat.S_ISREG(mode):
            raise _unsafe(os.fspath(path), mode)
        os.unlink(full)
        return
    dfd, name, shown = _parent(path, create=False)
    try:
        mode = os.stat(name, dir_fd=dfd, follow_symlinks=False).st_mode
        if not stat.S_ISREG(mode):
            raise _unsafe(shown, mode)
        os.unlink(name, dir_fd=dfd)
    finally:
        os.close(dfd)


def remove_dir(path: str | os.PathLike) -> None:
    """Remove the empty directory ``path`` (OSError when it is not empty, not there, or a
    link: a link is never removed)."""
    if not _DIR_FD:
        full = _checked_path(path, create=False)
        if os.path.islink(full):
            raise _unsafe(os.fspath(path), None)
        os.rmdir(full)
        return
    dfd, name, _ = _parent(path, create=False)
    try:
        os.rmdir(name, dir_fd=dfd)
    finally:
        os.close(dfd)


def make_dirs(path: str | os.PathLike) -> Path:
    """``mkdir -p path``, never through a link below a confined folder."""
    if not _DIR_FD:
        full = _checked_path(os.path.join(path, "."), create=False)
        os.makedirs(full, exist_ok=True)
        return Path(path)
    dfd, name, shown = _parent(os.path.join(os.fspath(path), "x"), create=True)
    os.close(dfd)
    return Path(path)


def _regular_or_absent(dfd: int, name: str, shown: str) -> None:
    """Refuse (:class:`UnsafePath`) a target ``name`` in folder ``dfd`` that exists and is not
    a regular file (a link, a FIFO, a folder): it is replaced only when it is one of ours."""
    try:
        mode = os.stat(name, dir_fd=dfd, follow_symlinks=False).st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISREG(mode):
        raise _unsafe(shown, mode)


def move_file(src: str | os.PathLike, dst: str | os.PathLike) -> None:
    """Move the regular file ``src`` (of ours, e.g. a worker's picture) to ``dst`` under the
    same rules as :func:`atomic_write_bytes` for the target."""
    if _DIR_FD:
        dfd, name, shown = _parent(dst, create=True)
        try:
            _regular_or_absent(dfd, name, shown)
            try:
                os.rename(src, name, dst_dir_fd=dfd)
                return
            except OSError as exc:
                if exc.errno != errno.EXDEV:
                    raise
        finally:
            os.close(dfd)
    data = read_regular(src, 1 << 31)
    atomic_write_bytes(dst, data, durable=False)
    os.unlink(src)
