"""Segmentations as other tools write them: every case of ``../shared/corpora/real-segs.tar.gz`` (highdicom, dcmqi,
rt-utils, dicompyler-core, DicomRTTool, CERR, TotalSegmentator, pyradiomics, SlicerRT) renders or is refused in one
line as its ``cases.tsv`` says, and every label keeps the volume its source holds, within 2 %.

``cases.tsv`` was computed from the files with pydicom, nibabel, pynrrd and NumPy (its ``build_cases.py``), never
with voxrender: each structure counted on its own mask, so a structure inside another keeps its voxels.
"""

import json
import re
import tarfile

import pytest
from conftest import ROOT, absent
from test_cli import run

CORPUS = ROOT.parent / "shared" / "corpora" / "real-segs.tar.gz"
PYNRRD_DATA = ROOT.parent / "shared" / "corpora" / "pynrrd-tests-data.tar.gz"
TOLERANCE = 0.02
# Cases still wrong, each with its reason; strict, so a case fixed here fails until it is taken off the list.
KNOWN_WRONG = {}


def _unpacked(tarball, folder):
    if not tarball.exists():
        absent(f"the corpus {tarball} is absent (it lives in ../shared/corpora beside the checkout)")
    with tarfile.open(tarball) as archive:
        archive.extractall(folder, filter="data")
    return folder


def _corpus_folder(tmp_path_factory):
    return _unpacked(CORPUS, tmp_path_factory.mktemp("corpus")) / "real-segs"


@pytest.fixture(scope="module")
def corpus(tmp_path_factory):
    return _corpus_folder(tmp_path_factory)


def _cases():
    """The rows of cases.tsv, read from the tarball without unpacking the rest (the ids name the tests)."""
    if not CORPUS.exists():
        return [pytest.param(None, id="corpus-absent")]
    with tarfile.open(CORPUS) as archive:
        text = archive.extractfile("real-segs/cases.tsv").read().decode()
    lines = text.splitlines()
    header = lines[0].lstrip("# ").split("\t")
    rows = [dict(zip(header, line.split("\t"), strict=True)) for line in lines[1:] if line.strip()]
    return [pytest.param(row, id=row["id"], marks=[pytest.mark.xfail(reason=KNOWN_WRONG[row["id"]], strict=True)]
                         if row["id"] in KNOWN_WRONG else []) for row in rows]


def _key(name):
    """Names compare without case, spaces, underscores or hyphens (cases.tsv's rule)."""
    return re.sub(r"[\s_\-]", "", name).lower()


def _expected(field):
    """``NAME~ML|NAME~ML`` as ``{key: ml}``; ``-`` is nothing."""
    if field == "-":
        return {}
    return {_key(name): float(ml) for name, ml in (item.rsplit("~", 1) for item in field.split("|"))}


@pytest.mark.parametrize("case", _cases())
def test_every_corpus_case_renders_or_is_refused_as_its_source_says(case, corpus, tmp_path):
    if case is None:
        pytest.skip("the corpus is absent")
    labels = corpus / case["labels"]
    listed, picture = tmp_path / "labels.json", tmp_path / "picture.png"
    common = ("--size", "96", "--labels-out", listed, "-o", picture)
    if case["mode"] == "pair":
        result = run("render", corpus / case["image"], "--labels-from", labels, *common)
    else:
        result = run("render", labels, "--labels", *common)
    assert "Traceback" not in result.output and result.exit_code in (0, 2), result.output
    if result.exit_code == 2:
        lines = result.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
        assert case["expect"] in ("refuse", "either"), f"refused though valid: {lines[0]}"
        assert not picture.exists() and not listed.exists()
        return
    assert case["expect"] in ("picture", "either"), "drew a picture of an input its source says cannot be drawn"
    assert picture.exists()
    found = {}
    for label in json.loads(listed.read_text())["labels"]:
        found[f"#{label['label']}"] = label
        if label.get("name"):
            found[_key(label["name"])] = label
    for name, ml in _expected(case["must"]).items():
        assert name in found, f"{name} is missing: {sorted(found)}"
        # cases.tsv counts what lies on the image's files: a SEG frame on a slice set aside from an uneven series is
        # beyond the image read, and counted apart (ml_outside_image), with a warning
        held = found[name]["ml"] + (found[name].get("ml_outside_image", 0) if "setting aside" in result.stderr else 0)
        assert held == pytest.approx(ml, rel=TOLERANCE), f"{name}: {found[name]} mL, not {ml}"
        if "ml_outside_image" in found[name]:
            assert f"{found[name]['name']}: " in result.stderr and "lies outside it" in result.stderr
    for name in (_key(n) for n in case["mustnot"].split("|") if n != "-"):
        assert name not in found or not found[name]["voxels"], f"{name} has content: {found[name]}"


@pytest.mark.parametrize(("labels", "said"), [
    ("highdicom/seg_image_sm_dots_tiled_full.dcm", "tiled segmentation of a slide (TILED_FULL"),    # not "damaged"
])
def test_a_refusal_gives_the_right_reason(corpus, tmp_path, labels, said):
    result = run("render", corpus / labels, "--labels", "-o", tmp_path / "x.png")
    lines = result.stderr.strip().splitlines()
    assert result.exit_code == 2 and len(lines) == 1 and said in lines[0] and "damaged" not in lines[0], result.stderr


def test_a_gzip_nrrd_with_byte_skip_minus_one_reads_as_pynrrd_reads_it(tmp_path):
    """pynrrd's own test file: byte skip -1 (the voxels end the inflated stream) with gzip data was refused."""
    import nrrd
    import numpy as np

    from voxrender import io

    data = _unpacked(PYNRRD_DATA, tmp_path) / "pynrrd-tests-data" / "nrrd" / "tests" / "data"
    path = data / "BallBinary30x30x30_gz_byteskip_minus_one.nrrd"
    expected, _ = nrrd.read(str(path), index_order="C")
    values = io.read_volume(path, reorient=False).values
    assert values.shape == expected.shape and np.array_equal(values, expected) and values.any()


@pytest.mark.parametrize("name", ["Bladder_Union_PTV", "Expanded_5_5_5_Rectum"])
def test_an_early_slicer_segmentation_lies_in_the_pelvis_of_its_ct(corpus, name):
    """SlicerRT's .seg.nrrd files of 2016 (4-D, no 'space') were refused as 'needs 4 vectors of 3 numbers'. Read as
    3D Slicer reads them (RAS, from the corner of Segmentation_Extent), the bladder and rectum lie in the middle of
    the patient left to right, inside the extent of the CT they were drawn on, the rectum behind the bladder."""
    import numpy as np

    from voxrender import io

    def bounds(volume):
        corners = np.array([[0, 0, 0], np.array(volume.values.shape[::-1]) - 1])
        return np.sort(volume.meta["origin"] + corners * volume.spacing @ volume.direction.T, axis=0)

    ct = io.read_volume(corpus / "slicerrt" / "TinyPatientCT.nrrd")
    ct = bounds(ct) + np.outer([-1, 1], ct.spacing) / 2                 # the CT's voxels' outer faces
    segmentation = io.read_volume(corpus / "slicerrt" / f"EclipseProstate_{name}.seg.nrrd")
    low, high = bounds(segmentation)
    assert np.all(low >= ct[0]) and np.all(high <= ct[1])
    assert abs((low[0] + high[0]) / 2) < 40                             # mm from the midline, left to right
    assert segmentation.meta["label_table"]["1"]["name"] == name
    assert (low[1] + high[1]) / 2 > (-20 if "Rectum" in name else -60)   # posterior is +y in LPS
