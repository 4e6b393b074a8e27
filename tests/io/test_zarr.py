"""voxrender.io.zarr: Zarr arrays (formats 2 and 3) and OME-Zarr images (NGFF 0.4 and 0.5).

The files are written with zarr.  ome-zarr's writer could not be installed beside this project's pinned fsspec (its
s3fs dependency wants an older one), so the OME-Zarr images are zarr groups whose attributes are written as the
NGFF specification lays them out (0.4: ``multiscales`` in a format-2 group's attributes; 0.5: under ``"ome"`` in a
format-3 group's).
"""

import shutil
import subprocess
import sys

import numpy as np
import pytest
import zarr
from formats import random_stack, refused_cuts

from voxrender import io
from voxrender.errors import InputError
from voxrender.io import zarr as zarr_io
from voxrender.io._shared import identity_progress


def write_ome(path, values, version="0.4", units=("micrometer", "micrometer", "nanometer"), scale=(2.0, 0.5, 250.0),
              translation=(10.0, 20.0, 30000.0), count=3, orientations=None, channel_names=None):
    """An OME-Zarr image of ``count`` levels (each half the last along every spatial axis) of ``values``, whose
    axes are t, c, z, y, x when it has five (else z, y, x); ``scale`` and ``translation`` are those of level 0
    (z, y, x, in ``units``)."""
    fmt = 2 if version == "0.4" else 3
    group = zarr.open_group(str(path), mode="w", zarr_format=fmt)
    lead = values.ndim - 3
    axes = [{"name": "t", "type": "time", "unit": "second"}, {"name": "c", "type": "channel"}][2 - lead:]
    for name, unit, side in zip("zyx", units, orientations or (None,) * 3, strict=True):
        axes.append({"name": name, "type": "space", "unit": unit} |
                    ({"orientation": {"type": "anatomical", "value": side}} if side else {}))
    datasets = []
    for k in range(count):
        step = (slice(None),) * lead + (slice(None, None, 2 ** k),) * 3
        group.create_array(str(k), data=np.ascontiguousarray(values[step]), chunks=(1,) * lead + (2, 4, 4))
        datasets.append({"path": str(k), "coordinateTransformations": [
            {"type": "scale", "scale": [1.0] * lead + [s * 2 ** k for s in scale]},
            {"type": "translation", "translation": [0.0] * lead + list(translation)}]})
    multiscales = [{"name": "image", "axes": axes, "datasets": datasets} | ({"version": version} if fmt == 2 else {})]
    attributes = {"multiscales": multiscales}
    if channel_names:
        attributes["omero"] = {"channels": [{"label": name} for name in channel_names]}
    group.attrs.update(attributes if fmt == 2 else {"ome": {"version": version, **attributes}})
    return path


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_plain_arrays(tmp_path, zarr_format):
    stack = random_stack()
    zarr.create_array(store=str(tmp_path / "v.zarr"), data=stack, chunks=(2, 4, 3), zarr_format=zarr_format)
    volume = zarr_io.read_zarr(tmp_path / "v.zarr", identity_progress)
    assert np.array_equal(volume.values, stack) and volume.spacing == (1.0, 1.0, 1.0)
    assert volume.meta["level"] == 0 and volume.meta["levels"] == [stack.shape] and volume.direction is None


def test_big_endian_and_half_floats_come_in_native_order(tmp_path):
    stack = random_stack()
    zarr.create_array(store=str(tmp_path / "big.zarr"), data=stack.astype(">u2"), zarr_format=2)
    values = zarr_io.open_zarr(tmp_path / "big.zarr").read()
    assert values.dtype == np.dtype("=u2") and np.array_equal(values, stack)
    zarr.create_array(store=str(tmp_path / "half.zarr"), data=stack.astype(np.float16))
    stack16 = zarr_io.open_zarr(tmp_path / "half.zarr")
    assert stack16.dtype == np.float32 and np.array_equal(stack16.read(), stack.astype(np.float16))


