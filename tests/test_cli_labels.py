"""Segmentations in colour through the commands: label maps, windows, presets, colour tables, legends, batch."""

import csv
import json

import imageio.v3 as iio
import nibabel as nib
import nrrd
import numpy as np
import pytest
from test_cli import assert_bad_input, run
from test_labels import nested

from voxrender.outputs.output import write_nifti
from voxrender.pictures.colours import PRESETS, palette


@pytest.fixture
def label_file(tmp_path):
    return write_nifti(tmp_path / "seg.nii.gz", nested())


@pytest.fixture
def ct_file(tmp_path):
    """A CT-like image of the same grid: 1000 inside every label, 0 outside; the box is denser (1500)."""
    labels = nested()
    values = np.where(labels > 0, 1000, 0).astype(np.int16)
    values[labels == 3] = 1500
    return write_nifti(tmp_path / "ct.nii.gz", values)


def colours_of(picture):
    """The distinct colours of a picture's brightest pixels, as hue directions (brightness removed)."""
    rgb = picture.reshape(-1, 3).astype(float)
    lit = rgb[rgb.sum(axis=1) > 60]
    return lit / lit.sum(axis=1, keepdims=True)


def test_labels_render_in_their_colours_with_every_output(tmp_path, label_file):
    out = tmp_path / "l.png"
    result = run("render", label_file, "--labels", "--size", "64", "--view", "left",
                 "--labels-out", tmp_path / "l.json", "--label-png", tmp_path / "l16.png",
                 "--stats-json", tmp_path / "s.json", "-o", out)
    assert result.exit_code == 0, result.output
    listed = json.loads((tmp_path / "l.json").read_text())["labels"]
    label_png = iio.imread(tmp_path / "l16.png")
    assert label_png.dtype == np.uint16 and set(np.unique(label_png)) - {0} == {v["label"] for v in listed}
    for entry in listed:
        assert entry["pixels"] == int((label_png == entry["label"]).sum())
        assert tuple(entry["colour"]) == palette([entry["label"]])[entry["label"]]
        assert entry["name"] == f"label {entry['label']}"
    stats = json.loads((tmp_path / "s.json").read_text())
    assert stats["stats"]["label_pixels"] == {str(v["label"]): v["pixels"] for v in listed}
    picture = iio.imread(out)
    assert picture.ndim == 3                                  # in colour
    for entry in listed:                                      # each label's pixels have its hue
        hue = np.array(entry["colour"], float) / sum(entry["colour"])
        shown = picture[(label_png == entry["label"]) & (picture.sum(axis=2) > 60)].astype(float)
        assert np.abs(shown / shown.sum(axis=1, keepdims=True) - hue).max() < 0.05
    result = run("render", label_file, "--labels", "--size", "64", "--view", "left", "--legend", "-o",
                 tmp_path / "legend.png")
    assert result.exit_code == 0, result.output
    legend = iio.imread(tmp_path / "legend.png")
    assert legend.shape[1] > 64 and np.array_equal(legend[:, :64], picture)  # 3 names are much of 64 pixels
    for entry in listed:                                            # a swatch of each label's colour
        assert (legend == entry["colour"]).all(axis=2).sum() >= 9 * 9


def test_a_long_legend_goes_beside_the_picture_not_over_it(tmp_path):
    """40 labels at --size 128 covered the whole object with their names (issue 33, item 8): the legend goes on a
    panel to the right, in columns, and the picture itself is what it is without one."""
    labels = np.zeros((40, 40, 40), np.uint8)
    for k in range(40):                                       # 40 slabs side by side, all seen from the front
        labels[4:36, 4:36, k] = k + 1
    label_file = write_nifti(tmp_path / "many.nii.gz", labels)
    made = {}
    for name, legend in (("plain", []), ("legend", ["--legend"])):
        result = run("render", label_file, "--labels", "--size", "128", "--view", "anterior", *legend,
                     "--labels-out", tmp_path / f"{name}.json", "-o", tmp_path / f"{name}.png")
        assert result.exit_code == 0, result.output
        made[name] = iio.imread(tmp_path / f"{name}.png")
    plain, legend = made["plain"], made["legend"]
    assert legend.shape[0] == 128 and legend.shape[1] > 128
    assert np.array_equal(legend[:, :128], plain)              # nothing drawn over the object
    panel = legend[:, 128:]
    shown = json.loads((tmp_path / "legend.json").read_text())["labels"]
    assert len(shown) == 40
    for entry in shown:                                        # a swatch of each label's colour, on the panel
        assert (panel == entry["colour"]).all(axis=2).sum() >= 9 * 9, entry


