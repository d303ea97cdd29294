"""What pytest keeps of a scenario case once its report is handled, made small.

pytest's terminal reporter keeps every item's call report to the end of the run (the summary
line counts them, ``-r`` lists them, the failures section shows their ``longrepr``). A report
carries a fresh ``keywords`` dict (~0.3 KB: the item's name, its parameter id, its marks, its
module and folders), empty ``sections`` and ``user_properties`` lists and pytest-html's
empty ``extras`` list: ~0.45 KB a case that nothing reads once every plugin has handled the
report, 45 MB of a 100,000-case campaign (issue #35). :func:`slim_report` keeps what is
read later (node id, location, outcome, longrepr, sections with content, durations) and
shares the rest (:func:`.controller.compact_stash` gives back what an item's stash grew by
for its case).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import Any

#: the keywords every case of a test shares, by the keys they have beside the item's own
_SHARED: dict[tuple[str, ...], dict[str, Any]] = {}


class CaseKeywords(Mapping):
    """A case report's keywords: the item's own name and parameter id, read from the
    report's location (``"TestX.test_y[halton-002]"``: no string of its own), over a dict the
    cases of its test share. Read-only, as a handled report's keywords are."""

    __slots__ = ("_domain", "_shared")

    def __init__(self, domain: str, shared: Mapping[str, Any]):
        self._domain = domain
        self._shared = shared

    def _own(self) -> tuple[str, ...]:
        head, bracket, param = self._domain.partition("[")
        name = head.rpartition(".")[2] + bracket + param
        return (name, param[:-1]) if bracket and param.endswith("]") else (name,)

    def __getitem__(self, key: str) -> Any:
        if key in self._own():
            return 1
        return self._shared[key]

    def __iter__(self) -> Iterator[str]:
        yield from self._own()
        yield from self._shared

    def __len__(self) -> int:
        return len(self._own()) + len(self._shared)

    def __contains__(self, key: object) -> bool:
        return key in self._shared or key in self._own()

    def __repr__(self) -> str:
        return repr(dict(self))


def slim_report(report: Any) -> None:
    """Make a handled scenario case's report small (see the module's text); its outcome, its
    text and what the terminal summary, ``-r`` and the failures section show stay the same."""
    keywords, location = report.keywords, report.location
    if isinstance(keywords, dict) and isinstance(location, tuple) and len(location) == 3 \
            and isinstance(location[2], str) and all(v == 1 for v in keywords.values()):
        view = CaseKeywords(location[2], {})
        own = view._own()
        if all(k in keywords for k in own):  # else not a case's keywords: left as they are
            rest = tuple(k for k in keywords if k not in own)
            shared = _SHARED.get(rest)
            if shared is None:
                if len(_SHARED) > 1024:  # tests of many different keyword sets: nothing to share
                    _SHARED.clear()
                shared = _SHARED[rest] = dict.fromkeys(rest, 1)
            view._shared = shared
            report.keywords = view
    for name in ("sections", "user_properties"):
        if not getattr(report, name, True):
            setattr(report, name, ())  # read (iterated) later, never extended
    if getattr(report, "extras", True) == []:
        del report.extras  # pytest-html's, read while it handles the report