def test_a_group_of_one_array_reads_it_and_one_of_two_names_them(tmp_path):
    stack = random_stack()
    group = zarr.open_group(str(tmp_path / "g.zarr"), mode="w")
    group.create_array("volume", data=stack)
    assert np.array_equal(zarr_io.read_zarr(tmp_path / "g.zarr", None).values, stack)
    group.create_array("other", data=stack)
    with pytest.raises(InputError, match=r"g.zarr is a Zarr group of 2 arrays .*(volume|other).*; give the folder"):
        zarr_io.read_zarr(tmp_path / "g.zarr", None)


def test_leading_axes_of_one_are_dropped_and_others_refused(tmp_path):
    stack = random_stack()
    zarr.create_array(store=str(tmp_path / "v.zarr"), data=stack[None])
    assert np.array_equal(zarr_io.read_zarr(tmp_path / "v.zarr", None).values, stack)
    zarr.create_array(store=str(tmp_path / "flat.zarr"), data=stack[0])
    with pytest.raises(InputError, match="flat.zarr holds a 6x7 array; voxrender needs a 3-D array"):
        zarr_io.read_zarr(tmp_path / "flat.zarr", None)


@pytest.mark.parametrize("version", ["0.4", "0.5"])
def test_ome_zarr_levels_spacing_and_origin(tmp_path, version):
    values = random_stack((8, 12, 16))
    path = write_ome(tmp_path / "image.ome.zarr", values, version)
    volume = zarr_io.read_zarr(path, None)
    assert np.array_equal(volume.values, values)
    # x in nanometres, y and z in micrometres: spacing (x, y, z) in mm
    assert volume.spacing == pytest.approx((250e-6, 0.5e-3, 2e-3))
    assert volume.meta["origin"] == pytest.approx([0.03, 0.02, 0.01])
    assert volume.meta["levels"] == [(8, 12, 16), (4, 6, 8), (2, 3, 4)]
    assert volume.meta["spacing_from"] == f"OME-Zarr {version} scale" and volume.direction is None
    coarse = zarr_io.read_zarr(path, None, level=2)
    assert np.array_equal(coarse.values, values[::4, ::4, ::4]) and coarse.meta["level"] == 2
    assert coarse.spacing == pytest.approx((1e-3, 2e-3, 8e-3))
    assert zarr_io.levels(path) == [(8, 12, 16), (4, 6, 8), (2, 3, 4)]


def test_a_level_that_does_not_exist_is_refused_naming_the_levels(tmp_path):
    path = write_ome(tmp_path / "image.ome.zarr", random_stack((8, 12, 16)))
    with pytest.raises(InputError, match=r"has no level 3; its levels \(z, y, x\) are 0 \(8, 12, 16\), "
                                         r"1 \(4, 6, 8\), 2 \(2, 3, 4\), 0 the finest") as caught:
        zarr_io.read_zarr(path, None, level=3)
    assert caught.value.parameter == "level"
    zarr.create_array(store=str(tmp_path / "v.zarr"), data=random_stack())
    with pytest.raises(InputError, match=r"has no level 1; its levels \(z, y, x\) are 0 \(5, 6, 7\)"):
        zarr_io.open_zarr(tmp_path / "v.zarr", level=1)


def test_choose_level_takes_the_finest_that_fits_the_picture(tmp_path):
    path = write_ome(tmp_path / "image.ome.zarr", random_stack((8, 12, 16)))
    assert [zarr_io.choose_level(path, pixels) for pixels in (100, 16, 15, 8, 4, 1)] == [0, 0, 1, 1, 2, 2]


def test_units_without_a_known_length_are_taken_as_mm_and_said(tmp_path):
    path = write_ome(tmp_path / "image.ome.zarr", random_stack((8, 12, 16)), units=("millimeter", "furlong", None))
    volume = zarr_io.read_zarr(path, None)
    assert volume.spacing == pytest.approx((250.0, 0.5, 2.0))
    assert volume.meta["spacing_from"] == "OME-Zarr 0.4 scale, taken as mm for y (furlong), x (no unit)"