def test_an_animation_takes_frames_whose_legends_differ_in_width(tmp_path):
    """From the front 32 labels are seen (a legend beside the frame), from the back one (in its corner): the GIF
    holds every frame, the narrower ones widened to the widest."""
    labels = np.zeros((40, 40, 40), np.uint8)
    for k in range(4, 36):
        labels[4:36, 4:30, k] = k + 1
    labels[4:36, 30:36, 4:36] = 41                            # a plate that hides them all from behind
    label_file = write_nifti(tmp_path / "many.nii.gz", labels)
    result = run("batch", label_file, "--labels", "--view", "anterior", "--view", "posterior", "--size", "96",
                 "--legend", "--gif", "--jobs", "1", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.output
    front, back = (iio.imread(tmp_path / "out" / "many" / f"{view}.png") for view in ("anterior", "posterior"))
    assert front.shape[1] > 96 == back.shape[1]
    frames = iio.imread(tmp_path / "out" / "many.gif")
    assert frames.shape[:3] == (2, 96, front.shape[1])


def test_a_colour_table_names_the_labels(tmp_path, label_file):
    (tmp_path / "t.csv").write_text("label,name,r,g,b\n2,ball,10,200,10\n3,box,200,10,10\n")
    result = run("render", label_file, "--labels", "--colours", tmp_path / "t.csv", "--size", "48",
                 "--labels-out", tmp_path / "l.json", "-o", tmp_path / "l.png")
    assert result.exit_code == 0, result.output
    listed = {v["label"]: v for v in json.loads((tmp_path / "l.json").read_text())["labels"]}
    assert listed[2]["name"] == "ball" and listed[3]["colour"] == [200, 10, 10]


def test_label_picks_labels_as_one_object_in_one_colour(tmp_path, label_file):
    result = run("render", label_file, "--label", "3", "--colour", "#ff0000", "--size", "48", "-o", tmp_path / "a.png")
    assert result.exit_code == 0, result.output
    picture = iio.imread(tmp_path / "a.png")
    lit = picture[picture.sum(axis=2) > 0]
    assert len(lit) and (lit[:, 1] == 0).all() and (lit[:, 2] == 0).all()
    result = run("render", label_file, "--label", "2,3", "--labels", "--size", "48", "--labels-out",
                 tmp_path / "l.json", "-o", tmp_path / "b.png")
    assert result.exit_code == 0, result.output
    assert {v["label"] for v in json.loads((tmp_path / "l.json").read_text())["labels"]} <= {2, 3}


def test_a_ct_with_its_label_map(tmp_path, ct_file, label_file):
    """--labels-from pairs a CT with its labels; a threshold then also selects the CT's values."""
    result = run("render", ct_file, "--labels-from", label_file, "--size", "48", "--labels-out",
                 tmp_path / "all.json", "-o", tmp_path / "all.png")
    assert result.exit_code == 0, result.output
    result = run("render", ct_file, "--labels-from", label_file, "--threshold", "1200", "--size", "48",
                 "--labels-out", tmp_path / "dense.json", "-o", tmp_path / "dense.png")
    assert result.exit_code == 0, result.output
    dense = json.loads((tmp_path / "dense.json").read_text())["labels"]
    every = json.loads((tmp_path / "all.json").read_text())["labels"]
    # the volumes are each label's own, as without the threshold; the picture shows only what passes it, and says so
    assert [(v["label"], v["voxels"], v["ml"]) for v in dense] == [(v["label"], v["voxels"], v["ml"]) for v in every]
    assert [v["label"] for v in dense if v["pixels"]] == [3]
    assert all(v["shown"] == "the picture shows it within the threshold 1200" for v in dense)
    assert all("shown" not in v for v in every)


def test_windows_and_presets(tmp_path, ct_file):
    for args in (["--threshold", "500:1200"], ["--threshold", ":1200"], ["--preset", "bone"]):
        result = run("render", ct_file, *args, "--size", "32", "-o", tmp_path / "w.png", "--stats-json",
                     tmp_path / "w.json")
        assert result.exit_code == 0, (args, result.output)
    picture = iio.imread(tmp_path / "w.png")
    lit = picture[picture.sum(axis=2) > 120].astype(float)
    bone = np.array(PRESETS["bone"].colour, float)
    assert np.abs(lit / lit.sum(axis=1, keepdims=True) - bone / bone.sum()).max() < 0.05
    result = run("presets")
    assert result.exit_code == 0 and all(name in result.output for name in PRESETS)
    assert "300: HU" in result.output


def test_encoded_labels_keep_their_colours(tmp_path, label_file):
    (tmp_path / "t.json").write_text(json.dumps({"3": {"name": "box", "colour": [1, 2, 250]}}))
    result = run("encode", label_file, "--labels", "-o", tmp_path / "l.vxs")
    assert result.exit_code == 0 and "3 labels" in result.output, result.output
    result = run("render", tmp_path / "l.vxs", "--colours", tmp_path / "t.json", "--size", "40",
                 "--labels-out", tmp_path / "l.json", "-o", tmp_path / "l.png")
    assert result.exit_code == 0, result.output
    assert {v["label"]: v["name"] for v in json.loads((tmp_path / "l.json").read_text())["labels"]}[3] == "box"


def test_seg_nrrd_names_and_colours(tmp_path):
    header = {"space": "left-posterior-superior", "space directions": np.eye(3), "encoding": "raw",
              "Segment0_Name": "ball", "Segment0_Color": "0 1 0", "Segment0_LabelValue": "2",
              "Segment0_Layer": "0", "Segment1_Name": "box", "Segment1_Color": "1 0 0",
              "Segment1_LabelValue": "3", "Segment1_Layer": "0"}
    nrrd.write(str(tmp_path / "s.seg.nrrd"), np.ascontiguousarray(nested()), header, index_order="C")
    result = run("render", tmp_path / "s.seg.nrrd", "--labels", "--size", "48", "--labels-out",
                 tmp_path / "l.json", "-o", tmp_path / "l.png")
    assert result.exit_code == 0, result.output
    listed = {v["label"]: v for v in json.loads((tmp_path / "l.json").read_text())["labels"]}
    assert listed[2]["name"] == "ball" and listed[2]["colour"] == [0, 255, 0]
    assert listed[3]["name"] == "box" and listed[3]["colour"] == [255, 0, 0]


def test_bad_label_inputs_end_in_one_line(tmp_path, label_file, ct_file):
    out = tmp_path / "out.png"
    fractional = write_nifti(tmp_path / "f.nii.gz", nested().astype(np.float32) * 0.5)
    far = tmp_path / "far.nii.gz"                                   # the label map of another patient position
    nib.save(nib.Nifti1Image(nested().T, np.array([[-1, 0, 0, 0], [0, -1, 0, 0], [0, 0, 1, 500.0], [0, 0, 0, 1]])),
             far)
    (tmp_path / "bad.csv").write_text("label,name,r,g,b\n2,ball,10,200,10\n3,box,red,0,0\n")
    cases = [
        (["render", fractional, "--labels"], ["error: " + str(fractional), "not a label map", "non-integer", "0.5"]),
        (["render", label_file, "--label", "9"], ["--label", "9", "holds 1, 2, 3"]),
        (["render", label_file, "--labels", "--colours", tmp_path / "bad.csv"], ["--colours", "row 3"]),
        (["render", ct_file, "--threshold", "900:100"], ["--threshold", "lo is above hi"]),
        (["render", ct_file, "--labels-from", far], ["--labels-from", "does not overlap the image", "z 499.5 to"]),
        (["render", ct_file, "--preset", "liver"], ["--preset", "unknown preset", "bone"]),
        (["render", ct_file, "--preset", "bone", "--threshold", "300"], ["--preset", "not both"]),
        (["render", label_file, "--labels", "--threshold", "2"], ["--threshold", "selected by its labels"]),
        (["render", ct_file, "--threshold", "500", "--label-png", tmp_path / "l.png"], ["--label-png", "single"]),
        (["render", label_file, "--label", "two"], ["--label", "separated by commas"]),
        (["render", label_file, "--labels", "--colour", "#12"], ["--colour", "not a colour"]),
    ]
    for args, words in cases:
        result = run(*args, "--size", "32", "-o", out)
        assert_bad_input(result, *words)
        assert not out.exists() and not (tmp_path / "l.png").exists(), args
        blamed = result.stderr.split()[1]
        assert not blamed.startswith("--") or blamed.rstrip(":") in args, result.stderr   # a flag that was given


def test_batch_pairs_images_with_label_maps(tmp_path, ct_file, label_file):
    (tmp_path / "m.csv").write_text(f"input,labels\n{ct_file.name},{label_file.name}\n{ct_file.name},\n")
    result = run("batch", "--manifest", tmp_path / "m.csv", "--threshold", "500", "--view", "left",
                 "--view", "anterior", "--size", "40", "--per-label", "--jobs", "1", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.output
    with open(tmp_path / "out" / "summary.csv") as f:
        rows = list(csv.DictReader(f))
    assert [r["labels"] for r in rows[:2]] != ["", ""] and all(int(r["labels"]) >= 2 for r in rows[:2])
    assert [r["labels"] for r in rows[2:]] == ["", ""]                  # the second row is a plain CT
    volumes = {v["label"]: v for v in json.loads(rows[0]["label_volumes"])}
    assert {label: v["voxels"] for label, v in volumes.items()} == \
        {int(v): int((nested() == v).sum()) for v in (1, 2, 3)}           # 1 mm voxels: the file's own counts
    assert all(v["ml"] == round(v["voxels"] / 1000, 3) for v in volumes.values()) and rows[2]["label_volumes"] == ""
    made = sorted(p.name for p in (tmp_path / "out" / "ct").iterdir())
    assert "left-label3.png" in made and "anterior.png" in made
    alone = iio.imread(tmp_path / "out" / "ct" / "left-label3.png")
    assert alone.shape[:2] == (40, 40) and alone.any()


def test_info_lists_the_labels_of_a_label_map(label_file):
    result = run("info", label_file, "--labels", "--json")
    assert result.exit_code == 0, result.output
    labels = json.loads(result.output)["labels"]
    expected = np.unique(nested(), return_counts=True)
    assert {int(k): v["voxels"] for k, v in labels.items()} == {int(v): int(c)
                                                                for v, c in zip(*expected, strict=True) if v}
    assert all(v["ml"] == round(v["voxels"] / 1000, 3) for v in labels.values())     # 1 mm voxels


def test_every_label_list_gives_voxels_and_millilitres(tmp_path):
    """The number a QC reader compares first: each label's volume, on anisotropic voxels, in info and --labels-out."""
    labels = nested()
    path = write_nifti(tmp_path / "seg.nii.gz", labels, spacing=(0.5, 0.5, 2.0))
    info = json.loads(run("info", path, "--labels", "--json").output)["labels"]
    out = run("render", path, "--labels", "--size", "48", "--labels-out", tmp_path / "l.json", "-o", tmp_path / "l.png")
    assert out.exit_code == 0, out.output
    listed = {v["label"]: v for v in json.loads((tmp_path / "l.json").read_text())["labels"]}
    for label in (1, 2, 3):
        truth = int((labels == label).sum()) * 0.5 * 0.5 * 2.0 / 1000
        assert info[str(label)]["ml"] == pytest.approx(truth, rel=1e-4)     # to 5 digits: a landmark's 2 % too
        assert listed[label]["ml"] == pytest.approx(truth, rel=1e-4)        # counted on the file's own grid
        assert listed[label]["voxels"] == int((labels == label).sum())      # its voxels, not the 0.5 mm cubes


def test_label_options_with_a_single_object_are_refused(tmp_path, ct_file, label_file):
    for args, words in [(["--colours", tmp_path / "t.csv"], ["--colours", "single"]), (["--legend"], ["--legend"]),
                        (["--labels-out", tmp_path / "l.json"], ["--labels-out"])]:
        (tmp_path / "t.csv").write_text("label,name,r,g,b\n1,a,1,2,3\n")
        assert_bad_input(run("render", ct_file, "--threshold", "500", *args, "-o", tmp_path / "o.png"), *words)
        assert not (tmp_path / "o.png").exists()
    assert_bad_input(run("render", ct_file, "--labels-from", tmp_path / "none.nii.gz", "-o", tmp_path / "o.png"),
                     "--labels-from", "none.nii.gz")


def test_a_sheet_of_views_by_labels(tmp_path, label_file, ct_file):
    result = run("sheet", label_file, "--labels", "--per-label", "--view", "left", "--view", "anterior",
                 "--size", "48", "-o", tmp_path / "s.png")
    assert result.exit_code == 0 and "4 rows x 2 views" in result.output, result.output
    sheet = iio.imread(tmp_path / "s.png").reshape(-1, 3).astype(float)
    lit = sheet[sheet.sum(axis=1) > 60]
    hues = lit / lit.sum(axis=1, keepdims=True)
    for label in (2, 3):                                     # each label is drawn in its own colour
        colour = np.array(palette([label])[label], float)
        assert (np.abs(hues - colour / colour.sum()).max(axis=1) < 0.03).sum() > 100, label
    assert_bad_input(run("sheet", ct_file, "--threshold", "500", "--per-label", "-o", tmp_path / "t.png"),
                     "--per-label", "labels")
    assert_bad_input(run("sheet", label_file, label_file, "--labels", "--per-label", "-o", tmp_path / "t.png"),
                     "one input")


def test_several_presets_make_one_object_of_labelled_tissues(tmp_path):
    """A CT phantom in HU: air, soft tissue (40) and a bone block (700); skin,bone labels the tissue 1, the bone 2."""
    labels = nested()
    values = np.where(labels > 0, 40, -1000).astype(np.int16)
    values[labels == 3] = 700
    ct = write_nifti(tmp_path / "hu.nii.gz", values)
    result = run("render", ct, "--preset", "skin,bone", "--view", "left", "--size", "48", "--labels-out",
                 tmp_path / "l.json", "--label-png", tmp_path / "l.png", "-o", tmp_path / "p.png")
    assert result.exit_code == 0, result.output
    listed = {v["name"]: v for v in json.loads((tmp_path / "l.json").read_text())["labels"]}
    assert set(listed) == {"skin", "bone"}
    assert listed["bone"]["colour"] == list(PRESETS["bone"].colour) and listed["bone"]["label"] == 2
    picture = iio.imread(tmp_path / "p.png")
    bone = iio.imread(tmp_path / "l.png") == 2
    hue = np.array(PRESETS["bone"].colour, float)
    shown = picture[bone & (picture.sum(axis=2) > 60)].astype(float)
    assert len(shown) and np.abs(shown / shown.sum(axis=1, keepdims=True) - hue / hue.sum()).max() < 0.05
    assert_bad_input(run("render", ct, "--preset", "skin,liver", "-o", tmp_path / "x.png"), "--preset", "liver")
    assert_bad_input(run("render", ct, "--preset", "skin,bone", "--labels", "-o", tmp_path / "x.png"),
                     "--preset", "not both")
    assert not (tmp_path / "x.png").exists()


def test_classify_takes_the_last_window_that_holds_a_value():
    from voxrender.io import Volume
    from voxrender.object.prep import Interval, classify

    values = np.array([[[-1000, -200, 100, 400, 2000]]], np.int16)
    labels, _ = classify(Volume(values, (1, 1, 1)), [Interval(-300), Interval(300, 1000)])
    assert labels.tolist() == [[[0, 1, 1, 2, 1]]]


def test_a_label_map_on_another_grid_is_placed_by_patient_position(tmp_path, ct_file, label_file):
    """Was refused for its shape (or, of the same shape, given the CT's spacing unchecked): the map is resampled by
    the two voxel-to-patient affines, here stored in another orientation (axes permuted and flipped) at the same
    positions, and then on a grid shifted by one voxel."""
    from formats import stored

    from voxrender.space import orient

    values, spacing, direction = stored(nested(), "SAL", spacing=(1.0, 1.0, 1.0))
    lps = np.eye(4)
    lps[:3, :3] = direction * spacing
    lps[:3, 3] = -lps[:3, :3] @ orient.canonical_corner(values.shape, direction)   # canonical (0, 0, 0) at 0 mm
    nib.save(nib.Nifti1Image(values.T, np.diag([-1.0, -1.0, 1.0, 1.0]) @ lps), tmp_path / "sal.nii")
    shifted = np.diag([-1.0, -1.0, 1.0, 1.0])
    shifted[:3, 3] = [-1.0, 0, 0]                            # one voxel toward the patient's left (RAS -x)
    nib.save(nib.Nifti1Image(nested()[:, :, :-1].T, shifted), tmp_path / "shifted.nii")

    def label_image(map_path, name):
        result = run("render", ct_file, "--labels-from", map_path, "--size", "48", "--scale", "1.5", "--label-png",
                     tmp_path / f"{name}.png", "-o", tmp_path / f"{name}-rgb.png")
        assert result.exit_code == 0, result.output
        return iio.imread(tmp_path / f"{name}.png")

    reference = label_image(label_file, "reference")
    np.testing.assert_array_equal(label_image(tmp_path / "sal.nii", "sal"), reference)
    on_grid = np.zeros_like(nested())
    on_grid[:, :, 1:] = nested()[:, :, :-1]                  # the shifted map, as it lies on the CT's grid
    expected = label_image(write_nifti(tmp_path / "on-grid.nii", on_grid), "on-grid")
    np.testing.assert_array_equal(label_image(tmp_path / "shifted.nii", "shifted"), expected)
    assert np.count_nonzero(expected != reference) > 10


def test_info_of_an_image_and_its_label_map_tells_both_grids_and_how_they_relate(tmp_path, ct_file):
    coarse = np.diag([-2.0, -2.0, 2.0, 1.0])
    coarse[:3, 3] = [-1.0, 0.0, 3.0]                         # RAS: 1 mm toward L, 3 mm toward S
    nib.save(nib.Nifti1Image(nested()[::2, ::2, ::2].T.copy(), coarse), tmp_path / "coarse.nii.gz")
    result = run("info", ct_file, "--labels-from", tmp_path / "coarse.nii.gz", "--json")
    assert result.exit_code == 0, result.output
    summary = json.loads(result.stdout)
    assert summary["grids"][0].startswith("label map grid: ") and summary["grids"][1].startswith("image grid: ")
    assert summary["grids"][2].startswith("relation: shifted by") and "2x coarser" in summary["grids"][2]
    assert set(summary["labels"]) == {"1", "2", "3"} and all(v["voxels"] > 0 for v in summary["labels"].values())
    text = run("info", ct_file, "--labels-from", tmp_path / "coarse.nii.gz").stdout
    assert "\n  relation: shifted by" in text and "\nlabels: 3\n  1 label 1: " in text
    # a notebook asks the library for the same records
    import voxrender
    from voxrender.object.prep import LabelSelection

    described = voxrender.describe(ct_file, prepare=voxrender.PrepOptions(
        labels=LabelSelection(source=tmp_path / "coarse.nii.gz")))
    assert json.loads(json.dumps(described, default=float)) == summary


def test_info_of_a_mask_folder_lists_empty_masks_and_overlaps(tmp_path):
    folder = tmp_path / "segmentations"
    folder.mkdir()
    liver, spleen = np.zeros((2, 8, 10, 12), np.uint8)
    liver[2:6, 2:6, 2:8] = 1
    spleen[2:6, 2:6, 6:10] = 1                               # 4 x 4 x 2 voxels in both
    for name, mask in (("liver", liver), ("spleen", spleen), ("kidney_left", np.zeros_like(liver))):
        write_nifti(folder / f"{name}.nii.gz", mask)
    summary = json.loads(run("info", folder, "--labels", "--json").stdout)
    assert {v["name"]: v["voxels"] for v in summary["labels"].values()} == {"kidney_left": 0, "liver": 96,
                                                                           "spleen": 64}     # each its own
    assert summary["overlaps"] == [{"labels": [2, 3], "names": ["liver", "spleen"], "voxels": 32}]
    text = run("info", folder, "--labels").stdout
    assert "  1 kidney_left: 0 voxels, 0 mL" in text and "  liver and spleen: 32 voxels" in text


def test_a_mask_folder_takes_anatomy_colours_and_a_colour_table_by_name(tmp_path):
    from voxrender.pictures.colours import anatomy_colour

    folder = tmp_path / "segmentations"
    folder.mkdir()
    for name, box in (("liver", np.s_[2:6, 2:6, 2:6]), ("spleen", np.s_[2:6, 2:6, 8:11]),
                      ("tumour", np.s_[7:9, 7:9, 2:4])):
        mask = np.zeros((10, 10, 12), np.uint8)
        mask[box] = 1
        write_nifti(folder / f"{name}.nii.gz", mask)
    result = run("render", folder, "--labels", "--size", "48", "--labels-out", tmp_path / "a.json", "-o",
                 tmp_path / "a.png")
    assert result.exit_code == 0, result.output
    listed = {v["name"]: v for v in json.loads((tmp_path / "a.json").read_text())["labels"]}
    assert [listed[n]["label"] for n in ("liver", "spleen", "tumour")] == [1, 2, 3]          # sorted names
    assert tuple(listed["liver"]["colour"]) == anatomy_colour("liver") and listed["tumour"]["colour"]
    (tmp_path / "t.csv").write_text("label,name,r,g,b\n40,spleen,1,2,3\n")                  # another number
    result = run("render", folder, "--labels", "--size", "48", "--colours", tmp_path / "t.csv", "--labels-out",
                 tmp_path / "b.json", "-o", tmp_path / "b.png")
    listed = {v["name"]: v for v in json.loads((tmp_path / "b.json").read_text())["labels"]}
    assert listed["spleen"]["colour"] == [1, 2, 3] and listed["spleen"]["label"] == 2
    assert tuple(listed["liver"]["colour"]) == anatomy_colour("liver")


def test_a_manifest_labels_column_takes_a_mask_folder(tmp_path, ct_file):
    folder = tmp_path / "segmentations"
    folder.mkdir()
    for label in (1, 2, 3):
        write_nifti(folder / f"part{label}.nii.gz", (nested() == label).astype(np.uint8))
    (tmp_path / "m.csv").write_text(f"input,labels\n{ct_file.name},{folder.name}\n")
    result = run("batch", "--manifest", tmp_path / "m.csv", "--view", "left", "--size", "40", "--jobs", "1",
                 "-o", tmp_path / "out")
    assert result.exit_code == 0, result.output
    with open(tmp_path / "out" / "summary.csv") as f:
        row = next(csv.DictReader(f))
    volumes = json.loads(row["label_volumes"])
    assert [(v["name"], v["voxels"]) for v in volumes] == [(f"part{k}", int((nested() == k).sum())) for k in (1, 2, 3)]


def test_a_label_map_reaching_beyond_its_image_says_how_much_of_each_structure_lies_outside(tmp_path):
    """A map (nibabel) of slices z 0..19 on a CT of slices z 0..9: the half of each structure beyond the CT is in no
    picture and no count on the CT's grid; a warning names it, and --labels-out gives it apart."""
    affine = np.diag([-1.0, -1.0, 1.0, 1.0])                  # RAS, so the LPS axes: x left, y back, z up
    ct = np.zeros((16, 16, 10), np.int16)                     # x, y, z
    nib.save(nib.Nifti1Image(ct, affine), tmp_path / "ct.nii.gz")
    labels = np.zeros((16, 16, 20), np.uint8)
    labels[2:8, 2:8, :] = 1                                   # 20 slices: 10 inside the CT, 10 beyond it
    labels[9:14, 9:14, 12:] = 2                               # wholly beyond it
    labels[9:14, 2:6, 2:6] = 3                                # wholly inside
    nib.save(nib.Nifti1Image(labels, affine), tmp_path / "labels.nii.gz")
    result = run("render", tmp_path / "ct.nii.gz", "--labels-from", tmp_path / "labels.nii.gz", "--size", "48",
                 "--labels-out", tmp_path / "l.json", "-o", tmp_path / "l.png")
    assert result.exit_code == 0, result.output
    assert "label 1: 50 % (0.36 mL); label 2: 100 % (0.2 mL)" in result.stderr
    listed = {v["label"]: v for v in json.loads((tmp_path / "l.json").read_text())["labels"]}
    assert listed[1]["ml"] == pytest.approx(0.36) and listed[1]["ml_outside_image"] == pytest.approx(0.36)
    assert 2 not in listed and "ml_outside_image" not in listed[3]
