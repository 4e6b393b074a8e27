import re
import warnings

import numpy as np
import pydicom
import pytest
from conftest import data_path
from dicom_files import write_series
from formats import refused_cuts
from pydicom.dataset import Dataset
from pydicom.sequence import Sequence
from rtstruct_files import (
    Roi,
    circle,
    references_of,
    rtstruct_dataset,
    save,
    series_affine,
    square,
    traced_contours,
    write_rtstruct,
    write_rtstruct_of_labels,
)
from skimage.draw import polygon2mask

from voxrender import io
from voxrender._shared import label_sets
from voxrender.errors import InputError
from voxrender.io.dicomfile import is_rtstruct
from voxrender.io.rtstruct import check_reference, fill_even_odd, read_rtstruct
from voxrender.object.pipeline import read_labels

SPACING = (1.0, 1.0, 2.0)                   # x, y, z in mm
SHAPE = (20, 40, 40)                        # z, y, x


def write_ct(folder, shape=SHAPE, spacing=SPACING, direction=None, stored=None):
    """A CT series (flat -1024 HU, or ``stored`` + -1024) written by write_series, read back; and its files."""
    stored = np.zeros(shape, np.int16) if stored is None else stored
    paths = write_series(folder, stored, spacing=spacing, direction=direction)
    return io.read_volume(folder), paths


def read_quietly(path, image):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        return read_rtstruct(path, image)


def centres(shape=SHAPE, spacing=SPACING):
    """The LPS positions (mm) of the voxel centres of an axial series by write_series: x, y, z arrays [z, y, x]."""
    z, y, x = np.meshgrid(*(np.arange(n) for n in shape), indexing="ij")
    return x * spacing[0], y * spacing[1], -100 + z * spacing[2]


# ---------------------------------------------------------------- the fill


@pytest.mark.parametrize("seed", range(4))
def test_even_odd_fill_is_skimages_centre_in_rule_and_xor(seed):
    rng = np.random.default_rng(seed)
    shape = (23, 31)
    polygons = [rng.uniform(-3, 34, (n, 2)) for n in (3, 7, 25)]      # self-crossing, partly off the plane
    polygons.append(np.array([[5.3, 4.1], [20.7, 4.4], [21.2, 18.6], [4.7, 17.35]]))
    expected = np.zeros(shape, bool)
    for p in polygons:
        expected ^= polygon2mask(shape, p[:, ::-1])                    # skimage takes (row, column)
    assert np.array_equal(fill_even_odd(polygons, shape), expected)
    assert expected.any() and not expected.all()


def test_a_centre_on_an_edge_belongs_right_of_and_below_it():
    inside = fill_even_odd([np.array([[1.0, 1.0], [4.0, 1.0], [4.0, 3.0], [1.0, 3.0]])], (5, 6))
    assert np.array_equal(np.argwhere(inside.any(axis=1)).ravel(), [1, 2])
    assert np.array_equal(np.argwhere(inside.any(axis=0)).ravel(), [1, 2, 3])
    # two squares sharing an edge cover its centres once
    left = np.array([[0.5, 0.5], [2.0, 0.5], [2.0, 3.5], [0.5, 3.5]])
    right = left + [1.5, 0]
    both = fill_even_odd([left], (5, 6)).astype(int) + fill_even_odd([right], (5, 6))
    assert both.max() == 1 and both.sum() == 3 * 3


# ---------------------------------------------------------------- shapes


