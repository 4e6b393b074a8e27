"""The batch's index page: one row per study, for a reader scanning a batch of many studies at a glance.

A row shows the study's QC sheet and views as thumbnails linked to the pictures, its labels with their colour,
voxels and millilitres, and flags what needs a look: a failure (with its error), labels that other studies of the
batch have but this one lacks (:func:`missing_labels`), and overlapping labels.  A study with turntable frames
gets a turntable: a picture whose frame follows the pointer across it (a mouse moving over it, or a finger or pen
dragged along it).

The page is one static file, its style and script inline: it opens from the disk (``file://``) with no server
and asks nothing of the network.  Its links are relative, so the batch's folder can be moved or copied whole.
"""

from __future__ import annotations

import html
import json
from dataclasses import dataclass
from pathlib import Path, PurePath

from .._shared.files import atomic_output
from ..errors import InputError


@dataclass
class StudyRow:
    """What the index page shows of one study of a batch.

    Parameters
    ----------
    name : str
        The study's name in the batch.
    input : str
        Its input path.
    error : str
        Why it failed; ``""`` when it did not.
    sheet : str, optional
        Its QC sheet (a PNG), relative to the page's folder.
    pictures : list of (str, str)
        Its views: ``(caption, PNG path relative to the page's folder)``.
    turntable : list of str
        Its turntable's frames (PNG paths relative to the page's folder), in turning order; empty for none.
    labels : list of dict
        ``{"label": int, "name": str, "colour": [r, g, b], "voxels": int, "ml": float}``, colours 0-255.
    overlaps : list of dict
        ``{"names": [a, b], "voxels": int}``: pairs of labels that claimed the same voxels.
    seconds : float, optional
        How long the study took.
    flags : list of str
        Its cohort flags in words (:func:`voxrender.review.flags.in_words`): a flagged study comes first.
    severity : tuple, optional
        How bad its flags are, smaller worse (:func:`voxrender.review.flags.severity`): the flagged studies are
        shown the worst first.
    verdict, note : str
        An earlier reviewer's verdict (``pass``, ``fail``, ``unsure`` or empty) and note (:func:`read_verdicts`);
        the browser's own, kept in its local storage, come over them.
    """

    name: str
    input: str
    error: str = ""
    sheet: str | None = None
    pictures: list = ()
    turntable: list = ()
    labels: list = ()
    overlaps: list = ()
    seconds: float | None = None
    flags: list = ()
    severity: tuple = ()
    verdict: str = ""
    note: str = ""


VERDICTS = ("pass", "fail", "unsure")
# Studies shown at a time: the others stay in the page, hidden, so that the browser lays out and draws a page of
# them (and fetches its thumbnails only), not the whole cohort; the keys move across pages.
PAGE = 100
VERDICT_COLUMNS = ("study", "input", "labels", "verdict", "note", "reviewer", "time")


def read_verdicts(path):
    r"""The verdicts of a ``verdicts.csv`` the index page exported (:data:`VERDICT_COLUMNS`), ``{study: (verdict,
    note)}``; a study without a verdict or note is left out.

    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "verdicts.csv"
    >>> _ = path.write_text("study,input,labels,verdict,note,reviewer,time\nct-1,a,liver,fail,\"cut, at L2\",ab,t\n")
    >>> read_verdicts(path)
    {'ct-1': ('fail', 'cut, at L2')}
    """
    import csv

    from .._shared.text import from_spreadsheet_cell

    try:
        with open(path, newline="", encoding="utf-8-sig") as f:
            rows = list(csv.DictReader(f))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise InputError(f"cannot read the verdicts {path}: {exc}", parameter="verdicts") from None
    if rows and not {"study", "verdict"} <= set(rows[0]):
        raise InputError(f"the verdicts {path} need 'study' and 'verdict' columns, as the index page exports them",
                         parameter="verdicts")
    found = {}
    for number, row in enumerate(rows, start=2):
        verdict = str(row.get("verdict") or "").strip().lower()
        if verdict and verdict not in VERDICTS:
            raise InputError(f"the verdicts {path}, line {number}: {verdict!r} is not a verdict; choose "
                             f"{', '.join(VERDICTS)} or none", parameter="verdicts")
        note = from_spreadsheet_cell(str(row.get("note") or ""))
        if verdict or note:
            found[from_spreadsheet_cell(str(row.get("study") or ""))] = (verdict, note)
    return found


