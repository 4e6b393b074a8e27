"""voxrender.io.nifti: NIfTI-1 and -2, and folders of NIfTI files."""

import numpy as np
import pytest
from formats import refused_cuts

from voxrender import io
from voxrender.errors import InputError


def test_nifti_scaling_and_4d_frames(tmp_path):
    import nibabel

    data = np.arange(4 * 5 * 6 * 2, dtype=np.int16).reshape(6, 5, 4, 2)      # [i, j, k, t]
    image = nibabel.Nifti1Image(data, np.diag([2.0, 3.0, 4.0, 1.0]))
    image.header.set_slope_inter(0.5, 10)
    nibabel.save(image, str(tmp_path / "four.nii.gz"))
    with pytest.raises(InputError, match="holds 2 volumes") as info:
        io.read_volume(tmp_path / "four.nii.gz")
    assert info.value.parameter == "frame"
    with pytest.raises(InputError, match="is not a volume") as info:
        io.read_volume(tmp_path / "four.nii.gz", frame=2)
    volume = io.read_volume(tmp_path / "four.nii.gz", frame=1, reorient=False)
    assert volume.shape == (4, 5, 6) and volume.spacing == (2.0, 3.0, 4.0)
    assert np.allclose(volume.values, data[..., 1].transpose(2, 1, 0) * 0.5 + 10)
    assert io.read_volume(tmp_path / "four.nii.gz", frame=1).meta["reoriented"] == "RAS -> LPS: flipped x, y"


def test_nifti_with_a_bad_pixdim_or_truncated(tmp_path):
    import nibabel

    nibabel.save(nibabel.Nifti1Image(np.zeros((4, 4, 4), np.int16), np.eye(4)), str(tmp_path / "flat.nii"))
    with open(tmp_path / "flat.nii", "r+b") as f:           # nibabel mends a zero pixdim when it saves an image,
        header = nibabel.Nifti1Header.from_fileobj(f)      # so the header is written back on its own
        header["pixdim"][2] = 0
        f.seek(0)
        header.write_to(f)
    with pytest.raises(InputError, match="pixdim"):
        io.read_volume(tmp_path / "flat.nii")
    nibabel.save(nibabel.Nifti1Image(np.random.default_rng(0).random((20, 20, 20)), np.eye(4)),
                 str(tmp_path / "whole.nii.gz"))
    (tmp_path / "cut.nii.gz").write_bytes((tmp_path / "whole.nii.gz").read_bytes()[:4000])
    with pytest.raises(InputError, match="cut.nii.gz"):
        io.read_volume(tmp_path / "cut.nii.gz")


def test_nifti_without_sform_or_qform_warns(tmp_path):
    import nibabel

    image = nibabel.Nifti1Image(np.zeros((3, 4, 5), np.int16), None)
    image.header.set_sform(None, code=0)
    image.header.set_qform(None, code=0)
    nibabel.save(image, str(tmp_path / "bare.nii"))
    with pytest.warns(UserWarning, match="neither sform nor qform"):
        volume = io.read_volume(tmp_path / "bare.nii")
    assert volume.shape == (5, 4, 3) and volume.meta["orientation_from"].startswith("unknown")


def test_nifti_2(tmp_path):
    import nibabel

    data = np.random.default_rng(2).integers(0, 9, (5, 4, 3)).astype(np.int16)       # [i, j, k]
    nibabel.save(nibabel.Nifti2Image(data, np.diag([-1.0, -1.0, 2.0, 1.0])), str(tmp_path / "two.nii"))
    volume = io.read_volume(tmp_path / "two.nii")                  # stored LPS (negative x, y in RAS): as stored
    assert np.array_equal(volume.values, data.transpose(2, 1, 0)) and volume.spacing == (1.0, 1.0, 2.0)


@pytest.mark.parametrize("name", ["three.nii.gz", "three.nrrd"])
def test_a_frame_of_a_3d_file_is_refused(tmp_path, name):
    import nibabel
    import nrrd

    data = np.zeros((3, 4, 5), np.int16)
    if name.endswith(".nrrd"):
        nrrd.write(str(tmp_path / name), data)
    else:
        nibabel.save(nibabel.Nifti1Image(data, np.eye(4)), str(tmp_path / name))
    with pytest.raises(InputError, match="holds one volume; a frame number applies to 4-D files") as info:
        io.read_volume(tmp_path / name, frame=0)
    assert info.value.parameter == "frame"


