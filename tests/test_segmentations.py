"""Segmentations paired with their image through the commands: a DICOM SEG with its CT series (given by path, or
found in the study's folder), on its own geometry, and one made on another series."""

import json
import shutil

import imageio.v3 as iio
import numpy as np
import pytest
from seg_files import blobs, write_ct, write_ct_and_seg
from test_cli import assert_bad_input, run

from voxrender import io
from voxrender.outputs.output import write_nifti
from voxrender.space.grids import patient_affine

NAMES = ["liver", "spleen", "kidney_left"]


@pytest.fixture
def study(tmp_path):
    """A CT series, its SEG of :func:`organs`, and the same labels as a NIfTI on the CT's grid (written at the CT's
    origin, so that it pairs by position as the SEG does)."""
    ct, seg = write_ct_and_seg(tmp_path, blobs(), NAMES)
    volume = io.read_volume(ct)
    nifti = write_nifti(tmp_path / "labels.nii.gz", blobs(), volume.spacing, volume.meta["origin"])
    return ct, seg, nifti


def label_image(tmp_path, name, *args):
    result = run("render", *args, "--size", "64", "--scale", "1.5", "--view", "left", "--label-png",
                 tmp_path / f"{name}.png", "--labels-out", tmp_path / f"{name}.json",
                 "-o", tmp_path / f"{name}-rgb.png")
    assert result.exit_code == 0, result.output
    return iio.imread(tmp_path / f"{name}.png"), json.loads((tmp_path / f"{name}.json").read_text())["labels"]


def test_a_ct_with_its_seg_renders_the_label_image_of_the_map_it_was_written_from(tmp_path, study):
    ct, seg, nifti = study
    from_map, _ = label_image(tmp_path, "map", ct, "--labels-from", nifti)
    from_seg, listed = label_image(tmp_path, "seg", ct, "--labels-from", seg)
    np.testing.assert_array_equal(from_seg, from_map)
    assert set(np.unique(from_seg)) == {0, 1, 2, 3}
    assert [(v["label"], v["name"]) for v in listed] == list(enumerate(NAMES, 1))           # names from the SEG
    voxel_ml = float(np.prod(io.read_volume(ct).spacing)) / 1000
    expected = [int((blobs() == k).sum()) * voxel_ml for k in (1, 2, 3)]
    assert [v["ml"] for v in listed] == [pytest.approx(ml, rel=1e-4) for ml in expected]


def test_a_seg_alone_renders_on_its_own_geometry_and_in_the_study_folder_beside_its_ct(tmp_path, study):
    ct, seg, _ = study
    alone, listed = label_image(tmp_path, "alone", seg, "--labels")
    assert set(np.unique(alone)) == {0, 1, 2, 3} and [v["name"] for v in listed] == NAMES
    folder = tmp_path / "study"
    shutil.copytree(ct, folder)
    shutil.copy(seg, folder / "seg.dcm")                                  # one folder: the slices and their SEG
    beside, _ = label_image(tmp_path, "beside", folder, "--labels-from", folder)
    np.testing.assert_array_equal(beside, label_image(tmp_path, "apart", ct, "--labels-from", seg)[0])


def test_a_seg_of_another_series_is_refused_naming_both(tmp_path, study):
    _, seg, _ = study
    other = tmp_path / "other"
    write_ct(other, blobs().shape)
    result = run("render", other, "--labels-from", seg, "-o", tmp_path / "x.png")
    assert_bad_input(result, "--labels-from", "was made on series", "but the image is series")
    assert not (tmp_path / "x.png").exists()


def test_info_lists_a_segs_segments(tmp_path, study):
    _, seg, _ = study
    summary = json.loads(run("info", seg, "--labels", "--json").stdout)
    assert [v["name"] for v in summary["labels"].values()] == NAMES
    assert summary["format"] == "seg"


def test_a_ct_with_its_rtstruct_renders_the_label_image_of_the_masks_it_outlines(tmp_path, study):
    """The planar contours of each ROI, traced from the labels and written by pydicom, drawn on the CT's grid."""
    from rtstruct_files import references_of, write_rtstruct_of_labels

    ct, _, nifti = study
    volume = io.read_volume(ct)
    structure_set = write_rtstruct_of_labels(tmp_path / "rs.dcm", blobs(), patient_affine(volume), NAMES,
                                             [(220, 60, 40), (60, 160, 60), (40, 90, 200)],
                                             **references_of(sorted(ct.iterdir())))
    from_map, _ = label_image(tmp_path, "map", ct, "--labels-from", nifti)
    from_rtstruct, listed = label_image(tmp_path, "rs", ct, "--labels-from", structure_set)
    np.testing.assert_array_equal(from_rtstruct, from_map)
    assert [(v["name"], v["colour"]) for v in listed] == [("liver", [220, 60, 40]), ("spleen", [60, 160, 60]),
                                                          ("kidney_left", [40, 90, 200])]
    summary = json.loads(run("info", ct, "--labels-from", structure_set, "--json").stdout)
    assert {v["name"]: v["voxels"] for v in summary["labels"].values()} == \
        {name: int((blobs() == k).sum()) for k, name in enumerate(NAMES, 1)}
    assert_bad_input(run("render", structure_set, "-o", tmp_path / "x.png"), "is an RTSTRUCT", "its CT series")
    other = tmp_path / "other"
    write_ct(other, blobs().shape)
    assert_bad_input(run("render", other, "--labels-from", structure_set, "-o", tmp_path / "x.png"),
                     "--labels-from", str(volume.meta["series"]))


