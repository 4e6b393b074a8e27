"""voxrender.io.masks: a folder of binary masks (TotalSegmentator's segmentations/) read as one label map."""

import warnings

import numpy as np
import pytest
from conftest import data_path

import voxrender
from voxrender import io
from voxrender._shared import label_sets
from voxrender.errors import InputError
from voxrender.space.grids import patient_affine

# a grid stored as NIfTI usually is (RAS: x toward the right, y toward the front), so reading flips x and y
SPACING, ORIGIN = (0.8, 0.9, 2.5), (30.0, -12.0, 7.5)
STORED_LPS = np.diag([-1.0, -1.0, 1.0, 1.0])               # nibabel's RAS affine of a grid stored LPS: read as is


def ras_affine(spacing=SPACING, origin=ORIGIN):
    affine = np.diag([*spacing, 1.0])
    affine[:3, 3] = origin
    return affine


def save_nifti(path, values, affine=None):
    """``values[z, y, x]`` as a NIfTI file (nibabel stores [i, j, k]) on ``affine`` (RAS, nibabel's)."""
    import nibabel

    affine = ras_affine() if affine is None else affine
    nibabel.save(nibabel.Nifti1Image(np.ascontiguousarray(values.transpose(2, 1, 0)), affine), str(path))


def split(folder, labels, names, save=save_nifti, suffix=".nii.gz"):
    """The masks of a label map (label k is ``names[k - 1]``), one file each, as a segmentation tool writes them."""
    folder.mkdir(exist_ok=True)
    for k, name in enumerate(names, start=1):
        save(folder / f"{name}{suffix}", (labels == k).astype(np.uint8))
    return folder


def phantom():
    """Three structures on a 24 x 20 x 16 grid, numbered by their names' order: aorta, liver, spleen."""
    zz, yy, xx = np.mgrid[:16, :20, :24]
    labels = np.zeros((16, 20, 24), np.uint8)
    labels[(xx - 8) ** 2 + (yy - 9) ** 2 + (zz - 7) ** 2 <= 30] = 2           # liver: a ball
    labels[3:13, 4:6, 16:18] = 1                                               # aorta: a bar
    labels[10:14, 12:18, 14:22] = 3                                            # spleen: a box
    return labels


NAMES = ("aorta", "liver", "spleen")


def test_a_mask_folder_is_the_label_map_it_was_split_from(tmp_path):
    labels = phantom()
    folder = split(tmp_path / "segmentations", labels, NAMES)
    (folder / "statistics.json").write_text("{}")                  # notes beside the masks are left alone
    save_nifti(tmp_path / "map.nii.gz", labels)
    assert io.detect_format(folder) == "masks"
    volume, whole = io.read_volume(folder), io.read_volume(tmp_path / "map.nii.gz")
    assert volume.values.dtype == np.uint8 and np.array_equal(volume.values, whole.values)
    assert np.array_equal(volume.values, labels[:, ::-1, ::-1])     # RAS -> LPS: x and y flipped
    assert volume.spacing == pytest.approx(whole.spacing) and volume.meta["origin"] == pytest.approx(
        whole.meta["origin"])
    assert np.allclose(patient_affine(volume), patient_affine(whole))
    assert volume.meta["format"] == "masks" and volume.meta["masks"] == 3
    assert volume.meta["label_table"] == {str(k): {"name": name, "colour": None} for k, name in enumerate(NAMES, 1)}
    assert volume.meta["overlaps"] == [] and volume.meta["empty_labels"] == []
    assert volume.meta["masks_reoriented"] == "aorta.nii.gz: RAS -> LPS: flipped x, y"


def test_masks_are_numbered_by_the_natural_order_of_their_names(tmp_path):
    folder = tmp_path / "ribs"
    folder.mkdir()
    for z, name in enumerate(["rib_10", "rib_2", "Liver", "rib_1"]):
        mask = np.zeros((4, 3, 3), np.uint8)
        mask[z] = 1
        save_nifti(folder / f"{name}.nii.gz", mask, np.eye(4))
    volume = io.read_volume(folder)
    table = volume.meta["label_table"]
    assert [table[str(k)]["name"] for k in range(1, 5)] == ["Liver", "rib_1", "rib_2", "rib_10"]
    assert volume.values[:, 0, 0].tolist() == [4, 3, 1, 2]      # slice z held rib_10, rib_2, Liver, rib_1


