"""voxrender.io.seg: DICOM SEG (BINARY, FRACTIONAL, LABELMAP) read as a label map, from SEGs highdicom writes."""

import numpy as np
import pydicom
import pytest
from conftest import data_path
from formats import refused_cuts
from seg_files import SHAPE, blobs, complete_sources, write_ct, write_ct_and_seg, write_seg

from voxrender import io
from voxrender._shared import label_sets
from voxrender.errors import InputError
from voxrender.io import seg as seg_reader
from voxrender.space.grids import patient_affine

SPACING = (0.7, 0.8, 2.5)                               # spacing (x, y, z) in mm
NAMES = ["liver", "spleen", "kidney"]
COLOURS = [(221, 130, 101), (157, 108, 162), (185, 102, 83)]


def read(path):
    return io.read_volume(path, format="seg")


def write_pair(folder, labels, kind="BINARY", direction=None, colours=None, **options):
    """A CT whose HU values are ``labels`` (so reading it gives them as the CT's reader orders them) and its SEG."""
    sources = write_ct(folder / "ct", labels.shape, SPACING, direction, values=labels)
    segments = labels
    if kind == "FRACTIONAL":
        segments = np.stack([(labels == k).astype(np.float32) for k in range(1, len(NAMES) + 1)], axis=-1)
    seg_path = write_seg(folder / "seg.dcm", sources, segments, NAMES, kind, colours=colours, **options)
    return folder / "ct", seg_path


def on_grid_of(volume, image):
    """``volume``'s values placed on ``image``'s grid (both read, so reoriented): they must lie on its voxels."""
    assert np.allclose(volume.spacing, image.spacing) and np.allclose(volume.direction, image.direction, atol=1e-6)
    corner = np.linalg.inv(patient_affine(image)) @ [*volume.meta["origin"], 1.0]
    assert np.allclose(corner[:3], np.rint(corner[:3]), atol=1e-4), corner
    x, y, z = np.rint(corner[:3]).astype(int)
    assert min(x, y, z) >= 0
    placed = np.zeros(image.shape, volume.values.dtype)
    nz, ny, nx = volume.shape
    placed[z:z + nz, y:y + ny, x:x + nx] = volume.values
    return placed


@pytest.mark.parametrize("kind", ["BINARY", "FRACTIONAL", "LABELMAP"])
def test_seg_reads_the_label_map_it_was_written_from(tmp_path, kind):
    labels = blobs()
    ct_folder, seg_path = write_pair(tmp_path, labels, kind)
    ct, seg = io.read_volume(ct_folder), read(seg_path)
    assert seg.meta["format"] == "seg" and seg.meta["segmentation_type"] == kind
    assert seg.values.dtype == np.uint8 and seg.shape[1:] == ct.shape[1:] and seg.shape[0] < ct.shape[0]
    assert np.array_equal(on_grid_of(seg, ct), ct.values)
    assert seg.spacing == pytest.approx(SPACING)
    assert seg.meta["overlaps"] == [] and seg.meta["empty_labels"] == []
    assert seg.meta["referenced_series"] == pydicom.dcmread(next(ct_folder.iterdir())).SeriesInstanceUID
    assert seg.meta["frame_of_reference"] == ct.meta["frame_of_reference"] != ""
    assert [seg.meta["label_table"][str(k)]["name"] for k in (1, 2, 3)] == NAMES


@pytest.mark.parametrize("kind", ["BINARY", "LABELMAP"])
def test_frames_are_placed_as_highdicom_places_them(tmp_path, kind):
    import highdicom

    _, seg_path = write_pair(tmp_path, blobs(), kind)
    volume = seg_reader.read_seg(seg_path, lambda items, length, label: items)
    theirs = highdicom.seg.segread(seg_path).get_volume(combine_segments=True)
    assert np.array_equal(volume.values, theirs.array)
    assert volume.meta["origin"] == pytest.approx(theirs.affine[:3, 3])