def test_a_seg_of_a_few_slices_pairs_without_a_warning(tmp_path, study):
    """A SEG stores only the frames that hold a segment, so its grid is shorter than its CT's by design: the
    warning for extents that differ (meant for maps that do not correspond) said so of every such SEG."""
    ct, seg, _ = study
    result = run("render", ct, "--labels-from", seg, "--size", "32", "-o", tmp_path / "x.png")
    assert result.exit_code == 0 and "warning" not in result.stderr, result.stderr


def test_the_patients_outline_is_left_out_of_the_surface_and_outlined_in_slices(tmp_path, study):
    """An RTSTRUCT whose EXTERNAL ROI, BODY, holds the organs: its surface would hide them, so it is left out of
    the surface with one warning and still listed with its volume; --with-body draws it; in slices it is outlined
    at its own edge, not filled, and not outlined around each organ inside it."""
    from rtstruct_files import references_of, write_rtstruct_of_labels

    ct, _, _ = study
    volume = io.read_volume(ct)
    body = np.zeros(blobs().shape, bool)
    body[:, 2:-2, 2:-2] = True                                # every organ lies inside it
    assert body[blobs() > 0].all()
    structure_set = write_rtstruct_of_labels(tmp_path / "rs.dcm", blobs(), patient_affine(volume), NAMES,
                                             outline=body, **references_of(sorted(ct.iterdir())))
    result = run("render", ct, "--labels-from", structure_set, "--size", "64", "--labels-out", tmp_path / "l.json",
                 "-o", tmp_path / "organs.png")
    assert result.exit_code == 0, result.output
    assert "BODY (label 4) is left out of the surface" in result.stderr and "--with-body" in result.stderr
    listed = {v["name"]: v for v in json.loads((tmp_path / "l.json").read_text())["labels"]}
    assert listed["BODY"]["pixels"] == 0 and listed["BODY"]["voxels"] == int(body.sum())
    assert all(listed[name]["pixels"] > 0 for name in NAMES)
    result = run("render", ct, "--labels-from", structure_set, "--with-body", "--size", "64", "--labels-out",
                 tmp_path / "b.json", "-o", tmp_path / "body.png")
    assert result.exit_code == 0 and "left out" not in result.stderr, result.output
    listed = {v["name"]: v for v in json.loads((tmp_path / "b.json").read_text())["labels"]}
    assert listed["BODY"]["pixels"] > 0


def test_a_structure_inside_another_is_outlined_by_its_own_edge():
    """BODY around an organ: BODY's outline is the outer edge only (it was drawn around the organ too, since the
    picture shows the organ there); as an envelope it is not filled; the organ keeps its own outline and fill."""
    from voxrender._shared import label_sets
    from voxrender.pictures.display import DisplayWindow
    from voxrender.qc.slices import slice_picture

    painter = label_sets.Painter((1, 20, 20), 2)
    body = np.zeros((1, 20, 20), bool)
    body[0, 2:18, 2:18] = True
    organ = np.zeros((1, 20, 20), bool)
    organ[0, 7:13, 7:13] = True
    painter.paint(1, (slice(None),), body)
    painter.paint(2, (slice(None),), organ)
    codes, sets = painter.finish()
    labels = label_sets.resolve(codes, sets)[0]
    table = {1: ("BODY", (0, 255, 0)), 2: ("organ", (255, 0, 0))}
    window = DisplayWindow(0, 1)

    def draw(overlay, **kwargs):
        return slice_picture(np.zeros((20, 20)), (1.0, 1.0), window, labels, table, overlay, opacity=0.5,
                             scale_bar=False, **kwargs)

    green = (draw("outline", shared=(codes[0], sets)) == (0, 255, 0)).all(axis=2)
    assert green[2, 2:18].all() and green[2:18, 2].all()          # the skin
    assert not green[5:15, 5:15].any()                            # not around the organ
    before = (draw("outline") == (0, 255, 0)).all(axis=2)
    assert before[6, 7:13].any()                                  # as it was: BODY's edge around the organ
    filled = draw("fill", shared=(codes[0], sets), envelopes=(1,))
    grey = slice_picture(np.zeros((20, 20)), (1.0, 1.0), window, overlay=None, scale_bar=False)
    assert (filled[4, 4] == grey[4, 4]).all() and (filled[2, 2] == (0, 255, 0)).all()   # BODY: outlined only
    assert filled[10, 10, 0] > grey[10, 10, 0] and filled[10, 10, 1] < grey[10, 10, 1]   # the organ: filled
