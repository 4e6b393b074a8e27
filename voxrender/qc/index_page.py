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
from pathlib import PurePath

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
    from .._shared.label_sets import label_key

    studies = [study for study in studies if not study.error and study.labels]
    present = {study.name: {label_key(label["name"], label["label"]): label["name"] for label in study.labels
                            if label["voxels"] > 0} for study in studies}
    seen = {}                                           # key -> the name it first had in the batch
    for names in present.values():
        for key, name in names.items():
            seen.setdefault(key, name)
    missing = {}
    for study in studies:               # a key the batch has seen is another study's when this one lacks it
        lacking = [name for key, name in seen.items() if key not in present[study.name]]
        if lacking:
            missing[study.name] = lacking
    return missing


def write_index(path, studies, title="voxrender batch"):
    """Write the batch's index page to ``path``: one row per study, the counts that need a look at the top.

    Parameters
    ----------
    path : str or Path
        The page (``index.html``); the studies' picture paths are relative to its folder.
    studies : sequence of StudyRow
        The rows, in the order shown.
    title : str
        The page's title and heading.

    Notes
    -----
    Every text from the studies is HTML-escaped and every path URL-quoted, so names, inputs and errors holding
    ``<``, ``&``, ``"``, ``#`` or ``%`` show as they are.  Thumbnails load lazily, as they scroll into view;
    a turntable's frames when the pointer first comes to it.  The page is written atomically.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> write_index(folder / "index.html", [StudyRow("head & neck", "in/head", seconds=2.5)])
    >>> "head &amp; neck" in (folder / "index.html").read_text()
    True
    """
    studies = list(studies)
    missing = missing_labels(studies)
    # the flagged studies first, the worst first (the lowest Dice, else the most flags and the largest |z|); the
    # others in the batch's order
    order = sorted(range(len(studies)), key=lambda k: (not studies[k].flags, tuple(studies[k].severity), k))
    rows = [_row(number, studies[k], missing.get(studies[k].name, []), hidden=number > PAGE)
            for number, k in enumerate(order, 1)]
    counts = [(len(studies), "studies", ""),
              (sum(bool(study.flags) for study in studies), "flagged", "warn"),
              (sum(bool(study.error) for study in studies), "failed", "bad"),
              (len(missing), "with missing labels", "warn"),
              (sum(bool(study.overlaps) for study in studies if not study.error), "with overlaps", "warn")]
    summary = " ".join(f'<span class="count {kind if number else ""}"><b>{number}</b> {what}</span>'
                       for number, what, kind in counts)
    summary += f' <span class="count" id="reviewed"><b>0</b> of {len(studies)} reviewed</span>'
    page = _PAGE.format(title=_text(title), summary=summary, rows="\n".join(rows), style=_STYLE,
                        script=_SCRIPT.replace("%PAGE%", str(PAGE)))
    with atomic_output(path) as tmp:
        tmp.write_text(page, encoding="utf-8")


def _text(value):
    """Any text from the data, safe inside an element or a quoted attribute."""
    return html.escape(str(value), quote=True)


def _url(path):
    """A relative path as a link: forward slashes, URL-quoted (a space, ``#`` or ``%`` in a name stays a name)."""
    from urllib.parse import quote

    return _text(quote(PurePath(path).as_posix()))


def _thumbnail(path, caption, size):
    """A lazily loaded thumbnail linked to its picture, with its caption under it."""
    link = _url(path)
    return (f'<figure><a href="{link}"><img src="{link}" loading="lazy" decoding="async" class="{size}" '
            f'alt="{_text(caption)}"></a><figcaption>{_text(caption)}</figcaption></figure>')


