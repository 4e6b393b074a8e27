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
    page = _PAGE.format(title=_text(title), summary=summary, data=data, style=_STYLE,
                        script=_SCRIPT.replace("%PAGE%", str(PAGE)))
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
    """The page's data: ``{"legend": [[name, label, colour, key], ...], "studies": [...]}``, each study a dict that
    holds only what it has (its name and input always; ``error``, ``sheet``, ``views`` as ``[caption, url]``,
    ``turntable`` as urls, ``labels`` as ``[legend index, voxels, ml]`` and the note of what is ``shown``, ``missing``
    as legend indices, ``overlaps`` as ``[name, name, voxels]``, ``seconds``, ``flags``, ``verdict``, ``note``).  A
    label's name, number, colour and key (:func:`voxrender._shared.label_sets.label_key`, which the page matches
    missing labels by) are said once, in the legend: a cohort's studies share them.

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
    return {"legend": legend, "studies": records}


def _text(value):
    """Any text from the data, safe inside an element or a quoted attribute."""
    return html.escape(str(value), quote=True)


def _url(path):
    """A relative path as a link: forward slashes, URL-quoted (a space, ``#`` or ``%`` in a name stays a name)."""
    from urllib.parse import quote

    return quote(PurePath(path).as_posix())


_STYLE = """
body{font:13px/1.35 system-ui,sans-serif;margin:12px 16px;color:#222;background:#fff}
h1{font-size:18px;margin:0 0 6px}
.summary{margin:0 0 10px;display:flex;gap:14px;align-items:center;flex-wrap:wrap}
.count.bad{color:#b00020}.count.warn{color:#8a5a00}
table.studies{border-collapse:collapse;width:100%}
.studies>thead th{position:sticky;top:0;background:#f2f2f2;text-align:left;font-weight:600;padding:4px 6px;
 border-bottom:1px solid #bbb;z-index:1}
.studies>tbody>tr>td{padding:4px 6px;border-bottom:1px solid #e2e2e2;vertical-align:top}
tr.failed{background:#fdecee}
.name{font-weight:600;overflow-wrap:anywhere}.input{color:#666;font-size:11px;overflow-wrap:anywhere}
.error{color:#b00020;font-weight:600;white-space:pre-wrap;max-width:60em;margin-bottom:4px}
.flag{display:inline-block;margin:0 3px 3px 0;padding:1px 6px;border-radius:3px;font-size:11px;font-weight:700;
 text-transform:uppercase;white-space:nowrap}
.flag.bad{background:#b00020;color:#fff}.flag.warn{background:#ffc940;color:#3a2a00}
figure{display:inline-block;margin:0 6px 2px 0;vertical-align:top;text-align:center}
figcaption{font-size:11px;color:#555;max-width:140px;overflow:hidden;text-overflow:ellipsis;white-space:nowrap}
img{background:#000;display:block}
img.sheet{height:96px;min-width:48px}img.view{height:96px;min-width:48px}
img.turntable{height:128px;min-width:64px;cursor:ew-resize;touch-action:none;user-select:none}
table.labels{border-collapse:collapse;font-size:12px}
table.labels td{padding:0 6px 0 0;white-space:nowrap}
td.n{text-align:right;font-variant-numeric:tabular-nums}
.swatch{display:inline-block;width:10px;height:10px;margin-right:4px;border:1px solid #0004;vertical-align:-1px}
tr.missing td{color:#8a5a00;font-weight:600}tr.missing td:first-child::after{content:" \\26A0"}
tr.overlap td{color:#8a5a00}
.reason{font-size:12px;color:#5a3d00}
.verdict{margin-top:4px}.verdict button{font-size:11px;margin:0 2px 2px 0;padding:1px 5px;border:1px solid #999;
 border-radius:3px;background:#fff;cursor:pointer}
.verdict input.note{font-size:11px;width:11em;display:block;margin-top:2px}
tr[data-verdict="pass"] button[data-give="pass"]{background:#2e7d32;color:#fff}
tr[data-verdict="fail"] button[data-give="fail"]{background:#b00020;color:#fff}
tr[data-verdict="unsure"] button[data-give="unsure"]{background:#ffc940}
tr.selected>td{background:#e8f0fe}tr.selected>td:first-child{box-shadow:inset 3px 0 #1a73e8}
.keys{color:#666;font-size:11px}
"""

_SCRIPT = r"""
// The studies are data (the JSON block above); the rows of the page shown are built from them, so the browser lays
// out, draws and fetches the pictures of a page of studies, whatever the cohort's size.
(function () {
  var data = JSON.parse(document.getElementById("studies").textContent);
  var legend = data.legend, studies = data.studies, PAGE = %PAGE%;
  var body = document.querySelector("table.studies > tbody");
  var show = document.getElementById("show"), search = document.getElementById("search");
  var reviewer = document.getElementById("reviewer");
  var folder = location.pathname.replace(/[^/]*$/, ""), prefix = "voxrender:" + folder + ":";
  var byName = new Map(), written = studies.slice(), byNameOrder = null;
  var order = written, matched = written, page = 0, rendered = [], current = null;

  studies.forEach(function (study, k) {
    study.verdict = study.verdict || "";
    study.note = study.note || "";
    study.number = k + 1;
    study.kind = study.error ? "failed" : (study.missing || study.overlaps || study.flags ? "flagged" : "clean");
    study.labelNames = (study.labels || []).filter(function (l) { return l[1] > 0; })
      .map(function (l) { return legend[l[0]][0]; }).join(", ");
    study.text = (study.name + " " + study.input + " " + study.labelNames).toLowerCase();
    byName.set(study.name, study);
  });

  // Verdicts: kept at once in this browser's local storage, keyed by the batch's folder and the study, over those
  // the page was written with (--verdicts); exported and imported as verdicts.csv.
  try {
    for (var i = 0; i < localStorage.length; i++) {
      var name = localStorage.key(i), study = name.startsWith(prefix) && byName.get(name.slice(prefix.length));
      if (study) {
        study.kept = JSON.parse(localStorage.getItem(name)) || {};
        study.verdict = study.kept.verdict || "";
        study.note = study.kept.note || "";
      }
    }
  } catch (e) { /* storage refused (a private window): the page's own verdicts stand */ }
  function keep(study) {
    study.kept = {verdict: study.verdict, note: study.note, reviewer: reviewer.value, time: new Date().toISOString()};
    try { localStorage.setItem(prefix + study.name, JSON.stringify(study.kept)); } catch (e) {}
  }

  // A study's row.
  function esc(text) {
    return String(text).replace(/[&<>"']/g, function (c) { return "&#" + c.charCodeAt(0) + ";"; });
  }
  function thumbnail(url, caption, kind) {
    return '<figure><a href="' + esc(url) + '"><img src="' + esc(url) + '" loading="lazy" decoding="async" class="' +
      kind + '" alt="' + esc(caption) + '"></a><figcaption>' + esc(caption) + "</figcaption></figure>";
  }
  var count = new Intl.NumberFormat("en-US");
  var millilitres = new Intl.NumberFormat("en-US", {minimumFractionDigits: 1, maximumFractionDigits: 1});
  function row(study) {
    var flags = "", overlaps = study.overlaps || [], reasons = study.flags || [];
    var missing = (study.missing || []).map(function (k) { return legend[k][0]; });
    if (study.error) { flags += '<span class="flag bad">failed</span>'; }
    if (missing.length) {
      flags += '<span class="flag warn" title="' + esc(missing.join(", ")) + '">missing ' + missing.length + "</span>";
    }
    if (overlaps.length) { flags += '<span class="flag warn">overlap ' + overlaps.length + "</span>"; }
    if (reasons.length) {
      flags += '<span class="flag warn" title="' + esc(reasons.join("; ")) + '">flags ' + reasons.length + "</span>" +
        reasons.slice(0, 6).map(function (r) { return '<div class="reason">' + esc(r) + "</div>"; }).join("");
    }
    var about = '<div class="name">' + esc(study.name) + '</div><div class="input">' + esc(study.input) + "</div>" +
      (study.seconds == null ? "" : '<div class="input">' + study.seconds.toFixed(1) + " s</div>");
    var verdict = '<div class="verdict">' + ["pass", "fail", "unsure"].map(function (v) {
      return '<button type="button" data-give="' + v + '" title="' + v + " (" + v[0] + ')">' + v + "</button>";
    }).join("") + '<input class="note" type="text" placeholder="note (n)" value="' + esc(study.note) + '"></div>';
    var views = (study.error ? '<div class="error">' + esc(study.error) + "</div>" : "") +
      (study.views || []).map(function (v) { return thumbnail(v[1], v[0], "view"); }).join("");
    var frames = study.turntable || [];
    var turntable = frames.length ? '<figure><img class="turntable" src="' + esc(frames[0]) + '" loading="lazy" ' +
      'data-frames="' + esc(JSON.stringify(frames)) + '" tabindex="0" draggable="false" alt="turntable of ' +
      esc(study.name) +
      '"><figcaption>' + frames.length + " frames, move across</figcaption></figure>" : "";
    // a label is matched by its key (the legend's last item): "hip right" is "hip_right"
    var lacking = new Set((study.missing || []).map(function (k) { return legend[k][3]; })), present = new Set();
    var labels = (study.labels || []).map(function (l) {
      var name = legend[l[0]][0], colour = legend[l[0]][2];
      present.add(legend[l[0]][3]);
      return "<tr" + (lacking.has(legend[l[0]][3]) ? ' class="missing"' : "") + '><td><span class="swatch" ' +
        'style="background:rgb(' + colour.join(",") + ')"></span>' + esc(name) +
        (l[3] ? ' <span class="note">(' + esc(l[3]) + ")</span>" : "") + '</td><td class="n">' + count.format(l[1]) +
        '</td><td class="n">' + millilitres.format(l[2]) + " mL</td></tr>";
    }).concat((study.missing || []).filter(function (k) { return !present.has(legend[k][3]); }).map(function (k) {
      return '<tr class="missing"><td>' + esc(legend[k][0]) + '</td><td colspan="2">missing</td></tr>';
    }), overlaps.map(function (o) {
      return '<tr class="overlap"><td colspan="3">overlap: ' + o.slice(0, -1).map(esc).join(" / ") + ", " +
        count.format(o[o.length - 1]) + " voxels</td></tr>";
    })).join("");
    return '<tr class="' + study.kind + (study === current ? " selected" : "") + '" data-study="' +
      esc(study.name) + '" data-input="' + esc(study.input) + '" data-labels="' + esc(study.labelNames) +
      '" data-verdict="' + esc(study.verdict) + '"><td class="n">' + study.number + "</td><td>" +
      about + verdict + "</td><td>" + flags + "</td><td>" +
      (study.sheet ? thumbnail(study.sheet, "QC sheet", "sheet") : "") + '</td><td class="views">' + views +
      "</td><td>" + turntable + "</td><td>" + (labels ? '<table class="labels">' + labels + "</table>" : "") +
      "</td></tr>";
  }

  // The page of the matching studies shown.
  function render() {
    var pages = Math.max(1, Math.ceil(matched.length / PAGE));
    page = Math.min(Math.max(page, 0), pages - 1);
    var shown = matched.slice(page * PAGE, (page + 1) * PAGE);
    if (shown.length !== rendered.length || shown.some(function (s, k) { return s !== rendered[k]; })) {
      rendered = shown;
      body.innerHTML = shown.map(row).join("");
    }
    document.getElementById("page").textContent = "page " + (page + 1) + " of " + pages;
  }
  function element(study) { var k = rendered.indexOf(study); return k < 0 ? null : body.rows[k]; }
  function studyOf(node) {
    var tr = node.closest && node.closest("table.studies > tbody > tr");
    return tr ? rendered[tr.sectionRowIndex] : null;
  }
  function select(study) {
    if (!study) { return; }
    var before = current && element(current);
    if (before) { before.classList.remove("selected"); }
    current = study;
    var at = matched.indexOf(study);
    if (at >= 0 && Math.floor(at / PAGE) !== page) { page = Math.floor(at / PAGE); render(); }
    var tr = element(study);
    if (tr) { tr.classList.add("selected"); tr.scrollIntoView({block: "nearest"}); }
  }
  function step(by) {            // the next shown study that way, on the next page when it is there
    var at = matched.indexOf(current) + by;
    if (at >= 0 && at < matched.length) { select(matched[at]); }
  }
  function turn(by) {
    page += by;
    if (page >= 0 && page * PAGE < matched.length) { render(); select(matched[page * PAGE]); }
    else { page -= by; }
  }

  // What is shown: the studies that pass the filter and hold the search's words in their name, input or labels.
  var filters = {
    all: function () { return true; },
    flagged: function (s) { return s.kind !== "clean"; },
    unreviewed: function (s) { return !s.verdict; },
    failed: function (s) { return s.kind === "failed"; },
    fail: function (s) { return s.verdict === "fail"; }
  };
  function filter(event, place) {
    var words = search.value.toLowerCase().split(/\s+/).filter(Boolean);
    matched = order.filter(function (s) {
      return filters[show.value](s) && words.every(function (w) { return s.text.indexOf(w) >= 0; });
    });
    [].forEach.call(show.options, function (option) {
      option.textContent = option.textContent.replace(/ \(\d+\)$/, "") + " (" + order.filter(filters[option.value])
        .length + ")";
    });
    document.querySelector("#reviewed b").textContent = studies.filter(function (s) { return s.verdict; }).length;
    var at = matched.indexOf(current);
    if (at >= 0) { page = Math.floor(at / PAGE); render(); select(current); return; }
    // the selected study left the view: the first shown, or after a verdict under "no verdict yet" the next one
    render();
    if (matched.length) { select(matched[Math.min(place || 0, matched.length - 1)]); }
  }
  function give(study, verdict) {
    study.verdict = verdict;
    keep(study);
    var tr = element(study);
    if (tr) { tr.dataset.verdict = verdict; }
    filter(null, matched.indexOf(study));
  }

  show.addEventListener("change", filter);
  search.addEventListener("input", filter);
  document.getElementById("order").addEventListener("change", function (event) {
    if (event.target.value === "name" && !byNameOrder) {
      var collator = new Intl.Collator(undefined, {numeric: true});
      byNameOrder = written.slice().sort(function (a, b) { return collator.compare(a.name, b.name); });
    }
    order = event.target.value === "name" ? byNameOrder : written;
    filter();
  });
  document.querySelector('[data-action="previous-page"]').addEventListener("click", function () { turn(-1); });
  document.querySelector('[data-action="next-page"]').addEventListener("click", function () { turn(1); });

  // The rows' own controls, listened to once for all rows.
  body.addEventListener("click", function (event) {
    var study = studyOf(event.target), button = event.target.closest("button[data-give]");
    if (!study) { return; }
    select(study);
    if (button) { give(study, button.dataset.give); }
  });
  body.addEventListener("input", function (event) {
    var study = studyOf(event.target);
    if (study && event.target.matches("input.note")) { study.note = event.target.value; keep(study); }
  });

  // The turntable: the frame is the pointer's place across the picture (left edge the first frame, right edge the
  // last), so a mouse turns it by moving over it and a finger or pen by dragging (captured, so it may leave the
  // picture); the arrow keys step it.  Its frames are fetched when the pointer or the focus first comes to it, and
  // let go with its row when the page turns.
  function turntable(event) { return event.target.closest && event.target.closest("img.turntable"); }
  function frames(img) { return img.frames || (img.frames = JSON.parse(img.dataset.frames)); }
  function load(event) {
    var img = turntable(event);
    if (img && !img.preloaded) {
      img.preloaded = frames(img).map(function (src) { var frame = new Image(); frame.src = src; return frame; });
    }
  }
  function showFrame(img, k) {
    var all = frames(img);
    k = Math.min(all.length - 1, Math.max(0, k));
    if (k !== (img.frame || 0)) { img.frame = k; img.src = all[k]; }
  }
  function follow(event) {
    var img = turntable(event);
    if (img) {
      var box = img.getBoundingClientRect();
      showFrame(img, Math.floor((event.clientX - box.left) / box.width * frames(img).length));
    }
  }
  body.addEventListener("pointerover", load);
  body.addEventListener("focusin", load);
  body.addEventListener("pointerdown", function (event) {
    var img = turntable(event);
    if (img) { img.setPointerCapture(event.pointerId); follow(event); }
  });
  body.addEventListener("pointermove", follow);

  reviewer.value = (function () { try { return localStorage.getItem("voxrender:reviewer") || ""; } catch (e) {} })()
    || "";
  reviewer.addEventListener("input", function () {
    try { localStorage.setItem("voxrender:reviewer", reviewer.value); } catch (e) {}
  });
  document.addEventListener("keydown", function (event) {
    var target = event.target;
    if (target.matches && target.matches("input")) {    // typing; Enter or Escape hands the keys back
      if (event.key === "Enter" || event.key === "Escape") { target.blur(); }
      return;
    }
    if (event.ctrlKey || event.metaKey || event.altKey || !current) { return; }
    var moves = {j: 1, ArrowDown: 1, k: -1, ArrowUp: -1}, verdicts = {p: "pass", f: "fail", u: "unsure"};
    var spin = {ArrowLeft: -1, ArrowRight: 1}[event.key];
    if (spin && turntable(event)) {
      event.preventDefault();
      var n = frames(target).length;
      showFrame(target, ((target.frame || 0) + spin + n) % n);
    } else if (event.key in moves) { event.preventDefault(); step(moves[event.key]); }
    else if (event.key in verdicts) { event.preventDefault(); give(current, verdicts[event.key]); }
    else if (event.key === "n") {
      var tr = element(current);
      if (tr) { event.preventDefault(); tr.querySelector("input.note").focus(); }
    }
  });

  function cell(text) {          // quoted, and a text a spreadsheet would run as a formula kept as text
    text = String(text == null ? "" : text);
    if (/^[=+\-@\t\r]/.test(text) && isNaN(Number(text))) { text = "'" + text; }
    return '"' + text.replace(/"/g, '""') + '"';
  }
  document.querySelector('[data-action="export"]').addEventListener("click", function () {
    var lines = ["study,input,labels,verdict,note,reviewer,time"];
    order.forEach(function (s) {
      var kept = s.kept || {};
      lines.push([s.name, s.input, s.labelNames, s.verdict, s.note, kept.reviewer || reviewer.value, kept.time || ""]
                 .map(cell).join(","));
    });
    var link = document.createElement("a");
    link.href = URL.createObjectURL(new Blob([lines.join("\r\n") + "\r\n"], {type: "text/csv"}));
    link.download = "verdicts.csv";
    document.body.appendChild(link);
    link.click();
    link.remove();
  });
  function parse(text) {         // RFC 4180: quoted fields, doubled quotes, CRLF or LF
    var table = [], fields = [], field = "", quoted = false;
    for (var i = 0; i < text.length; i++) {
      var c = text[i];
      if (quoted) {
        if (c === '"' && text[i + 1] === '"') { field += '"'; i++; }
        else if (c === '"') { quoted = false; }
        else { field += c; }
      } else if (c === '"') { quoted = true; }
      else if (c === ",") { fields.push(field); field = ""; }
      else if (c === "\n" || c === "\r") {
        if (c === "\r" && text[i + 1] === "\n") { i++; }
        fields.push(field); table.push(fields); fields = []; field = "";
      } else { field += c; }
    }
    if (field || fields.length) { fields.push(field); table.push(fields); }
    return table;
  }
  function plain(text) { return /^'[=+\-@\t\r]/.test(text) ? text.slice(1) : text; }
  var picker = document.getElementById("import-file");
  document.querySelector('[data-action="import"]').addEventListener("click", function () { picker.click(); });
  picker.addEventListener("change", function () {
    if (!picker.files.length) { return; }
    picker.files[0].text().then(function (text) {
      var table = parse(text.replace(/^\ufeff/, "")), head = table.shift() || [], at = {};
      head.forEach(function (name, k) { at[name.trim()] = k; });
      table.forEach(function (fields) {
        var study = byName.get(plain(fields[at.study] || ""));
        var verdict = (fields[at.verdict] || "").trim().toLowerCase();
        if (!study || (verdict && ["pass", "fail", "unsure"].indexOf(verdict) < 0)) { return; }
        study.verdict = verdict;
        study.note = plain(fields[at.note] || "");
        keep(study);
      });
      rendered = [];             // the rows shown, written again with their verdicts and notes
      filter();
      picker.value = "";
    });
  });

  current = studies[0] || null;
  filter();
})();
"""

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