def test_a_folder_of_nifti_files_says_what_it_holds(tmp_path):
    """A segmentation's folder, one file per organ (TotalSegmentator's segmentations/), is not a stack of slices: as
    NIfTI it is refused, pointing at the masks format."""
    import nibabel

    folder = tmp_path / "segmentations"
    folder.mkdir()
    for organ in ("spleen", "liver", "kidney_left", "stomach"):
        nibabel.save(nibabel.Nifti1Image(np.zeros((4, 4, 4), np.uint8), np.eye(4)), str(folder / f"{organ}.nii.gz"))
    (folder / "statistics.json").write_text("{}")
    assert io.detect_format(folder) == "masks"                    # read as one label map (tests/io/test_masks.py)
    with pytest.raises(InputError, match=r"segmentations holds 4 NIfTI volume files \(kidney_left.nii.gz, "
                                         r"liver.nii.gz, spleen.nii.gz, ...\), not slices; give one of them, or the "
                                         r"folder as one label map of masks"):
        io.read_volume(folder, format="nifti")
    (folder / "scan.raw").write_bytes(b"\0" * 64)          # something else beside them: not a folder of volumes
    assert not io.READERS["nifti"].sniff(folder)


@pytest.mark.parametrize("name", ["cut.nii", "cut.nii.gz"])
def test_cut_nifti_files_are_bad_input(tmp_path, name):
    import nibabel

    data = np.random.default_rng(0).integers(0, 999, (9, 8, 7)).astype(np.int16)
    nibabel.save(nibabel.Nifti1Image(data, np.eye(4)), str(tmp_path / name))
    assert refused_cuts(tmp_path / name, lambda: io.read_volume(tmp_path / name)) >= 30


def _header(shape, dtype=np.int16):
    import nibabel

    header = nibabel.Nifti1Header()
    header.set_data_dtype(dtype)
    header.set_data_shape(shape)
    header.set_sform(np.eye(4), 1)
    header["vox_offset"] = 352
    return header


@pytest.mark.parametrize("name", ["huge.nii", "huge.nii.gz"])
def test_a_header_promising_more_than_the_file_holds_says_both(tmp_path, name):
    """30000³ int16 over 64 bytes: was 'out of memory; --crop a subregion' (exit 1)."""
    import gzip

    header = _header((30000, 30000, 30000))
    whole = header.binaryblock + bytes(4) + bytes(64)                # the header, its extension flag, 64 bytes
    (tmp_path / name).write_bytes(gzip.compress(whole) if name.endswith(".gz") else whole)
    with pytest.raises(InputError, match=r"holds 64 bytes of voxels, of the 54 TB its header promises"):
        io.read_volume(tmp_path / name)


def test_a_volume_too_big_for_memory_is_refused_with_its_size(tmp_path, monkeypatch):
    import nibabel

    from voxrender.io import _shared

    nibabel.save(nibabel.Nifti1Image(np.zeros((20, 20, 20, 3), np.int16), np.eye(4)), str(tmp_path / "v.nii.gz"))
    monkeypatch.setattr(_shared, "free_memory", lambda: 10_000)
    with pytest.raises(InputError, match=r"its 20x20x20 int16 voxels take 16 kB, more than the 10 kB of memory"):
        io.read_volume(tmp_path / "v.nii.gz", frame=1)


def test_a_cifti_file_is_named_not_a_volume(tmp_path):
    """A CIFTI-2 dense scalar file (values on brainordinates): was an internal error (exit 1) in render and info."""
    import nibabel
    from nibabel import cifti2

    voxels = cifti2.BrainModelAxis.from_mask(np.ones((2, 2, 2), bool), affine=np.eye(4))
    image = cifti2.Cifti2Image(np.zeros((2, len(voxels)), np.float32), header=(cifti2.ScalarAxis(["a", "b"]), voxels))
    image.nifti_header.set_intent("ConnDenseScalar")
    nibabel.save(image, str(tmp_path / "c.dscalar.nii"))
    with pytest.raises(InputError, match=r"c.dscalar.nii is a CIFTI-2 file \(ConnDenseScalar: .*\), not a spatial "
                                         "volume"):
        io.read_volume(tmp_path / "c.dscalar.nii")


def test_a_surface_in_nifti_is_named_not_a_volume(tmp_path):
    import nibabel

    image = nibabel.Nifti1Image(np.zeros((1, 1, 1, 1, 12, 3), np.float32), np.eye(4))
    image.header.set_intent("pointset")
    nibabel.save(image, str(tmp_path / "points.nii"))
    with pytest.raises(InputError, match=r"holds a point set \(a surface's vertices\), not a spatial volume"):
        io.read_volume(tmp_path / "points.nii")


