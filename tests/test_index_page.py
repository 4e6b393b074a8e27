"""The batch's index page, in a real browser: headless Chromium driven by Playwright, the page opened from the disk.

Without the playwright package or /usr/bin/chromium the browser tests skip, saying which is absent; under CI=true
they fail instead (CI installs both, and must run them).
"""

from pathlib import Path
from urllib.parse import unquote, urlparse

import numpy as np
import pytest
from conftest import absent

from benchmarks.index_page import chromium, chromium_absent
from voxrender.errors import InputError
from voxrender.outputs.output import write_png
from voxrender.qc.index_page import StudyRow, missing_labels, write_index

SCREENSHOT = Path("/tmp/index/screenshot.png")
FRAMES = 12
ERROR = 'cannot read <b>&"x.dcm": not a DICOM file'


def label(number, name, colour, voxels):
    return {"label": number, "name": name, "colour": colour, "voxels": voxels, "ml": voxels / 1000}


BRAIN = label(1, "brain", [230, 160, 140], 1_200_000)
SKULL = label(2, "skull", [240, 235, 210], 800_000)


def make_batch(folder):
    """A batch's folder: four studies, one with a turntable whose frames differ, one with a missing label (and names
    needing URL quoting), one with an overlap, one failed."""
    rng = np.random.default_rng(0)

    def png(relative, shape=(96, 128)):
        path = folder / relative
        path.parent.mkdir(parents=True, exist_ok=True)
        write_png(path, rng.integers(0, 256, (*shape, 3), dtype=np.uint8))
        return relative

    frames = []
    for k in range(FRAMES):     # a light bar that walks across: every frame a different picture
        frame = np.full((96, 96), 40, np.uint8)
        frame[:, 8 * k:8 * k + 8] = 200
        frames.append(f"head/turn/frame_{k:02d}.png")
        (folder / "head/turn").mkdir(parents=True, exist_ok=True)
        write_png(folder / frames[-1], frame)
    odd = "chest #2 100%"
    return [
        StudyRow("head", "/data/head", sheet=png("head/sheet.png", (200, 300)),
                 pictures=[("front", png("head/front.png")), ("left", png("head/left.png"))],
                 turntable=frames, labels=[BRAIN, SKULL], seconds=12.25),
        StudyRow(odd, f"/data/{odd}", sheet=png(f"{odd}/sheet.png", (200, 300)),
                 pictures=[("front", png(f"{odd}/front view.png"))], labels=[BRAIN], seconds=8.0),
        StudyRow("abdomen", "/data/abdomen", sheet=png("abdomen/sheet.png", (200, 300)),
                 pictures=[("front", png("abdomen/front.png"))], labels=[BRAIN, SKULL],
                 overlaps=[{"names": ["brain", "skull"], "voxels": 7}], seconds=9.5),
        StudyRow("broken", "/data/broken", error=ERROR, seconds=0.1),
    ]


# -- the page's text, without a browser ------------------------------------------------------------------------------

def test_missing_labels_by_name_across_the_batch():
    studies = [StudyRow("a", "a", labels=[BRAIN, SKULL]),
               StudyRow("b", "b", labels=[BRAIN, {**SKULL, "voxels": 0}]),   # present but empty: missing
               StudyRow("c", "c", labels=[SKULL]),
               StudyRow("d", "d", error="failed", labels=[])]                # failed: its flag is its failure
    assert missing_labels(studies) == {"b": ["skull"], "c": ["brain"]}
    assert missing_labels([StudyRow("alone", "x", labels=[BRAIN])]) == {}
    # a label held only by a failed study is nobody's missing label
    assert missing_labels([StudyRow("a", "a"), StudyRow("d", "d", error="x", labels=[BRAIN])]) == {}


def test_page_escapes_text_and_quotes_paths(tmp_path):
    studies = make_batch(tmp_path)
    write_index(tmp_path / "index.html", studies, title="QC <batch> & co")
    page = (tmp_path / "index.html").read_text()
    assert ERROR not in page and '<b>&"' not in page               # the studies are JSON with no "<", ">" or "&"
    assert r'cannot read \u003cb\u003e\u0026\"x.dcm\"' in page
    assert "<title>QC &lt;batch&gt; &amp; co</title>" in page
    assert '"chest%20%232%20100%25/front%20view.png"' in page
    assert "http" not in page.replace('name="viewport"', "")   # nothing asked of the network
    assert not list(tmp_path.glob(".index.html*"))              # written atomically: no temporary left


