"""Every value a renderer can meet: NaN and inf voxels, constant volumes, one voxel thick or a single voxel, and a
CT padded outside its scan circle; each renders, or ends in one true line.
"""

import json
import warnings

import imageio.v3 as iio
import nibabel as nib
import numpy as np
import pytest
from click.testing import CliRunner
from conftest import data_path
from dicom_files import write_series

from voxrender._render import METHODS
from voxrender.cli import main
from voxrender.io import Volume, read_volume
from voxrender.object import prep
from voxrender.object.segments import encode
from voxrender.pictures._picture import RenderOptions, picture
from voxrender.space.view import PRESETS, View


def run(*args):
    return CliRunner().invoke(main, [str(a) for a in args])


def one_line_error(result, *words):
    assert result.exit_code == 2, result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), result.stderr
    assert all(word in lines[0] for word in words), lines[0]
    return lines[0]


def lit(path):
    return int(np.count_nonzero(iio.imread(path)))


# ---------------------------------------------------------------- NaN and inf

@pytest.fixture
def nan_nifti(tmp_path):
    """A float NIfTI written by nibabel: a cube of 100 in 0, with NaN and inf voxels, some inside the cube."""
    values = np.zeros((32, 32, 32), np.float32)
    values[8:24, 8:24, 8:24] = 100
    values[0, 0, :5] = np.nan
    values[12, 12, 12] = np.nan
    values[1, 1, 1] = np.inf
    values[2, 2, 2] = -np.inf
    path = tmp_path / "nan.nii"
    nib.save(nib.Nifti1Image(values, np.eye(4)), path)
    return path


def test_otsu_leaves_out_nan_and_inf():
    values = np.array([0, 0, 0, 10, 10, 10], np.float32)
    spoilt = np.concatenate([values, [np.nan, np.inf, -np.inf]]).astype(np.float32)
    assert prep.otsu_threshold(spoilt) == prep.otsu_threshold(values)
    assert prep.value_range(spoilt) == (0.0, 10.0)
    assert prep.non_finite_counts(spoilt) == {"nan": 1, "inf": 2} and prep.non_finite_counts(values) == {}
    with pytest.raises(prep.InputError, match="every value is NaN or infinite"):
        prep.otsu_threshold(np.array([np.nan, np.inf]))


def test_otsu_is_unchanged_on_finite_values():
    """The histogram of every value, as before: the same bits (the golden images rest on it)."""
    from skimage.filters import threshold_otsu

    values = np.random.default_rng(0).normal(size=(8, 16, 16)).astype(np.float32)
    values[2:6] += 4
    counts, edges = np.histogram(values, bins=1024, range=(float(values.min()), float(values.max())))
    centres = (edges[:-1] + edges[1:]) / 2
    otsu = float(threshold_otsu(hist=(counts, centres)))
    occupied = centres[counts > 0]
    expected = float((occupied[occupied <= otsu][-1] + occupied[occupied > otsu][0]) / 2)
    assert prep.otsu_threshold(values) == expected


def test_windows_leave_out_nan_and_inf():
    values = np.array([[[np.nan, np.inf, -np.inf, 500.0, 0.0]]])
    for threshold in (prep.Interval(300), prep.Interval(None, 1000), 300.0):
        mask, _ = prep.binarize(Volume(values), threshold)
        assert mask.tolist() == [[[False, False, False, True, threshold == prep.Interval(None, 1000)]]]


def test_nan_voxels_render(tmp_path, nan_nifti):
    """Was: internal error, 'supplied range of [nan, nan] is not finite' (exit 1), in the default Otsu threshold."""
    result = run("render", nan_nifti, "-o", tmp_path / "nan.png", "--stats-json", tmp_path / "nan.json")
    assert result.exit_code == 0 and not result.stderr, result.output
    assert lit(tmp_path / "nan.png") > 1000
    assert json.loads((tmp_path / "nan.json").read_text())["object"]["voxels"] == 16 ** 3 - 1


def test_a_nan_voxel_keeps_the_grey_normals():
    """Resampled, the normals come from a cubic spline of the values, whose prefilter spread one NaN to all."""
    from scipy import ndimage

    from voxrender.object.pipeline import encode_volume

    zz, yy, xx = np.mgrid[:24, :24, :24] - 11.5
    ball = ndimage.gaussian_filter(100.0 * (np.sqrt(xx ** 2 + yy ** 2 + zz ** 2) < 8), 1).astype(np.float32)
    clean = encode_volume(Volume(ball, (1, 1, 2))).normals
    ball[1, 1, 1] = np.nan
    spoilt = encode_volume(Volume(ball, (1, 1, 2))).normals
    assert spoilt.source == "grey values" and np.array_equal(spoilt.index, clean.index) and len(clean.index) > 1000


