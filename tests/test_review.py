"""voxrender.review: agreement with a reference, held to DeepMind's surface-distance on the same masks."""

import warnings
from pathlib import Path

import nibabel as nib
import numpy as np
import pytest
from scipy import ndimage

from voxrender.errors import InputError
from voxrender.io import Volume
from voxrender.review.agreement import agreement
from voxrender.review.surfaces import dice, surface_distances, surfel_areas

SPACING = (0.7, 0.9, 2.5)                                        # x, y, z mm: thin in-plane, thick slices


def _blob(seed, shape=(30, 40, 50)):
    rng = np.random.default_rng(seed)
    return ndimage.gaussian_filter(rng.random(shape), 3) > 0.5


def _damaged(mask):
    """The damages a cohort holds: eroded, shifted, cut, a stray fragment, and two thin ones."""
    cut, stray, thin = mask.copy(), mask.copy(), np.zeros_like(mask)
    cut[:, :, mask.shape[2] // 2:] = False
    stray[2:4, 2:4, 2:4] = True
    thin[10:12, 5:35, 5:45] = True
    return {"same": mask, "eroded": ndimage.binary_erosion(mask), "shifted": np.roll(mask, (1, 2, 0), (0, 1, 2)),
            "cut": cut, "stray": stray, "thin": thin, "thin moved": np.roll(thin, 1, 0)}


@pytest.mark.parametrize("damage", ["same", "eroded", "shifted", "cut", "stray", "thin", "thin moved"])
def test_every_surface_metric_equals_surface_distance_on_the_same_masks(damage):
    """Dice, HD95, ASSD (the area-weighted mean over both surfaces, from surface-distance's two directed means)
    and the normalised surface Dice at 1 and 2 mm, within 1e-9: the same definitions, computed apart."""
    deepmind = pytest.importorskip("surface_distance", reason="surface-distance is a test dependency")
    reference = _blob(0)
    test = _damaged(reference)[damage]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                          # its scipy.ndimage.filters namespace
        theirs = deepmind.compute_surface_distances(reference, test, SPACING[::-1])    # gt, pred; z, y, x spacing
    ours = surface_distances(test, reference, SPACING)
    assert ours.hausdorff() == pytest.approx(deepmind.compute_robust_hausdorff(theirs, 95), rel=1e-9)
    to_test, to_reference = deepmind.compute_average_surface_distance(theirs)
    areas = theirs["surfel_areas_gt"].sum(), theirs["surfel_areas_pred"].sum()
    pooled = (to_test * areas[0] + to_reference * areas[1]) / sum(areas)
    assert ours.assd() == pytest.approx(pooled, rel=1e-9)
    for tolerance in (1.0, 2.0):
        assert ours.surface_dice(tolerance) == pytest.approx(
            deepmind.compute_surface_dice_at_tolerance(theirs, tolerance), rel=1e-9)
    assert dice(test, reference) == pytest.approx(deepmind.compute_dice_coefficient(reference, test), rel=1e-12)


def test_the_surface_areas_are_those_of_surface_distance():
    """The 256 corner patterns' areas, from marching cubes, equal surface-distance's table of normals."""
    tables = pytest.importorskip("surface_distance.lookup_tables", reason="surface-distance is a test dependency")
    for spacing in [(1.0, 1.0, 1.0), (2.5, 0.9, 0.7)]:
        np.testing.assert_allclose(surfel_areas(spacing),
                                   tables.create_table_neighbour_code_to_surface_area(spacing), atol=1e-6)


def test_an_empty_side_has_no_surface_distance():
    ball = _blob(1)
    found = surface_distances(ball, np.zeros_like(ball), SPACING)
    assert np.isnan(found.hausdorff()) and np.isnan(found.assd()) and found.surface_dice(2.0) == 0.0


def _masks(folder, masks, affine):
    """A folder of NIfTI masks, written by nibabel: ``{name: mask[z, y, x]}``."""
    folder.mkdir()
    for name, mask in masks.items():
        nib.save(nib.Nifti1Image(mask.transpose(2, 1, 0).astype(np.uint8), affine), folder / f"{name}.nii.gz")
    return folder


def test_agreement_matches_structures_by_name_and_reports_one_sided_ones(tmp_path):
    """A reference of two hips and a bladder, a test whose names are spelled otherwise, whose right hip is eroded
    and which lacks the bladder but has a rectum: matched by name, the worst first."""
    affine = np.diag([-SPACING[0], -SPACING[1], SPACING[2], 1.0])
    shape = (30, 40, 50)
    nib.save(nib.Nifti1Image(np.zeros(shape[::-1], np.int16), affine), tmp_path / "ct.nii.gz")
    left, right, bladder = np.zeros(shape, bool), np.zeros(shape, bool), np.zeros(shape, bool)
    left[5:25, 5:20, 5:20], right[5:25, 5:20, 30:45], bladder[10:20, 25:35, 20:28] = True, True, True
    reference = _masks(tmp_path / "reference", {"hip_left": left, "hip_right": right, "urinary_bladder": bladder},
                       affine)
    test = _masks(tmp_path / "test", {"Left hip": left, "hip-right": ndimage.binary_erosion(right),
                                      "rectum": bladder}, affine)
    rows = agreement(tmp_path / "ct.nii.gz", test, reference)
    by_name = {row["name"]: row for row in rows}
    assert set(by_name) == {"hip_left", "hip_right", "urinary_bladder", "rectum"}
    assert by_name["hip_left"]["dice"] == 1.0 and by_name["hip_left"]["hd95_mm"] == 0.0
    assert by_name["hip_left"]["present"] == "both" and by_name["hip_left"]["reference_label"] == 1
    assert 0.5 < by_name["hip_right"]["dice"] < 1 and by_name["hip_right"]["volume_diff_ml"] < 0
    assert by_name["urinary_bladder"]["present"] == "reference only" and by_name["urinary_bladder"]["dice"] == 0.0
    assert by_name["rectum"]["present"] == "test only" and np.isnan(by_name["rectum"]["hd95_mm"])
    assert [row["dice"] for row in rows] == sorted(row["dice"] for row in rows)            # the worst first
    expected_ml = int(right.sum()) * float(np.prod(SPACING)) / 1000
    assert by_name["hip_right"]["reference_ml"] == pytest.approx(expected_ml, rel=1e-4)


def test_a_bad_reference_is_named_as_the_reference(tmp_path):
    image = Volume(np.zeros((4, 4, 4), np.int16), (1.0, 1.0, 1.0))
    labels = Volume(np.ones((4, 4, 4), np.uint8), (1.0, 1.0, 1.0))
    with pytest.raises(InputError, match="the reference") as info:
        agreement(image, labels, tmp_path / "absent.nii.gz")
    assert info.value.parameter == "reference"
    with pytest.raises(InputError) as info:
        agreement(image, labels, labels, tolerance_mm=-1)
    assert info.value.parameter == "tolerance_mm"


def test_the_agreement_command_writes_its_picture_and_metrics(tmp_path):
    from test_cli import assert_bad_input, run

    test_agreement_matches_structures_by_name_and_reports_one_sided_ones(tmp_path)     # writes the files
    result = run("agreement", tmp_path / "ct.nii.gz", "--labels-from", tmp_path / "test", "--reference",
                 tmp_path / "reference", "--size", "96", "-o", tmp_path / "a.png", "--metrics-out",
                 tmp_path / "m.csv")
    assert result.exit_code == 0, result.output
    assert "the worst, " in result.stdout and "on one side only (" in result.stderr
    import csv

    import imageio.v3 as iio

    with open(tmp_path / "m.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert [row["name"] for row in rows][:2] == ["rectum", "urinary_bladder"]          # Dice 0 first, by name
    assert {row["name"]: row["dice"] for row in rows}["hip_left"] == "1"
    picture = iio.imread(tmp_path / "a.png")
    assert picture.ndim == 3 and picture.shape[1] >= 4 * 96                   # three slices and the surface
    assert_bad_input(run("agreement", tmp_path / "ct.nii.gz", "--labels-from", tmp_path / "test", "--reference",
                         tmp_path / "absent", "-o", tmp_path / "b.png"), "--reference")
    assert not (tmp_path / "b.png").exists()


def _cohort():
    """Twelve studies of one liver and kidney: near-identical volumes (a voxel apart), one tiny liver, one in three
    pieces, one touching the border, one without its kidney, one with an empty kidney."""
    rows = []
    for k in range(12):
        study = f"s{k:02d}"
        liver = {"study": study, "label": 1, "name": "liver", "voxels": 1_500_000 + k, "ml": 1500.0 + k / 1000,
                 "components": 1, "border": False}
        kidney = {"study": study, "label": 2, "name": "kidney_left" if k % 2 else "Left kidney", "voxels": 150_000,
                  "ml": 150.0, "components": 1, "border": False}
        if k == 3:
            liver.update(voxels=300_000, ml=300.0)
        if k == 5:
            liver.update(components=3)
        if k == 7:
            liver.update(border=True)
        if k == 9:
            kidney = None
        if k == 10:
            kidney.update(voxels=0, ml=0.0)
        rows += [liver] + ([kidney] if kidney else [])
    return rows


def test_cohort_flags_name_what_is_unlike_the_rest_and_nothing_else():
    from voxrender import cohort_flags

    flags = cohort_flags(_cohort())
    # 'kidney_left' and 'Left kidney' are one structure, and a voxel's difference in the livers is no outlier
    assert {(f["study"], f["flag"]) for f in flags} == {("s03", "volume"), ("s05", "components"), ("s07", "border"),
                                                        ("s09", "missing"), ("s10", "empty")}
    volume = next(f for f in flags if f["flag"] == "volume")
    assert volume["value"] == 300.0 and volume["cohort"] == pytest.approx(1500.006) and volume["z"] < -3.5


def test_agreement_flags_and_the_worst_first():
    from voxrender.review.flags import cohort_flags, in_words, severity

    rows = [{"study": s, "label": 1, "name": "liver", "voxels": 10, "ml": 1.0, "dice": d, "nsd": n}
            for s, d, n in [("good", 0.95, 0.97), ("bad", 0.42, 0.5), ("fair", 0.79, 0.9)]]
    flags = cohort_flags(rows, min_dice=0.8, min_nsd=0.8)
    assert [(f["study"], f["flag"]) for f in flags] == [("bad", "dice"), ("bad", "nsd"), ("fair", "dice")]
    assert in_words(flags[0]) == "liver: dice 0.420, below 0.8"
    ordered = sorted({f["study"] for f in flags}, key=lambda s: severity([f for f in flags if f["study"] == s]))
    assert ordered == ["bad", "fair"]


def test_a_batch_of_damaged_copies_puts_the_worst_first_and_the_identical_last(tmp_path):
    """One CT, its reference (two hips and a bladder), and copies of it: identical, eroded, shifted, cut, emptied
    and with a stray fragment, a row each of a manifest with its name; agreement.csv and flags.csv hold them, and
    the index puts the worst first."""
    import csv

    from test_cli import run

    affine = np.diag([-SPACING[0], -SPACING[1], SPACING[2], 1.0])
    shape = (30, 40, 50)
    nib.save(nib.Nifti1Image(np.zeros(shape[::-1], np.int16), affine), tmp_path / "ct.nii.gz")
    left, right, bladder = np.zeros(shape, bool), np.zeros(shape, bool), np.zeros(shape, bool)
    left[5:25, 5:20, 5:20], right[5:25, 5:20, 30:45], bladder[10:20, 25:35, 20:28] = True, True, True
    structures = {"hip_left": left, "hip_right": right, "urinary_bladder": bladder}
    _masks(tmp_path / "reference", structures, affine)
    cut = right.copy()
    cut[15:] = False
    stray = bladder.copy()
    stray[2:4, 30:33, 40:43] = True
    edge = bladder.copy()
    edge[10:20, 25:35, 20:] = True                            # out to the edge of the field of view
    copies = {"identical": {}, "eroded": {"hip_left": ndimage.binary_erosion(left, iterations=2)},
              "shifted": {"urinary_bladder": np.roll(bladder, 3, axis=2)}, "cut": {"hip_right": cut},
              "emptied": {"urinary_bladder": np.zeros(shape, bool)}, "stray": {"urinary_bladder": stray},
              "edge": {"urinary_bladder": edge}}
    lines = ["input,name,labels,reference"]
    for name, changed in copies.items():
        _masks(tmp_path / name, {**structures, **changed}, affine)
        lines.append(f"ct.nii.gz,{name},{name},reference")
    (tmp_path / "m.csv").write_text("\n".join(lines) + "\n")
    result = run("batch", "--manifest", tmp_path / "m.csv", "--size", "32", "--jobs", "1", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.output
    with open(tmp_path / "out" / "agreement.csv", newline="") as f:
        agreement_rows = list(csv.DictReader(f))
    dice = {(r["study"], r["name"]): float(r["dice"]) for r in agreement_rows}
    assert all(dice[("identical", n)] == 1.0 for n in structures)
    assert dice[("emptied", "urinary_bladder")] == 0.0 and dice[("eroded", "hip_left")] < 0.8
    with open(tmp_path / "out" / "flags.csv", newline="") as f:
        flagged = {(r["study"], r["flag"]) for r in csv.DictReader(f)}
    assert ("emptied", "dice") in flagged and ("eroded", "dice") in flagged and ("stray", "components") in flagged
    assert ("edge", "border") in flagged
    assert not any(study == "identical" for study, _ in flagged)
    from voxrender.qc.index_page import read_index

    shown = [study.name for study in read_index(tmp_path / "out" / "index.html")]
    assert shown[0] == "emptied" and shown[-1] == "identical", shown


def test_slices_and_sheet_take_a_reference(tmp_path):
    """slices --reference shows both / labels only / reference only and the table; sheet --reference adds the
    table to a QC sheet; without labels, with a crop, or on a sheet that is not a QC sheet, one line each."""
    import imageio.v3 as iio
    from test_cli import assert_bad_input, run

    test_agreement_matches_structures_by_name_and_reports_one_sided_ones(tmp_path)     # writes the files
    ct, common = tmp_path / "ct.nii.gz", ("--labels-from", tmp_path / "test", "--reference", tmp_path / "reference")
    plain = run("slices", ct, "--labels-from", tmp_path / "test", "--size", "64", "-o", tmp_path / "plain.png")
    agreed = run("slices", ct, *common, "--size", "64", "--legend", "-o", tmp_path / "agreed.png")
    assert plain.exit_code == 0 and agreed.exit_code == 0, agreed.output
    taller = iio.imread(tmp_path / "agreed.png")
    assert taller.shape[0] > iio.imread(tmp_path / "plain.png").shape[0]            # the table under the slices
    from voxrender.review.agreement import CLASSES

    shown = {tuple(int(v) for v in c) for c in np.unique(taller.reshape(-1, 3), axis=0)}
    # the legend's swatches: the hips agree, the bladder is the reference's alone (the test's rectum in its place
    # is under it: where sides disagree, the reference-only class shows over the test-only one)
    assert {CLASSES[1][1], CLASSES[3][1]} <= shown
    result = run("sheet", ct, *common, "--slices", "axial", "--views", "anterior", "--size", "64",
                 "-o", tmp_path / "sheet.png")
    assert result.exit_code == 0, result.output
    assert_bad_input(run("slices", ct, "--reference", tmp_path / "reference", "-o", tmp_path / "x.png"),
                     "--reference", "--labels-from")
    assert_bad_input(run("slices", ct, *common, "--crop", "0:10,0:10,0:10", "-o", tmp_path / "x.png"), "--crop")
    assert_bad_input(run("sheet", ct, *common, "--views", "anterior", "-o", tmp_path / "x.png"), "--reference",
                     "--slices or --projection")
    assert not (tmp_path / "x.png").exists()


def test_a_label_source_is_paired_with_its_image_once_per_study(tmp_path, monkeypatch):
    """sheet --reference and a batch with a reference read and place the labels once, for the pictures and the
    agreement both, and measure what agreement() measures; a study already in the cache is read for its agreement."""
    import csv

    from test_cli import run

    import voxrender.object.pipeline as pipeline
    import voxrender.qc.study as study

    test_agreement_matches_structures_by_name_and_reports_one_sided_ones(tmp_path)     # writes the files
    expected = agreement(tmp_path / "ct.nii.gz", tmp_path / "test", tmp_path / "reference")
    reads = []

    def counted(source, image, read=None):
        reads.append(Path(source).name)
        return read_labels(source, image, read)

    read_labels = pipeline.read_labels
    monkeypatch.setattr(pipeline, "read_labels", counted)
    monkeypatch.setattr(study, "read_labels", counted)
    common = ("--labels-from", tmp_path / "test", "--reference", tmp_path / "reference")
    result = run("sheet", tmp_path / "ct.nii.gz", *common, "--slices", "axial", "--views", "anterior", "--size",
                 "32", "-o", tmp_path / "sheet.png")
    assert result.exit_code == 0, result.output
    assert sorted(reads) == ["reference", "test"], reads
    for runs in (["test", "reference"], ["reference"]):              # encoded now; then from the cache
        reads.clear()
        result = run("batch", tmp_path / "ct.nii.gz", *common, "--size", "32", "--jobs", "1", "-o", tmp_path / "out")
        assert result.exit_code == 0, result.output
        assert sorted(reads) == sorted(runs + ["test"] * (runs == ["reference"])), reads
        with open(tmp_path / "out" / "agreement.csv", newline="") as file:
            dice = {row["name"]: float(row["dice"]) for row in csv.DictReader(file)}
        assert dice == pytest.approx({row["name"]: row["dice"] for row in expected})
