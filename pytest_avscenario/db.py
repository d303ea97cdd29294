"""The replay database: counterexamples kept between runs as plain JSON files.

Every failing case (minimized when shrinking succeeded) is stored so the next run replays
it first, like Hypothesis's example database but readable and reviewable: one JSON file
per (test, counterexample) in ``.avscenario/`` at the rootdir, holding the parameters, the
rho values, the case seed, the feature space it was found in (description and
fingerprint, so a changed scenario is noticed instead of replayed blindly), the versions
that found it and whether it was minimized. Files are written atomically (a temporary
file in the same directory, then ``os.replace``: :mod:`pytest_avscenario.files`), so concurrent pytest-xdist workers and a
CI cache merged from several jobs never show a half-written entry. File names are a hash
of (test, parameters) — never user text — and file contents are only ever parsed as
strict JSON: nothing read is executed, and no path is taken from a file's content.

A file is data anyone may have edited, so it is checked before anything uses it: one that
cannot be parsed (huge integers, deep nesting, wrong types, a seed that is no case seed) is
skipped with one warning, and at collection :func:`replay_params` checks each stored value
against its test's declared space. A skipped file is left on disk for the user to fix or
delete. Saving or deleting that fails raises :class:`DatabaseError`; the plugin turns it
into a line of the case's failure text and one warning, never a hidden failure.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import stat
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

from .codec import rho_from_json, rho_to_json
from .files import atomic_write_bytes, read_regular, unlink_file

if TYPE_CHECKING:
    from .space import FeatureSpace

__all__ = ["FORMAT", "NEAR", "DatabaseError", "Entry", "ReplayDB", "Stored", "departure",
           "near_duplicate", "replay_params", "space_changes"]

#: version of the entry format this module writes and reads
FORMAT = 1
#: what an entry's "kind" field says; JSON without it is some other tool's file
_KIND = "pytest-avscenario counterexample"
#: <12 hex of the test id>-<20 hex of (test, params)>.json
_NAME = re.compile(r"^([0-9a-f]{12})-([0-9a-f]{20})\.json$")
#: entries are a few kB; anything far larger is not ours and is not read into memory
_MAX_BYTES = 4 * 1024 * 1024
#: JSON nesting an entry may have: an entry is 3 levels deep plus a parameter's own value (a
#: Choice option may be a list or an object); deeper content is not ours, and refusing it
#: here keeps every later step (hashing, comparing) far from Python's recursion limit
_MAX_DEPTH = 32
#: case seeds are 63-bit (``case.stable_seed``); anything else is not a seed the plugin wrote
SEED_RANGE = "an integer from 0 to 2**63-1"
_SEED_END = 2**63


#: how close two stored counterexamples' parameters are, in the sampler's unit coordinates
#: (a fraction of each parameter's range), to be the same one found twice (:meth:`ReplayDB.store`)
NEAR = 0.05


@dataclass(frozen=True)
class Stored:
    """What :meth:`ReplayDB.store` did: ``entry`` is the stored counterexample that stands for
    the case (the new one, or the one already there when ``written`` is False); ``replaced``
    the files of the entries it made redundant (deleted), ``problems`` why any could not be."""

    entry: "Entry"
    written: bool
    replaced: tuple[Path, ...] = ()
    #: why a redundant entry could not be deleted (it stays; the new one is stored)
    problems: tuple[str, ...] = ()


def _unit(dist: Any, value: Any) -> float | None:
    try:
        u = float(dist.to_unit(value))
    except (TypeError, ValueError, KeyError, ArithmeticError):
        return None
    return u if math.isfinite(u) else None


def near_duplicate(space: FeatureSpace, a: Mapping[str, Any], b: Mapping[str, Any], near: float = NEAR) -> bool:
    """Whether parameter sets ``a`` and ``b`` are the same counterexample found twice: every
    parameter departs from its nominal value in both or in neither, categories are equal, and
    numbers lie within ``near`` of each other in unit coordinates."""
    for name, dist in space.parameters.items():
        if dist.kind == "constant":
            continue
        if name not in a or name not in b:
            return False
        if dist.kind == "categorical":
            if _canon(a[name]) != _canon(b[name]):
                return False
            continue
        ua, ub, un = _unit(dist, a[name]), _unit(dist, b[name]), _unit(dist, dist.nominal)
        if ua is None or ub is None or un is None:
            return False
        if (abs(ua - un) > 1e-12) != (abs(ub - un) > 1e-12) or abs(ua - ub) > near:
            return False
    return True


def departure(space: FeatureSpace, params: Mapping[str, Any]) -> float:
    """How far ``params`` lie from the nominal scenario: the sum over parameters of the
    distance in unit coordinates (1 per category that is not the nominal one)."""
    total = 0.0
    for name, dist in space.parameters.items():
        if dist.kind == "constant" or name not in params:
            continue
        if dist.kind == "categorical":
            total += 0.0 if _canon(params[name]) == _canon(dist.nominal) else 1.0
            continue
        u, un = _unit(dist, params[name]), _unit(dist, dist.nominal)
        total += 1.0 if u is None or un is None else abs(u - un)
    return total


class DatabaseError(OSError):
    """The replay database directory cannot be used (it is a file, or cannot be read or
    written); the message names the path and what to do."""


@dataclass(frozen=True)
class Entry:
    """One stored counterexample. ``path`` is where it lives (derived from the test and
    parameters, never read from the file); ``created`` is a Unix timestamp."""

    test: str
    params: dict
    rho: dict[str, float]
    seed: int
    fingerprint: str
    space: dict
    minimized: bool
    versions: dict[str, str]
    format: int
    path: Path
    created: float
    #: the sampled case it was minimized from: {"case": its id in the test ("halton-007"),
    #: "params": its parameters as found}; None in entries written before it was recorded
    found: dict | None = None

    def to_json(self) -> dict[str, Any]:
        """The file content (plain JSON; ±inf rho as strings)."""
        out = {
            "kind": _KIND,
            "format": self.format,
            "test": self.test,
            "params": self.params,
            "rho": {k: rho_to_json(v) for k, v in self.rho.items()},
            "seed": self.seed,
            "fingerprint": self.fingerprint,
            "space": self.space,
            "minimized": self.minimized,
            "versions": self.versions,
            "created": self.created,
        }
        if self.found is not None:
            out["found"] = self.found
        return out

    @property
    def violated(self) -> frozenset[str]:
        """The metrics the stored case violates (ρ < 0)."""
        return frozenset(m for m, v in self.rho.items() if v < 0)


class _Invalid(ValueError):
    """A file or snapshot item that is not a readable entry (the message says why)."""


def entry_name(test: str, params: Mapping[str, Any]) -> str:
    """The file name of the entry for (test, params): hashes only, so it cannot escape the
    directory whatever the test id or parameter values contain."""
    test_hash = hashlib.sha256(test.encode("utf-8", "surrogatepass")).hexdigest()[:12]
    blob = json.dumps([test, _plain(params)], sort_keys=True, ensure_ascii=True,
                      separators=(",", ":"), allow_nan=False)
    case_hash = hashlib.sha256(blob.encode()).hexdigest()[:20]
    return f"{test_hash}-{case_hash}.json"


class ReplayDB:
    """Counterexamples in one directory (created on the first save).

    ``entries()`` re-lists the directory on every call but parses only new or changed
    files. ``warnings`` collects one message per skipped file (path and reason), each file
    reported once per instance.
    """

    def __init__(self, directory: str | os.PathLike):
        self.directory = Path(directory)
        self.warnings: list[str] = []
        self._warned: set[str] = set()
        # file name -> ((mtime_ns, size), Entry or None when invalid)
        self._cache: dict[str, tuple[tuple[int, int], Entry | None]] = {}
        self._snapshot: list[Entry] | None = None
        #: saves and deletes that failed this run (the plugin warns on the first one only)
        self.write_failures = 0
        self._check_directory()

    # ------------------------------------------------------------------ reading
    def entries(self, test: str | None = None) -> list[Entry]:
        """Valid entries, oldest first then by file name; ``test`` filters by test id."""
        if self._snapshot is not None:
            found = list(self._snapshot)
        else:
            found = list(self._scan())
        if test is not None:
            found = [e for e in found if e.test == test]
        return sorted(found, key=lambda e: (e.created, e.path.name))

    def _scan(self) -> Iterable[Entry]:
        self._check_directory()
        try:
            listing = list(os.scandir(self.directory))
        except FileNotFoundError:
            return []
        except OSError as exc:
            raise DatabaseError(
                f"cannot read the replay database directory {self.directory}: "
                f"{exc.strerror or exc}; fix its permissions or pass another --avs-db"
            ) from exc
        seen = set()
        out = []
        for item in listing:
            if not _NAME.match(item.name):
                continue  # temporary files, READMEs, other tools' files: not ours
            seen.add(item.name)
            entry = self._load(item)
            if entry is not None:
                out.append(entry)
        for name in set(self._cache) - seen:
            del self._cache[name]
        return out

    def _load(self, item: os.DirEntry) -> Entry | None:
        path = self.directory / item.name
        try:
            st = item.stat(follow_symlinks=False)
        except OSError as exc:
            self._warn(path, f"cannot be read ({exc.strerror or exc})")
            return None
        stamp = (st.st_mtime_ns, st.st_size)
        cached = self._cache.get(item.name)
        if cached is not None and cached[0] == stamp:
            return cached[1]
        entry = None
        try:
            if not stat.S_ISREG(st.st_mode):
                raise _Invalid("is not a regular file (symlinks are not followed)")
            if st.st_size > _MAX_BYTES:
                raise _Invalid(f"is {st.st_size} bytes, too large to be an entry")
            raw = read_regular(path, _MAX_BYTES)  # never a link, never blocks on a FIFO
            entry = _parse(raw, path)
        except _Invalid as exc:
            self._warn(path, str(exc))
        except OSError as exc:
            self._warn(path, f"cannot be read ({exc.strerror or exc})")
        self._cache[item.name] = (stamp, entry)
        return entry

    def _warn(self, path: Path, why: str) -> None:
        if path.name in self._warned:
            return
        self._warned.add(path.name)
        self.warnings.append(f"skipped {path}: {why}; not replayed, left on disk for you to "
                             "fix or delete")

    # ------------------------------------------------------------------ writing
    def save(self, test: str, params: Mapping[str, Any], rho: Mapping[str, float], seed: int,
             space: FeatureSpace, minimized: bool, versions: Mapping[str, str],
             found: Mapping[str, Any] | None = None) -> Entry:
        """Store a counterexample; saving the same (test, params) again rewrites the same
        file (keeping its creation time), so the database holds it once. ``found``: the
        sampled case it comes from, ``{"case": id, "params": values as found}``."""
        if not isinstance(test, str) or not test:
            raise ValueError(f"test must be a non-empty string, got {test!r}")
        params = _plain(params)
        if not isinstance(params, dict):
            raise ValueError(f"params must be a mapping, got {type(params).__name__}")
        name = entry_name(test, params)
        path = self.directory / name
        created = time.time()
        existing = self._read_existing(path)
        if existing is not None and existing.test == test and existing.params == params:
            created = existing.created
        entry = Entry(
            test=test,
            params=params,
            rho={str(k): float(v) for k, v in rho.items()},
            seed=_as_int(seed, "seed"),
            fingerprint=space.fingerprint(),
            space=_plain(space.describe()),
            minimized=bool(minimized),
            versions={str(k): str(v) for k, v in versions.items()},
            format=FORMAT,
            path=path,
            created=float(created),
            found=None if found is None else {"case": str(found["case"]),
                                              "params": _plain(found["params"])},
        )
        text = json.dumps(entry.to_json(), indent=2, sort_keys=True, allow_nan=False)
        self._write_atomically(path, text.encode("utf-8"))
        return entry

    def store(self, test: str, params: Mapping[str, Any], rho: Mapping[str, float], seed: int,
              space: FeatureSpace, minimized: bool, versions: Mapping[str, str],
              found: Mapping[str, Any] | None = None, *, near: float = NEAR) -> "Stored":
        """:meth:`save` a counterexample unless the database holds it already, and replace what
        it makes redundant: one file per counterexample however often runs find it.

        Among this test's entries of the same declaration (fingerprint), another entry is the
        same counterexample when it was minimized from the same sampled case (same case id,
        values as found and seed), or, both minimized, when it is a *near-duplicate*: it
        violates the same metrics and departs from the nominal scenario in the same
        parameters, by values within ``near`` of each other in the sampler's unit coordinates
        (categories equal) — minimizing drives failures found apart to the same boundary.
        Cases stored as found (shrinking off or without success) are distinct samples and
        are kept each. Of a
        near-duplicate pair, or two minimized from the same case, the one closer to the
        nominal scenario stays (what minimizing aims for; the stored one on a tie). What
        goes is deleted only if it is one of this database's entries (its name, kind and
        content agree); anything else in the directory is never touched.
        """
        name = entry_name(test, _plain(params))
        fingerprint = space.fingerprint()
        violated = frozenset(m for m, v in rho.items() if v < 0)
        origin = None if found is None else (str(found["case"]), _canon(found["params"]))
        replaced: list[Entry] = []
        for other in self._current(test):
            if other.path.name == name or other.fingerprint != fingerprint:
                continue
            same_case = origin is not None and other.found is not None and other.seed == seed and \
                (other.found["case"], _canon(other.found["params"])) == origin
            if not same_case and not (minimized and other.minimized and other.violated == violated
                                      and near_duplicate(space, params, other.params, near)):
                continue
            if departure(space, other.params) <= departure(space, params):
                return Stored(other, written=False)
            replaced.append(other)
        entry = self.save(test, params, rho, seed, space, minimized, versions, found)
        gone, left = [], []
        for other in replaced:
            try:
                self.delete(other)
                gone.append(other.path)
            except DatabaseError as exc:  # stored all the same; the redundant file stays
                left.append(str(exc))
        return Stored(entry, written=True, replaced=tuple(gone), problems=tuple(left))

    def redundant(self, entry: Entry, space: FeatureSpace, *, near: float = NEAR) -> Entry | None:
        """The stored entry that makes ``entry`` redundant, by :meth:`store`'s rule (the same
        counterexample, at least as close to the nominal scenario, the older one on a tie),
        or None: how a database that gathered near-duplicates before it was deduplicated at
        saving sheds them, one replay at a time."""
        fingerprint = space.fingerprint()
        mine = departure(space, entry.params)
        origin = None if entry.found is None else (entry.found["case"], _canon(entry.found["params"]))
        for other in self._current(entry.test):
            if other.path.name == entry.path.name or other.fingerprint != fingerprint \
                    or entry.fingerprint != fingerprint:
                continue
            same_case = origin is not None and other.found is not None and other.seed == entry.seed \
                and (other.found["case"], _canon(other.found["params"])) == origin
            if not same_case and not (entry.minimized and other.minimized and other.violated == entry.violated
                                      and near_duplicate(space, entry.params, other.params, near)):
                continue
            theirs = departure(space, other.params)
            if theirs < mine or (theirs == mine and (other.created, other.path.name)
                                 < (entry.created, entry.path.name)):
                return other
        return None

    def _current(self, test: str) -> list[Entry]:
        """``test``'s entries on disk now (not an xdist snapshot: another worker may have
        stored one since the run started)."""
        try:
            found = list(self._scan())
        except DatabaseError:
            return []
        return sorted((e for e in found if e.test == test), key=lambda e: (e.created, e.path.name))

    def _read_existing(self, path: Path) -> Entry | None:
        try:
            return _parse(read_regular(path, _MAX_BYTES), path)
        except (OSError, _Invalid):
            return None

    def _write_atomically(self, path: Path, data: bytes) -> None:
        self._check_directory()
        try:
            # the package's one atomic writer: a hidden temporary name no entry pattern
            # matches, fsynced, replaced, readable by a shared CI cache (not mkstemp's 0600)
            atomic_write_bytes(path, data, durable=True)
        except OSError as exc:
            raise DatabaseError(
                f"cannot write the replay database {self.directory}: {exc.strerror or exc}; "
                "make it a writable directory, pass another --avs-db, or --avs-db=none"
            ) from exc

    def delete(self, entry: Entry) -> None:
        """Remove a stored counterexample (already gone is fine: another worker did it)."""
        name = entry_name(entry.test, entry.params)
        path = self.directory / name  # recomputed: an Entry's path field is never trusted
        try:
            unlink_file(path)  # an entry of ours: never a link or a FIFO the user put there
        except FileNotFoundError:
            pass
        except OSError as exc:
            raise DatabaseError(
                f"cannot delete {path} from the replay database: {exc.strerror or exc}"
            ) from exc
        self._cache.pop(name, None)
        if self._snapshot is not None:
            self._snapshot = [e for e in self._snapshot if e.path.name != name]

    # ------------------------------------------------------------------ xdist
    def snapshot(self) -> list[dict]:
        """All valid entries as plain JSON (what pytest-xdist ships to its workers)."""
        return [e.to_json() for e in self.entries()]

    @classmethod
    def from_snapshot(cls, directory: str | os.PathLike, data: Iterable[Mapping]) -> "ReplayDB":
        """A database whose ``entries()`` are ``data`` (from :meth:`snapshot`), so every
        worker collects the same replays; saves and deletes still go to ``directory``."""
        db = cls(directory)
        entries = []
        for i, item in enumerate(data):
            try:
                if not isinstance(item, Mapping):
                    raise _Invalid("is not a JSON object")
                name = entry_name(str(item.get("test")), item.get("params") or {})
                entries.append(_entry_from_json(dict(item), db.directory / name))
            except _Invalid as exc:
                db.warnings.append(f"skipped snapshot item {i}: {exc}")
            except (ValueError, TypeError, OverflowError, RecursionError, MemoryError) as exc:
                db.warnings.append(f"skipped snapshot item {i}: {_unreadable(exc)}")
        db._snapshot = entries
        return db

    # ------------------------------------------------------------------ helpers
    def _check_directory(self) -> None:
        d = self.directory
        if d.exists() and not d.is_dir():
            raise DatabaseError(
                f"the replay database {d} is not a directory; remove that file "
                "or pass another path with --avs-db"
            )
        for parent in d.parents:
            if parent.exists():
                if not parent.is_dir():
                    raise DatabaseError(
                        f"the replay database {d} cannot be created: {parent} is a file; "
                        "move that file or pass another path with --avs-db"
                    )
                break

    def __repr__(self) -> str:
        return f"ReplayDB({str(self.directory)!r})"


def space_changes(old: Mapping[str, Any], new: FeatureSpace) -> list[str]:
    """Names of parameters added, removed or changed between a stored space description
    and the current space: new parameters in declaration order, then removed ones."""
    new_desc = {n: {k: v for k, v in d.items() if k != "unit"} for n, d in new.describe().items()}
    old = dict(old) if isinstance(old, Mapping) else {}
    old = {n: {k: v for k, v in d.items() if k != "unit"} if isinstance(d, Mapping) else d for n, d in old.items()}
    changed = [n for n, d in new_desc.items() if n not in old or _canon(old[n]) != _canon(d)]
    removed = [n for n in old if n not in new_desc]
    return changed + removed


# --------------------------------------------------------------------------- parsing


def _reject_constant(name: str) -> Any:
    raise _Invalid(f"contains {name}, which is not JSON")


#: what parsing untrusted bytes may raise besides a decode error: Python's limit on integer
#: digits (ValueError), deep nesting (RecursionError), numbers beyond a float (OverflowError)
_UNREADABLE = (ValueError, TypeError, OverflowError, RecursionError, MemoryError)


def _parse(raw: bytes, path: Path) -> Entry:
    if len(raw) > _MAX_BYTES:
        raise _Invalid("is too large to be an entry")
    if not raw.strip():
        raise _Invalid("is empty")
    try:
        data = json.loads(raw.decode("utf-8"), parse_constant=_reject_constant)
    except UnicodeDecodeError:
        raise _Invalid("is not UTF-8 text") from None
    except json.JSONDecodeError as exc:
        raise _Invalid(f"is not valid JSON (truncated or corrupt: {exc.msg} at "
                       f"line {exc.lineno} column {exc.colno})") from None
    except _Invalid:
        raise
    except _UNREADABLE as exc:
        raise _Invalid(_unreadable(exc)) from None
    try:
        _check_depth(data)
        entry = _entry_from_json(data, path)
        name = entry_name(entry.test, entry.params)
    except _Invalid:
        raise
    except _UNREADABLE as exc:
        raise _Invalid(_unreadable(exc)) from None
    if name != path.name:
        raise _Invalid(f"the entry of {_shown_test(entry.test)}: its name does not match its "
                       "test and parameters (renamed or edited)")
    return entry


def _unreadable(exc: BaseException) -> str:
    """Why parsed-but-unusable content is not an entry, in the user's terms."""
    if isinstance(exc, RecursionError):
        return "is nested too deeply to be an entry"
    if isinstance(exc, MemoryError):
        return "is too large to read into memory"
    if isinstance(exc, ValueError) and "digits" in str(exc):
        return (f"holds an integer of more than {sys.get_int_max_str_digits()} digits, "
                "more than Python reads")
    if isinstance(exc, OverflowError):
        return "holds a number too large for a float"
    return f"is not a readable entry ({type(exc).__name__}: {str(exc)[:120]})"