def test_seg_is_read_from_its_planes_positions_not_their_order(tmp_path):
    """highdicom stores the planes from the top down: the reader follows the affine, whatever the order."""
    labels = blobs()
    _, seg_path = write_pair(tmp_path, labels)
    volume = seg_reader.read_seg(seg_path, lambda items, length, label: items)
    assert volume.direction[2, 2] in (1.0, -1.0)
    stored = volume.values if volume.direction[2, 2] > 0 else volume.values[::-1]
    occupied = np.flatnonzero(labels.any(axis=(1, 2)))
    assert np.array_equal(stored, labels[occupied[0]:occupied[-1] + 1])
    top = -100 + SPACING[2] * (occupied[-1] if volume.direction[2, 2] < 0 else occupied[0])
    assert volume.meta["origin"] == pytest.approx([0, 0, top])


def test_names_and_colours_round_trip(tmp_path):
    _, seg_path = write_pair(tmp_path, blobs(), colours=COLOURS[:2] + [None])
    table = read(seg_path).meta["label_table"]
    assert [table[k]["name"] for k in ("1", "2", "3")] == NAMES
    for k, colour in enumerate(COLOURS[:2], start=1):
        assert np.abs(np.subtract(table[str(k)]["colour"], colour)).max() <= 1
    assert table["3"]["colour"] is None


def test_sparse_frames_land_on_their_slices(tmp_path):
    labels = np.zeros(SHAPE, np.uint8)
    labels[3, 2:6, 4:9] = 1
    labels[8, 10:12, 3:5] = 2                 # slices 4 to 7 hold nothing: no frame is stored for them
    ct_folder, seg_path = write_ct_and_seg(tmp_path, labels, NAMES[:2], spacing=SPACING)
    assert pydicom.dcmread(seg_path, stop_before_pixels=True).NumberOfFrames == 2
    ct, seg = io.read_volume(ct_folder), read(seg_path)
    assert seg.shape[0] == 6
    placed = on_grid_of(seg, ct)
    assert np.array_equal(placed, labels)     # the CT is axial, stored as read: canonical already


def test_overlapping_segments_each_keep_their_voxels_and_the_smaller_shows(tmp_path):
    masks = np.zeros(SHAPE + (3,), np.uint8)
    masks[2:6, 2:8, 2:8, 0] = 1
    masks[4:8, 5:10, 5:10, 1] = 1              # 2 x 3 x 3 voxels shared with segment 1
    masks[6:8, 5:7, 5:7, 2] = 1               # inside segment 2 alone
    sources = write_ct(tmp_path / "ct", SHAPE, SPACING)
    names = ["a", "b", "c", "empty"]
    masks = np.concatenate([masks, np.zeros(SHAPE + (1,), np.uint8)], axis=-1)
    seg = read(write_seg(tmp_path / "seg.dcm", sources, masks, names))
    ct = io.read_volume(tmp_path / "ct")
    codes = on_grid_of(seg, ct)
    sets = seg.meta["label_sets"]
    for k in (1, 2, 3):                       # each segment keeps its own voxels
        assert np.array_equal(label_sets.member_mask(codes, sets, k), masks[..., k - 1] > 0), k
    expected = np.zeros(SHAPE, np.uint8)
    for k in (1, 2, 3):                       # sizes 144, 100, 8: the smaller written last, shown
        expected[masks[..., k - 1] > 0] = k
    assert np.array_equal(label_sets.resolve(codes, sets), expected)
    assert seg.meta["overlaps"] == [{"labels": [1, 2], "names": ["a", "b"], "voxels": 18},
                                    {"labels": [2, 3], "names": ["b", "c"], "voxels": 8, "inside": "c"}]
    assert seg.meta["empty_labels"] == [4] and seg.meta["label_table"]["4"]["name"] == "empty"


@pytest.mark.parametrize("largest", [255, 100])               # 100: one half is stored exactly, as 50
def test_fractional_holds_voxels_of_at_least_one_half(tmp_path, largest):
    fractions = np.zeros(SHAPE + (1,), np.float32)
    fractions[5, 2:4, 2:4, 0] = 0.4
    fractions[5, 6:8, 6:8, 0] = 0.6
    fractions[5, 10:12, 10:12, 0] = 0.5
    sources = write_ct(tmp_path / "ct", SHAPE, SPACING)
    seg = read(write_seg(tmp_path / "seg.dcm", sources, fractions, ["tumour"], "FRACTIONAL",
                         max_fractional_value=largest))
    assert seg.shape == (1, 20, 24)
    assert np.array_equal(np.argwhere(seg.values[0]), np.argwhere(fractions[5, ..., 0] >= 0.5))
    assert seg.values[0, 2:4, 2:4].max() == 0 and seg.values[0, 6:8, 6:8].min() == 1


