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


class ItemKeywords(CaseKeywords):
    """A finished item's keywords: as :class:`CaseKeywords`, its own name and parameter id
    reading True, as pytest's node keywords read them."""

    __slots__ = ()

    def __getitem__(self, key: str) -> Any:
        if key in self._own():
            return True
        return self._shared[key]


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


#: one empty set of extra keywords for every finished item (``frozenset()`` makes a new one)
_NO_MATCHES: frozenset[str] = frozenset()


def slim_item(item: Any) -> None:
    """A scenario case's item once its protocol has ended (setup, call, teardown and their
    reports handled): what pytest left on it for that run, which nothing reads any more, goes
    (issue #35: ~0.6 KB an item of a 100,000-item run, kept to its end by ``session.items``).
    Its stash (pytest's skip and xfail marks evaluated for the run, tmp_path's outcome per
    phase, our ``sent`` flag) becomes an empty dict; its empty ``extra_keyword_matches`` set
    (read by ``-k`` at collection) the empty frozenset; its empty ``_report_sections`` and
    ``user_properties`` lists (filled while it runs) empty tuples; its case's slot (the
    sampler, index, seed and parameter values the case was made from, held in its
    ``callspec``: ~0.3 KB) None, as the row holds them now. Its node id, name, location,
    keywords, marks and parameter id stay: a plugin's end-of-run summary may read those."""
    from .controller import empty_stash

    empty_stash(item)
    d = getattr(item, "__dict__", None)
    if d is None:
        return
    if type(d.get("extra_keyword_matches")) is set and not d["extra_keyword_matches"]:
        item.extra_keyword_matches = _NO_MATCHES
    for name in ("_report_sections", "user_properties"):
        if type(d.get(name)) is list and not d[name]:
            setattr(item, name, ())
    params = getattr(d.get("callspec"), "params", None)
    if type(params) is dict and type(params.get("case")).__name__ == "CaseSlot":
        params["case"] = None
    _share_keywords(item)


#: the keywords the finished items of a test share (beside their own name and parameter id),
#: by their keys and values' identities
_ITEM_SHARED: dict[tuple[tuple[str, int], ...], dict[str, Any]] = {}


def _share_keywords(item: Any) -> None:
    """The item's keywords (pytest's ``NodeKeywords``: a dict of its own, ~0.3 KB, chained to
    its parents') as a :class:`CaseKeywords` view: its own name and parameter id read from
    its location, over one dict the finished items of its test share holding every other
    keyword with its value (its parents' too). The same keys, and values equal to those read
    before; left as they are when the keys do not split that way."""
    keywords, location = getattr(item, "keywords", None), getattr(item, "location", None)
    if type(keywords).__name__ != "NodeKeywords" or not isinstance(location, tuple) \
            or len(location) != 3 or not isinstance(location[2], str):
        return
    view = ItemKeywords(location[2], {})
    own = view._own()
    try:
        everything = {k: keywords[k] for k in keywords}
    except Exception:  # noqa: BLE001 - an odd keyword mapping: left as it is
        return
    if not all(k in everything and everything[k] is True for k in own):
        return
    rest = tuple((k, id(v)) for k, v in everything.items() if k not in own)
    shared = _ITEM_SHARED.get(rest)
    if shared is None:
        if len(_ITEM_SHARED) > 1024:  # tests of many different keyword sets: nothing to share
            _ITEM_SHARED.clear()
        # holds the values: the ids in its key stay theirs while it lives
        shared = _ITEM_SHARED[rest] = {k: v for k, v in everything.items() if k not in own}
    view._shared = shared
    item.keywords = view