def test_a_spheres_contours_rasterise_within_a_voxel_of_the_sphere(tmp_path):
    ct, paths = write_ct(tmp_path / "ct")
    centre, radius = np.array([19.3, 20.2, -81.1]), 14.6
    slices_z = -100 + np.arange(SHAPE[0]) * SPACING[2]
    contours = [circle(centre[:2], np.sqrt(radius ** 2 - (z - centre[2]) ** 2), z)
                for z in slices_z if abs(z - centre[2]) < radius]
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("sphere", contours)], **references_of(paths))
    labels = read_rtstruct(path, ct)
    assert labels.shape == ct.shape and labels.spacing == ct.spacing and labels.meta["origin"] == ct.meta["origin"]
    x, y, z = centres()
    distance = np.sqrt((x - centre[0]) ** 2 + (y - centre[1]) ** 2 + (z - centre[2]) ** 2)
    sphere = labels.values == 1
    assert sphere[distance < radius - 1].all() and not sphere[distance > radius + 1].any()
    in_plane = np.sqrt((x - centre[0]) ** 2 + (y - centre[1]) ** 2)
    section = np.sqrt(np.clip(radius ** 2 - (z - centre[2]) ** 2, 0, None))
    # within a slice it is the 64-gon: exact away from a sliver at the circle
    assert sphere[in_plane < section - 0.02].all() and not sphere[in_plane > section + 1e-6].any()
    assert labels.meta["contours"] == len(contours) and labels.meta["empty_labels"] == []


def test_a_hollow_ring_keeps_its_hole(tmp_path):
    ct, paths = write_ct(tmp_path / "ct")
    contours = [c for z in (-90, -88, -86) for c in (circle((20, 20), 12, z), circle((20.2, 19.9), 6, z))]
    labels = read_rtstruct(write_rtstruct(tmp_path / "rs.dcm", [Roi("ring", contours)]), ct)
    x, y, z = centres()
    rho = np.hypot(x - 20, y - 20)
    ring = labels.values == 1
    on = np.isin(z, (-90, -88, -86))
    assert not ring[on & (rho < 5.5)].any() and ring[on & (rho > 7) & (rho < 11.5)].all()
    assert not ring[on & (rho > 12.1)].any() and not ring[~on].any()


def test_masks_traced_into_contours_come_back_voxel_for_voxel(tmp_path):
    from scipy import ndimage

    noise = ndimage.gaussian_filter(np.random.default_rng(3).normal(size=SHAPE), (1, 3, 3))
    labels = np.where(noise > 0.04, 1, np.where(noise < -0.05, 2, 0)).astype(np.uint8)
    labels[:, :2] = labels[:, -2:] = 0
    labels[10, 14:26, 14:26], labels[10, 18:21, 18:22] = 1, 0          # a hole, which stays one
    ct, paths = write_ct(tmp_path / "ct")
    path = write_rtstruct_of_labels(tmp_path / "rs.dcm", labels, series_affine(SPACING), ["high", "low"],
                                    **references_of(paths))
    read = read_rtstruct(path, ct)
    assert np.array_equal(read.values, labels) and read.values[10, 19, 19] == 0


# ---------------------------------------------------------------- names, numbers, overlaps


def test_labels_follow_roi_numbers_with_names_and_colours(tmp_path):
    ct, _ = write_ct(tmp_path / "ct")
    rois = [Roi("PTV", [square((10, 10), 6, -90)], (255, 0, 0), number=7),
            Roi("GTV", [square((30, 10), 4, -90)], None, number=2),
            Roi("cord", [square((10, 30), 2, -80)], (0, 128, 255), number=5),
            Roi("marker", [], number=9)]
    labels = read_rtstruct(write_rtstruct(tmp_path / "rs.dcm", rois), ct)
    assert labels.meta["label_table"] == {"1": {"name": "GTV", "colour": None},
                                          "2": {"name": "cord", "colour": [0, 128, 255]},
                                          "3": {"name": "PTV", "colour": [255, 0, 0]},
                                          "4": {"name": "marker", "colour": None}}
    assert labels.meta["roi_numbers"] == {"1": 2, "2": 5, "3": 7, "4": 9}
    assert np.bincount(labels.values.ravel()).tolist() == [40 * 40 * 20 - 16 - 4 - 36, 16, 4, 36]
    assert labels.meta["empty_labels"] == [4] and labels.meta["format"] == "rtstruct"
    assert labels.values[5, 10, 30] == 1 and labels.values[10, 30, 10] == 2 and labels.values[5, 10, 10] == 3