@pytest.mark.parametrize("name, direction", [
    ("sagittal", np.array([[0, 0, 1], [1, 0, 0], [0, -1, 0]], float)),       # x toward P, y toward I, z toward L
    ("oblique", np.array([[np.cos(0.3), -np.sin(0.3), 0], [np.sin(0.3), np.cos(0.3), 0], [0, 0, 1]])),
])
def test_seg_of_a_sagittal_or_oblique_series_is_placed_by_its_planes(tmp_path, name, direction, recwarn):
    labels = blobs()
    ct_folder, seg_path = write_pair(tmp_path, labels, direction=direction)
    stored = seg_reader.read_seg(seg_path, lambda items, length, label: items)
    assert not np.allclose(stored.direction, np.eye(3))
    assert np.allclose(np.abs(stored.direction[:, :2]), np.abs(direction[:, :2]), atol=1e-6)
    ct, seg = io.read_volume(ct_folder), read(seg_path)
    assert np.array_equal(on_grid_of(seg, ct), ct.values)        # same direction, spacing and voxels


def test_is_seg(tmp_path):
    ct_folder, seg_path = write_ct_and_seg(tmp_path, blobs(), NAMES)
    note = tmp_path / "note.txt"
    note.write_text("not DICOM")
    assert seg_reader.is_seg(seg_path)
    assert not any(seg_reader.is_seg(p) for p in (next(ct_folder.iterdir()), ct_folder, note))


def test_what_is_not_a_seg_is_refused(tmp_path):
    ct_folder, seg_path = write_ct_and_seg(tmp_path, blobs(), NAMES)
    with pytest.raises(InputError, match="is a DICOM file but not a SEG .*CT") as info:
        read(next(ct_folder.iterdir()))
    assert info.value.parameter == "format"
    note = tmp_path / "note.dcm"
    note.write_text("not DICOM")
    with pytest.raises(InputError, match="note.dcm is not a DICOM file"):
        read(note)
    with pytest.raises(InputError, match="is a folder; the seg format reads one DICOM SEG file"):
        read(ct_folder)


