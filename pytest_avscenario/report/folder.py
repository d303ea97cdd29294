"""The report directory one run owns: its lock, its manifest of our files, its fallback.

``--avs-report DIR`` is a directory people share: two pytest runs of one checkout (a
developer's and an editor's test runner), a CI job re-run in the same workspace, or a
project folder that already holds an ``index.html`` of its own. A run therefore *claims*
the directory before it writes there (:func:`claim_report_dir`):

* it takes an exclusive OS lock on ``DIR/.avs-lock`` (``fcntl.flock``: released by the
  kernel when the process ends, however it ends), and writes its pid there for the next
  run's warning. Where ``fcntl`` is missing (Windows) there is no lock;
* ``DIR/.avs-manifest.json`` lists every file a run of ours wrote in the directory; a new
  run deletes exactly those (our files of the earlier run), and records each file it is
  about to write *before* writing it, so a killed run's files are still known. A new name
  is appended as one line to ``DIR/.avs-manifest.log`` (constant cost per file, however many
  the report holds); the log is folded into the JSON when the run releases the directory,
  and a killed run's log is read with its JSON;
* a file at one of the names we write (``index.html``, ``tables/<slug>-1a2b3c4d.csv`` …)
  that the manifest does not list belongs to somebody else: we neither delete nor
  overwrite it, and neither do we touch a directory another live run holds. The run then
  uses the first free sibling ``DIR-2``, ``DIR-3``, … and the caller warns with the reasons.

Every file of the report is written atomically (:func:`atomic_write_bytes`), except the
error tables, which grow row by row (the writer is :mod:`pytest_avscenario.files`, shared
with the replay database and the pictures). The folder is *confined* there: nothing is
written, read or deleted through a symbolic link below it, nor opened unless it is a
regular file. A link or a special file at one of our names (``.avs-lock``, ``cases``,
``errors.jsonl`` …) is somebody else's too: the run uses a sibling and says which path was
in the way. Nothing here imports pytest.
"""

from __future__ import annotations

import errno
import json
import os
import re
import stat
from pathlib import Path
from typing import Any, IO

from .. import files
from ..files import atomic_write_bytes, atomic_write_text


__all__ = ["ReportFolder", "ReportDirBusy", "claim_report_dir", "describe_fallback", "is_own_name",
           "atomic_write_bytes", "atomic_write_text", "MANIFEST", "LOCK", "MAX_SIBLINGS",
           "MAIN_JSONL", "SHRINK_JSONL", "TABLES_DIR"]

MAIN_JSONL = "errors.jsonl"
SHRINK_JSONL = "shrink.jsonl"
TABLES_DIR = "tables"

MANIFEST = ".avs-manifest.json"
MANIFEST_LOG = ".avs-manifest.log"  # names added since the JSON was last written, one a line
LOCK = ".avs-lock"

#: ``DIR``, then ``DIR-2`` … ``DIR-<MAX_SIBLINGS>``: more concurrent runs than this is a loop
#: somewhere, not a workload, and the run is then reported in the terminal only
MAX_SIBLINGS = 20

# The names a run of ours writes: fixed names at the top, "<readable>-<8 hex>" + our suffixes
# below. Only these can be in our way, and only these are ever deleted.
_TOP = {MAIN_JSONL, SHRINK_JSONL, "summary.json", "index.html"}
#: the largest manifest read (a few hundred bytes per case; far beyond any report)
_MAX_MANIFEST = 256 * 1024 * 1024
_SUB = {
    TABLES_DIR: re.compile(r"[^/]+-[0-9a-f]{8}(\.shrink)?\.csv"),
    "plots": re.compile(r"[^/]+-[0-9a-f]{8}\.(space|rho)\.png"),
    # a case's pictures, recording, card and exports: "<slug>-<hash>[.<kind>].(png|gif|json|
    # html|xosc|xodr)" (a map copied beside the exports: "<map>-<hash>.xodr"); its OSI trace,
    # named by OSI's convention: "<UTC time>_sv_<OSI>_<protobuf>_<frames>_<slug>-<hash>.osi";
    # the cards' shared replay player: "replay-<hash>.js"
    "cases": re.compile(r"[^/]+-[0-9a-f]{8}(\.[A-Za-z0-9_.-]+)?\.(png|gif|json|html|xosc|xodr)"
                        r"|[0-9]{8}T[0-9]{6}Z_sv_[0-9]+_[0-9]+_[0-9]+_[A-Za-z0-9-]+-[0-9a-f]{8}\.osi"
                        r"|replay-[0-9a-f]{8}\.js"),
}