def test_overlapping_rois_each_keep_their_voxels_and_an_organ_inside_body_shows(tmp_path):
    ct, _ = write_ct(tmp_path / "ct")
    rois = [Roi("body", [square((20, 20), 20, z) for z in (-90, -88)]),
            Roi("lung", [square((25, 20), 10, z) for z in (-90, -88, -86)]),     # 5 of its 10 columns in body
            Roi("heart", [square((14, 20), 4, -90)])]                            # inside body
    labels = read_rtstruct(write_rtstruct(tmp_path / "rs.dcm", rois), ct)
    assert labels.meta["overlaps"] == [{"labels": [1, 2], "names": ["body", "lung"], "voxels": 2 * 100},
                                       {"labels": [1, 3], "names": ["body", "heart"], "voxels": 16, "inside": "heart"}]
    codes, sets = labels.values, labels.meta["label_sets"]
    assert label_sets.structure_counts(codes, sets) == {1: 2 * 400, 2: 3 * 100, 3: 16}
    shown = np.bincount(label_sets.resolve(codes, sets).ravel(), minlength=4)[1:].tolist()
    assert shown == [2 * 400 - 2 * 100 - 16, 3 * 100, 16]          # heart and lung are smaller than body
    assert labels.meta["empty_labels"] == [] and labels.meta["overlap_rule"] == label_sets.RULE


# ---------------------------------------------------------------- contours not drawn


def test_contours_not_drawn_are_counted_in_one_warning(tmp_path):
    ct, _ = write_ct(tmp_path / "ct")
    tilted = square((20, 20), 10, -90)
    tilted[:2, 2] += 3                                   # two corners 1.5 slices above the others
    contours = [square((20, 20), 10, -90),                                       # drawn
                square((20, 20), 10, -90)[:2],                                   # two points
                (square((20, 20), 10, -80), "POINT"), (square((20, 20), 10, -80), "OPEN_PLANAR"),
                square((20, 20), 10, -85),                                       # half-way between slices
                square((20, 20), 6, -89.4),                                      # a finer plane beside -90
                square((20, 20), 10, -200), square((120, 20), 10, -80),          # off the slices, off the plane
                tilted]
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("body", contours)])
    with pytest.warns(UserWarning) as caught:
        labels = read_rtstruct(path, ct)
    assert len(caught) == 1
    message = str(caught[0].message)
    assert "8 of its 9 contours are not drawn" in message and "rs.dcm" in message
    for count, words in [(2, "points or open lines"), (1, "fewer than 3 points"), (2, "between the image's slices"),
                         (2, "outside the image"), (1, "not lie in one of the image's slice planes")]:
        assert f"{count} {SKIPPED_START[words]}" in message, (words, message)
    assert np.bincount(labels.values.ravel())[1] == 100 and labels.values[5].sum() == 100
    assert labels.meta["skipped_contours"] == {"open": 2, "few": 1, "between": 2, "outside": 2, "not_planar": 1}


SKIPPED_START = {"points or open lines": "are points or open lines", "fewer than 3 points": "have fewer than 3 points",
                 "between the image's slices": "lie between the image's slices",
                 "outside the image": "lie outside the image",
                 "not lie in one of the image's slice planes": "do not lie in one of the image's slice planes"}


def test_contours_all_outside_the_image_are_refused(tmp_path):
    ct, paths = write_ct(tmp_path / "ct")
    rois = [Roi("GTV", [square((20, 20), 8, z) for z in (-20, -10)])]
    path = write_rtstruct(tmp_path / "rs.dcm", rois, series_uid="1.2.99")
    with pytest.raises(InputError) as info:
        read_rtstruct(path, ct)
    message = str(info.value)
    assert "none of the 2 contours" in message and "rs.dcm" in message and "give the CT it was drawn on" in message
    assert "z -20 to -10 mm" in message and "z -100 to -62 mm" in message
    assert "1.2.99" in message and ct.meta["series"] in message                  # it names the other series