def test_the_page_reads_back_as_written(tmp_path):
    """read_index gives the rows written, the flagged first, each as it was but for its severity."""
    import json
    from dataclasses import asdict, replace

    from voxrender.qc.index_page import read_index

    studies = make_batch(tmp_path)
    studies[2] = replace(studies[2], flags=["brain: volume 1200 mL, the cohort 900 (z 4.1)"], severity=(1.0, -1, 4.1),
                         verdict="fail", note="see the sheet")
    write_index(tmp_path / "index.html", studies)

    def plain(rows):                                    # an empty tuple is an empty list, as JSON keeps it
        return [json.loads(json.dumps(asdict(row))) for row in rows]

    assert plain(read_index(tmp_path / "index.html")) == plain([replace(studies[2], severity=()), *studies[:2],
                                                               studies[3]])
    (tmp_path / "other.html").write_text("<html></html>")
    with pytest.raises(InputError, match="cannot read the index page"):
        read_index(tmp_path / "other.html")


def test_page_in_a_missing_folder_is_refused(tmp_path):
    with pytest.raises(InputError, match="does not exist"):
        write_index(tmp_path / "no such folder" / "index.html", [])


# -- in the browser ----------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def browser():
    """Headless Chromium, one for the module (Playwright's sync API runs one at a time); without it the tests skip,
    saying why, or fail under CI=true, which installs it."""
    if chromium_absent():
        absent(f"browser test: {chromium_absent()}")
    with chromium() as launched:
        yield launched


@pytest.fixture(scope="module")
def opened(tmp_path_factory, browser):
    """The page of a made batch, open in headless Chromium; with the console's and the page's errors."""
    folder = tmp_path_factory.mktemp("batch")
    write_index(folder / "index.html", make_batch(folder))
    errors = []
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    page = context.new_page()
    page.set_default_timeout(10_000)
    page.on("console", lambda message: message.type == "error" and errors.append(message.text))
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto((folder / "index.html").as_uri())
    yield page, folder, errors
    context.close()


def test_page_loads_without_errors_and_every_image_decodes(opened):
    page, folder, errors = opened
    decoded = page.evaluate("""async () => {
        const images = [...document.images];
        images.forEach(img => { img.loading = "eager"; });     // load the lazy thumbnails too
        return Promise.all(images.map(img => img.decode().then(() => [img.src, img.naturalWidth],
                                                                () => [img.src, 0])));
    }""")
    assert len(decoded) == 1 + 3 + 4    # the turntable, the sheets, the views
    assert [src for src, width in decoded if width == 0] == []
    assert errors == []


def test_every_link_is_a_file_in_the_folder(opened):
    page, folder, _ = opened
    urls = page.evaluate("""() => [
        ...[...document.querySelectorAll("a[href]")].map(a => a.href),
        ...[...document.querySelectorAll("img[src]")].map(img => img.src),
        ...[...document.querySelectorAll("img.turntable")].flatMap(
            img => JSON.parse(img.dataset.frames).map(f => new URL(f, document.baseURI).href)),
    ]""")
    assert len(urls) == 7 + 8 + FRAMES   # the links (sheets, views), the images (and the turntable), its frames
    for url in urls:
        parts = urlparse(url)
        assert parts.scheme == "file", url
        path = Path(unquote(parts.path))
        assert path.is_file() and path.is_relative_to(folder), url
    assert (folder / "chest #2 100%/front view.png").as_uri() in urls


def test_turntable_follows_the_pointer(opened):
    page, folder, errors = opened
    turntable = page.locator("img.turntable")
    assert turntable.evaluate("img => img.preloaded === undefined")  # no frame fetched before the pointer comes
    turntable.scroll_into_view_if_needed()
    box = turntable.bounding_box()
    y = box["y"] + box["height"] / 2

    def frame_at(k):
        """Put the pointer over frame k's share of the picture's width; the frame the picture then shows."""
        page.mouse.move(box["x"] + (k + 0.5) * box["width"] / FRAMES, y)
        return turntable.evaluate("img => img.src")

    first = turntable.evaluate("img => img.src")
    assert first == (folder / "head/turn/frame_00.png").as_uri()
    page.mouse.move(box["x"] + 1, y)
    page.mouse.down()
    shown = [frame_at(k) for k in (3, 7, 11, 5)]
    page.mouse.move(box["x"] + box["width"] + 200, y)      # dragged past the edge: held at the last frame
    beyond = turntable.evaluate("img => img.src")
    page.mouse.up()
    assert shown == [(folder / f"head/turn/frame_{k:02d}.png").as_uri() for k in (3, 7, 11, 5)]
    assert beyond == (folder / "head/turn/frame_11.png").as_uri()
    assert turntable.evaluate("img => img.complete && img.naturalWidth") == 96
    assert turntable.evaluate("img => img.preloaded.length") == FRAMES        # fetched once it was reached
    assert errors == []