def test_five_axes_with_one_time_point_and_one_channel(tmp_path):
    values = random_stack((8, 12, 16))
    path = write_ome(tmp_path / "image.ome.zarr", values[None, None], "0.5")
    volume = zarr_io.read_zarr(path, None, level=1)
    assert np.array_equal(volume.values, values[::2, ::2, ::2])
    assert volume.spacing == pytest.approx((0.5e-3, 1e-3, 4e-3))


def test_more_channels_are_refused_naming_them(tmp_path):
    values = np.stack([random_stack((8, 12, 16), seed) for seed in range(2)])[None]
    path = write_ome(tmp_path / "image.ome.zarr", values, channel_names=["DAPI", "GFP"])
    with pytest.raises(InputError, match=r"holds 2 channels \(axis 'c': DAPI, GFP\); voxrender reads one time point "
                                         "of one channel"):
        zarr_io.read_zarr(path, None)
    path = write_ome(tmp_path / "times.ome.zarr", np.moveaxis(values, 0, 1))
    with pytest.raises(InputError, match=r"holds 2 time points \(axis 't'\)"):
        zarr_io.open_zarr(path)


def test_slabs_read_from_open_zarr_make_read_zarr(tmp_path):
    values = random_stack((9, 12, 16))
    path = write_ome(tmp_path / "image.ome.zarr", values[None, None], "0.5")
    stack = zarr_io.open_zarr(path)
    assert stack.shape == (9, 12, 16) and stack.dtype == np.uint16
    slabs = [stack.read_slices(z0, min(z0 + 3, 9)) for z0 in range(0, 9, 3)]        # across the chunks of 2 slices
    assert np.array_equal(np.concatenate(slabs), zarr_io.read_zarr(path, None).values)
    assert stack.spacing == zarr_io.read_zarr(path, None).spacing


def test_a_slab_reads_only_its_chunks(tmp_path):
    """A garbled chunk past the slab is not read: the slab comes whole, the whole array is refused."""
    zarr.create_array(store=str(tmp_path / "v.zarr"), data=random_stack((6, 4, 4)), chunks=(2, 4, 4), zarr_format=3)
    (tmp_path / "v.zarr" / "c" / "2" / "0" / "0").write_bytes(b"garbled")
    stack = zarr_io.open_zarr(tmp_path / "v.zarr")
    assert stack.read_slices(0, 4).shape == (4, 4, 4)
    with pytest.raises(InputError, match=r"v.zarr: the chunks holding slices 3 to 5 are damaged"):
        stack.read_slices(3, 6)


def test_missing_chunks_are_the_fill_value(tmp_path):
    array = zarr.create_array(store=str(tmp_path / "v.zarr"), shape=(4, 4, 4), chunks=(2, 4, 4), dtype=np.int16,
                              fill_value=-7, zarr_format=2)
    array[2:] = 5
    values = zarr_io.read_zarr(tmp_path / "v.zarr", None).values
    assert (values[:2] == -7).all() and (values[2:] == 5).all()


def test_booleans_become_zero_and_one_and_strings_are_refused(tmp_path):
    mask = random_stack() > 1500
    zarr.create_array(store=str(tmp_path / "mask.zarr"), data=mask)
    stack = zarr_io.open_zarr(tmp_path / "mask.zarr")
    assert stack.dtype == np.uint8 and np.array_equal(stack.read(), mask)
    zarr.create_array(store=str(tmp_path / "words.zarr"), data=np.full((2, 2, 2), "word"), zarr_format=2)
    with pytest.raises(InputError, match="words.zarr holds .* values; voxrender needs a numeric array"):
        zarr_io.read_zarr(tmp_path / "words.zarr", None)