def test_an_rtstruct_of_points_only_is_refused(tmp_path):
    ct, _ = write_ct(tmp_path / "ct")
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("iso", [(np.array([[20.0, 20, -90]]), "POINT")])])
    with pytest.raises(InputError, match="no closed contour .*1 are points or open lines"):
        read_rtstruct(path, ct)


# ---------------------------------------------------------------- other grids


def _rotation_about_l(degrees):
    a = np.radians(degrees)
    row, column = np.array([1.0, 0, 0]), np.array([0, np.cos(a), np.sin(a)])
    return np.stack([row, column, np.cross(row, column)], axis=1)


GRIDS = {"flipped": np.diag([-1.0, -1.0, 1.0]),
         "sagittal": np.stack([[0, 1.0, 0], [0, 0, -1.0], [-1.0, 0, 0]], axis=1),
         "coronal": np.stack([[1.0, 0, 0], [0, 0, -1.0], [0, 1.0, 0]], axis=1),
         "tilted": _rotation_about_l(15)}


@pytest.mark.parametrize("name", GRIDS)
def test_contours_on_a_flipped_sagittal_or_tilted_grid_land_on_their_voxels(tmp_path, name):
    direction = GRIDS[name]
    spacing = (0.8, 1.1, 2.5)
    z, y, x = np.mgrid[:7, :12, :10]
    blob = ((x - 4.5) / 3.5) ** 2 + ((y - 5) / 4) ** 2 <= 1 - ((z - 3) / 4) ** 2    # stored [z, y, x]
    blob |= (x >= 7) & (y >= 9) & (z >= 2)                                           # a corner: tells flips apart
    blob[3, 4:6, 3:6] = False                                                        # and a hole
    stored = blob.astype(np.int16) * 1000
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)                                 # the tilted grid is oblique
        ct, paths = write_ct(tmp_path / "ct", stored.shape, spacing, direction, stored)
    contours = traced_contours(blob, series_affine(spacing, direction))
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("blob", contours)], **references_of(paths))
    labels = read_rtstruct(path, ct)
    assert labels.shape == ct.shape and np.array_equal(labels.direction, ct.direction)
    assert np.array_equal(labels.values == 1, ct.values > -500)
    assert labels.meta["contours"] == len(contours)


# ---------------------------------------------------------------- its image


def test_another_series_than_the_one_drawn_on_is_refused(tmp_path):
    ct, paths = write_ct(tmp_path / "ct")
    rois = [Roi("GTV", [square((20, 20), 8, -90)])]
    drawn = read_rtstruct(write_rtstruct(tmp_path / "rs.dcm", rois, **references_of(paths)), ct)
    assert drawn.meta["referenced_series"] == ct.meta["series"]
    check_reference(drawn.meta, ct)
    other = read_rtstruct(write_rtstruct(tmp_path / "other.dcm", rois, series_uid="1.2.826.0.1.77"), ct)
    with pytest.raises(InputError) as info:
        check_reference(other.meta, ct)
    assert info.value.parameter == "labels_from"
    assert "1.2.826.0.1.77" in str(info.value) and ct.meta["series"] in str(info.value)
    assert "other.dcm" in str(info.value)
    unknown = read_rtstruct(write_rtstruct(tmp_path / "unknown.dcm", rois), ct)
    assert unknown.meta["referenced_series"] == ""
    check_reference(unknown.meta, ct)                                   # nothing to compare: no error


def test_another_frame_of_reference_is_refused_when_no_series_says(tmp_path):
    ct, _ = write_ct(tmp_path / "ct")
    rois = [Roi("GTV", [square((20, 20), 8, -90)])]
    labels = read_rtstruct(write_rtstruct(tmp_path / "rs.dcm", rois, frame_of_reference="1.2.5"), ct)
    assert labels.meta["frame_of_reference"] == "1.2.5"
    check_reference(labels.meta, ct)                                    # the CT says no frame of reference
    ct.meta["frame_of_reference"] = "1.2.6"
    with pytest.raises(InputError, match="frame of reference 1.2.5.* 1.2.6"):
        check_reference(labels.meta, ct)


