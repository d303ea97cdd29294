"""The end-of-run step in one call: from the run's rows to the finished report.

On the controller, once every case has ended (``pytest_sessionfinish``), the plugin calls
:func:`finish_report` with the report directory, the rows it holds in memory (every row of
the run, the xdist workers' included) and what it knows of each scenario test. It computes
the paper's summary, writes ``summary.json``, the pictures and ``index.html``, and returns
the summary rows for the terminal table and the JUnit suite properties. The numbers come from
those rows, never from re-reading ``errors.jsonl``, so nothing else writing in the directory
can change them; without ``rows`` (a script on a finished report) the tables are read back.

Each part (the summary, ``summary.json``, each test's plots, ``index.html``) is guarded on
its own when ``on_error`` is given: a part that raises is reported there and the others are
still written, so one test's odd data cannot cost the whole report.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

from ..files import make_dirs, unlink_file
from ..outcome import CaseRow
from .coverage import DEFAULT_TOL
from .summary import SummaryRow, TestInfo, summarize, summary_to_json
from .table import MAIN_JSONL, SHRINK_JSONL, TABLES_DIR, atomic_write_text, file_slug, read_rows

__all__ = ["finish_report", "SUMMARY_JSON"]

SUMMARY_JSON = "summary.json"

#: counterexamples of one test that get a card page and a line in the index: each failure
#: mode's representative first, then the minimized ones, then in the order they ran; the
#: others are in the error table (a 100,000-case campaign may have 30,000 counterexamples,
#: ~0.5 ms of the end of the run each)
MAX_CARDS = 1000

OnError = Callable[[str, "str | None", Exception], None]


def finish_report(
    directory: str | os.PathLike,
    tests: Mapping[str, TestInfo] | None = None,
    *,
    rows: Iterable[CaseRow | Mapping[str, Any]] | None = None,
    folder: Any = None,
    on_error: OnError | None = None,
    seed: Any = None,
    versions: Mapping[str, Any] | None = None,
    pictures: bool = True,
    case_images: Mapping[str, Mapping[str, Any]] | None = None,
    tol: float = DEFAULT_TOL,
    within_radius: float | None = 0.1,
    verdicts: Mapping[tuple[str, str], Any] | None = None,
    case_files: Mapping[str, Mapping[str, str]] | None = None,
    rerun: Callable[[CaseRow], str | None] | None = None,
    partial: str | None = None,
    baseline: Any = None,
    driver: Mapping[str, Any] | None = None,
    card_sections: Callable[[CaseRow], Sequence[tuple[str, str]]] | None = None,
    interrupted: str | None = None,
    drawn: Callable[[str, list[CaseRow]], Mapping[str, Path] | None] | None = None,
    known_coverage: Callable[[str, str, list[CaseRow]], tuple | None] | None = None,
    known_modes: Callable[[str, str, list[CaseRow], tuple[str, ...]], tuple | None] | None = None,
) -> list[SummaryRow]:
    """Summarize the run and write the rest of the report under ``directory``.

    ``tests``: ``{test nodeid: TestInfo(metrics, space)}`` in collection order. ``rows``: the
    run's rows, main table and shrink candidates (default: read back from the directory's
    JSONL tables). ``folder``: the :class:`~.folder.ReportFolder` whose manifest records each
    file before it is written (default: the directory's own). ``on_error(part, test,
    exception)``: guard each part and report a failing one there (default: raise).
    ``pictures`` False skips the PNGs (and matplotlib's import) but still writes
    ``index.html``. ``case_images``: ``{test: {caption: path}}`` pictures of single cases
    (e.g. the GIF and worst-moment PNG of each minimized counterexample), listed after the
    test's plots. ``verdicts``: the campaigns' rejection reasons (see
    :func:`.summary.summarize`). ``case_files``: ``{item id: {kind: path}}`` what each
    failing case left (its pictures and recording; see :class:`.cards.CaseFiles`);
    ``rerun(row)``: the command that re-runs a case, for its card. ``partial``: why this run
    re-ran only some cases (its page says so and links to the campaign's report in ``..``).
    ``baseline``: an earlier run's summary (:func:`~pytest_avscenario.acceptance.load_baseline`,
    the file of ``--avs-baseline``): the index opens with the comparison (:mod:`.compare`) and
    ``summary.json`` holds it as ``"comparison"`` (not for a ``partial`` run). ``interrupted``:
    why the run ended before all its cases ran — ``summary.json`` says ``"interrupted": true``
    (and the reason), so that nobody reads its verdicts as a finished run's or takes it for a
    baseline unawares. ``card_sections(row)``: more ``(title, html)`` sections for a
    counterexample's card (the plugin's ``pytest_avscenario_card_sections`` hook). Every
    counterexample gets a card page under ``cases/``. ``driver``: the identity of the options'
    driver, the run's when no row names one; ``summary.json`` holds the run's driver as
    ``"driver"`` and each campaign's as its ``"driver"``, the index names it (see
    :mod:`.drivers`). ``drawn(test, rows)``: the plots of ``test`` already drawn from these
    main-table rows (``{kind: path}``), or None to draw them here; ``known_coverage``,
    ``known_modes``: see :func:`.summary.summarize` (both: :mod:`.ahead`). Returns the summary rows.
    """
    from .folder import ReportFolder

    root = Path(directory)
    own_folder = folder is None  # then this call ends the folder's run: its log is folded
    folder = folder if folder is not None else ReportFolder(root)
    if rows is None:
        rows = read_rows(root) + read_rows(root, shrink=True)
    rows = [CaseRow.coerce(r) for r in rows]
    main = [r for r in rows if r.origin != "shrink"]

    def part(name: str, test: str | None, make: Callable[[], Any]) -> Any:
        try:
            return make()
        except Exception as exc:
            if on_error is None:
                raise
            on_error(name, test, exc)
            return None

    summary = part("the summary", None, lambda: summarize(
        rows, tests, tol=tol, within_radius=within_radius, verdicts=verdicts, on_error=on_error,
        known_coverage=known_coverage, known_modes=known_modes)) or []

    comparison = None
    if baseline is not None and not partial:  # some cases of a campaign: no rate to compare
        from .compare import compare

        comparison = part("the comparison with the baseline", None, lambda: compare(summary, baseline))

    from .drivers import baseline_driver_warning, drivers_of

    run_driver, test_drivers = drivers_of(main, driver)
    driver_warning = None if comparison is None else baseline_driver_warning(run_driver, baseline)

    def write_summary() -> None:
        tests_json = summary_to_json(summary)
        for entry in tests_json:
            entry["driver"] = test_drivers.get(entry["test"])
        data = {"seed": seed, "driver": run_driver, "versions": dict(versions or {}), "tests": tests_json}
        if interrupted:
            data["interrupted"], data["stopped"] = True, interrupted
        if comparison is not None:
            data["comparison"] = comparison.to_json()
        text = json.dumps(data, indent=2, allow_nan=False, default=str) + "\n"
        atomic_write_text(folder.add(root / SUMMARY_JSON), text)

    part(SUMMARY_JSON, None, write_summary)
    images: dict[str, Any] = {}
    tables: dict[str, list[Path]] = {"": [p for p in (root / MAIN_JSONL, root / SHRINK_JSONL, root / SUMMARY_JSON) if p.exists()]}
    by_test: dict[str, list[Any]] = {}
    for r in main:
        by_test.setdefault(r.test, []).append(r)
    for test in dict.fromkeys([s.test for s in summary] + list(by_test)):
        slug = file_slug(test)
        tables[test] = [p for p in (root / TABLES_DIR / f"{slug}.csv", root / TABLES_DIR / f"{slug}.shrink.csv") if p.exists()]

    sections: dict[str, list[str]] = {}
    for test in dict.fromkeys([s.test for s in summary] + list(by_test)):
        made = part("the counterexample pages", test, lambda test=test: _cards(
            root, folder, test, by_test.get(test, []), (tests or {}).get(test), case_files or {}, rerun,
            [s for s in summary if s.test == test], card_sections))
        if made:
            sections[test] = made

    # after the cards: plots made ahead (drawn) had the time of the summary and the cards
    for test in dict.fromkeys([s.test for s in summary] + list(by_test)):
        if pictures and by_test.get(test):
            made = drawn(test, by_test[test]) if drawn is not None else None
            images[test] = made if made is not None else part(
                "the plots", test, lambda test=test: _plot(root, folder, test, by_test[test], tests))
    for test, extra in (case_images or {}).items():  # pictures a caller adds to a test's own
        merged = dict(images.get(test) or {})
        merged.update({caption: path for caption, path in extra.items() if Path(path).exists()})
        images[test] = merged
    images = {test: pics for test, pics in images.items() if pics}

    def write_page() -> None:
        from .cards import e, href
        from .html import INDEX, write_index

        from ..sim.drivers.identity import identity_text

        meta = {}
        if run_driver is not None:
            meta["driver under test"] = identity_text(run_driver)
        if seed is not None:
            meta["seed"] = seed
        meta.update({k: v for k, v in (versions or {}).items()})
        banner = None
        if interrupted:
            banner = (f"An interrupted run ({e(interrupted)}): the cases that finished before it "
                      "stopped; its verdicts are not those of the whole campaign.")
        elif partial:
            banner = (f"A re-run of some cases ({e(partial)}): this report holds them alone. "
                      f"The campaign's report: <a href='../index.html'>../index.html</a>.")
        elif (root / "rerun" / INDEX).exists():
            banner = (f"The latest re-run of single cases has a report of its own: "
                      f"<a href='{href(root, root / 'rerun' / INDEX)}'>rerun/index.html</a>.")
        preamble = []
        if driver_warning is not None:
            preamble.append(f"<p class='banner'>Warning: {e(driver_warning)}.</p>")
        if comparison is not None:
            from .compare import comparison_html
            from .html import mode_anchor

            preamble.append(comparison_html(
                comparison, link=lambda test, sampler, mode: f"#{mode_anchor(test, sampler, mode)}"))
        folder.add(root / INDEX)
        write_index(root, summary, images, tables, meta=meta, sections=sections, banner=banner,
                    preamble=preamble)

    part("index.html", None, write_page)
    if own_folder:
        folder.close()
    return summary


def _cards(root: Path, folder: Any, test: str, rows: list[CaseRow], info: TestInfo | None,
           case_files: Mapping[str, Mapping[str, str]], rerun: Callable[[CaseRow], str | None] | None,
           campaigns: list[SummaryRow] = (),
           card_sections: Callable[[CaseRow], Sequence[tuple[str, str]]] | None = None) -> list[str]:
    """Write a card page per counterexample of ``test``; the index's HTML listing its failure
    modes (of ``campaigns``, its summary rows) and its counterexamples."""
    from .cards import CaseFiles, card_name, card_rows, counterexample_table, render_card
    from .html import mode_labels, mode_table

    failing = card_rows(rows)
    if not failing:
        return []
    found = len(failing)
    if found > MAX_CARDS:
        first = {m.representative for s in campaigns for m in s.modes}
        ranked = sorted(failing, key=lambda r: (r.item not in first, r.minimized is None))
        keep = {r.item for r in ranked[:MAX_CARDS]}
        failing = [r for r in failing if r.item in keep]
    cases = root / "cases"
    make_dirs(cases)
    space = info.space if info is not None else None
    metrics = info.metrics if info is not None else ()

    player: list[str] = []  # the shared player script's name, once written

    def slider(data: Mapping[str, Any], row: CaseRow) -> str:
        # the data knows its own first violation and critical agent: those of the case it
        # recorded (the minimized one, when there is one), not necessarily the row's
        from .player import player_file, player_html

        if not player:
            name, text = player_file()
            atomic_write_text(folder.add(cases / name), text, durable=False)
            player.append(name)
        return player_html(data, element_id="replay", player=player[0])

    labels = mode_labels(campaigns)
    described = {item: f"{labels[item]} ({m.what}: {m.rule})"
                 for s in campaigns for m in s.modes for item in m.items if item in labels}
    folder.add_all(cases / card_name(row) for row in failing)
    for row in failing:
        files = CaseFiles(dict(case_files.get(row.item) or {}))
        page = render_card(cases, row, metrics=metrics, space=space, mode=described.get(row.item),
                           files=files, rerun=rerun(row) if rerun is not None else None,
                           index_href=f"../index.html#t-{file_slug(test)}", player=slider,
                           sections=card_sections(row) if card_sections is not None else ())
        atomic_write_text(cases / card_name(row), page, durable=False)  # one of many
        recording = files.get("recording")
        if recording is not None and "id='replay-data'" in page and folder.owns(recording):
            # the card holds the recording now (its replay-data script): one copy per report,
            # so ~700 counterexamples cost ~15 KB each, not ~19
            try:
                unlink_file(recording)
            except FileNotFoundError:
                pass
    minimized = sum(r.minimized is not None for r in card_rows(rows))
    pages = "one page each" if found == len(failing) else (
        f"pages for {len(failing)} of them (each failure mode's representative, the minimized ones, "
        f"then in the order they ran); all are in {MAIN_JSONL}")
    return [mode_table(root, campaigns, rows),
            f"<details class='cex'><summary>{found} counterexample{'s' if found != 1 else ''}"
            f"{f' ({minimized} minimized)' if minimized else ''}: {pages}</summary>",
            counterexample_table(root, failing, modes=labels or None), "</details>"]


def _plot(root: Path, folder: Any, test: str, rows: list[CaseRow],
          tests: Mapping[str, TestInfo] | None) -> dict[str, Path]:
    from .plots import plot_paths, plot_test

    for path in plot_paths(root, test).values():
        folder.add(path)
    from .cards import unit_of

    info = (tests or {}).get(test)
    space = info.space if info is not None else None
    units = {n: unit_of(space, n) for n in getattr(space, "parameters", {}) or {}}
    return plot_test(root, test, rows, metrics=(info.metrics or None) if info else None,
                     units={n: u for n, u in units.items() if u})