def is_own_name(rel: str) -> bool:
    """Whether ``rel`` (a path relative to the report directory, ``/``-separated) is a name
    a run of ours writes."""
    parts = rel.split("/")
    if len(parts) == 1:
        return rel in _TOP
    return len(parts) == 2 and parts[0] in _SUB and bool(_SUB[parts[0]].fullmatch(parts[1]))


class ReportDirBusy(OSError):
    """No directory among ``DIR``, ``DIR-2`` … could be claimed."""


class ReportFolder:
    """One report directory and the manifest of the files we wrote in it.

    Without :func:`claim_report_dir` (e.g. an :class:`~.table.ErrorTable` used on its own)
    there is no lock, but files written through :meth:`add` are still recorded, so the next
    run knows they are ours.
    """

    def __init__(self, path: str | os.PathLike):
        self.path = Path(path)
        files.confine(self.path)
        self.files: set[str] = set()
        self.manifest_unreadable = False
        self._lock: IO[str] | None = None
        self._log: IO[str] | None = None
        manifest = self.path / MANIFEST
        if os.path.lexists(manifest):
            try:
                data = json.loads(files.read_regular(manifest, _MAX_MANIFEST).decode("utf-8"))
                self.files = {f for f in data["files"] if isinstance(f, str)}
            except (OSError, ValueError, KeyError, TypeError):
                self.manifest_unreadable = True  # then no file counts as ours
            else:
                self.files |= self._logged()

    def _logged(self) -> set[str]:
        """The names a run appended to the log (complete lines only: a line cut short by a
        killed process names no file)."""
        try:
            text = files.read_regular(self.path / MANIFEST_LOG, _MAX_MANIFEST).decode("utf-8")
        except (OSError, ValueError):
            return set()
        return {line for line in text.split("\n")[:-1] if line}

    def _rel(self, path: str | os.PathLike) -> str:
        rel = Path(os.path.relpath(os.path.abspath(path), os.path.abspath(self.path))).as_posix()
        if rel == ".." or rel.startswith("../"):
            raise ValueError(f"{path} is not inside the report directory {self.path}")
        return rel

    def owns(self, path: str | os.PathLike) -> bool:
        """Whether ``path`` lies inside this directory."""
        try:
            Path(path).resolve().relative_to(self.path.resolve())
        except ValueError:
            return False
        return True

    def add(self, path: str | os.PathLike) -> Path:
        """Record ``path`` (a file inside the directory) as ours, before writing it."""
        rel = self._rel(path)
        if rel not in self.files:
            self._append([rel])
        return Path(path)

    def add_all(self, paths: Any) -> list[Path]:
        """:meth:`add` for many files at once (one write to the log)."""
        out = [Path(p) for p in paths]
        new = sorted({self._rel(p) for p in out} - self.files)
        if new:
            self._append(new)
        return out

    def _append(self, rels: list[str]) -> None:
        if self._log is None:
            if not (self.path / MANIFEST).exists():
                self._save()  # the log only ever extends a manifest that exists
            self._log = files.open_regular(self.path / MANIFEST_LOG, "a")
        self._log.write("".join(f"{rel}\n" for rel in rels))
        self._log.flush()  # in the OS's hands before the file is written: a killed run's too
        self.files.update(rels)

    def _save(self) -> None:
        """Write the whole manifest as JSON, then drop the log it now contains."""
        atomic_write_text(self.path / MANIFEST, json.dumps(
            {"written_by": "pytest-avscenario", "files": sorted(self.files)}, indent=1) + "\n")
        if self._log is not None:
            self._log.close()
            self._log = None
        try:
            files.unlink_file(self.path / MANIFEST_LOG)  # ours: its names are in the JSON now
        except FileNotFoundError:
            pass

    def compact(self) -> None:
        """Fold this run's log into the JSON manifest (when the run ends; nothing to do when
        it added no file)."""
        if self._log is not None:
            self._save()

    def foreign(self) -> list[str]:
        """Files at names we write that the manifest does not list (somebody else's)."""
        found = []
        for name in sorted(_TOP):
            if (self.path / name).is_file() and name not in self.files:
                found.append(name)
        for sub in _SUB:
            folder = self.path / sub
            if not folder.is_dir():
                continue
            for f in sorted(folder.iterdir()):
                rel = f"{sub}/{f.name}"
                if is_own_name(rel) and f.is_file() and rel not in self.files:
                    found.append(rel)
        return found

    def in_the_way(self) -> list[str]:
        """Our names (the lock, the manifest, the pages, tables, ``cases/`` …) taken by a
        symbolic link or a special file: none is ever written, read or deleted through."""
        found = []
        for name in sorted(_TOP | {LOCK, MANIFEST, MANIFEST_LOG}):
            mode = _lmode(self.path / name)
            if mode is not None and not stat.S_ISREG(mode):
                found.append(name)
        for sub in sorted(_SUB):
            mode = _lmode(self.path / sub)
            if mode is None:
                continue
            if not stat.S_ISDIR(mode):
                found.append(sub)
                continue
            for f in sorted(os.scandir(self.path / sub), key=lambda e: e.name):
                rel = f"{sub}/{f.name}"
                if is_own_name(rel) and not f.is_file(follow_symlinks=False):
                    found.append(rel)
        return found

    def clear(self) -> None:
        """Delete the files an earlier run of ours wrote (as the manifest lists them), then
        ``tables/``, ``plots/`` and ``cases/`` if that left them empty; start a new manifest."""
        for rel in sorted(self.files):
            if not is_own_name(rel):
                continue  # the lock file, or a hand-edited entry: never deleted
            try:
                files.unlink_file(self.path / rel)
            except FileNotFoundError:
                pass
        for sub in _SUB:
            try:
                files.remove_dir(self.path / sub)
            except OSError:
                pass  # missing, or somebody else's files live there too
        self.files = {LOCK} if self._lock is not None else set()
        self._save()

    # -- the lock --------------------------------------------------------------------------
    def lock(self) -> tuple[bool, str]:
        """Try to take the directory's lock without waiting: ``(taken, holder's pid or "")``.

        True also where the platform has no ``flock`` or the file system refuses locks."""
        try:
            import fcntl
        except ImportError:
            return True, ""
        fh = files.open_regular(self.path / LOCK, "a+")
        try:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            holder = fh.read().strip()
            fh.close()
            return False, holder if holder.isdigit() else ""
        except OSError:
            fh.close()  # e.g. a network file system without locks: go on unlocked
            return True, ""
        fh.seek(0)
        fh.truncate()
        fh.write(f"{os.getpid()}\n")
        fh.flush()
        self._lock = fh
        return True, ""

    def close(self) -> None:
        """This run adds no more files: fold its log into the JSON (when that fails, e.g. on
        a full disk, the log stays and the next run reads it with the JSON)."""
        try:
            self.compact()
        except OSError:
            pass
        finally:
            if self._log is not None:
                self._log.close()
                self._log = None

    def release(self) -> None:
        """:meth:`close`, and give the lock back (the kernel does so too when the process
        ends)."""
        self.close()
        if self._lock is not None:
            self._lock.close()
            self._lock = None


