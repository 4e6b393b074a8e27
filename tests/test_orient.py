"""The canonical patient frame: orientation codes, flips and permutations, and one phantom through every format."""

import numpy as np
import pytest
from formats import SPACING, phantom, stored, write_dicom, write_metaimage, write_nifti, write_nrrd

from voxrender.errors import InputError
from voxrender.object import segments
from voxrender.object.pipeline import PrepOptions, ReadOptions, load_segments
from voxrender.pictures._picture import RenderOptions, picture
from voxrender.space import orient
from voxrender.space.view import PRESETS

CODES = ["LPS", "RAS", "AIL", "SLA"]          # DICOM's, NIfTI's, and two permuted, flipped ones


@pytest.mark.parametrize("code", ["LPS", "RAS", "LPI", "AIL", "SLA", "prs"])
def test_codes_round_trip(code):
    assert orient.code_of(orient.direction_of(code)) == code.upper()


@pytest.mark.parametrize("code", ["LPX", "LLS", "LP", "RASL", "", "123"])
def test_bad_codes(code):
    with pytest.raises(InputError) as info:
        orient.direction_of(code)
    assert info.value.parameter == "orientation"


@pytest.mark.parametrize("code", CODES)
def test_stored_volumes_come_back_canonical(code):
    canonical = phantom()
    values, spacing, direction = stored(canonical, code)
    back, back_spacing, remaining, _ = orient.to_canonical(values, spacing, direction)
    assert np.array_equal(back, canonical) and back_spacing == SPACING and np.allclose(remaining, np.eye(3))


def test_an_oblique_volume_is_shown_in_the_nearest_orientation_with_a_warning():
    tilt = np.radians(5)
    direction = np.array([[np.cos(tilt), -np.sin(tilt), 0], [np.sin(tilt), np.cos(tilt), 0], [0, 0, 1]])
    with pytest.warns(UserWarning, match="oblique: a voxel axis is 5.00 degrees"):
        values, _, _, note = orient.to_canonical(phantom(), SPACING, direction)
    assert np.array_equal(values, phantom()) and note == "LPS -> LPS: as stored"


def pictures(path, **read):
    encoded = load_segments(path, ReadOptions(**read), PrepOptions(threshold=500))
    options = RenderOptions(size=(48, 48), scale=1.5)
    return [picture(encoded.segments, options.view(*PRESETS[name]), options).image.depth
            for name in ("anterior", "left", "superior")]


def test_one_phantom_in_every_format_and_orientation_gives_the_same_pictures(tmp_path):
    """NIfTI (.nii, .nii.gz), NRRD (attached, gzip, detached, RAS space), MetaImage and DICOM, each stored in
    LPS, RAS and permuted, flipped orders: identical depth images at anterior, left and superior."""
    canonical = phantom()
    np.save(tmp_path / "canonical.npy", canonical)
    expected = pictures(tmp_path / "canonical.npy", spacing=SPACING)
    left, right = expected[1][:, :24], expected[1][:, 24:]
    assert np.isfinite(expected[0]).sum() > 200 and not np.array_equal(left, right[:, ::-1])   # asymmetric
    for code in CODES:
        values, spacing, direction = stored(canonical, code)
        files = [write_nifti(tmp_path / f"{code}.nii", values, spacing, direction),
                 write_nifti(tmp_path / f"{code}.nii.gz", values, spacing, direction),
                 write_nrrd(tmp_path / f"{code}.nrrd", values, spacing, direction, encoding="gzip"),
                 write_nrrd(tmp_path / f"{code}-ras.nrrd", values, spacing, direction, "right-anterior-superior"),
                 write_nrrd(tmp_path / f"{code}.nhdr", values, spacing, direction),
                 write_metaimage(tmp_path / f"{code}.mha", values, spacing, direction)]
        if np.linalg.det(direction) > 0:        # a DICOM series is sorted along its slices' normal: right-handed
            write_dicom(tmp_path / f"{code}-dicom", values, spacing, direction)
            files.append(tmp_path / f"{code}-dicom")
        if code != "LPS":                       # without reorienting, the stored order shows: the test can fail
            assert not np.array_equal(pictures(files[1], reorient=False)[0], expected[0])
        for path in files:
            for got, want in zip(pictures(path), expected, strict=True):
                assert np.array_equal(np.isfinite(got), np.isfinite(want)), path
                assert np.allclose(got[np.isfinite(got)], want[np.isfinite(want)], atol=1e-5), path


def test_headerless_inputs_take_an_orientation_code(tmp_path):
    canonical = phantom()
    values, spacing, _ = stored(canonical, "RAI")
    np.save(tmp_path / "rai.npy", values)
    np.save(tmp_path / "canonical.npy", canonical)
    expected = pictures(tmp_path / "canonical.npy", spacing=SPACING)
    for got, want in zip(pictures(tmp_path / "rai.npy", spacing=spacing, orientation="RAI"), expected, strict=True):
        assert np.array_equal(got, want)
    kept = load_segments(tmp_path / "rai.npy", ReadOptions(orientation="RAI", reorient=False),
                         PrepOptions(threshold=500, resample=False))
    assert np.array_equal(kept.segments.to_mask(), values >= 500)      # --no-reorient keeps the stored order
    assert segments.encode(values >= 500).voxel_count == kept.segments.voxel_count


@pytest.mark.parametrize("code", ["RAS", "LPS", "LIA", "ASR"])
def test_a_voxel_keeps_its_patient_position_when_the_volume_is_reoriented(tmp_path, code):
    """patient_affine of the reoriented volume puts every voxel where the stored volume's affine does."""
    import nibabel

    from voxrender.io import read_volume
    from voxrender.space.grids import patient_affine

    direction = orient.ras_to_lps(orient.direction_of(code))    # the code's axes, written as NIfTI's RAS
    affine = np.eye(4)
    affine[:3, :3] = direction * [0.5, 0.8, 2.0]
    affine[:3, 3] = [10.0, -20.0, 30.0]
    values = np.arange(4 * 5 * 6, dtype=np.int16).reshape(6, 5, 4)          # [z, y, x], every value once
    nibabel.save(nibabel.Nifti1Image(values.T, affine), tmp_path / "v.nii")
    stored, canonical = (read_volume(tmp_path / "v.nii", reorient=flag) for flag in (False, True))
    for volume in (stored, canonical):
        z, y, x = np.unravel_index(np.arange(values.size), volume.shape)
        order = np.argsort(volume.values[z, y, x])
        points = (patient_affine(volume) @ np.stack([x, y, z, np.ones_like(x)])[:, order])[:3]
        if volume is stored:
            expected = points
    np.testing.assert_allclose(points, expected, atol=1e-5)
    assert orient.code_of(canonical.direction) == "LPS"