@pytest.mark.parametrize(("zarr_format", "name"), [(2, ".zarray"), (2, ".zattrs"), (3, "zarr.json")])
def test_garbled_metadata_is_bad_input(tmp_path, zarr_format, name):
    array = zarr.create_array(store=str(tmp_path / "v.zarr"), data=random_stack(), zarr_format=zarr_format)
    array.attrs["note"] = "a note"                                       # so that format 2 writes a .zattrs
    metadata = tmp_path / "v.zarr" / name
    assert refused_cuts(metadata, lambda: zarr_io.read_zarr(tmp_path / "v.zarr", None)) >= 5
    text = metadata.read_bytes()
    for garbled in (text.replace(b'"', b"'"), text.rstrip()[:-1], b"\xff\xfe" + text[2:]):
        metadata.write_bytes(garbled)
        with pytest.raises(InputError, match="v.zarr"):
            zarr_io.read_zarr(tmp_path / "v.zarr", None)


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_cut_chunks_are_bad_input(tmp_path, zarr_format):
    zarr.create_array(store=str(tmp_path / "v.zarr"), data=random_stack(), chunks=(5, 6, 7), zarr_format=zarr_format)
    chunk = next(p for p in (tmp_path / "v.zarr").rglob("*") if p.is_file() and p.name[0].isdigit())
    assert refused_cuts(chunk, lambda: zarr_io.read_zarr(tmp_path / "v.zarr", None)) >= 30


@pytest.mark.parametrize("zarr_format", [2, 3])
def test_a_damaged_chunk_leaves_no_chunk_read_pending_at_exit(tmp_path, zarr_format):
    """zarr gathers a slab's chunk reads on its event loop and stops at the first that fails: the others are waited
    for, so the process ends on the error alone (fuzz case zarr/zarr_format=2 2.2.0 empty: "Task was destroyed
    but it is pending!" and "Event loop is closed" after it)."""
    zarr.create_array(store=str(tmp_path / "v.zarr"), data=random_stack((12, 16, 16)), chunks=(4, 4, 4),
                      zarr_format=zarr_format)
    chunks = sorted(p for p in (tmp_path / "v.zarr").rglob("*") if p.is_file() and p.name[0].isdigit())
    chunks[0].write_bytes(b"")
    script = ("import pathlib, sys; from voxrender.io import zarr as z; from voxrender.errors import InputError\n"
              "try:\n    z.read_zarr(pathlib.Path(sys.argv[1]), None)\nexcept InputError as e:\n    print(e)\n")
    done = subprocess.run([sys.executable, "-c", script, str(tmp_path / "v.zarr")], capture_output=True, text=True,
                          timeout=60)
    assert "are damaged" in done.stdout and done.stderr == ""


@pytest.mark.parametrize("version", ["0.4", "0.5"])
def test_damaged_ome_zarr_is_bad_input(tmp_path, version):
    path = write_ome(tmp_path / "image.ome.zarr", random_stack((8, 12, 16)), version)
    shutil.rmtree(path / "1")
    with pytest.raises(InputError, match=r"image.ome.zarr: the dataset '1' that its multiscales metadata names is "
                                         "missing"):
        zarr_io.read_zarr(path, None)
    path = write_ome(tmp_path / "image.ome.zarr", random_stack((8, 12, 16)), version)
    group = zarr.open_group(str(path), mode="r+")
    attributes = group.attrs.asdict()
    inner = attributes["ome"] if version == "0.5" else attributes
    inner["multiscales"][0]["datasets"][0]["coordinateTransformations"][0]["scale"] = [1.0, "two"]
    group.attrs.update(attributes)
    with pytest.raises(InputError, match=r"the OME-Zarr metadata of .*image.ome.zarr is damaged: dataset '0''s scale"):
        zarr_io.read_zarr(path, None)
    metadata = path / (".zattrs" if version == "0.4" else "zarr.json")
    assert refused_cuts(metadata, lambda: zarr_io.read_zarr(path, None)) >= 5