def _check_depth(data: Any) -> None:
    """Refuse JSON nested deeper than any entry (iteratively: no recursion on hostile input)."""
    stack = [(data, 1)]
    while stack:
        value, depth = stack.pop()
        if isinstance(value, (dict, list)):
            if depth > _MAX_DEPTH:
                raise _Invalid(f"is nested more than {_MAX_DEPTH} levels deep, deeper than any entry")
            stack.extend((v, depth + 1) for v in (value.values() if isinstance(value, dict) else value))


def _entry_from_json(data: Any, path: Path) -> Entry:
    if not isinstance(data, dict) or data.get("kind") != _KIND:
        raise _Invalid("is not a pytest-avscenario entry (foreign JSON)")
    fmt = data.get("format")
    if fmt != FORMAT:
        raise _Invalid(f"has entry format version {_short(fmt)}; this pytest-avscenario reads "
                       f"version {FORMAT}")
    test = data.get("test")
    if not isinstance(test, str) or not test:
        raise _Invalid("has a missing or malformed 'test' field")
    of = f"the entry of {_shown_test(test)}"

    def field(name: str, kinds: type | tuple[type, ...]) -> Any:
        value = data.get(name)
        # bool is an int in Python, but a seed of `true` is a malformed file
        if not isinstance(value, kinds) or (isinstance(value, bool) and kinds is not bool):
            what = "a missing" if name not in data else f"a malformed ({_short(value)})"
            raise _Invalid(f"{of} has {what} {name!r} field")
        return value

    params = field("params", dict)
    rho_raw = field("rho", dict)
    try:
        rho = {str(k): rho_from_json(v) for k, v in rho_raw.items()}
    except (TypeError, ValueError, OverflowError):
        raise _Invalid(f"{of} has a malformed 'rho' field (robustness values are numbers, "
                       "'inf' or '-inf')") from None
    seed = data.get("seed")
    if isinstance(seed, bool) or not isinstance(seed, int) or not 0 <= seed < _SEED_END:
        what = "no 'seed'" if "seed" not in data else f"'seed' {_short(seed)}"
        raise _Invalid(f"{of} has {what}, not a case seed ({SEED_RANGE})")
    fingerprint = field("fingerprint", str)
    space = field("space", dict)
    minimized = field("minimized", bool)
    versions = field("versions", dict)
    if not all(isinstance(v, str) for v in versions.values()):
        raise _Invalid(f"{of} has a malformed 'versions' field")
    created = field("created", (int, float))
    try:
        created = float(created)
    except OverflowError:
        created = math.inf
    if not math.isfinite(created):
        raise _Invalid(f"{of} has a malformed 'created' field (not a Unix time)")
    found = data.get("found")
    if found is not None and not (isinstance(found, dict) and isinstance(found.get("case"), str)
                                  and isinstance(found.get("params"), dict)):
        raise _Invalid(f"{of} has a malformed 'found' field")
    return Entry(test=test, params=params, rho=rho, seed=seed, fingerprint=fingerprint,
                 space=space, minimized=minimized, versions=dict(versions), format=fmt,
                 path=path, created=created, found=found)