def _sibling(requested: Path, n: int) -> Path:
    return requested if n == 1 else requested.with_name(f"{requested.name}-{n}")


def claim_report_dir(requested: str | os.PathLike, *,
                     max_siblings: int = MAX_SIBLINGS) -> tuple[ReportFolder, list[str]]:
    """Claim ``requested`` or its first free sibling for this process's report.

    Returns the locked, cleared :class:`ReportFolder` and, when it is not ``requested``, one
    sentence per directory passed over saying why. Raises :class:`ReportDirBusy` when every
    candidate is taken, OSError when ``requested`` is a file or a directory cannot be created
    or cleared.
    """
    requested = Path(requested)
    reasons: list[str] = []
    for n in range(1, max_siblings + 1):
        path = _sibling(requested, n)
        if path.exists() and not path.is_dir():
            if n == 1:  # a mistake in the option rather than a directory somebody uses
                raise NotADirectoryError(errno.ENOTDIR, "a file, not a directory", str(path))
            reasons.append(f"{path} is a file, not a directory")
            continue
        existed = path.is_dir()
        lock_existed = (path / LOCK).exists()
        folder = ReportFolder(path)
        if existed:
            links = folder.in_the_way()
            if links:
                reasons.append(_links_reason(path, links))
                continue
        if existed and not lock_existed:
            # Look before creating a lock file there: a folder of somebody else's stays as it was.
            foreign = folder.foreign()
            if foreign:
                reasons.append(_foreign_reason(path, foreign, folder))
                continue
        path.mkdir(parents=True, exist_ok=True)
        taken, holder = folder.lock()
        if not taken:
            pid = f" (pid {holder})" if holder else ""
            reasons.append(f"{path} is in use by another pytest run{pid}")
            continue
        folder = _reread(folder)  # the manifest as the previous holder left it
        try:
            foreign = folder.foreign()
            if foreign:
                folder.release()
                reasons.append(_foreign_reason(path, foreign, folder))
                continue
            folder.clear()
        except BaseException:
            folder.release()  # a folder this run cannot use stays free for the next
            raise
        return folder, reasons
    raise ReportDirBusy("; ".join(reasons) + f"; no free directory among {requested} … "
                        f"{_sibling(requested, max_siblings)}")