def test_a_folder_without_zarr_metadata_is_bad_input(tmp_path):
    (tmp_path / "empty.zarr").mkdir()
    with pytest.raises(InputError, match="empty.zarr holds no Zarr metadata"):
        zarr_io.read_zarr(tmp_path / "empty.zarr", None)


def test_anatomical_axes_give_the_direction(tmp_path):
    values = random_stack((8, 12, 16))
    path = write_ome(tmp_path / "image.ome.zarr", values, orientations=("superior-to-inferior",
                                                                        "anterior-to-posterior", "left-to-right"))
    stack = zarr_io.open_zarr(path)
    assert stack.direction.astype(int).tolist() == [[-1, 0, 0], [0, 1, 0], [0, 0, -1]]         # x R, y P, z I
    assert stack.meta["orientation_from"] == "OME-Zarr axes' anatomical orientation (NGFF RFC-4)"
    path = write_ome(tmp_path / "twice.ome.zarr", values, orientations=("left-to-right", "anterior-to-posterior",
                                                                        "left-to-right"))
    assert zarr_io.open_zarr(path).direction is None


def test_holds_zarr(tmp_path):
    zarr.create_array(store=str(tmp_path / "v.zarr"), data=random_stack(), zarr_format=2)
    write_ome(tmp_path / "image.ome.zarr", random_stack((8, 12, 16)), "0.5")
    (tmp_path / "other").mkdir()
    assert [zarr_io.holds_zarr(tmp_path / name) for name in ("v.zarr", "image.ome.zarr", "other")] == \
        [True, True, False]


def test_read_volume_and_open_stack_find_zarr(tmp_path):
    values = random_stack((8, 12, 16))
    path = write_ome(tmp_path / "image.ome.zarr", values, "0.5",
                     orientations=("inferior-to-superior", "posterior-to-anterior", "right-to-left"))
    volume = io.read_volume(path, level=1)
    assert volume.meta["format"] == "zarr" and volume.meta["level"] == 1
    assert volume.meta["orientation"] == "LAS" and volume.meta["reoriented"].startswith("LAS -> LPS")
    assert np.array_equal(volume.values, values[::2, ::2, ::2][:, ::-1])
    stack = io.open_stack(path, level=1)
    assert np.array_equal(stack.read_slices(0, stack.shape[0]), volume.values)
    zarr.create_array(store=str(tmp_path / "plain"), data=values, zarr_format=2)      # no suffix: sniffed
    assert np.array_equal(io.read_volume(tmp_path / "plain").values, values)


def test_render_picks_the_level_that_suits_the_picture_and_says_so(tmp_path):
    from click.testing import CliRunner

    from voxrender.cli import main

    z, y, x = np.mgrid[:32, :48, :64]
    ball = (((x - 32) / 24) ** 2 + ((y - 24) / 18) ** 2 + ((z - 16) / 12) ** 2 < 1).astype(np.uint8) * 100
    write_ome(tmp_path / "ball.ome.zarr", ball, scale=(1.0, 1.0, 1.0), units=("millimeter",) * 3)
    runner = CliRunner()
    done = runner.invoke(main, ["render", str(tmp_path / "ball.ome.zarr"), "--threshold", "50", "--size", "40",
                                "-o", str(tmp_path / "small.png")])
    assert done.exit_code == 0, done.output
    assert "level 1 of its 3 levels" in done.output            # 32x24x16 fits 40 pixels; 64x48x32 does not
    done = runner.invoke(main, ["render", str(tmp_path / "ball.ome.zarr"), "--threshold", "50", "--size", "40",
                                "--level", "0", "-o", str(tmp_path / "fine.png")])
    assert done.exit_code == 0 and "level" not in done.output, done.output
    done = runner.invoke(main, ["encode", str(tmp_path / "ball.ome.zarr"), "--threshold", "50", "--level", "2",
                                "--max-memory", "1K", "-o", str(tmp_path / "coarse.vxs")])
    assert done.exit_code == 0 and "16x12x8 voxels" in done.output and "streamed" in done.output, done.output
