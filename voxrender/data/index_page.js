// The studies are data (the JSON block above); the rows of the page shown are built from them, so the browser lays
// out, draws and fetches the pictures of a page of studies, whatever the cohort's size.
(function () {
  var data = JSON.parse(document.getElementById("studies").textContent);
  var legend = data.legend, studies = data.studies, PAGE = data.page;
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