def _reread(locked: ReportFolder) -> ReportFolder:
    fresh = ReportFolder(locked.path)
    fresh._lock, locked._lock = locked._lock, None
    return fresh


def _links_reason(path: Path, links: list[str]) -> str:
    shown = ", ".join(str(path / f) for f in links[:3]) + (f" and {len(links) - 3} more" if len(links) > 3 else "")
    return f"{shown} {'is a symbolic link or not a regular file' if len(links) == 1 else 'are symbolic links or special files'}; pytest-avscenario writes through none"


def _lmode(path: Path) -> int | None:
    try:
        return os.lstat(path).st_mode
    except OSError:
        return None


def _foreign_reason(path: Path, foreign: list[str], folder: ReportFolder) -> str:
    shown = ", ".join(str(path / f) for f in foreign[:3]) + (f" and {len(foreign) - 3} more" if len(foreign) > 3 else "")
    why = (f"{path / MANIFEST} is unreadable" if folder.manifest_unreadable
           else f"not listed in {path / MANIFEST}" if (path / MANIFEST).exists()
           else "there is no manifest of ours")
    return f"{path} holds files pytest-avscenario did not write ({shown}: {why})"


def describe_fallback(requested: Path, used: Path, reasons: list[str]) -> str:
    """The one warning of a run that writes its report to a sibling directory."""
    return (f"avscenario: the report goes to {used} instead of {requested}: " + "; ".join(reasons)
            + ". Nothing there was deleted or overwritten; give each concurrent run its own "
            "--avs-report directory, or move those files away")
