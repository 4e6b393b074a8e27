"""The QC features of issue 23 through the command line: slices, projections, the QC sheet, DICOM pictures and the
batch's index page; the same options give the same pictures whichever command draws them, and bad input is one line.
"""

import json

import imageio.v3 as iio
import numpy as np
import pytest
from dicom_files import write_series
from test_cli import assert_bad_input, run

from voxrender.outputs.output import write_nifti
from voxrender.pictures.display import DisplayWindow

SHAPE = (16, 18, 20)                    # z, y, x: 1 mm voxels
CENTRE = np.array(SHAPE) // 2
BRIGHT = (8, 13, 10)                    # z, y, x of one bright voxel inside the body, 5 mm behind the centre


def body_hu():
    """A CT in HU: air around a soft-tissue ball (25 to 95 HU, denser toward the head) with a denser core (300 HU)
    and one bright voxel (3000 HU) behind the centre, so that a thin slab about the centre leaves it out.
    """
    zz, yy, xx = np.mgrid[:SHAPE[0], :SHAPE[1], :SHAPE[2]]
    r2 = (zz - CENTRE[0]) ** 2 + (yy - CENTRE[1]) ** 2 + (xx - CENTRE[2]) ** 2
    values = np.full(SHAPE, -1000, np.int16)
    values[r2 <= 49] = (20 + 5 * zz)[r2 <= 49]
    values[r2 <= 9] = 300
    values[BRIGHT] = 3000
    return values