def missing_labels(studies):
    """The labels each study lacks that other studies of the batch have, by name as
    :func:`voxrender._shared.label_sets.label_key` matches them (``hip right`` is ``hip_right``; unnamed labels by
    number, among themselves).

    A study lacks a label when it has none of that name, or has it with 0 voxels.  Failed studies, and studies
    without labels (a CT alone), are left out on both sides: they show no labels to compare.

    Parameters
    ----------
    studies : sequence of StudyRow

    Returns
    -------
    dict
        ``{study name: [label names]}``, only for the studies that lack some, each list in the order the labels
        first appear in the batch.

    Examples
    --------
    >>> liver = {"label": 1, "name": "liver", "colour": [200, 80, 60], "voxels": 900, "ml": 0.9}
    >>> spleen = {"label": 2, "name": "spleen", "colour": [60, 80, 200], "voxels": 300, "ml": 0.3}
    >>> missing_labels([StudyRow("a", "a.nrrd", labels=[liver, spleen]),
    ...                 StudyRow("b", "b.nrrd", labels=[liver, {**spleen, "voxels": 0}]),
    ...                 StudyRow("c", "c.nrrd", error="cannot read c.nrrd"), StudyRow("d", "d.nrrd")])
    {'b': ['spleen']}
    >>> missing_labels([StudyRow("seg", "s.dcm", labels=[{**liver, "name": "hip right"}]),      # one structure
    ...                 StudyRow("masks", "m/", labels=[{**liver, "name": "hip_right"}])])
    {}
    """
    return {name: list(lacking.values()) for name, lacking in _lacking(studies).items()}


def _lacking(studies):
    """:func:`missing_labels` by key: ``{study name: {label key: the name it first had in the batch}}``."""
    from .._shared.label_sets import label_key

    studies = [study for study in studies if not study.error and study.labels]
    present = {study.name: {label_key(label["name"], label["label"]): label["name"] for label in study.labels
                            if label["voxels"] > 0} for study in studies}
    seen = {}                                           # key -> the name it first had in the batch
    for names in present.values():
        for key, name in names.items():
            seen.setdefault(key, name)
    lacking = {}
    for study in studies:               # a key the batch has seen is another study's when this one lacks it
        keys = {key: name for key, name in seen.items() if key not in present[study.name]}
        if keys:
            lacking[study.name] = keys
    return lacking


def write_index(path, studies, title="voxrender batch"):
    """Write the batch's index page to ``path``: the studies as data, shown a page at a time, the counts that need a
    look at the top.

    Parameters
    ----------
    path : str or Path
        The page (``index.html``); the studies' picture paths are relative to its folder.
    studies : sequence of StudyRow
        The rows; the flagged ones are shown first, the worst first, the others in this order.
    title : str
        The page's title and heading.

    Notes
    -----
    The studies are one JSON block in the page (:func:`read_index` reads it back), a few hundred bytes each, and its
    script builds the rows of the page shown (:data:`PAGE` studies), so a cohort of 10,000 opens in a second: the
    browser parses, lays out and draws a page of rows, not the cohort, and fetches only their thumbnails, lazily, and
    a turntable's frames when the pointer first comes to it.  Every text reaches the page as text (the JSON escapes
    ``<``, ``>`` and ``&``; the script escapes what it writes), every path is URL-quoted, so names, inputs and errors
    holding ``<``, ``&``, ``"``, ``#`` or ``%`` show as they are.  The page is written atomically.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> write_index(folder / "index.html", [StudyRow("head & neck", "in/head", seconds=2.5)])
    >>> read_index(folder / "index.html")[0].name
    'head & neck'
    """
    studies = list(studies)
    missing = _lacking(studies)
    # the flagged studies first, the worst first (the lowest Dice, else the most flags and the largest |z|); the
    # others in the batch's order
    studies = [studies[k] for k in sorted(range(len(studies)),
                                          key=lambda k: (not studies[k].flags, tuple(studies[k].severity), k))]
    counts = [(len(studies), "studies", ""),
              # what "show flagged" shows: a cohort flag, a failure, a missing label or an overlap
              (sum(bool(study.flags or study.error or study.overlaps or study.name in missing) for study in studies),
               "flagged", "warn"),
              (sum(bool(study.error) for study in studies), "failed", "bad"),
              (len(missing), "with missing labels", "warn"),
              (sum(bool(study.overlaps) for study in studies if not study.error), "with overlaps", "warn")]
    summary = " ".join(f'<span class="count {kind if number else ""}"><b>{number}</b> {what}</span>'
                       for number, what, kind in counts)
    summary += f' <span class="count" id="reviewed"><b>0</b> of {len(studies)} reviewed</span>'
    data = json.dumps(_records(studies, missing), ensure_ascii=False, separators=(",", ":"))
    # In a script element only "</script" or "<!--" could end it early: no "<" (nor ">", "&") is left as such.
    data = data.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")
    page = _PAGE.format(title=_text(title), summary=summary, data=data, style=_resource("index_page.css"),
                        script=_resource("index_page.js"))
    with atomic_output(path) as tmp:
        tmp.write_text(page, encoding="utf-8")