def test_each_mask_keeps_its_own_voxels_the_smallest_shows_and_overlaps_say_which_is_inside(tmp_path):
    folder = tmp_path / "masks"
    folder.mkdir()
    boxes = {"a": slice(0, 10), "b": slice(5, 15), "c": slice(8, 20), "d_empty": slice(0, 0), "e_in_a": slice(2, 4)}
    for name, x in boxes.items():
        mask = np.zeros((3, 4, 20), np.uint8)                   # [z, y, x]
        mask[:, :, x] = 1
        save_nifti(folder / f"{name}.nii.gz", mask, STORED_LPS)
    volume = io.read_volume(folder)
    codes, sets = volume.values, volume.meta["label_sets"]
    per_column = 3 * 4
    own = label_sets.structure_counts(codes, sets)
    assert own == {1: 10 * per_column, 2: 10 * per_column, 3: 12 * per_column, 5: 2 * per_column}
    for label, name in enumerate(boxes, start=1):               # each mask's own voxels, exactly
        expected = np.zeros(20, bool)
        expected[boxes[name]] = True
        assert (label_sets.member_mask(codes, sets, label)[0, 0] == expected).all(), name
    # the pictures show the smallest structure at a shared voxel, the lower label of two of one size (a and b)
    assert label_sets.resolve(codes, sets)[0, 0].tolist() == [1, 1, 5, 5, 1, 1, 1, 1, 1, 1] + [2] * 5 + [3] * 5
    assert volume.meta["overlaps"] == [
        {"labels": [1, 2], "names": ["a", "b"], "voxels": 5 * per_column},
        {"labels": [1, 3], "names": ["a", "c"], "voxels": 2 * per_column},
        {"labels": [1, 5], "names": ["a", "e_in_a"], "voxels": 2 * per_column, "inside": "e_in_a"},
        {"labels": [2, 3], "names": ["b", "c"], "voxels": 7 * per_column}]
    assert volume.meta["overlap_rule"] == label_sets.RULE
    assert volume.meta["empty_labels"] == [4] and volume.meta["label_table"]["4"]["name"] == "d_empty"


@pytest.mark.parametrize(("values", "said"), [
    (np.arange(14, dtype=np.uint8).repeat(4).reshape(2, 4, 7),
     r"labels.nii.gz holds 14 distinct values \(0 .. 13\): it is a label map, not a mask; give it alone with labels"),
    (np.linspace(-1000, 400, 56, dtype=np.float32).reshape(2, 4, 7), r"labels.nii.gz holds grey values \(56 "
                                                                      r"distinct, -1000 .. 400\): it is an image"),
])
def test_a_file_that_is_not_a_mask_is_refused_naming_it(tmp_path, values, said):
    folder = split(tmp_path / "masks", np.ones((2, 4, 7), np.uint8), ["body"])
    save_nifti(folder / "labels.nii.gz", values)
    with pytest.raises(InputError, match=said):
        io.read_volume(folder)


def test_masks_of_other_values_and_types_are_masks(tmp_path):
    """0/255, float 0/1 and int16 0/-1 masks are binary: each is its structure."""
    folder = tmp_path / "masks"
    folder.mkdir()
    labels = phantom()
    kinds = {"aorta": (np.uint8, 255), "liver": (np.float32, 1.0), "spleen": (np.int16, -1)}
    for k, (name, (dtype, value)) in enumerate(kinds.items(), start=1):
        save_nifti(folder / f"{name}.nii.gz", np.where(labels == k, value, 0).astype(dtype))
    assert np.array_equal(io.read_volume(folder).values, labels[:, ::-1, ::-1])


def test_a_4d_file_is_refused_naming_it(tmp_path):
    import nibabel

    folder = split(tmp_path / "masks", np.ones((2, 4, 7), np.uint8), ["body"])
    nibabel.save(nibabel.Nifti1Image(np.zeros((7, 4, 2, 3), np.uint8), np.eye(4)), str(folder / "runs.nii.gz"))
    with pytest.raises(InputError, match=r"runs.nii.gz is a 4-D file"):
        io.read_volume(folder)


def test_two_masks_of_one_name_are_refused(tmp_path):
    folder = split(tmp_path / "masks", np.ones((2, 4, 7), np.uint8), ["liver"])
    save_nifti(folder / "liver.nii", np.ones((2, 4, 7), np.uint8))
    with pytest.raises(InputError, match=r"two masks of one name \(liver.nii, liver.nii.gz\)"):
        io.read_volume(folder)