def label_map(count=2):
    """``count`` labels of the body: boxes of two voxels along x, each in its own column of the ball."""
    labels = np.zeros(SHAPE, np.uint8)
    for k in range(count):
        labels[6:10, 7 + k % 4:8 + k % 4, 6 + 2 * (k // 4):8 + 2 * (k // 4)] = k + 1
    labels[7:9, 8:10, 9:11] = 1 if count else 0
    return labels


@pytest.fixture
def ct(tmp_path):
    (tmp_path / "in").mkdir(exist_ok=True)
    return write_nifti(tmp_path / "in" / "ct.nii.gz", body_hu())


@pytest.fixture
def seg(tmp_path):
    (tmp_path / "in").mkdir(exist_ok=True)
    return write_nifti(tmp_path / "in" / "seg.nii.gz", label_map())


@pytest.fixture
def dicom_ct(tmp_path):
    """The same body as a DICOM CT series (stored values HU + 1024), in study 1.2.3."""
    folder = tmp_path / "in" / "dicom"
    write_series(folder, body_hu().astype(np.int32) + 1024, spacing=(1.0, 1.0, 1.0))
    return folder


def rgb_of(path):
    """A PNG as RGB (a grey PNG repeated in three channels)."""
    image = iio.imread(path)
    return np.repeat(image[..., None], 3, axis=2) if image.ndim == 2 else image[..., :3]


def panel(picture, row, column, size, top=0, gap=4, caption=16):
    """Picture ``(row, column)`` of a sheet (:func:`voxrender.qc.sheet.sheet`) of ``size`` x ``size`` pictures, whose
    grid starts ``top`` pixels down.
    """
    y, x = top + gap + row * (size + caption + gap), gap + column * (size + gap)
    return picture[y:y + size, x:x + size]


# ---------------------------------------------------------------- 1. same options, same pictures

def test_render_and_batch_give_the_same_projection(tmp_path, ct):
    options = ["--threshold", "-500", "--projection", "mip", "--view", "left", "--size", "40"]
    result = run("render", ct, *options, "-o", tmp_path / "mip.png", "--stats-json", tmp_path / "mip.json")
    assert result.exit_code == 0, result.output
    result = run("batch", ct, *options, "-o", tmp_path / "out", "--jobs", "1")
    assert result.exit_code == 0, result.output
    alone, batched = iio.imread(tmp_path / "mip.png"), iio.imread(tmp_path / "out" / "ct" / "left.png")
    assert alone.shape[:2] == (40, 40) and np.array_equal(alone, batched)
    # the command pays for no surface normals (the batch, whose cache serves its surfaces too, does): same picture
    assert json.loads((tmp_path / "mip.json").read_text())["object"]["normals_from"].startswith("none")
    assert len(np.unique(alone)) > 3                        # grey values, not a silhouette


def test_slices_equal_the_sheets_slices(tmp_path, ct, seg):
    size = 48
    result = run("slices", ct, "--labels-from", seg, "--slices", "axial,sagittal", "--size", size,
                 "-o", tmp_path / "slices.png")
    assert result.exit_code == 0, result.output
    result = run("sheet", ct, "--labels-from", seg, "--threshold", "-500", "--views", "anterior",
                 "--slices", "axial,sagittal", "--size", size, "-o", tmp_path / "sheet.png")
    assert result.exit_code == 0, result.output
    slices, qc = rgb_of(tmp_path / "slices.png"), rgb_of(tmp_path / "sheet.png")
    title = 20                                               # the sheet's title band; its row 0 the surfaces
    for column in (0, 1):
        alone = panel(slices, 0, column, size)
        assert (alone != 0).any(axis=2).sum() > size * size // 4          # a slice, not a blank cell
        assert np.array_equal(alone, panel(qc, 1, column, size, top=title))


def test_slices_command_equals_the_library(tmp_path, ct, seg):
    from voxrender.object.pipeline import PrepOptions
    from voxrender.object.prep import LabelSelection
    from voxrender.qc.qc import SliceOptions, slice_pictures
    from voxrender.qc.sheet import sheet
    from voxrender.qc.study import load_study

    result = run("slices", ct, "--labels-from", seg, "--size", 40, "--overlay", "outline", "-o", tmp_path / "s.png")
    assert result.exit_code == 0, result.output
    study = load_study(ct, prepare=PrepOptions(labels=LabelSelection(None, True, seg)), encode=False)
    rows = slice_pictures(study, SliceOptions(overlay="outline", size=(40, 40)))
    expected = sheet([[rgb for _, rgb in row] for row in rows], [[caption for caption, _ in row] for row in rows])
    assert np.array_equal(rgb_of(tmp_path / "s.png"), expected)


def test_a_projection_turntable_on_dask_equals_the_worker_processes(tmp_path, ct):
    pytest.importorskip("distributed", reason="Dask is the extra 'distributed'")
    options = [ct, "--threshold", "-500", "--projection", "mip", "--turntable", "3", "--size", "24"]
    result = run("batch", *options, "-o", tmp_path / "dask", "--scheduler", "local", "--jobs", "2")
    assert result.exit_code == 0, result.output
    result = run("batch", *options, "-o", tmp_path / "one", "--jobs", "1")
    assert result.exit_code == 0, result.output
    names = sorted(p.name for p in (tmp_path / "one" / "ct").glob("*.png"))
    assert names == ["turn000.png", "turn001.png", "turn002.png"]
    for name in names:
        assert np.array_equal(iio.imread(tmp_path / "dask" / "ct" / name), iio.imread(tmp_path / "one" / "ct" / name))


# ---------------------------------------------------------------- 2. bad input: one line, exit 2, nothing written

@pytest.fixture
def vxs(tmp_path, ct):
    path = tmp_path / "in" / "ct.vxs"
    assert run("encode", ct, "--threshold", "-500", "-o", path).exit_code == 0
    return path


BAD = {
    "window width 0": (["slices", "{ct}", "--window", "40/0", "-o", "{out}/s.png"], ["--window", "width"]),
    "projection window width 0": (["render", "{ct}", "--projection", "mip", "--window", "40/-5", "-o",
                                   "{out}/p.png"], ["--window", "width"]),
    "at outside in mm": (["slices", "{ct}", "--at", "0,0,500", "-o", "{out}/s.png"], ["--at", "outside"]),
    "at outside in voxels": (["slices", "{ct}", "--at", "50,0,0vox", "-o", "{out}/s.png"], ["--at", "outside"]),
    "a DICOM picture not named .dcm": (["slices", "{ct}", "--dicom-out", "{out}/s.txt", "--dicom-study-from",
                                        "{ct}", "-o", "{out}/s.png"], ["--dicom-out", ".dcm"]),
    "the picture and the DICOM in one file": (["render", "{ct}", "--threshold", "-500", "--dicom-out", "{out}/p.png",
                                               "-o", "{out}/p.png"], ["--dicom-out", ".dcm"]),
    "the picture and a depth image in one file": (["render", "{ct}", "--threshold", "-500", "--depth-png",
                                                   "{out}/p.png", "-o", "{out}/p.png"],
                                                  ["--depth-png", "two outputs", "-o"]),
    "a label the map lacks": (["slices", "{ct}", "--labels-from", "{seg}", "--label", "9", "--at", "labels", "-o",
                               "{out}/s.png"], ["--label", "not in"]),
    "no label within the crop": (["slices", "{ct}", "--labels-from", "{seg}", "--crop", "0:2,0:2,0:2", "-o",
                                  "{out}/s.png"], ["no label", "crop"]),
    "at outside across another plane": (["slices", "{ct}", "--slices", "axial", "--at", "500,0,0vox", "-o",
                                         "{out}/s.png"], ["--at", "outside"]),
    "slab thicker than the volume": (["render", "{ct}", "--threshold", "-500", "--projection", "mip", "--slab", "500",
                                      "-o", "{out}/p.png"], ["--slab", "thicker"]),
    "dicom out of a NIfTI": (["render", "{ct}", "--threshold", "-500", "--dicom-out", "{out}/p.dcm", "-o",
                              "{out}/p.png"], ["not DICOM"]),
    "slices dicom out of a NIfTI": (["slices", "{ct}", "--dicom-out", "{out}/p.dcm", "-o", "{out}/p.png"],
                                    ["not DICOM"]),
    "overlay without labels": (["slices", "{ct}", "--overlay", "fill", "-o", "{out}/s.png"], ["--overlay", "labels"]),
    "slab without projection": (["render", "{ct}", "--threshold", "-500", "--slab", "4", "-o", "{out}/p.png"],
                                ["--slab", "projection"]),
    "projection of a vxs": (["render", "{vxs}", "--projection", "mip", "-o", "{out}/p.png"], ["grey values"]),
    "at labels without labels": (["slices", "{ct}", "--at", "labels", "-o", "{out}/s.png"], ["--at", "labels"]),
    "values out without projection": (["render", "{ct}", "--threshold", "-500", "--values-out", "{out}/v.npy", "-o",
                                       "{out}/p.png"], ["projection", "grey values"]),
    "depth out with projection": (["render", "{ct}", "--projection", "mip", "--depth-out", "{out}/d.npy", "-o",
                                   "{out}/p.png"], ["projection", "no depth"]),
    "batch slices without sheet": (["batch", "{ct}", "--slices", "axial", "-o", "{out}/batch"],
                                   ["--slices", "--sheet"]),
    "batch dicom out of a NIfTI": (["batch", "{ct}", "--threshold", "-500", "--dicom-out", "{{name}}/{{view}}.dcm",
                                    "-o", "{out}/batch"], ["not DICOM"]),
    "sheet window width 0": (["sheet", "{ct}", "--threshold", "-500", "--view", "left", "--projection", "mip",
                              "--window", "0/0", "-o", "{out}/q.png"], ["--window", "width"]),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_is_one_line_and_writes_nothing(tmp_path, ct, seg, vxs, case):
    args, words = BAD[case]
    out = tmp_path / "out"
    out.mkdir()
    result = run(*(a.format(ct=ct, seg=seg, vxs=vxs, out=out) for a in args))
    assert_bad_input(result, *words)
    assert list(out.rglob("*")) == []                        # no picture, no partial file, no folder


# ---------------------------------------------------------------- 3. DICOM pictures

def dicom_pixels(path):
    import pydicom

    ds = pydicom.dcmread(path)
    return ds, ds.pixel_array


def test_render_and_slices_write_a_dicom_of_the_source_study(tmp_path, dicom_ct):
    import pydicom

    source = pydicom.dcmread(next(dicom_ct.iterdir()), stop_before_pixels=True)
    commands = {"render": ["render", dicom_ct, "--threshold", "-500", "--projection", "mip", "--view", "anterior",
                           "--size", "32"],
                "slices": ["slices", dicom_ct, "--slices", "axial", "--size", "32"]}
    series = set()
    for name, command in commands.items():
        result = run(*command, "-o", tmp_path / f"{name}.png", "--dicom-out", tmp_path / f"{name}.dcm")
        assert result.exit_code == 0, result.output
        ds, pixels = dicom_pixels(tmp_path / f"{name}.dcm")
        assert ds.StudyInstanceUID == source.StudyInstanceUID == "1.2.3"
        assert ds.PatientID == source.get("PatientID", ds.PatientID)
        assert ds.SeriesInstanceUID != source.SeriesInstanceUID            # a new series of that study
        assert np.array_equal(pixels, rgb_of(tmp_path / f"{name}.png"))
        series.add(ds.SeriesInstanceUID)
    assert len(series) == 2


def test_dicom_study_from_joins_a_nifti_picture_to_the_series_study(tmp_path, ct, dicom_ct):
    result = run("slices", ct, "--slices", "coronal", "--size", "32", "--dicom-study-from", dicom_ct,
                 "--dicom-out", tmp_path / "s.dcm", "-o", tmp_path / "s.png")
    assert result.exit_code == 0, result.output
    ds, pixels = dicom_pixels(tmp_path / "s.dcm")
    assert ds.StudyInstanceUID == "1.2.3" and np.array_equal(pixels, rgb_of(tmp_path / "s.png"))
    result = run("render", ct, "--threshold", "-500", "--size", "32", "--dicom-study-from", dicom_ct,
                 "--dicom-out", tmp_path / "r.dcm", "-o", tmp_path / "r.png")
    assert result.exit_code == 0, result.output
    assert dicom_pixels(tmp_path / "r.dcm")[0].StudyInstanceUID == "1.2.3"


def test_a_batch_puts_a_studys_views_in_one_new_series(tmp_path, dicom_ct):
    result = run("batch", dicom_ct, "--threshold", "-500", "--view", "anterior", "--view", "left", "--size", "24",
                 "--dicom-out", "{name}/{view}.dcm", "-o", tmp_path / "out", "--jobs", "1")
    assert result.exit_code == 0, result.output
    found = {path.stem: dicom_pixels(path) for path in (tmp_path / "out").rglob("*.dcm")}
    assert sorted(found) == ["anterior", "left"]
    (front, front_pixels), (side, side_pixels) = found["anterior"], found["left"]
    assert front.SeriesInstanceUID == side.SeriesInstanceUID
    assert front.StudyInstanceUID == side.StudyInstanceUID == "1.2.3"
    assert sorted([int(front.InstanceNumber), int(side.InstanceNumber)]) == [1, 2]
    assert front.SOPInstanceUID != side.SOPInstanceUID
    png = {path.stem: rgb_of(path) for path in (tmp_path / "out").rglob("*.png") if path.parent.name != "sheets"}
    assert np.array_equal(front_pixels, png["anterior"]) and np.array_equal(side_pixels, png["left"])
    next((tmp_path / "out").rglob("left.dcm")).unlink()       # a re-run remakes it in the same series, same place
    result = run("batch", dicom_ct, "--threshold", "-500", "--view", "anterior", "--view", "left", "--size", "24",
                 "--dicom-out", "{name}/{view}.dcm", "-o", tmp_path / "out", "--jobs", "1")
    assert result.exit_code == 0 and "1 done earlier" in result.output, result.output
    again, _ = dicom_pixels(next((tmp_path / "out").rglob("left.dcm")))
    assert (again.SeriesInstanceUID, again.InstanceNumber) == (side.SeriesInstanceUID, side.InstanceNumber)


@pytest.mark.parametrize("unit", ["", "vox"])
def test_a_point_names_the_same_slice_with_and_without_a_crop(tmp_path, ct, unit):
    pictures = []
    for name, crop in (("whole", []), ("cropped", ["--crop", "0:20,0:18,4:16"])):
        result = run("slices", ct, "--slices", "axial", "--at", f"10,9,12{unit}", *crop, "--size", "32",
                     "-o", tmp_path / f"{name}.png")
        assert result.exit_code == 0, result.output
        pictures.append(panel(rgb_of(tmp_path / f"{name}.png"), 0, 0, 32))
    assert np.array_equal(*pictures)


# ---------------------------------------------------------------- 4. the QC sheet

def test_the_sheet_grows_with_its_label_table(tmp_path, ct):
    heights = {}
    for count in (2, 6):
        labels = write_nifti(tmp_path / f"seg{count}.nii.gz", label_map(count))
        path = tmp_path / f"sheet{count}.png"
        result = run("sheet", ct, "--labels-from", labels, "--threshold", "-500", "--views", "anterior,left",
                     "--slices", "axial,coronal,sagittal", "--projection", "mip", "--size", "40", "-o", path)
        assert result.exit_code == 0, result.output
        assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith("sheet")) == [
            f"sheet{c}.png" for c in (*heights, count)]              # one PNG, nothing beside it
        heights[count] = rgb_of(path).shape
    assert heights[2][1] == heights[6][1] == 3 * (40 + 4) + 4       # three columns of slices
    assert heights[6][0] > heights[2][0]


def test_batch_sheets_index_rerun_and_a_failed_study(tmp_path, ct):
    folder = ct.parent
    write_nifti(folder / "other.nii.gz", np.roll(body_hu(), 2, axis=2))
    (folder / "broken.nii.gz").write_bytes(b"not a volume")
    out = tmp_path / "out"
    command = ["batch", folder / "*.nii.gz", "--threshold", "-500", "--view", "anterior", "--projection", "mip",
               "--sheet", "--slices", "axial,coronal", "--size", "24", "-o", out, "--jobs", "1"]
    result = run(*command)
    assert result.exit_code == 2 and "broken.nii.gz" in result.stderr, result.output
    sheets = {p.name for p in (out / "sheets").iterdir()}
    assert sheets == {"ct.png", "other.png"}
    page = (out / "index.html").read_text()
    for name in ("ct", "other"):
        assert f'sheets/{name}.png"' in page
        assert rgb_of(out / "sheets" / f"{name}.png").shape[1] == 2 * (24 + 4) + 4     # two slices wide
    from voxrender.qc.index_page import read_index

    assert [study.error != "" for study in read_index(out / "index.html") if "broken.nii.gz" in study.input] == [True]
    stamps = {name: (out / "sheets" / name).stat().st_mtime_ns for name in sheets}
    result = run(*command)
    assert result.exit_code == 2 and "done earlier" in result.output, result.output
    assert {name: (out / "sheets" / name).stat().st_mtime_ns for name in sheets} == stamps


# ---------------------------------------------------------------- 5. projections

def test_a_slab_leaves_out_a_bright_voxel_behind_it(tmp_path, ct):
    values = {}
    for name, slab in (("full", []), ("slab", ["--slab", "4"])):
        result = run("render", ct, "--threshold", "-500", "--projection", "mip", "--view", "anterior", "--size", "40",
                     *slab, "--window", "1500/3000", "--values-out", tmp_path / f"{name}.npy",
                     "-o", tmp_path / f"{name}.png")
        assert result.exit_code == 0, result.output
        values[name] = np.load(tmp_path / f"{name}.npy")
    assert np.nanmax(values["full"]) == 3000                 # seen through the whole body
    assert np.nanmax(values["slab"]) == 300                  # the core, but not the voxel 5 mm behind the centre
    full, slab = rgb_of(tmp_path / "full.png"), rgb_of(tmp_path / "slab.png")
    assert (full == 255).all(axis=2).any() and not (slab == 255).any()      # the voxel's pixels, white no more


def test_values_out_is_float32_with_nan_where_rays_miss_and_the_window_maps_them(tmp_path, ct):
    result = run("render", ct, "--threshold", "-500", "--projection", "mip", "--view", "left", "--size", "48",
                 "--scale", "1", "--window", "0/100", "--values-out", tmp_path / "v.npy", "-o", tmp_path / "p.png")
    assert result.exit_code == 0, result.output
    values = np.load(tmp_path / "v.npy")
    assert values.dtype == np.float32 and values.shape == (48, 48)
    missed = np.isnan(values)
    assert missed.any() and (~missed).sum() == SHAPE[0] * SHAPE[1]     # a ray per voxel of the side at scale 1
    grey = rgb_of(tmp_path / "p.png")
    assert (grey[missed] == 0).all()                                   # the background, black
    expected = DisplayWindow(0, 100).to_uint8(values[~missed])
    assert np.array_equal(grey[~missed], np.repeat(expected[:, None], 3, axis=1))
    assert len(np.unique(expected)) > 2                                # the window spreads them


def test_a_projection_is_shown_through_one_window_for_every_view(tmp_path, dicom_ct):
    from voxrender.io import read_volume
    from voxrender.pictures.display import auto_window

    window = auto_window(read_volume(dicom_ct).values.max(axis=1))        # its MIP along y: the top of its values
    for view in ("left", "anterior"):
        result = run("render", dicom_ct, "--threshold", "-500", "--projection", "mip", "--view", view, "--size", "32",
                     "--values-out", tmp_path / f"{view}.npy", "-o", tmp_path / f"{view}.png")
        assert result.exit_code == 0, result.output
        values = np.load(tmp_path / f"{view}.npy")
        seen = np.isfinite(values)
        assert np.array_equal(rgb_of(tmp_path / f"{view}.png")[seen][:, 0], window.to_uint8(values[seen]))


def test_labels_out_of_a_projection_lists_its_labels(tmp_path, ct, seg):
    import json

    result = run("render", ct, "--labels-from", seg, "--projection", "mip", "--size", "32",
                 "--labels-out", tmp_path / "l.json", "-o", tmp_path / "p.png")
    assert result.exit_code == 0, result.output
    assert [row["label"] for row in json.loads((tmp_path / "l.json").read_text())["labels"]] == [1, 2]


def test_a_legend_on_a_projection_is_drawn_or_refused(tmp_path, ct, seg):
    made = {}
    for name, legend in (("plain", []), ("legend", ["--legend"])):
        result = run("render", ct, "--labels-from", seg, "--projection", "mip", "--size", "48", *legend,
                     "-o", tmp_path / f"{name}.png")
        made[name] = result
    if made["legend"].exit_code:
        assert_bad_input(made["legend"], "--legend")
    else:
        assert not np.array_equal(rgb_of(tmp_path / "plain.png"), rgb_of(tmp_path / "legend.png"))


def test_a_window_without_a_projection_is_refused(tmp_path, ct):
    out = tmp_path / "out"
    out.mkdir()
    assert_bad_input(run("render", ct, "--threshold", "-500", "--window", "40/400", "-o", out / "s.png"), "--window")
    assert list(out.iterdir()) == []


# ---------------------------------------------------------------- 6. notebook display

def test_a_picture_shows_itself_as_png():
    import io

    import voxrender
    from voxrender.object.segments import encode

    result = voxrender.picture(encode(body_hu() > 0), voxrender.View(30, 20, size=(24, 32), scale=1.0))
    data = result._repr_png_()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert np.array_equal(iio.imread(io.BytesIO(data)), result.rgb)


def test_a_volume_kept_in_its_stored_order_gets_no_patient_directions():
    from voxrender.io import Volume
    from voxrender.qc.qc import SliceOptions, slice_pictures
    from voxrender.qc.study import Study

    def yellow(meta):
        study = Study(Volume(np.arange(6 * 7 * 8, dtype=np.float32).reshape(6, 7, 8), (1.0, 1.0, 1.0), meta))
        rgb = slice_pictures(study, SliceOptions(("axial",), size=(64, 64)))[0][0][1]
        return ((rgb[..., 0] > 200) & (rgb[..., 1] > 150) & (rgb[..., 2] < 60)).any()    # the letters' colour

    assert yellow({"orientation": "RAS", "reoriented": "RAS -> LPS: flipped x, y"}) and yellow({})
    assert not yellow({"orientation": "RAS"})                                           # --no-reorient


def test_orientation_marks_on_a_volume_kept_in_its_stored_order_are_a_warning(tmp_path):
    import nibabel as nib

    values = np.full((8, 9, 10), -1000, np.int16)
    values[2:6, 2:7, 2:8] = 500
    nib.save(nib.Nifti1Image(values, np.diag([1.0, 1.0, 1.0, 1.0])), tmp_path / "ras.nii.gz")
    result = run("render", tmp_path / "ras.nii.gz", "--no-reorient", "--threshold", "0", "--orientation-marks",
                 "--size", "32", "-o", tmp_path / "p.png")
    assert result.exit_code == 0 and "no patient directions" in result.output


def test_a_slab_is_measured_in_mm_on_a_grid_kept_as_it_is(tmp_path):
    import json

    values = np.full((20, 12, 10), -1000, np.int16)            # 20 slices 2.5 mm apart: 50 mm along z
    values[2:18, 3:9, 3:7] = 40
    values[15, 6, 5] = 2000                                    # 7.5 mm above the centre (9.5 slices up)
    ct = write_nifti(tmp_path / "ct.nii.gz", values, spacing=(0.8, 1.0, 2.5))
    base = ["render", ct, "--threshold", "0", "--projection", "mip", "--view", "inferior", "--no-resample",
            "--size", "32"]
    assert_bad_input(run(*base, "--slab", "60", "-o", tmp_path / "thick.png"), "--slab", "thicker")
    for slab, brightest in (("10", 40), ("40", 2000)):
        result = run(*base, "--slab", slab, "--stats-json", tmp_path / "s.json", "--values-out", tmp_path / "v.npy",
                     "-o", tmp_path / "p.png")
        assert result.exit_code == 0, result.output
        low, high = json.loads((tmp_path / "s.json").read_text())["stats"]["slab"]
        assert (high - low) * 2.5 == pytest.approx(float(slab))           # Z' in slices of 2.5 mm
        assert np.nanmax(np.load(tmp_path / "v.npy")) == brightest