def replay_params(space: FeatureSpace, stored: Mapping[str, Any]) -> dict[str, Any]:
    """The parameters to replay for an entry's stored ``params`` in the declared ``space``.

    Each value becomes the space's own value — a float for a continuous parameter, an int for
    an integer one, the declared object for a Choice option or a constant — and missing
    constants are filled in, so a test body receives exactly what a sampler would give it.
    Raises ValueError naming the first parameter that is undeclared, missing, of the wrong
    type or outside its distribution (a hand-edited entry, or one from another version)."""
    unknown = [n for n in stored if n not in space.parameters]
    if unknown:
        names = ", ".join(_short(n) for n in unknown)
        raise ValueError(f"parameter {names} is not declared (declared: {', '.join(space.names)})")
    out: dict[str, Any] = {}
    for name, dist in space.parameters.items():
        if name in stored:
            out[name] = _declared_value(name, dist, stored[name])
        elif dist.kind == "constant":
            out[name] = dist.nominal
        else:
            raise ValueError(f"parameter {name!r} is missing")
    try:
        space.validate(out)  # whatever else the space itself checks
    except (ValueError, TypeError, OverflowError) as exc:
        raise ValueError(str(exc)) from None
    return out


def _declared_value(name: str, dist: Any, value: Any) -> Any:
    shown = f"parameter {name!r}={_short(value)}"
    number = isinstance(value, (int, float)) and not isinstance(value, bool)
    if dist.kind == "continuous":
        if not number:
            raise ValueError(f"{shown} is not a number ({dist!r} declares numbers)")
        try:
            v = float(value)
        except OverflowError:
            v = math.inf
        if not (math.isfinite(v) and dist.contains(v)):
            raise ValueError(f"{shown} lies outside {dist!r}")
        return v
    if dist.kind == "integer":
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        elif not number or isinstance(value, float):
            raise ValueError(f"{shown} is not an integer ({dist!r} declares integers)")
        if not dist.contains(value):
            raise ValueError(f"{shown} lies outside {dist!r}")
        return value
    if dist.kind == "categorical":
        options = tuple(getattr(dist, "options", ()))
        for option in options:
            if _same_value(option, value):
                return option
        raise ValueError(f"{shown} is not one of the options {_short(list(options))}")
    if dist.kind == "constant":
        if _same_value(dist.nominal, value):
            return dist.nominal
        raise ValueError(f"{shown} is not the declared constant {_short(dist.nominal)}")
    if not dist.contains(value):
        raise ValueError(f"{shown} lies outside {dist!r}")
    return value