def test_a_volume_of_nan_is_one_true_line(tmp_path):
    path = tmp_path / "all-nan.nii"
    nib.save(nib.Nifti1Image(np.full((4, 4, 4), np.nan, np.float32), np.eye(4)), path)
    line = one_line_error(run("render", path, "-o", tmp_path / "x.png"), "NaN or infinite")
    assert "--" not in line
    one_line_error(run("info", path), "NaN or infinite")
    for selection in (["--threshold", "0.5"], ["--preset", "bone"], ["--preset", "skin,bone"]):
        # was '--threshold: window 300: leaves no object voxel: ...; choose a threshold in that range' for a preset
        line = one_line_error(run("render", path, *selection, "-o", tmp_path / "x.png"), str(path), "NaN or infinite")
        assert "--" not in line and "range" not in line


def test_a_selection_that_holds_nothing_names_the_range_and_blames_only_a_given_flag(tmp_path):
    np.save(tmp_path / "low.npy", np.arange(64, dtype=np.int16).reshape(4, 4, 4))
    line = one_line_error(run("render", tmp_path / "low.npy", "--threshold", 100, "-o", tmp_path / "x.png"),
                          "--threshold: the threshold 100 holds no voxel", "range from 0 to 63")
    line = one_line_error(run("render", tmp_path / "low.npy", "--preset", "bone", "-o", tmp_path / "x.png"),
                          "the window 300 and above holds no voxel", "range from 0 to 63")
    assert line.endswith("(--threshold)") and not line.startswith("error: --")


# ---------------------------------------------------------------- constant, thin and single voxels

def test_a_constant_volume_says_so_and_renders_at_a_threshold(tmp_path):
    np.save(tmp_path / "constant.npy", np.full((8, 8, 8), 5, np.int16))
    line = one_line_error(run("render", tmp_path / "constant.npy", "-o", tmp_path / "c.png"), "every value is 5")
    assert "--threshold" not in line
    result = run("render", tmp_path / "constant.npy", "-o", tmp_path / "c.png", "--threshold", 5)
    assert result.exit_code == 0, result.output
    assert lit(tmp_path / "c.png") > 1000


def test_a_single_voxel_renders(tmp_path):
    np.save(tmp_path / "one.npy", np.full((1, 1, 1), 5, np.int16))
    result = run("render", tmp_path / "one.npy", "-o", tmp_path / "one.png", "--threshold", 1)
    assert result.exit_code == 0, result.output
    assert lit(tmp_path / "one.png") > 1000 and not result.stderr


def test_a_one_voxel_4d_nrrd_renders_its_frame(tmp_path):
    import nrrd

    path = tmp_path / "one4d.nrrd"
    nrrd.write(str(path), np.full((1, 1, 1, 1), 7, np.int16),
               {"kinds": ["domain", "domain", "domain", "list"], "space": "left-posterior-superior",
                "space directions": [[1, 0, 0], [0, 1, 0], [0, 0, 1], [np.nan] * 3]})
    result = run("render", path, "--frame", 0, "--threshold", 1, "-o", tmp_path / "one.png")
    assert result.exit_code == 0, result.output
    assert lit(tmp_path / "one.png") > 1000


@pytest.mark.parametrize("shape", [(1, 64, 64), (64, 64, 1), (64, 1, 64)])
def test_a_volume_one_voxel_thick_renders_from_every_named_view(tmp_path, shape):
    values = np.zeros(shape, np.int16)
    values[tuple(slice(None) if n == 1 else slice(16, 48) for n in shape)] = 100
    np.save(tmp_path / "slab.npy", values)
    for view in PRESETS:
        result = run("render", tmp_path / "slab.npy", "-o", tmp_path / f"{view}.png", "--view", view)
        assert result.exit_code == 0 and not result.stderr, (view, result.output)
        assert lit(tmp_path / f"{view}.png") >= 32, view


@pytest.mark.parametrize("method", sorted(METHODS))
def test_a_slab_thinner_than_a_pixel_edge_on_is_drawn(method):
    """A sagittal slice 600 voxels high, seen from below: at the fitted 0.8 pixels per voxel its one voxel of
    thickness is thinner than a pixel, and the framing puts it on a column of pixel centres.
    """
    slab = encode(np.ones((50, 600, 1), bool))
    for fit in ("object", "volume"):
        options = RenderOptions(method=method, fit=fit)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            result = picture(slab, options.view(*PRESETS["inferior"]), options)
        assert result.image.coverage.sum() >= 400, fit


def test_an_edge_on_slab_that_no_ray_meets_is_warned_of_with_the_view():
    slab = encode(np.ones((50, 64, 1), bool))
    options = RenderOptions(size=(64, 64), scale=0.5)
    with pytest.warns(UserWarning) as caught:
        result = picture(slab, options.view(*PRESETS["inferior"]), options)
    assert not result.image.coverage.any()
    (message,) = [str(w.message) for w in caught]
    assert "edge-on from the inferior view" in message and "left or right view" in message
    assert "1 voxel thick along x" in message and "--" not in message