def read_index(path):
    """The studies of an index page :func:`write_index` wrote, in the order it shows them.

    Parameters
    ----------
    path : str or Path
        The page.

    Returns
    -------
    list of StudyRow
        As they were written, but for their ``severity`` (the order holds it) and their ``ml``, to the microlitre.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> page = pathlib.Path(tempfile.mkdtemp()) / "index.html"
    >>> liver = {"label": 1, "name": "liver", "colour": [200, 80, 60], "voxels": 900, "ml": 0.9}
    >>> write_index(page, [StudyRow("a", "a.nrrd", labels=[liver]),
    ...                    StudyRow("b", "b.nrrd", flags=["liver: 0 mL"], severity=(0.0,))])
    >>> [(study.name, study.flags, [label["ml"] for label in study.labels]) for study in read_index(page)]
    [('b', ['liver: 0 mL'], []), ('a', [], [0.9])]
    """
    from urllib.parse import unquote

    try:
        text = Path(path).read_text(encoding="utf-8")
        data = json.loads(text.split(_DATA_START, 1)[1].split("</script>", 1)[0])
    except (OSError, UnicodeDecodeError, IndexError, ValueError) as exc:
        raise InputError(f"cannot read the index page {path}: {exc or 'no studies in it'}; give an index.html "
                         "that voxrender batch wrote", parameter="path") from None
    legend = data["legend"]
    studies = []
    for record in data["studies"]:
        labels = []
        for at, voxels, ml, *shown in record.get("labels", []):
            name, number, colour, _ = legend[at]
            labels.append({"label": number, "name": name, "colour": colour, "voxels": voxels, "ml": ml,
                           **({"shown": shown[0]} if shown else {})})
        studies.append(StudyRow(
            record["name"], record["input"], record.get("error", ""),
            unquote(record["sheet"]) if "sheet" in record else None,
            [(caption, unquote(url)) for caption, url in record.get("views", [])],
            [unquote(url) for url in record.get("turntable", [])], labels,
            [{"names": names, "voxels": voxels} for *names, voxels in record.get("overlaps", [])],
            record.get("seconds"), record.get("flags", []), (), record.get("verdict", ""), record.get("note", "")))
    return studies