def test_a_mask_on_a_coarser_shifted_flipped_grid_is_placed_by_position(tmp_path):
    """The first mask sets the grid; a ball written on a grid 2x coarser, shifted and flipped lands within one of
    its voxels of the analytic ball on that grid."""
    folder = tmp_path / "masks"
    folder.mkdir()
    fine = np.eye(4)                                          # RAS 1 mm, origin 0: LPS x = -i, y = -j
    corner = np.zeros((30, 32, 34), np.uint8)
    corner[:3, :3, :3] = 1                                   # [z, y, x] stored: LPS x, y near 0, z near 0
    save_nifti(folder / "a_corner.nii.gz", corner, fine)
    centre, radius = np.array([-16.2, -15.1, 14.3]), 8.0      # patient LPS, mm
    coarse = np.diag([2.0, -2.0, 2.0, 1.0])                  # RAS: y flipped (toward P), 2 mm
    coarse[:3, 3] = [-1.3, 32.3, -1.3]
    k, j, i = np.indices((18, 18, 20))
    lps = np.stack([-(2.0 * i - 1.3), -(-2.0 * j + 32.3), 2.0 * k - 1.3])
    save_nifti(folder / "b_ball.nii.gz", (np.linalg.norm(lps - centre[:, None, None, None], axis=0) <= radius)
               .astype(np.uint8), coarse)
    with pytest.warns(UserWarning, match=r"b_ball.nii.gz and the first mask, a_corner.nii.gz differ in extent by "
                                         r"[\d.]+ mm, more than one voxel \(1 mm\)"):
        volume = io.read_volume(folder)
    first = io.read_volume(folder / "a_corner.nii.gz")
    assert volume.shape == first.shape and np.allclose(patient_affine(volume), patient_affine(first))
    z, y, x = np.indices(volume.shape)
    affine = patient_affine(volume)
    points = np.einsum("ij,jzyx->izyx", affine[:3, :3], np.stack([x, y, z]).astype(float))
    distance = np.linalg.norm(points + affine[:3, 3, None, None, None] - centre[:, None, None, None], axis=0)
    ball = distance <= radius
    placed = volume.values == 2
    assert placed.sum() > 0.8 * ball.sum()
    assert np.abs(distance[placed != ball] - radius).max() <= 2.0
    assert np.array_equal(volume.values == 1, first.values == 1)  # and the first mask where it was


def test_masks_whose_grids_do_not_overlap_are_refused(tmp_path):
    folder = split(tmp_path / "masks", np.ones((4, 4, 4), np.uint8), ["a"])
    far = ras_affine()
    far[0, 3] = 900.0
    save_nifti(folder / "b.nii.gz", np.ones((4, 4, 4), np.uint8), far)
    with pytest.raises(InputError, match=r"b.nii.gz does not overlap the first mask, a.nii.gz: it spans x "):
        io.read_volume(folder)


def test_a_folder_of_nrrd_masks(tmp_path):
    import nrrd

    labels = phantom()

    def save_nrrd(path, values):                             # LPS, 0.7 x 0.7 x 2 mm, values [z, y, x]
        nrrd.write(str(path), values, {"space": "left-posterior-superior", "encoding": "gzip",
                                       "space directions": np.diag([0.7, 0.7, 2.0]),
                                       "space origin": [-5.0, 4.0, 100.0]}, index_order="C")

    folder = split(tmp_path / "masks", labels, NAMES, save=save_nrrd, suffix=".nrrd")
    volume = io.read_volume(folder)
    assert np.array_equal(volume.values, labels) and volume.spacing == (0.7, 0.7, 2.0)
    assert volume.meta["origin"] == [-5.0, 4.0, 100.0] and volume.meta["label_table"]["3"]["name"] == "spleen"
    assert io.read_volume(folder / "liver.nrrd").meta["format"] == "nrrd"


def test_the_nifti_format_named_for_a_mask_folder_points_at_masks(tmp_path):
    folder = split(tmp_path / "masks", phantom(), NAMES)
    with pytest.raises(InputError, match=r"not slices; give one of them, or the folder as one label map of masks"):
        io.read_volume(folder, format="nifti")
    with pytest.raises(InputError, match="masks input takes no frame"):
        io.read_volume(folder, frame=0)


def test_reading_reports_progress_over_the_files(tmp_path):
    folder = split(tmp_path / "masks", phantom(), NAMES)
    seen = []

    def progress(items, length, label):
        seen.append((length, label))
        return items

    io.read_volume(folder, progress=progress)
    assert seen == [(3, "reading masks")]


def the_map_with_names(path, folder):
    """The label map file read, with the names the mask folder gives its labels (which colour them)."""
    volume = io.read_volume(path)
    volume.meta["label_table"] = io.read_volume(folder).meta["label_table"]
    return volume


def test_a_mask_folder_renders_as_the_label_map_it_was_split_from(tmp_path):
    labels = phantom()
    folder = split(tmp_path / "segmentations", labels, NAMES)
    save_nifti(tmp_path / "map.nii.gz", labels)
    from_masks = voxrender.snapshot(folder, labels=True, size=(64, 64))
    assert np.array_equal(from_masks, voxrender.snapshot(the_map_with_names(tmp_path / "map.nii.gz", folder),
                                                         labels=True, size=(64, 64)))
    assert len(np.unique(from_masks.reshape(-1, 3), axis=0)) > 20
    # the pictures can differ: without one structure the folder draws another picture
    (folder / "spleen.nii.gz").unlink()
    assert not np.array_equal(from_masks, voxrender.snapshot(folder, labels=True, size=(64, 64)))