def _same_value(declared: Any, stored: Any) -> bool:
    """Whether a stored JSON value is a declared one: numbers by value (1 is 1.0, but True is
    not 1), anything else by its JSON form (a tuple option is stored as a list)."""
    import numpy as np  # here, not at import: loading the plugin must not load numpy

    def number(v: Any) -> bool:
        return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_))

    if number(declared) or number(stored):
        return number(declared) and number(stored) and declared == stored
    return _canon(declared) == _canon(stored)


def _short(value: Any, limit: int = 60) -> str:
    """``repr`` of a value read from a file, cut to ``limit`` characters."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _shown_test(test: str) -> str:
    """A test id read from a file, printable whatever it holds (lone surrogates included)."""
    text = test.encode("utf-8", "backslashreplace").decode("utf-8")
    return text if len(text) <= 200 else text[:199] + "…"


def _plain(value: Any) -> Any:
    """JSON-ready copy: numpy scalars to Python, tuples to lists; non-finite floats and
    non-JSON values are refused (a case's parameters are always plain and finite)."""
    import numpy as np  # here, not at import: loading the plugin must not load numpy

    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        if not math.isfinite(value):
            raise ValueError(f"parameters must be finite to be stored, got {value!r}")
        return value
    if value is None or isinstance(value, str):
        return value
    raise ValueError(f"{value!r} ({type(value).__name__}) cannot be stored as JSON")


def _canon(value: Any) -> str:
    try:
        return json.dumps(_plain(value), sort_keys=True)
    except ValueError:
        return repr(value)


def _as_int(value: Any, what: str) -> int:
    import numpy as np  # here, not at import: loading the plugin must not load numpy

    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{what} must be an int, got {value!r}")
    return int(value)