def test_flags_errors_and_counts_are_shown(opened):
    page, folder, _ = opened
    rows = page.locator("table.studies > tbody > tr")
    assert rows.count() == 4
    summary = " ".join(page.locator(".summary").inner_text().split())
    for count in ("4 studies", "3 flagged", "1 failed", "1 with missing labels", "1 with overlaps"):
        assert count in summary

    head, chest, abdomen, broken = (rows.nth(k) for k in range(4))
    assert head.get_attribute("class").split() == ["clean", "selected"] and head.locator(".flag").count() == 0
    assert chest.locator(".flag").inner_text().lower() == "missing 1"
    assert chest.locator("tr.missing").inner_text().split()[:2] == ["skull", "missing"]
    assert abdomen.locator(".flag").inner_text().lower() == "overlap 1"
    assert "overlap: brain / skull, 7 voxels" in abdomen.locator("tr.overlap").inner_text()
    assert broken.get_attribute("class") == "failed" and broken.locator(".flag").inner_text().lower() == "failed"
    error = broken.locator(".error")
    assert error.inner_text() == ERROR                  # shown as written, not read as markup
    assert error.locator("b").count() == 0
    assert error.evaluate("e => getComputedStyle(e).color") == "rgb(176, 0, 32)"

    SCREENSHOT.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=SCREENSHOT, full_page=True)

    page.locator("#show").select_option("flagged")     # the clean study goes; the flagged ones stay
    assert [rows.nth(k).get_attribute("data-study") for k in range(rows.count())] == [
        "chest #2 100%", "abdomen", "broken"]
    page.locator("#show").select_option("all")
    assert rows.count() == 4


def test_text_that_looks_like_markup_stays_text(tmp_path, browser):
    """A name that would close the data's script element, an error that is an image with a handler: both shown as
    written, nothing run."""
    name = "</script><script>window.ran = 1</script><!--"
    error = '<img src=x onerror="window.ran = 2">'
    write_index(tmp_path / "index.html", [StudyRow(name, "/data/<x>", error=error, labels=[BRAIN]),
                                          StudyRow("plain", "/data/plain", labels=[BRAIN])])
    errors = []
    page = _open(browser.new_context(), tmp_path / "index.html", errors)
    assert page.locator("tr.failed .name").inner_text() == name
    assert page.locator("tr.failed .error").inner_text() == error
    assert page.evaluate("() => window.ran") is None and page.locator("tbody img").count() == 0
    assert page.locator("table.studies > tbody > tr").count() == 2 and errors == []


def _open(context, path, errors):
    page = context.new_page()
    page.set_default_timeout(10_000)
    page.on("pageerror", lambda error: errors.append(str(error)))
    page.goto(path.as_uri())
    return page


def _verdicts(page):
    return page.evaluate("""() => Object.fromEntries([...document.querySelectorAll("tr[data-study]")].map(
        row => [row.dataset.study, [row.dataset.verdict, row.querySelector("input.note").value]]))""")