def test_the_series_drawn_on_in_another_frame_of_reference_is_drawn_with_one_warning(tmp_path):
    """rt-utils' rt.dcm: it references the CT's series and slice, under a FrameOfReferenceUID of its own."""
    ct, paths = write_ct(tmp_path / "ct")
    ct.meta["frame_of_reference"] = "1.2.6"
    references = {**references_of(paths), "frame_of_reference": "1.2.5"}
    labels = read_rtstruct(write_rtstruct(tmp_path / "rs.dcm", [Roi("GTV", [square((20, 20), 8, -90)])],
                                          **references), ct)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_reference(labels.meta, ct)
    assert len(caught) == 1 and "another frame of reference (1.2.5, the image's 1.2.6)" in str(caught[0].message)


def test_an_rtstruct_saved_without_preamble_or_file_meta_is_recognised_and_drawn(tmp_path):
    """rt-utils' dummy_rt.dcm once saved so; pydicom reads such a file with force=True."""
    ct, paths = write_ct(tmp_path / "ct")
    rois = [Roi("GTV", [square((20, 20), 8, -90)])]
    ds = rtstruct_dataset(rois, **references_of(paths))
    ds.preamble, ds.file_meta = None, pydicom.dataset.FileMetaDataset()
    ds.save_as(tmp_path / "bare.dcm", enforce_file_format=False, implicit_vr=True, little_endian=True)
    assert (tmp_path / "bare.dcm").read_bytes()[128:132] != b"DICM" and is_rtstruct(tmp_path / "bare.dcm")
    labels = read_labels(tmp_path / "bare.dcm", ct)
    assert np.array_equal(labels.values, read_rtstruct(write_rtstruct(tmp_path / "rs.dcm", rois,
                                                                      **references_of(paths)), ct).values)


# ---------------------------------------------------------------- what is not an RTSTRUCT, damaged ones


def test_is_rtstruct(tmp_path):
    _, paths = write_ct(tmp_path / "ct", shape=(2, 4, 4))
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("GTV", [square((2, 2), 2, -100)])])
    (tmp_path / "notes.txt").write_text("not DICOM")
    assert is_rtstruct(path) and is_rtstruct(str(path))
    assert not is_rtstruct(paths[0]) and not is_rtstruct(tmp_path) and not is_rtstruct(tmp_path / "notes.txt")


@pytest.mark.filterwarnings("ignore:Expected implicit VR:UserWarning")     # pydicom, on the text file
def test_what_is_not_an_rtstruct_is_refused(tmp_path):
    ct, paths = write_ct(tmp_path / "ct", shape=(2, 4, 4))
    (tmp_path / "notes.txt").write_text("not DICOM")
    for path, words in [(paths[0], "is not an RTSTRUCT (SOPClassUID 1.2.840.10008.5.1.4.1.1.2, modality CT)"),
                        (tmp_path / "notes.txt", "is not a DICOM RTSTRUCT"), (tmp_path, "is a folder")]:
        with pytest.raises(InputError) as info:
            read_rtstruct(path, ct)
        assert words in str(info.value) and str(path) in str(info.value) and "\n" not in str(info.value)


def test_cut_rtstructs_are_bad_input(tmp_path):
    ct, _ = write_ct(tmp_path / "ct")
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("ring", [circle((20, 20), r, z) for z in (-90, -88)
                                                             for r in (12, 6)], (1, 2, 3))])
    assert refused_cuts(path, lambda: read_rtstruct(path, ct)) >= 30