@pytest.mark.parametrize("offset", [100.0, 353.0, 1e30])
def test_a_damaged_vox_offset_is_bad_input_in_one_line(tmp_path, capfd, offset):
    """nibabel's 'vox offset ... too low' (and the repair it logs) were an internal error."""
    import nibabel

    nibabel.save(nibabel.Nifti1Image(np.zeros((4, 4, 4), np.int16), np.eye(4)), str(tmp_path / "v.nii"))
    whole = bytearray((tmp_path / "v.nii").read_bytes())
    whole[108:112] = np.float32(offset).tobytes()
    (tmp_path / "v.nii").write_bytes(bytes(whole))
    with pytest.raises(InputError, match="v.nii"):
        io.read_volume(tmp_path / "v.nii")
    assert capfd.readouterr().err == ""


@pytest.mark.parametrize("name", ["four.nii", "four.nii.gz"])
def test_a_cut_4d_file_is_bad_input(tmp_path, name):
    """nibabel's 'Whoops, not enough data in file' when it read a frame was an internal error (the fuzzing gate)."""
    import nibabel

    data = np.random.default_rng(0).integers(0, 999, (6, 5, 4, 3)).astype(np.int16)
    nibabel.save(nibabel.Nifti1Image(data, np.eye(4)), str(tmp_path / name))
    whole = (tmp_path / name).read_bytes()
    (tmp_path / name).write_bytes(whole[:len(whole) * 2 // 5])
    for frame in range(3):
        with pytest.raises(InputError, match=name):
            io.read_volume(tmp_path / name, frame=frame)


def test_only_voxels_read_into_memory_must_fit_there(tmp_path, monkeypatch):
    """Unscaled voxels of a .nii are memory-mapped (a crop then reads only its part); scaled ones are read."""
    import nibabel

    from voxrender.io import _shared

    nibabel.save(nibabel.Nifti1Image(np.zeros((20, 20, 20), np.int16), np.eye(4)), str(tmp_path / "mapped.nii"))
    scaled = nibabel.Nifti1Image(np.zeros((20, 20, 20), np.int16), np.eye(4))
    scaled.header.set_slope_inter(2, 1)
    nibabel.save(scaled, str(tmp_path / "scaled.nii"))
    monkeypatch.setattr(_shared, "free_memory", lambda: 10_000)
    assert io.read_volume(tmp_path / "mapped.nii").shape == (20, 20, 20)
    with pytest.raises(InputError, match="more than the 10 kB of memory free here"):
        io.read_volume(tmp_path / "scaled.nii")


def test_sizes_that_are_not_positive_are_bad_input(tmp_path):
    """dim (7, 0, -16512): nibabel gave an empty array of another shape, then "axes don't match array" (exit 1)."""
    import nibabel

    nibabel.save(nibabel.Nifti1Image(np.zeros((7, 6, 5), np.int16), np.eye(4)), str(tmp_path / "v.nii"))
    whole = bytearray((tmp_path / "v.nii").read_bytes())
    whole[42:48] = np.array([7, 0, -16512], "<i2").tobytes()        # dim[1:4]
    (tmp_path / "v.nii").write_bytes(bytes(whole))
    with pytest.raises(InputError, match=r"its sizes \(dim\) \[7, 0, -16512\] must be positive"):
        io.read_volume(tmp_path / "v.nii")


def add_label_map_to_nifti(img_in, label_map):
    """TotalSegmentator's own writer of its ``--ml`` label names (``totalsegmentator/nifti_ext_header.py``,
    https://github.com/wasserth/TotalSegmentator, Apache-2.0), as it is there: the names travel in a Caret XML
    label table, in a header extension of code 0, with colours that cycle through twelve."""
    import nibabel as nib

    colors = [[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 0], [255, 0, 255], [0, 255, 255], [255, 128, 0],
              [255, 0, 128], [128, 255, 128], [0, 128, 255], [128, 128, 128], [185, 170, 155]]
    xmlpre = '<?xml version="1.0" encoding="UTF-8"?> <CaretExtension>  <Date><![CDATA[2013-07-14T05:45:09]]></Date>   <VolumeInformation Index="0">   <LabelTable>'  # noqa: E501
    body = ""
    for label_id, label_name in label_map.items():
        rgb = colors[label_id % len(colors)]
        body += f'<Label Key="{label_id}" Red="{rgb[0] / 255}" Green="{rgb[1] / 255}" Blue="{rgb[2] / 255}" Alpha="1"><![CDATA[{label_name}]]></Label>\n'  # noqa: E501
    xmlpost = '  </LabelTable>  <StudyMetaDataLinkSet>  </StudyMetaDataLinkSet>  <VolumeType><![CDATA[Label]]></VolumeType>   </VolumeInformation></CaretExtension>'  # noqa: E501
    xml = xmlpre + "\n" + body + "\n" + xmlpost + "\n              "
    img_in.header.extensions.append(nib.nifti1.Nifti1Extension(0, bytes(xml, "utf-8")))
    return img_in


def test_a_totalsegmentator_multilabel_file_names_its_labels_and_colours_them_by_anatomy(tmp_path):
    """Its names were not read: the legend showed 'label 5'."""
    import nibabel

    from voxrender.pictures.colours import anatomy_colour, label_colours

    data = np.zeros((6, 6, 6), np.uint8)
    data[1:3, 1:3, 1:3], data[3:5, 3:5, 3:5] = 5, 6
    image = nibabel.Nifti1Image(data, np.eye(4))
    image.header.extensions.append(nibabel.nifti1.Nifti1Extension(6, b"a comment before the table"))
    names = {5: "liver", 6: "vertebrae_L1", 7: "kidney_left"}
    nibabel.save(add_label_map_to_nifti(image, names), tmp_path / "ml.nii.gz")
    volume = io.read_volume(tmp_path / "ml.nii.gz")
    assert volume.meta["label_table"] == {"5": {"name": "liver", "colour": None},
                                          "6": {"name": "vertebrae_L1", "colour": None},
                                          "7": {"name": "kidney_left", "colour": None}}
    assert label_colours([5, 6], volume.meta["label_table"]) == {
        5: ("liver", anatomy_colour("liver")), 6: ("vertebrae_L1", anatomy_colour("vertebrae_L1"))}
    assert anatomy_colour("liver") != anatomy_colour("vertebrae_L1")


def test_a_damaged_label_table_leaves_the_labels_numbered_with_a_warning(tmp_path):
    import nibabel

    image = nibabel.Nifti1Image(np.ones((4, 4, 4), np.uint8), np.eye(4))
    image.header.extensions.append(nibabel.nifti1.Nifti1Extension(0, b"<LabelTable><Label Key='x'>liver"))
    nibabel.save(image, tmp_path / "bad.nii")
    with pytest.warns(UserWarning, match="label table .* is damaged"):
        volume = io.read_volume(tmp_path / "bad.nii")
    assert "label_table" not in volume.meta and volume.values.sum() == 64


def test_nibabel_mending_a_header_prints_nothing(tmp_path, capfd):
    """nibabel logs what it mends ('sizeof_hdr should be 348') through its own handler: the quieted log replaced
    only its level, which let that line through on stderr beside voxrender's own (found by the fuzzing gate)."""
    import nibabel

    nibabel.save(nibabel.Nifti1Image(np.ones((4, 4, 4), np.uint8), np.eye(4)), str(tmp_path / "v.nii"))
    data = bytearray((tmp_path / "v.nii").read_bytes())
    data[:4] = (0).to_bytes(4, "little")                        # sizeof_hdr
    (tmp_path / "v.nii").write_bytes(bytes(data))
    capfd.readouterr()
    try:
        io.read_volume(tmp_path / "v.nii")
    except InputError:
        pass
    assert capfd.readouterr().err == ""


def test_a_workbench_label_table_keeps_its_colours(tmp_path):
    """Code 30 (Connectome Workbench): nibabel's get_content raised NotImplementedError for it (found by the
    fuzzing gate); its colours, unlike TotalSegmentator's, are the user's."""
    import nibabel

    image = nibabel.Nifti1Image(np.ones((4, 4, 4), np.uint8), np.eye(4))
    image.header.extensions.append(nibabel.nifti1.Nifti1Extension(
        30, b'<LabelTable><Label Key="1" Red="1" Green="0.5" Blue="0">cortex</Label></LabelTable>'))
    nibabel.save(image, tmp_path / "wb.nii")
    assert io.read_volume(tmp_path / "wb.nii").meta["label_table"] == {"1": {"name": "cortex",
                                                                             "colour": [255, 128, 0]}}