def test_verdicts_by_keyboard_survive_a_reload_and_go_out_and_back_in_as_csv(tmp_path, browser):
    """j/k move, p/f/u give a verdict, n edits the note; a reload keeps them (local storage); export writes
    verdicts.csv, which read_verdicts reads and import puts back into a fresh browser."""
    from voxrender.qc.index_page import read_verdicts

    studies = make_batch(tmp_path)
    studies[1] = StudyRow("=cmd|' /C calc'!A0", "/data/x", labels=[BRAIN])       # a name a spreadsheet would run
    write_index(tmp_path / "index.html", studies)
    errors = []
    context = browser.new_context(accept_downloads=True)
    page = _open(context, tmp_path / "index.html", errors)
    assert page.locator("tr.selected").get_attribute("data-study") == "head"       # the first, on load
    page.keyboard.press("p")
    page.keyboard.press("j")
    page.keyboard.press("f")
    page.keyboard.press("n")
    page.keyboard.type("cut at L2, \"see\" sheet")
    page.keyboard.press("Enter")
    page.keyboard.press("j")
    page.keyboard.press("u")
    page.keyboard.press("k")
    assert page.locator("tr.selected").get_attribute("data-study") == "=cmd|' /C calc'!A0"
    given = {"head": ["pass", ""], "=cmd|' /C calc'!A0": ["fail", 'cut at L2, "see" sheet'],
             "abdomen": ["unsure", ""], "broken": ["", ""]}
    assert _verdicts(page) == given
    assert " ".join(page.locator("#reviewed").inner_text().split()) == "3 of 4 reviewed"
    page.reload()
    assert _verdicts(page) == given                                                 # kept in local storage
    page.locator("#order").select_option("name")                                    # by name, and back
    names = page.evaluate("() => [...document.querySelectorAll('tr[data-study]')].map(r => r.dataset.study)")
    assert names == sorted(names, key=str.lower) and page.locator("tr.selected").get_attribute("data-study") == "head"
    page.keyboard.press("k")                                                        # moving follows the order shown
    assert page.locator("tr.selected").get_attribute("data-study") == names[names.index("head") - 1]
    page.locator("#order").select_option("worst")
    assert page.evaluate("() => document.querySelector('tr[data-study]').dataset.study") == "head"
    with page.expect_download() as download:
        page.locator('[data-action="export"]').click()
    exported = tmp_path / "verdicts.csv"
    download.value.save_as(exported)
    text = exported.read_text()
    assert text.startswith("study,input,labels,verdict,note,reviewer,time") and "\"'=cmd|" in text
    assert read_verdicts(exported) == {name: tuple(v) for name, v in given.items() if v[0]}
    context.close()

    fresh = browser.new_context()                                                   # another browser: nothing kept
    page = _open(fresh, tmp_path / "index.html", errors)
    assert all(v == ["", ""] for v in _verdicts(page).values())
    page.locator("#import-file").set_input_files(str(exported))
    page.wait_for_function("() => document.querySelector('#reviewed b').textContent === '3'")
    assert _verdicts(page) == given
    fresh.close()
    assert errors == []


def test_a_batch_takes_the_verdicts_of_an_earlier_review(tmp_path, browser):
    """voxrender batch --verdicts: a second batch's page shows the first review's verdicts."""
    from test_cli import run

    np.save(tmp_path / "ball.npy", np.pad(np.full((6, 6, 6), 1000, np.int16), 4))
    (tmp_path / "verdicts.csv").write_text("study,input,labels,verdict,note,reviewer,time\n"
                                           "ball,x,,fail,\"holes, see the left view\",ab,2026-12-06\n")
    result = run("batch", tmp_path / "ball.npy", "--threshold", "500", "--size", "32", "--jobs", "1", "--verdicts",
                 tmp_path / "verdicts.csv", "-o", tmp_path / "second")
    assert result.exit_code == 0, result.output
    errors = []
    page = _open(browser.new_context(), tmp_path / "second" / "index.html", errors)
    assert _verdicts(page) == {"ball": ["fail", "holes, see the left view"]}
    assert errors == []
    (tmp_path / "bad.csv").write_text("study,verdict\nball,maybe\n")
    from test_cli import assert_bad_input

    assert_bad_input(run("batch", tmp_path / "ball.npy", "--threshold", "500", "--verdicts", tmp_path / "bad.csv",
                         "-o", tmp_path / "third"), "--verdicts", "'maybe' is not a verdict")


def test_search_and_filters_show_what_they_say_and_the_keys_follow(tmp_path, browser):
    """The filters (flagged, no verdict yet, failed, verdict fail) and the search (a study's name or a label) show
    exactly their studies, each option counting them; j and k move among the studies shown."""
    write_index(tmp_path / "index.html", make_batch(tmp_path))
    errors = []
    page = _open(browser.new_context(), tmp_path / "index.html", errors)

    def shown():
        return page.evaluate("() => [...document.querySelectorAll('tr[data-study]')].filter(r => !r.hidden)"
                             ".map(r => r.dataset.study)")

    everything = shown()
    assert len(everything) == 4
    page.keyboard.press("f")                                            # head: fail
    for value, expected in [("flagged", [s for s in everything if s != "head"]), ("failed", ["broken"]),
                            ("fail", ["head"]), ("unreviewed", [s for s in everything if s != "head"]),
                            ("all", everything)]:
        page.locator("#show").select_option(value)
        assert shown() == expected, value
        label = page.locator(f'#show option[value="{value}"]').inner_text()
        assert label.endswith(f"({len(expected)})"), label
    page.locator("#search").fill("skull")                               # a label's name
    assert shown() == ["head", "abdomen"]
    page.locator("#search").fill("CHEST #2")                            # a study's, whatever the case
    assert shown() == ["chest #2 100%"]
    page.locator("#search").fill("")
    page.locator("#search").press("Enter")                             # the keys go back to the page
    page.locator("#show").select_option("failed")
    assert page.locator("tr.selected").get_attribute("data-study") == "broken"   # the selection follows the filter
    page.locator("#show").select_option("flagged")
    page.keyboard.press("k")
    assert page.locator("tr.selected").get_attribute("data-study") == shown()[-2]
    assert errors == []