def test_garbled_rtstructs_are_read_or_refused(tmp_path, monkeypatch):
    """Four bytes garbled at 40 places; the UIDs are fixed, so that the places, and what each garbles, are the same
    in every run (random UIDs of random lengths once left no place that is refused)."""
    import itertools

    import dicom_files
    import rtstruct_files
    from pydicom.uid import generate_uid

    made = itertools.count()
    for module in (dicom_files, rtstruct_files):
        monkeypatch.setattr(module, "generate_uid", lambda: generate_uid(entropy_srcs=[str(next(made))]))
    ct, _ = write_ct(tmp_path / "ct")
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("ring", [circle((20, 20), r, z) for z in (-90, -88)
                                                             for r in (12, 6)], (1, 2, 3)),
                                                Roi("cord", [square((10, 10), 4, -90)])])
    whole = path.read_bytes()
    expected = read_rtstruct(path, ct).values
    outcomes = []
    for at in np.linspace(132, len(whole) - 4, 40).astype(int):
        path.write_bytes(whole[:at] + b"\xff\x00\xff\x00" + whole[at + 4:])
        try:
            labels = read_quietly(path, ct)
        except InputError as exc:
            outcomes.append("refused")
            assert "rs.dcm" in str(exc) and "\n" not in str(exc)
        else:
            outcomes.append("skipped" if labels.meta["skipped_contours"] else "same"
                            if np.array_equal(labels.values, expected) else "empty" if labels.meta["empty_labels"]
                            else "changed unsaid")
    # what a garbled file loses is refused, counted as skipped contours, or an ROI listed as empty
    assert "changed unsaid" not in outcomes
    assert outcomes.count("refused") >= 2 and outcomes.count("skipped") >= 10


def _odd_contour_data(ds):
    item = ds.ROIContourSequence[0].ContourSequence[0]
    item.ContourData = list(item.ContourData)[:-1]


def _wrong_point_count(ds):
    ds.ROIContourSequence[0].ContourSequence[0].NumberOfContourPoints = 5


def _stored_text(item, tag, vr, text):
    """Store ``text`` as the value of ``tag`` as it is, unchecked (what a damaged file holds)."""
    from pydicom.dataelem import RawDataElement
    from pydicom.tag import Tag

    value = text.encode() + b" " * (len(text) % 2)
    item[tag] = RawDataElement(Tag(tag), vr, len(value), value, 0, False, True)


def _text_in_contour_data(ds):
    _stored_text(ds.ROIContourSequence[0].ContourSequence[0], 0x30060050, "DS", "1\\2\\x\\4\\5\\6\\7\\8\\9\\10\\11\\12")


def _no_geometric_type(ds):
    del ds.ROIContourSequence[0].ContourSequence[0].ContourGeometricType


def _nan_in_contour_data(ds):
    item = ds.ROIContourSequence[0].ContourSequence[0]
    item.ContourData = ["NaN"] + list(item.ContourData)[1:]


def _unknown_roi(ds):
    ds.ROIContourSequence[0].ReferencedROINumber = 42


@pytest.mark.parametrize("edit, why", [(_odd_contour_data, "damaged"), (_wrong_point_count, "damaged"),
                                       (_text_in_contour_data, "damaged"), (_no_geometric_type, "damaged"),
                                       (_nan_in_contour_data, "damaged"), (_unknown_roi, "no_roi")])
def test_damaged_contours_are_counted_and_skipped(tmp_path, edit, why):
    count = 2 if why == "no_roi" else 1                    # an unknown ROI: both its contours
    ct, _ = write_ct(tmp_path / "ct")
    ds = rtstruct_dataset([Roi("GTV", [square((20, 20), 8, -90), square((20, 20), 8, -88)]),
                           Roi("cord", [square((10, 10), 2, -90)])])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)                      # pydicom on the values it is given
        edit(ds)
        save(ds, tmp_path / "rs.dcm")
    with pytest.warns(UserWarning, match=re.escape(str(tmp_path / "rs.dcm")) + f": {count} of its 3 contours"):
        labels = read_rtstruct(tmp_path / "rs.dcm", ct)
    assert labels.meta["skipped_contours"] == {why: count}
    assert np.bincount(labels.values.ravel(), minlength=3)[1:].tolist() == ([64, 4] if why == "damaged" else [0, 4])


def _no_roi_contours(ds):
    del ds.ROIContourSequence


def _no_rois(ds):
    ds.StructureSetROISequence = Sequence()