def test_an_object_outside_the_picture_is_warned_of_without_a_flag(tmp_path):
    values = np.zeros((20, 20, 20), np.int16)
    values[:3, :3, :3] = 100
    np.save(tmp_path / "corner.npy", values)
    result = run("render", tmp_path / "corner.npy", "-o", tmp_path / "c.png", "--scale", 40, "--size", "32x32")
    assert result.exit_code == 0, result.output
    assert result.stderr.startswith("warning: the object falls outside the picture") and "--" not in result.stderr
    with pytest.warns(UserWarning, match="choose a smaller scale"):
        picture(encode(values > 0), View(size=(32, 32), scale=40.0))


# ---------------------------------------------------------------- a CT padded outside its scan circle

def padded_ct(slices=12, side=96, padding=-3024):
    """A CT in HU: padding outside the scan circle, air inside it, a head of soft tissue with a skull."""
    yy, xx = np.mgrid[:side, :side] - (side - 1) / 2
    radius = np.hypot(yy, xx)
    plane = np.where(radius < side / 2, -1000, padding)
    plane = np.where(radius < side / 4, 40, plane)
    plane = np.where((radius < side / 4) & (radius > side / 4 - 3), 800, plane)
    return np.stack([plane] * slices).astype(np.int16)


def test_the_padding_is_found_and_left_out_of_otsu():
    ct = padded_ct()
    volume = Volume(ct, meta={"units": "HU"})
    assert prep.padding_value(volume) == -3024
    assert prep.otsu_threshold(ct) < -1000 < prep.otsu_threshold(ct, -3024) < 40
    mask, info = prep.binarize(volume)
    assert -1000 < info["threshold"] < 40 and not mask[:, 0, 0].any() and mask[:, 48, 48].all()
    assert prep.padding_value(Volume(ct)) is None                      # not known to be HU: no rule
    assert prep.padding_value(Volume(ct, meta={"padding_value": -2000})) == -2000      # the DICOM tag
    air = padded_ct(padding=-1024)
    air[:, 40:56, 10:20] = -1024                                         # air clipped at -1024 HU inside too
    assert prep.padding_value(Volume(air, meta={"units": "HU"})) == -1024
    air[:, 20:76, 20:76] = np.where(air[:, 20:76, 20:76] == -1000, -1024, air[:, 20:76, 20:76])
    assert prep.padding_value(Volume(air, meta={"units": "HU"})) is None


def test_a_padded_ct_shows_the_patient(tmp_path):
    """Was: Otsu's threshold between the padding and the rest, so the picture showed the round scan field."""
    ct = padded_ct()
    write_series(tmp_path / "ct", ct + 1024, spacing=(1.0, 1.0, 1.0), intercept=-1024)
    result = run("render", tmp_path / "ct", "-o", tmp_path / "ct.png", "--stats-json", tmp_path / "ct.json")
    assert result.exit_code == 0, result.output
    report = json.loads((tmp_path / "ct.json").read_text())
    assert report["object"]["voxels"] == int((ct >= 40).sum())            # the head, not the scan circle
    assert -1000 < report["object"]["threshold"] < 40


def test_the_dicom_pixel_padding_value_is_left_out(tmp_path):
    """PixelPaddingValue (stored units; the reader rescales it) marks the padding wherever it lies."""
    import pydicom

    ct = padded_ct(padding=-1000)                   # air all round: the rule finds no padding
    ct[:, :, :10] = -3024                           # a band of padding the tag alone tells
    write_series(tmp_path / "ct", ct + 1024, spacing=(1.0, 1.0, 1.0), intercept=-1024)
    assert prep.padding_value(read_volume(tmp_path / "ct")) is None
    for path in (tmp_path / "ct").iterdir():
        ds = pydicom.dcmread(path)
        ds.add_new(0x00280120, "SS", -3024 + 1024)
        ds.save_as(path)
    volume = read_volume(tmp_path / "ct")
    assert volume.meta["padding_value"] == prep.padding_value(volume) == -3024
    _, info = prep.binarize(volume)
    assert -1000 < info["threshold"] < 40


def test_vhf_head_keeps_its_otsu_threshold():
    """The real head has no padding (air clipped at -1024 HU fills its corners and much of its circle too)."""
    volume = read_volume(data_path("vhf_head"))
    assert prep.padding_value(volume) is None
    assert prep.otsu_threshold(volume.values, prep.padding_value(volume)) == -445.2744140625


def test_a_slice_of_nan_resamples_without_a_warning():
    """Found by the fuzzing gate: scikit-image's warp clipped each resampled slice to its nanmin, which warned
    'All-NaN slice encountered' for a slice of NaN; linear interpolation needs no clip."""
    from voxrender.object.pipeline import PrepOptions, encode_volume

    values = np.full((6, 12, 12), 100, np.float32)
    values[:, 3:9, 3:9] = 900
    values[2] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        encoded = encode_volume(Volume(values, (0.7, 0.9, 1.0)), PrepOptions(threshold=500))
    assert encoded.voxel_count > 0