def _row(number, study, missing, hidden=False):
    """One study's table row."""
    flags = []
    if study.error:
        flags.append('<span class="flag bad">failed</span>')
    if missing:
        flags.append(f'<span class="flag warn" title="{_text(", ".join(missing))}">missing {len(missing)}</span>')
    if study.overlaps:
        flags.append(f'<span class="flag warn">overlap {len(study.overlaps)}</span>')
    if study.flags:
        reasons = list(study.flags)
        flags.append(f'<span class="flag warn" title="{_text("; ".join(reasons))}">flags {len(reasons)}</span>')
        flags += [f'<div class="reason">{_text(reason)}</div>' for reason in reasons[:6]]

    about = [f'<div class="name">{_text(study.name)}</div>', f'<div class="input">{_text(study.input)}</div>']
    if study.seconds is not None:
        about.append(f'<div class="input">{study.seconds:.1f} s</div>')

    sheet = _thumbnail(study.sheet, "QC sheet", "sheet") if study.sheet else ""
    views = "".join(_thumbnail(path, caption, "view") for caption, path in study.pictures)
    if study.error:
        views = f'<div class="error">{_text(study.error)}</div>' + views

    turntable = ""
    if study.turntable:
        frames = [_url(frame) for frame in study.turntable]
        # The frames' list as JSON in an attribute: the browser undoes the escaping before the script parses it.
        turntable = (f'<figure><img class="turntable" src="{frames[0]}" data-frames="{_text(json.dumps(frames))}" '
                     f'tabindex="0" draggable="false" alt="turntable of {_text(study.name)}">'
                     f'<figcaption>{len(frames)} frames, move across</figcaption></figure>')

    from .._shared.label_sets import label_key

    labels, lacking = [], {label_key(name) for name in missing}
    for label in study.labels:
        red, green, blue = (int(c) for c in label.get("colour") or (128, 128, 128))
        empty = ' class="missing"' if label_key(label["name"], label["label"]) in lacking else ""
        within = f' <span class="note">({_text(label["shown"])})</span>' if label.get("shown") else ""
        labels.append(f'<tr{empty}><td><span class="swatch" style="background:rgb({red},{green},{blue})"></span>'
                      f'{_text(label["name"])}{within}</td><td class="n">{int(label["voxels"]):,}</td>'
                      f'<td class="n">{float(label["ml"]):,.1f} mL</td></tr>')
    present = {label_key(label["name"], label["label"]) for label in study.labels}
    labels += [f'<tr class="missing"><td>{_text(name)}</td><td colspan="2">missing</td></tr>'
               for name in missing if label_key(name) not in present]
    labels += [f'<tr class="overlap"><td colspan="3">overlap: {" / ".join(_text(n) for n in overlap["names"])}, '
                f'{int(overlap["voxels"]):,} voxels</td></tr>' for overlap in study.overlaps]
    label_table = f'<table class="labels">{"".join(labels)}</table>' if labels else ""

    kind = "failed" if study.error else ("flagged" if flags else "clean")
    verdict = ('<div class="verdict">' + "".join(
        f'<button type="button" data-give="{v}" title="{v} ({v[0]})">{v}</button>' for v in VERDICTS)
        + f'<input class="note" type="text" placeholder="note (n)" value="{_text(study.note)}"></div>')
    names = ", ".join(label["name"] for label in study.labels if label.get("voxels"))
    cells = [f'<td class="n">{number}</td>', f'<td>{"".join(about)}{verdict}</td>', f'<td>{"".join(flags)}</td>',
             f"<td>{sheet}</td>", f'<td class="views">{views}</td>', f"<td>{turntable}</td>", f"<td>{label_table}</td>"]
    return (f'<tr class="{kind}" data-study="{_text(study.name)}" data-input="{_text(study.input)}" '
            f'data-labels="{_text(names)}" data-verdict="{_text(study.verdict)}"{" hidden" if hidden else ""}>'
            f'{"".join(cells)}</tr>')


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
body.only-flagged tr.clean{display:none}
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