@pytest.fixture(scope="module")
def vhf_tissues(tmp_path_factory):
    """vhf_head, every third slice and every third voxel across (3 mm), split into four tissues by HU ranges, named
    as TotalSegmentator names its masks; numbered by their names' order, as a mask folder is.
    """
    from voxrender.samples import tissue_labels

    slices = tmp_path_factory.mktemp("vhf")
    for number in range(1560, 1680, 3):                       # 40 slices of the skull and face
        (slices / f"vhf.{number}.dcm").symlink_to(data_path("vhf_head") / f"vhf.{number}.dcm")
    ct = io.read_volume(slices)
    hu = ct.values[:, ::3, ::3]
    tissues = {"brain": (hu >= -30) & (hu < 300), "skull": hu >= 300,
               "subcutaneous_fat": (hu >= -200) & (hu < -30), "trachea": tissue_labels(hu) == 3}
    labels = np.zeros(hu.shape, np.uint8)
    for k, mask in enumerate(tissues.values(), start=1):
        labels[mask] = k
    affine = patient_affine(ct) @ np.diag([3.0, 3.0, 1.0, 1.0])   # every third voxel across
    ras = np.diag([-1.0, -1.0, 1.0, 1.0]) @ affine
    folder = tmp_path_factory.mktemp("segmentations")
    split(folder, labels, list(tissues), save=lambda path, values: save_nifti(path, values, ras))
    save_nifti(folder.parent / "vhf_tissues.nii.gz", labels, ras)
    return folder, folder.parent / "vhf_tissues.nii.gz", labels


def test_vhf_head_tissue_masks_are_the_label_map_they_were_split_from(vhf_tissues):
    folder, whole, labels = vhf_tissues
    volume = io.read_volume(folder)
    assert np.array_equal(volume.values, labels) and np.array_equal(volume.values, io.read_volume(whole).values)
    assert [volume.meta["label_table"][str(k)]["name"] for k in range(1, 5)] == ["brain", "skull",
                                                                                 "subcutaneous_fat", "trachea"]
    assert volume.spacing == (3.0, 3.0, 3.0) and volume.meta["overlaps"] == []
    assert all(np.count_nonzero(labels == k) > 100 for k in range(1, 5))


def test_vhf_head_tissue_masks_render_as_their_label_map(vhf_tissues):
    folder, whole, _ = vhf_tissues
    clip = voxrender.Clip(x=(None, 85))                          # cut open: the skull and the airway show
    with warnings.catch_warnings():
        warnings.simplefilter("error")                          # same grid: no extent warning
        from_masks = voxrender.snapshot(folder, labels=True, size=(96, 96), view="left", clip=clip)
    from_map = voxrender.snapshot(the_map_with_names(whole, folder), labels=True, size=(96, 96), view="left",
                                  clip=clip)
    assert np.array_equal(from_masks, from_map)
    assert len(np.unique(from_masks.reshape(-1, 3), axis=0)) > 20      # four tissues, shaded


def test_a_pipelines_folder_is_read_as_written_and_what_is_not_a_mask_is_named_once(tmp_path):
    """TotalSegmentator --statistics --preview writes preview_total.png and statistics.json beside the masks."""
    import imageio.v3 as iio

    folder = split(tmp_path / "segmentations", phantom(), ["aorta", "liver", "spleen"])
    iio.imwrite(folder / "preview_total.png", np.zeros((8, 8, 3), np.uint8))
    (folder / "statistics.json").write_text('{"liver": {"volume": 1.0}}')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        volume = io.read_volume(folder)
    assert volume.meta["format"] == "masks" and len(volume.meta["label_table"]) == 3
    said = [str(w.message) for w in caught]
    assert len(said) == 1 and "preview_total.png, statistics.json" in said[0] and "not masks" in said[0]
    (folder / "mesh.vtk").write_bytes(b"# vtk DataFile")                  # a stray no pipeline writes beside masks
    with pytest.raises(InputError, match=r"holds files other than NIfTI or NRRD masks \(mesh.vtk\)"):
        io.read_volume(folder, format="masks")


def test_a_folder_of_one_volume_file_is_that_volume_and_of_one_mask_a_structure(tmp_path):
    ct = tmp_path / "ct"
    ct.mkdir()
    grey = np.linspace(-1000, 400, 2 * 4 * 7, dtype=np.float32).reshape(2, 4, 7)
    save_nifti(ct / "ct.nii.gz", grey)
    volume = io.read_volume(ct)
    assert np.array_equal(volume.values, io.read_volume(ct / "ct.nii.gz").values)
    assert "ct.nii.gz" in volume.meta["read_as"]
    one = split(tmp_path / "one", phantom(), ["aorta"])
    assert io.read_volume(one).meta["label_table"] == {"1": {"name": "aorta", "colour": None}}