@pytest.mark.parametrize("kind", ["BINARY", "LABELMAP"])
def test_cut_segs_are_bad_input(tmp_path, kind):
    _, seg_path = write_ct_and_seg(tmp_path, blobs(), NAMES, kind)
    size = seg_path.stat().st_size
    assert refused_cuts(seg_path, lambda: read(seg_path), count=20) == len(range(0, size, size // 20))


@pytest.mark.filterwarnings("ignore::UserWarning")                # pydicom's notes on the values it cannot take
def test_garbled_segs_are_read_or_refused(tmp_path):
    """Four bytes overwritten at 30 places: each file is read or refused with an InputError, nothing else."""
    _, seg_path = write_ct_and_seg(tmp_path, blobs(), NAMES)
    whole = seg_path.read_bytes()
    refused = 0
    for at in np.linspace(132, len(whole) - 4, 30).astype(int):
        seg_path.write_bytes(whole[:at] + b"\xff\x00\xff\x00" + whole[at + 4:])
        try:
            read(seg_path)
        except InputError as exc:
            refused += 1
            assert "seg.dcm" in str(exc) and "\n" not in str(exc)
    assert refused >= 5


def edited(seg_path, edit, name):
    """A copy of the SEG at ``seg_path`` with ``edit(ds)`` done to it by pydicom."""
    ds = pydicom.dcmread(seg_path)
    edit(ds)
    path = seg_path.with_name(name)
    ds.save_as(path)
    return path


def cut_pixels(ds):
    ds.PixelData = ds.PixelData[:len(ds.PixelData) // 2]


def no_frames(ds):
    del ds.PixelData
    ds.NumberOfFrames = 0
    ds.PerFrameFunctionalGroupsSequence = []


def unplaced_frame(ds):
    del ds.PerFrameFunctionalGroupsSequence[1].PlanePositionSequence


def no_groups(ds):
    del ds.PerFrameFunctionalGroupsSequence


def unknown_segment(ds):
    ds.PerFrameFunctionalGroupsSequence[0].SegmentIdentificationSequence[0].ReferencedSegmentNumber = 9


def two_on_one_plane(ds):
    groups = ds.PerFrameFunctionalGroupsSequence
    groups[1].PlanePositionSequence = groups[0].PlanePositionSequence


def uneven_planes(ds):                            # a plane a quarter of a slice off
    position = ds.PerFrameFunctionalGroupsSequence[0].PlanePositionSequence[0]
    position.ImagePositionPatient = [0, 0, float(position.ImagePositionPatient[2]) + 0.6]


def no_segments(ds):
    del ds.SegmentSequence


def frames_miscounted(ds):
    ds.NumberOfFrames = 3


@pytest.mark.parametrize("edit, message", [
    (cut_pixels, "holds .* of frames, of the .* its header promises"),
    (no_frames, "holds no frames: it segments nothing"),
    (unplaced_frame, "it lacks PlanePositionSequence"),
    (no_groups, "no PerFrameFunctionalGroupsSequence"),
    (unknown_segment, "belongs to segment 9, which its SegmentSequence does not describe"),
    (two_on_one_plane, "two frames of segment . lie on one plane"),
    (uneven_planes, "not a stack of parallel, evenly spaced planes"),
    (no_segments, "it lacks SegmentSequence"),
    (frames_miscounted, r"places \d+ frames .* but holds 3"),
])
def test_damaged_segs_are_bad_input(tmp_path, edit, message):
    labels = blobs()
    labels[6:, 0, 0] = 1                                          # every plane holds a frame of segment 1
    _, seg_path = write_ct_and_seg(tmp_path, labels, NAMES)
    path = edited(seg_path, edit, f"{edit.__name__}.dcm")
    with pytest.raises(InputError, match=message) as info:
        read(path)
    assert path.name in str(info.value) and "\n" not in str(info.value)


def test_labelmap_pixels_of_an_undescribed_segment_are_bad_input(tmp_path):
    _, seg_path = write_ct_and_seg(tmp_path, blobs(), NAMES, "LABELMAP")

    def forget_kidney(ds):
        del ds.SegmentSequence[3]                                 # item 0 is the background

    with pytest.raises(InputError, match="its pixels hold segment 3, which its SegmentSequence does not describe"):
        read(edited(seg_path, forget_kidney, "forgotten.dcm"))


@pytest.mark.filterwarnings("ignore:The string .* is unlikely to represent")      # highdicom on its PatientName
def test_vhf_head_ct_with_a_seg_of_its_skin_and_bone(tmp_path):
    folder = data_path("vhf_head")
    files = sorted(folder.glob("vhf.*.dcm"))[100:112]            # a block of slices through the skull
    ct_folder = tmp_path / "ct"
    ct_folder.mkdir()
    for f in files:
        (ct_folder / f.name).write_bytes(f.read_bytes())
    sources = complete_sources(sorted(ct_folder.iterdir()))
    sources.sort(key=lambda ds: float(ds.ImagePositionPatient[2]))
    hu = np.stack([ds.pixel_array.astype(np.int16) * int(ds.RescaleSlope) + int(ds.RescaleIntercept)
                   for ds in sources])
    labels = np.where(hu > 300, 2, np.where(hu > -300, 1, 0)).astype(np.uint8)
    seg = read(write_seg(tmp_path / "seg.dcm", sources, labels, ["skin", "bone"]))
    ct = io.read_volume(ct_folder)
    expected = np.where(ct.values > 300, 2, np.where(ct.values > -300, 1, 0))
    assert np.bincount(seg.values.ravel()).min() > 1000
    assert np.array_equal(on_grid_of(seg, ct), expected)
    assert seg.meta["referenced_series"] == ct.meta["series"]