# The turntable: the frame is the pointer's place across the picture (left edge the first frame, right edge the
# last), so a mouse turns it by moving over it and a finger or pen by dragging (captured, so it may leave the
# picture); the arrow keys step it.  Its frames are fetched when the pointer or the focus first comes to it, and
# kept: a page of many studies loads none of them up front.
_SCRIPT = r"""
document.querySelectorAll("img.turntable").forEach(function (img) {
  var frames = JSON.parse(img.dataset.frames), index = 0;
  function load() {              // the frames, fetched once the pointer or the keyboard comes to the turntable
    if (!img.preloaded) {
      img.preloaded = frames.map(function (src) { var frame = new Image(); frame.src = src; return frame; });
    }
  }
  img.addEventListener("pointerenter", load);
  img.addEventListener("focus", load);
  function show(i) {
    i = Math.min(frames.length - 1, Math.max(0, i));
    if (i !== index) { index = i; img.src = frames[i]; }
  }
  function follow(event) {
    var box = img.getBoundingClientRect();
    show(Math.floor((event.clientX - box.left) / box.width * frames.length));
  }
  img.addEventListener("pointerdown", function (event) { img.setPointerCapture(event.pointerId); follow(event); });
  img.addEventListener("pointermove", follow);
  img.addEventListener("keydown", function (event) {
    var step = {ArrowLeft: -1, ArrowRight: 1}[event.key];
    if (step) { event.preventDefault(); show((index + step + frames.length) % frames.length); }
  });
});
document.getElementById("only-flagged").addEventListener("change", function (event) {
  document.body.classList.toggle("only-flagged", event.target.checked);
});

// Verdicts: kept at once in this browser's local storage, keyed by the batch's folder and the study, over those
// the page was written with (--verdicts); exported and imported as verdicts.csv.
(function () {
  var rows = [].slice.call(document.querySelectorAll("tr[data-study]"));
  var folder = location.pathname.replace(/[^/]*$/, ""), selected = -1;
  var reviewer = document.getElementById("reviewer");
  function key(name) { return "voxrender:" + folder + ":" + name; }
  function stored(row) {
    try { return JSON.parse(localStorage.getItem(key(row.dataset.study)) || "null"); } catch (e) { return null; }
  }
  function keep(row) {
    var note = row.querySelector("input.note").value;
    try {
      localStorage.setItem(key(row.dataset.study), JSON.stringify({verdict: row.dataset.verdict, note: note,
        reviewer: reviewer.value, time: new Date().toISOString()}));
    } catch (e) { /* storage refused (a private window): the verdict stays on the page */ }
  }
  function count() {
    var done = rows.filter(function (row) { return row.dataset.verdict; }).length;
    document.querySelector("#reviewed b").textContent = done;
  }
  function give(row, verdict) { row.dataset.verdict = verdict; keep(row); count(); filter(); }
  function select(k) {
    if (!rows.length) { return; }
    k = Math.min(rows.length - 1, Math.max(0, k));
    if (selected >= 0) { rows[selected].classList.remove("selected"); }
    selected = k;
    rows[k].classList.add("selected");
    rows[k].scrollIntoView({block: "nearest"});
  }
  var PAGE = %PAGE%, page = 0, matched = rows.slice();
  function step(by) {            // the next shown study that way, on the next page when it is there
    var at = matched.indexOf(rows[selected]) + by;
    if (at < 0 || at >= matched.length) { return; }
    if (Math.floor(at / PAGE) !== page) { page = Math.floor(at / PAGE); paginate(); }
    select(rows.indexOf(matched[at]));
  }
  function paginate() {          // the page of the matching studies shown; the rest hidden
    var pages = Math.max(1, Math.ceil(matched.length / PAGE));
    page = Math.min(page, pages - 1);
    var on = new Set(matched.slice(page * PAGE, (page + 1) * PAGE));
    rows.forEach(function (row) { row.hidden = !on.has(row); });
    document.getElementById("page").textContent = "page " + (page + 1) + " of " + pages;
  }
  document.querySelector('[data-action="previous-page"]').addEventListener("click", function () {
    if (page > 0) { page--; paginate(); select(rows.indexOf(matched[page * PAGE])); }
  });
  document.querySelector('[data-action="next-page"]').addEventListener("click", function () {
    if ((page + 1) * PAGE < matched.length) { page++; paginate(); select(rows.indexOf(matched[page * PAGE])); }
  });
  // What is shown: the rows that pass the filter and hold the search's words in their name, input or labels.
  var filters = {
    all: function () { return true; },
    flagged: function (row) { return !row.classList.contains("clean"); },
    unreviewed: function (row) { return !row.dataset.verdict; },
    failed: function (row) { return row.classList.contains("failed"); },
    fail: function (row) { return row.dataset.verdict === "fail"; }
  };
  var show = document.getElementById("show"), search = document.getElementById("search");
  function filter() {
    var words = search.value.toLowerCase().split(/\s+/).filter(Boolean);
    var current = rows[selected];
    matched = rows.filter(function (row) {
      var text = (row.dataset.study + " " + row.dataset.input + " " + row.dataset.labels).toLowerCase();
      return filters[show.value](row) && words.every(function (w) { return text.indexOf(w) >= 0; });
    });
    var at = matched.indexOf(current);
    if (at >= 0) { page = Math.floor(at / PAGE); }
    paginate();
    [].forEach.call(show.options, function (option) {
      var n = rows.filter(filters[option.value]).length;
      option.textContent = option.textContent.replace(/ \(\d+\)$/, "") + " (" + n + ")";
    });
    if (selected >= 0 && rows[selected].hidden) {
      var first = rows.findIndex(function (row) { return !row.hidden; });
      if (first >= 0) { select(first); }
    }
  }
  show.addEventListener("change", filter);
  search.addEventListener("input", filter);
  search.addEventListener("keydown", function (event) {   // typing searches; Enter or Escape hands the keys back
    if (event.key === "Enter" || event.key === "Escape") { search.blur(); }
    event.stopPropagation();
  });
  rows.forEach(function (row) {
    var earlier = stored(row);
    if (earlier) {
      row.dataset.verdict = earlier.verdict || "";
      row.querySelector("input.note").value = earlier.note || "";
    }
    row.querySelectorAll("button[data-give]").forEach(function (button) {
      button.addEventListener("click", function () { select(rows.indexOf(row)); give(row, button.dataset.give); });
    });
    var note = row.querySelector("input.note");
    note.addEventListener("input", function () { keep(row); });
    note.addEventListener("keydown", function (event) {
      if (event.key === "Enter" || event.key === "Escape") { note.blur(); }
      event.stopPropagation();
    });
    row.addEventListener("click", function () { select(rows.indexOf(row)); });
  });
  try { reviewer.value = localStorage.getItem("voxrender:reviewer") || ""; } catch (e) {}
  reviewer.addEventListener("input", function () {
    try { localStorage.setItem("voxrender:reviewer", reviewer.value); } catch (e) {}
  });
  reviewer.addEventListener("keydown", function (event) { event.stopPropagation(); });
  document.addEventListener("keydown", function (event) {
    if (event.ctrlKey || event.metaKey || event.altKey || selected < 0) { return; }
    var row = rows[selected];
    var moves = {j: 1, ArrowDown: 1, k: -1, ArrowUp: -1};
    var verdicts = {p: "pass", f: "fail", u: "unsure"};
    if (event.key in moves) { event.preventDefault(); step(moves[event.key]); }
    else if (event.key in verdicts) { event.preventDefault(); give(row, verdicts[event.key]); }
    else if (event.key === "n") { event.preventDefault(); row.querySelector("input.note").focus(); }
  });
  function cell(text) {          // quoted, and a text a spreadsheet would run as a formula kept as text
    text = String(text == null ? "" : text);
    if (/^[=+\-@\t\r]/.test(text) && isNaN(Number(text))) { text = "'" + text; }
    return '"' + text.replace(/"/g, '""') + '"';
  }
  document.querySelector('[data-action="export"]').addEventListener("click", function () {
    var lines = ["study,input,labels,verdict,note,reviewer,time"];
    rows.forEach(function (row) {
      var kept = stored(row) || {};
      lines.push([row.dataset.study, row.dataset.input, row.dataset.labels, row.dataset.verdict,
                  row.querySelector("input.note").value, kept.reviewer || reviewer.value, kept.time || ""]
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
    var table = [], row = [], field = "", quoted = false;
    for (var i = 0; i < text.length; i++) {
      var c = text[i];
      if (quoted) {
        if (c === '"' && text[i + 1] === '"') { field += '"'; i++; }
        else if (c === '"') { quoted = false; }
        else { field += c; }
      } else if (c === '"') { quoted = true; }
      else if (c === ",") { row.push(field); field = ""; }
      else if (c === "\n" || c === "\r") {
        if (c === "\r" && text[i + 1] === "\n") { i++; }
        row.push(field); table.push(row); row = []; field = "";
      } else { field += c; }
    }
    if (field || row.length) { row.push(field); table.push(row); }
    return table;
  }
  function plain(text) { return /^'[=+\-@\t\r]/.test(text) ? text.slice(1) : text; }
  var picker = document.getElementById("import-file");
  document.querySelector('[data-action="import"]').addEventListener("click", function () { picker.click(); });
  picker.addEventListener("change", function () {
    if (!picker.files.length) { return; }
    picker.files[0].text().then(function (text) {
      var table = parse(text.replace(/^\ufeff/, "")), head = table.shift() || [];
      var at = {};
      head.forEach(function (name, k) { at[name.trim()] = k; });
      var byName = {};
      rows.forEach(function (row) { byName[row.dataset.study] = row; });
      table.forEach(function (fields) {
        var row = byName[plain(fields[at.study] || "")];
        var verdict = (fields[at.verdict] || "").trim().toLowerCase();
        if (!row || (verdict && ["pass", "fail", "unsure"].indexOf(verdict) < 0)) { return; }
        row.dataset.verdict = verdict;
        row.querySelector("input.note").value = plain(fields[at.note] || "");
        keep(row);
      });
      count();
      filter();
      picker.value = "";
    });
  });
  var body = document.querySelector("table.studies > tbody"), written = rows.slice();
  document.getElementById("order").addEventListener("change", function (event) {
    var current = rows[selected];
    rows = written.slice();
    if (event.target.value === "name") {
      rows.sort(function (a, b) { return a.dataset.study.localeCompare(b.dataset.study, undefined, {numeric: true}); });
    }
    rows.forEach(function (row) { body.appendChild(row); });
    selected = rows.indexOf(current);
    filter();
  });
  count();
  select(0);
  filter();
})();
"""

_PAGE = """<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width">
<link rel="icon" href="data:,"><title>{title}</title><style>{style}</style></head>
<body><h1>{title}</h1>
<div class="summary">{summary}<label><input type="checkbox" id="only-flagged"> only studies with a flag</label>
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
<tbody>
{rows}
</tbody></table>
<script>{script}</script>
</body></html>
"""