def test_a_cohort_is_shown_a_page_at_a_time_and_the_keys_cross_the_pages(tmp_path, browser):
    """250 studies: a page of 100 is laid out (the others hidden, their thumbnails not fetched), j past its last
    study turns the page, the counts and the search take the whole cohort."""
    from voxrender.qc.index_page import PAGE

    studies = [StudyRow(f"s{n:03d}", f"/data/s{n:03d}", labels=[BRAIN] if n % 2 else [BRAIN, SKULL])
               for n in range(250)]
    write_index(tmp_path / "index.html", studies)
    errors = []
    page = _open(browser.new_context(), tmp_path / "index.html", errors)

    def shown():
        return page.evaluate("() => [...document.querySelectorAll('tr[data-study]')].filter(r => !r.hidden)"
                             ".map(r => r.dataset.study)")

    assert PAGE == 100 and shown() == [f"s{n:03d}" for n in range(100)]
    assert page.locator("#page").inner_text() == "page 1 of 3"
    for _ in range(99):
        page.keyboard.press("j")
    assert page.locator("tr.selected").get_attribute("data-study") == "s099"
    page.keyboard.press("j")                                            # past the page's last: the next page
    assert page.locator("tr.selected").get_attribute("data-study") == "s100"
    assert shown()[0] == "s100" and page.locator("#page").inner_text() == "page 2 of 3"
    page.keyboard.press("k")
    assert page.locator("tr.selected").get_attribute("data-study") == "s099" and shown()[-1] == "s099"
    assert page.locator('#show option[value="all"]').inner_text().endswith("(250)")
    page.locator("#search").fill("s242")
    assert shown() == ["s242"]
    page.locator("#search").fill("")                                    # all again, the found study kept in view
    assert page.locator("tr.selected").get_attribute("data-study") == "s242"
    assert page.locator("#page").inner_text() == "page 3 of 3"
    page.locator('[data-action="previous-page"]').click()
    assert page.locator("#page").inner_text() == "page 2 of 3" and shown()[0] == "s100"
    page.locator("#show").select_option("unreviewed")                 # reviewing what is left: a verdict moves on
    page.keyboard.press("p")
    assert page.locator("tr.selected").get_attribute("data-study") == "s101" == shown()[0]
    assert page.locator('#show option[value="unreviewed"]').inner_text().endswith("(249)")
    assert errors == []


def test_a_cohort_of_10000_studies_is_one_page_that_stays_small(tmp_path, browser):
    """The 10,000 synthetic studies of the benchmark, from their rows alone: a page of them is in the document, fewer
    than 100 pictures are asked for at load, 200 presses of j cross two pages to the 201st study, and showing the
    flagged studies shows exactly them, page after page.  (How fast: ``python -m benchmarks.index_page``.)"""
    from benchmarks.index_page import cohort
    from voxrender.qc.index_page import PAGE

    studies = cohort(10_000)
    write_index(tmp_path / "index.html", studies)
    assert (tmp_path / "index.html").stat().st_size < 300 * len(studies)        # a few hundred bytes a study
    errors, pictures = [], []
    context = browser.new_context(viewport={"width": 1280, "height": 800})
    context.on("request", lambda request: request.url.endswith(".png") and pictures.append(request.url))
    page = _open(context, tmp_path / "index.html", errors)
    page.wait_for_timeout(500)                                                 # the lazy thumbnails in view asked for
    rows = page.locator("table.studies > tbody > tr")
    assert rows.count() == PAGE and 0 < len(pictures) < 100
    flagged = [study.name for study in studies if study.flags]                 # shown first
    for _ in range(200):
        page.keyboard.press("j")
    order = flagged + [study.name for study in studies if not study.flags]
    assert page.locator("tr.selected").get_attribute("data-study") == order[200]
    assert page.locator("#page").inner_text() == f"page 3 of {len(studies) // PAGE}"
    page.locator("#show").select_option("flagged")
    shown = []
    for _ in range(len(flagged) // PAGE):
        shown += page.evaluate("() => [...document.querySelectorAll('tr[data-study]')].map(r => r.dataset.study)")
        page.locator('[data-action="next-page"]').click()
    assert shown == flagged and page.locator('#show option[value="flagged"]').inner_text() == "flagged (200)"
    context.close()
    assert errors == []