def _records(studies, missing):
    """The page's data: ``{"page": PAGE, "legend": [[name, label, colour, key], ...], "studies": [...]}``, each study
    a dict that holds only what it has (its name and input always; ``error``, ``sheet``, ``views`` as ``[caption,
    url]``, ``turntable`` as urls, ``labels`` as ``[legend index, voxels, ml]`` and the note of what is ``shown``,
    ``missing`` as legend indices, ``overlaps`` as ``[name, name, voxels]``, ``seconds``, ``flags``, ``verdict``,
    ``note``).  A label's name, number, colour and key (:func:`voxrender._shared.label_sets.label_key`, which the page
    matches missing labels by) are said once, in the legend: a cohort's studies share them.

    ``missing`` is :func:`_lacking`'s.
    """
    from .._shared.label_sets import label_key

    def entry(label):
        return label["name"], int(label["label"]), tuple(int(c) for c in label.get("colour") or (128, 128, 128))

    at = {}                                             # a label's entry -> its place in the legend
    for study in studies:
        for label in study.labels:
            at.setdefault(entry(label), len(at))
    legend = [[name, number, list(colour), label_key(name, number)] for name, number, colour in at]
    by_key = {}                                         # a missing key is another study's label: in the legend
    for place, (*_, key) in enumerate(legend):
        by_key.setdefault(key, place)

    records = []
    for study in studies:
        record = {"name": study.name, "input": study.input}
        if study.error:
            record["error"] = study.error
        if study.sheet:
            record["sheet"] = _url(study.sheet)
        if study.pictures:
            record["views"] = [[caption, _url(path)] for caption, path in study.pictures]
        if study.turntable:
            record["turntable"] = [_url(frame) for frame in study.turntable]
        if study.labels:
            record["labels"] = [[at[entry(label)], int(label["voxels"]), round(float(label["ml"]), 3)]
                                + ([label["shown"]] if label.get("shown") else []) for label in study.labels]
        if missing.get(study.name):
            record["missing"] = [by_key[key] for key in missing[study.name]]
        if study.overlaps:
            record["overlaps"] = [[*overlap["names"], int(overlap["voxels"])] for overlap in study.overlaps]
        if study.seconds is not None:
            record["seconds"] = round(float(study.seconds), 2)
        if study.flags:
            record["flags"] = list(study.flags)
        if study.verdict:
            record["verdict"] = study.verdict
        if study.note:
            record["note"] = study.note
        records.append(record)
    return {"page": PAGE, "legend": legend, "studies": records}


def _text(value):
    """Any text from the data, safe inside an element or a quoted attribute."""
    return html.escape(str(value), quote=True)


def _url(path):
    """A relative path as a link: forward slashes, URL-quoted (a space, ``#`` or ``%`` in a name stays a name)."""
    from urllib.parse import quote

    return quote(PurePath(path).as_posix())


def _resource(name):
    """The page's style or script, kept beside the package's data as files of their own language."""
    from importlib import resources

    return resources.files("voxrender").joinpath(f"data/{name}").read_text(encoding="utf-8")


# The studies' JSON is read back from between this and the next "</script>" (read_index).
_DATA_START = '<script type="application/json" id="studies">'
_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width">
<link rel="icon" href="data:,"><title>{title}</title><style>{style}</style></head>
<body><h1>{title}</h1>
<div class="summary">{summary}
<label>order <select id="order"><option value="worst">worst first</option><option value="name">by name</option>
</select></label>
<label>show <select id="show"><option value="all">all</option><option value="flagged">flagged</option>
<option value="unreviewed">no verdict yet</option><option value="failed">failed</option>
<option value="fail">verdict fail</option></select></label>
<input type="search" id="search" placeholder="study or label" size="14">
<span><button type="button" data-action="previous-page" title="the page before">&lsaquo;</button>
<span id="page">page 1</span>
<button type="button" data-action="next-page" title="the page after">&rsaquo;</button></span>
<label>reviewer <input type="text" id="reviewer" size="8"></label>
<button type="button" data-action="export">export verdicts.csv</button>
<button type="button" data-action="import">import</button><input type="file" id="import-file" accept=".csv" hidden>
<span class="keys">j/k: next, previous; p/f/u: pass, fail, unsure; n: note</span></div>
<table class="studies"><thead><tr><th>#</th><th>study</th><th>flags</th><th>sheet</th><th>views</th><th>turntable</th>
<th>labels</th></tr></thead>
<tbody></tbody></table>
<script type="application/json" id="studies">{data}</script>
<script>{script}</script>
</body></html>
"""