def _no_structure_set(ds):
    del ds.StructureSetROISequence


def _no_roi_number(ds):
    del ds.StructureSetROISequence[0].ROINumber


def _two_rois_of_one_number(ds):
    ds.StructureSetROISequence[1].ROINumber = 1


def _roi_number_text(ds):
    _stored_text(ds.StructureSetROISequence[0], 0x30060022, "IS", "one")


def _roi_contours_of_no_item(ds):
    ds.ROIContourSequence = Sequence([Dataset()])


@pytest.mark.parametrize("edit, message", [
    (_no_roi_contours, "describes 2 ROIs but holds no contour"),
    (_roi_contours_of_no_item, "describes 2 ROIs but holds no contour"),
    (_no_rois, "describes no ROIs"), (_no_structure_set, "describes no ROIs"),
    (_no_roi_number, "damaged structure set (it lacks ROINumber)"),
    (_roi_number_text, "damaged structure set"),
    (_two_rois_of_one_number, "numbers two ROIs 1")])
def test_damaged_structure_sets_are_bad_input(tmp_path, edit, message):
    ct, _ = write_ct(tmp_path / "ct")
    ds = rtstruct_dataset([Roi("GTV", [square((20, 20), 8, -90)]), Roi("cord", [square((10, 10), 2, -90)])])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)
        edit(ds)
        save(ds, tmp_path / "rs.dcm")
    with pytest.raises(InputError) as info:
        read_quietly(tmp_path / "rs.dcm", ct)
    assert message in str(info.value) and "rs.dcm" in str(info.value) and "\n" not in str(info.value)


def test_a_colour_of_two_values_is_no_colour(tmp_path):
    ct, _ = write_ct(tmp_path / "ct")
    ds = rtstruct_dataset([Roi("GTV", [square((20, 20), 8, -90)], (10, 20, 30))])
    ds.ROIContourSequence[0].ROIDisplayColor = [10, 20]
    labels = read_rtstruct(save(ds, tmp_path / "rs.dcm"), ct)
    assert labels.meta["label_table"]["1"]["colour"] is None


# ---------------------------------------------------------------- real data


def test_vhf_head_skin_contours_traced_from_the_ct_rasterise_to_its_threshold(tmp_path):
    folder = data_path("vhf_head")
    ct_folder = tmp_path / "ct"
    ct_folder.mkdir()
    for f in sorted(folder.glob("vhf.*.dcm"))[100:106]:                   # a few slices through the head
        (ct_folder / f.name).write_bytes(f.read_bytes())
    headers = sorted((pydicom.dcmread(p) for p in ct_folder.iterdir()), key=lambda d: float(d.ImagePositionPatient[2]))
    hu = np.stack([d.pixel_array.astype(np.int16) * int(d.RescaleSlope) + int(d.RescaleIntercept) for d in headers])
    column_step, row_step = float(headers[0].PixelSpacing[1]), float(headers[0].PixelSpacing[0])
    slice_step = float(headers[1].ImagePositionPatient[2]) - float(headers[0].ImagePositionPatient[2])
    affine = series_affine((column_step, row_step, slice_step),
                           origin=[float(v) for v in headers[0].ImagePositionPatient])
    contours = traced_contours(hu, affine, level=-299.5, outside=-1024)   # HU > -300: skin and all within
    path = write_rtstruct(tmp_path / "rs.dcm", [Roi("skin", contours, (177, 122, 101))],
                          **references_of(sorted(ct_folder.iterdir())))
    ct = io.read_volume(ct_folder)
    labels = read_rtstruct(path, ct)
    check_reference(labels.meta, ct)
    assert labels.meta["referenced_series"] == ct.meta["series"] == str(headers[0].SeriesInstanceUID)
    assert labels.meta["frame_of_reference"] == str(headers[0].FrameOfReferenceUID)
    skin = ct.values > -300
    assert skin.sum() > 6 * 20000 and len(contours) > 6
    assert np.array_equal(labels.values == 1, skin)          # within a voxel at the boundary: here, voxel for voxel
