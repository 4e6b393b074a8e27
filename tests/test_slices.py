"""Slices with label overlays: orientation (proved on the view contract), true aspect, overlays, points, labels."""

from pathlib import Path

import numpy as np
import pytest
from conftest import data_path
from scipy import ndimage

from voxrender.errors import InputError
from voxrender.io import Volume
from voxrender.pictures.display import CT_WINDOWS, DisplayWindow
from voxrender.pictures.marks import edge_letters
from voxrender.qc.slices import PLANES, SlicePoint, label_slices, plane_image, round_length, slice_index, slice_picture
from voxrender.space.view import View

SHAPE = (6, 7, 8)                         # nz, ny, nx: every axis its own length, so a wrong turn shows
BLACK = DisplayWindow(1000, 10)           # every value below 995 is black
RED = (255, 0, 0)


def coded(shape=SHAPE):
    """A volume whose every voxel holds its own grid point: ``values[z, y, x] = (x, y, z)``."""
    zz, yy, xx = np.indices(shape)
    return np.stack([xx, yy, zz], axis=-1)


@pytest.mark.parametrize("plane", PLANES)
def test_plane_reads_as_its_view_preset_sees_it(plane):
    """Each pixel's voxel, mapped by the preset's View.to_image: X' grows along the columns, Y' down the rows,
    and Z' (the depth) is one for the whole slice: the picture is the renderers' picture of that preset."""
    values = coded()
    index = 2
    image, _ = plane_image(values, (1, 1, 1), plane, index)
    xs, ys, zs = View.preset(PLANES[plane]).to_image(image[..., 0], image[..., 1], image[..., 2], SHAPE)
    assert np.ptp(zs) == 0
    assert (np.diff(xs, axis=1) == 1).all() and (np.diff(xs, axis=0) == 0).all()
    assert (np.diff(ys, axis=0) == 1).all() and (np.diff(ys, axis=1) == 0).all()


@pytest.mark.parametrize("plane", PLANES)
def test_edge_letters_name_the_sides_the_picture_shows(plane):
    """A mark on each side of the patient (at the volume's faces) lands at the edge whose letter names it."""
    values = coded()
    image, _ = plane_image(values, (1, 1, 1), plane, 1)
    letters = edge_letters(View.preset(PLANES[plane]))
    toward = {"L": (0, 1), "R": (0, -1), "P": (1, 1), "A": (1, -1), "S": (2, 1), "I": (2, -1)}
    ends = [n - 1 for n in SHAPE[::-1]]                          # the largest x, y, z
    for edge, letter in letters.items():
        axis, sign = toward[letter]
        on_side = image[..., axis] == (ends[axis] if sign > 0 else 0)
        rows, columns = np.nonzero(on_side)
        where = {"left": (columns == 0).all(), "right": (columns == image.shape[1] - 1).all(),
                 "top": (rows == 0).all(), "bottom": (rows == image.shape[0] - 1).all()}
        assert rows.size and where[edge], (plane, edge, letter)


def test_the_radiological_conventions():
    """Axial from the feet: the patient's left on the right, the front up; coronal and sagittal: the head up,
    sagittal seen from the left: the front on the left."""
    assert edge_letters(View.preset(PLANES["axial"])) == {"left": "R", "right": "L", "top": "A", "bottom": "P"}
    assert edge_letters(View.preset(PLANES["coronal"])) == {"left": "R", "right": "L", "top": "S", "bottom": "I"}
    assert edge_letters(View.preset(PLANES["sagittal"])) == {"left": "A", "right": "P", "top": "S", "bottom": "I"}
    volume = np.zeros((20, 20, 20))
    volume[8:12, 8:12, 15:] = 1                                  # a mark on the patient's left (large x)
    for plane in ("axial", "coronal"):
        image, _ = plane_image(volume, (1, 1, 1), plane, 10)
        columns = np.nonzero(image)[1]
        assert columns.min() >= 15, plane


def test_true_aspect_of_anisotropic_voxels():
    """0.5 x 0.5 x 2 mm voxels: the coronal picture is as many mm high as the slices are thick."""
    nz, ny, nx = 10, 6, 24
    values = np.zeros((nz, ny, nx))
    image, pixel_mm = plane_image(values, (0.5, 0.5, 2.0), "coronal", 3)
    assert image.shape == (nz, nx) and pixel_mm == (2.0, 0.5)
    picture = slice_picture(image, pixel_mm, BLACK, overlay=None, scale_bar=False)
    height, width = picture.shape[:2]
    assert height / width == pytest.approx((nz * 2.0) / (nx * 0.5))
    assert (height, width) == (40, 24)                           # at the finer spacing, 0.5 mm a pixel


def test_fitted_slice_is_letterboxed_and_centred():
    labels = np.ones((10, 20), np.uint8)
    picture = slice_picture(np.zeros((10, 20)), (1.0, 1.0), BLACK, labels, {1: ("all", RED)}, opacity=1.0,
                            size=(100, 60), scale_bar=False, background=(0, 0, 255))
    assert picture.shape == (100, 60, 3)
    red = (picture == RED).all(axis=2)
    rows, columns = np.nonzero(red)
    assert (columns.min(), columns.max()) == (0, 59)
    assert (rows.min(), rows.max() + 1) == (35, 65)                # 30 rows of 60 / 20 * 10, in the middle
    assert (picture[~red] == (0, 0, 255)).all()


def disc(size=24, radius=7.0):
    yy, xx = np.mgrid[:size, :size]
    return ((yy - 11.5) ** 2 + (xx - 11.5) ** 2 <= radius ** 2).astype(np.uint8)


@pytest.mark.parametrize("factor", [1, 4])
def test_outline_is_one_pixel_wide(factor):
    labels = disc()
    size = (24 * factor, 24 * factor)
    picture = slice_picture(np.zeros(labels.shape), (1.0, 1.0), BLACK, labels, {1: ("disc", RED)},
                            overlay="outline", size=size, scale_bar=False)
    outline = (picture == RED).all(axis=2)
    shown = np.kron(labels, np.ones((factor, factor), np.uint8)).astype(bool)       # the disc as drawn
    assert (outline == (shown & ~ndimage.binary_erosion(shown))).all()
    middle = outline[size[0] // 2]
    assert middle.sum() == 2                                     # crossing the disc meets its rim twice, once each
    assert (picture[~outline] == 0).all()                        # unfilled: the rest keeps its (black) grey


@pytest.mark.parametrize("opacity", [0.0, 0.25, 0.4, 1.0])
def test_fill_colour_at_the_given_opacity(opacity):
    window = DisplayWindow(0, 255)
    grey = np.full((4, 4), 100.0 - 127.5)                        # 100 through the window
    assert window.to_uint8(grey)[0, 0] == 100
    labels = np.zeros((4, 4), np.uint8)
    labels[1:3, 1:3] = 3
    colour = (200, 40, 10)
    picture = slice_picture(grey, (1.0, 1.0), window, labels, {3: ("x", colour)}, opacity=opacity,
                            scale_bar=False)
    expected = np.rint(100 * (1 - opacity) + np.array(colour) * opacity)
    assert (picture[1:3, 1:3] == expected).all()
    assert (picture[0] == 100).all()


def test_both_fills_and_outlines():
    labels = disc()
    picture = slice_picture(np.zeros(labels.shape), (1.0, 1.0), BLACK, labels, {1: ("disc", (200, 0, 0))},
                            overlay="both", opacity=0.5, scale_bar=False)
    assert tuple(picture[12, 12]) == (100, 0, 0)                 # inside: half
    assert tuple(picture[12, 5]) == (200, 0, 0)                  # on the rim: the full colour


def test_window_maps_the_grey():
    window = DisplayWindow(40, 80)
    grey = np.array([[0.0, 40.0, 80.0, 1000.0]])
    picture = slice_picture(grey, (1.0, 1.0), window, overlay=None, scale_bar=False)
    assert picture[0, :, 0].tolist() == [0, 128, 255, 255]
    assert (picture[..., 0] == picture[..., 2]).all()


def test_grey_is_resampled_linearly_and_labels_to_the_nearest():
    grey = np.array([[0.0, 0.0, 100.0, 100.0]])                  # one row, 4 mm a row: four screen rows
    labels = np.array([[0, 1, 2, 0]])
    picture = slice_picture(grey, (4.0, 1.0), DisplayWindow(50, 100), labels, {1: ("a", RED), 2: ("b", RED)},
                            overlay="outline", scale_bar=False)
    assert picture.shape == (4, 4, 3)
    assert (picture[:, 0, 0] == 0).all() and (picture[:, 3, 0] == 255).all()
    assert (picture[:, 1:3] == RED).all()                           # each label a whole column, at every row


def test_many_labels_take_their_colours_from_one_lookup():
    yy, xx = np.mgrid[:200, :200]
    labels = (yy // 10 * 20 + xx // 10 + 1).astype(np.uint16)      # 400 labels, 10 x 10 pixels each
    rng = np.random.default_rng(1)
    colours = rng.integers(0, 256, (401, 3))
    table = {k: (f"l{k}", tuple(int(c) for c in colours[k])) for k in range(1, 401)}
    picture = slice_picture(np.zeros(labels.shape), (1.0, 1.0), BLACK, labels, table, opacity=1.0,
                            scale_bar=False)
    assert (picture == colours[labels]).all()
    with_legend = slice_picture(np.zeros(labels.shape), (1.0, 1.0), BLACK, labels, table, legend=True,
                                scale_bar=False)
    plain = slice_picture(np.zeros(labels.shape), (1.0, 1.0), BLACK, labels, table, scale_bar=False)
    assert with_legend.shape[1] > plain.shape[1]               # 400 names: beside the slice, not over it
    assert np.array_equal(with_legend[:, :plain.shape[1]], plain)


def test_labels_without_a_table_take_the_palette():
    from voxrender.pictures.colours import label_colours

    labels = np.zeros((4, 4), np.uint8)
    labels[:2] = 5
    picture = slice_picture(np.zeros((4, 4)), (1.0, 1.0), BLACK, labels, opacity=1.0, scale_bar=False)
    assert tuple(picture[0, 0]) == label_colours([5])[5][1]


def test_legend_lists_only_the_labels_the_slice_shows():
    labels = np.zeros((120, 160), np.uint8)
    labels[10:20, 10:20] = 2
    table = {1: ("absent", (0, 255, 0)), 2: ("shown", (255, 0, 255))}
    picture = slice_picture(np.zeros(labels.shape), (1.0, 1.0), BLACK, labels, table, opacity=0.0, legend=True,
                            scale_bar=False)
    assert (picture == (255, 0, 255)).all(axis=2).any()
    assert not (picture == (0, 255, 0)).all(axis=2).any()
    assert picture.shape == (120, 160, 3)                      # one name: in the corner, the picture unchanged


def test_scale_bar_is_a_round_length_of_a_fifth_of_the_width():
    assert [round_length(v) for v in (0.9, 1.6, 4.0, 12.0, 28.0, 102.4)] == [1, 2, 5, 10, 20, 100]
    picture = slice_picture(np.zeros((100, 200)), (0.5, 0.5), BLACK, overlay=None)        # 100 mm wide
    white = (picture == 255).all(axis=2)
    assert not white[:, :100].any()                                   # at the right
    rows = np.nonzero(white.any(axis=1))[0]
    bar = white[rows.max()]
    # 20 mm at 0.5 mm a pixel
    assert bar.sum() == 20 / 0.5 and white[rows.min()].sum() == 40    # a bar 4 pixels thick
    text = picture[:rows.min() - 1].max(axis=2) > 100                 # smoothed text, written above the bar
    assert text[:, 100:].any() and not text[:, :100].any()


def test_letters_are_written_at_their_edges():
    letters = edge_letters(View.preset(PLANES["axial"]))
    picture = slice_picture(np.zeros((64, 64)), (1.0, 1.0), BLACK, overlay=None, letters=letters, scale_bar=False)
    yellow = (picture[..., 0] > 60) & (picture[..., 2] == 0)         # the text is smoothed: yellowish
    for edge, band in {"top": yellow[:14, 24:40], "bottom": yellow[-14:, 24:40], "left": yellow[24:40, :12],
                       "right": yellow[24:40, -12:]}.items():
        assert band.any(), edge
    assert not yellow[16:-16, 16:-16].any()


def volume_at(origin=(10.0, 20.0, -30.0)):
    return Volume(np.zeros((8, 12, 16)), (0.5, 0.5, 2.0), {"origin": list(origin)})


def test_slice_index_from_a_point():
    volume = volume_at()
    assert [slice_index(volume, plane) for plane in PLANES] == [4, 6, 8]
    voxels = SlicePoint(3, 5, 7, unit="voxel")
    assert [slice_index(volume, plane, voxels) for plane in PLANES] == [7, 5, 3]
    mm = SlicePoint(10 + 0.5 * 3, 20 + 0.5 * 5.4, -30 + 2 * 7.2)
    assert [slice_index(volume, plane, mm) for plane in PLANES] == [7, 5, 3]
    nearest = SlicePoint(10 + 0.5 * 2.6, 20 + 0.5 * 4.5, -30 + 2 * 6.6)          # the voxel holding the point
    assert [slice_index(volume, plane, nearest) for plane in PLANES] == [7, 5, 3]


def test_slice_index_in_mm_follows_the_direction():
    """A volume whose x runs toward the patient's right (direction -1): mm go through the inverse affine."""
    volume = volume_at(origin=(0.0, 0.0, 0.0))
    volume.direction = np.diag([-1.0, 1.0, 1.0])
    assert slice_index(volume, "sagittal", SlicePoint(-2.0, 0, 0)) == 4


@pytest.mark.parametrize("point, extent", [(SlicePoint(0, 0, 20), "z from 0 to 7"),
                                           (SlicePoint(0, 0, -31.5), "z from -30 to -16 mm")])
def test_a_point_outside_the_volume_is_refused_with_its_extent(point, extent):
    with pytest.raises(InputError) as error:
        slice_index(volume_at(), "axial", SlicePoint(point.x, point.y, point.z, unit="voxel")
                    if extent.endswith("7") else point)
    assert error.value.parameter == "at"
    assert extent in str(error.value)


def test_a_point_on_the_last_voxels_outer_face_is_inside():
    assert slice_index(volume_at(), "axial", SlicePoint(0, 0, 7.5, unit="voxel")) == 7
    with pytest.raises(InputError):
        slice_index(volume_at(), "axial", SlicePoint(0, 0, 7.51, unit="voxel"))


def test_bad_points_are_refused():
    for bad in (dict(unit="inch"), dict(z=float("nan"))):
        with pytest.raises(InputError) as error:
            SlicePoint(**{"x": 0, "y": 0, "z": 0, **bad})
        assert error.value.parameter == "at"


def test_label_slices_centroid_and_largest():
    labels = np.zeros((10, 9, 8), np.uint8)
    labels[2:5, 1:3, 1:3] = 1                           # z 2..4, x 1..2: centroid z 3, x 1.5 (rounds up)
    labels[7, 4:9, 6] = 4                               # a line along y at z 7, x 6
    labels[8, 4, 6] = 4
    assert label_slices(labels, "axial") == {1: 3, 4: 7}
    assert label_slices(labels, "sagittal") == {1: 2, 4: 6}
    assert label_slices(labels, "coronal") == {1: 2, 4: 6}            # y 4..8 and 4: (30 + 4) / 6
    assert label_slices(labels, "coronal", how="largest") == {1: 1, 4: 4}
    assert label_slices(labels, "axial", how="largest") == {1: 2, 4: 7}
    assert label_slices(np.zeros((2, 2, 2), np.uint8), "axial") == {}


def test_unknown_choices_name_their_parameter():
    labels = np.zeros((2, 3, 4), np.uint8)
    cases = [(lambda: label_slices(labels, "axial", how="middle"), "at"),
             (lambda: label_slices(labels, "oblique"), "slices"),
             (lambda: plane_image(labels, (1, 1, 1), "transverse", 0), "slices"),
             (lambda: slice_index(volume_at(), "frontal"), "slices"),
             (lambda: slice_picture(np.zeros((4, 4)), (1, 1), BLACK), "overlay"),
             (lambda: slice_picture(np.zeros((4, 4)), (1, 1), BLACK, overlay="outline"), "overlay"),
             (lambda: slice_picture(np.zeros((4, 4)), (1, 1), BLACK, labels[0, :, :4].repeat(2, 0)[:4],
                                    overlay="edges"), "overlay"),
             (lambda: slice_picture(np.zeros((4, 4)), (1, 1), BLACK, np.zeros((4, 4), int), opacity=1.5),
              "opacity"),
             (lambda: slice_picture(np.zeros((4, 4)), (1, 1), BLACK, np.zeros((3, 4), int)), "labels")]
    for call, parameter in cases:
        with pytest.raises(InputError) as error:
            call()
        assert error.value.parameter == parameter
    slice_picture(np.zeros((4, 4)), (1, 1), BLACK, overlay=None)          # the grey slice alone


def test_vhf_head_in_three_planes():
    """The real head with labels by HU (soft, bone) in the three planes; the pictures go to /tmp/slices/."""
    from PIL import Image

    from voxrender.io import read_volume

    volume = read_volume(data_path("vhf_head"))
    hu = volume.values
    labels = np.zeros(hu.shape, np.uint8)
    labels[(hu >= -300) & (hu < 300)] = 1
    labels[hu >= 300] = 2
    table = {1: ("soft", (220, 120, 100)), 2: ("bone", (241, 214, 145))}
    out = Path("/tmp/slices")
    out.mkdir(exist_ok=True)
    for plane in PLANES:
        index = slice_index(volume, plane)
        grey, pixel_mm = plane_image(hu, volume.spacing, plane, index)
        shown, _ = plane_image(labels, volume.spacing, plane, index)
        picture = slice_picture(grey, pixel_mm, CT_WINDOWS["bone"], shown, table, overlay="both", size=(256, 256),
                                letters=edge_letters(View.preset(PLANES[plane])), legend=True)
        Image.fromarray(picture).save(out / f"test_vhf_{plane}.png")
        assert picture.shape == (256, 256, 3)
        assert (picture == (241, 214, 145)).all(axis=2).sum() > 50, plane        # bone outlined
    # the head up in the coronal slice: its top row crosses the crown, its bottom row the neck, much wider
    grey, _ = plane_image(hu, volume.spacing, "coronal", slice_index(volume, "coronal"))
    assert (grey[-1] > -300).sum() > 3 * (grey[0] > -300).sum()


def test_a_mask_is_label_one_and_a_legend_needs_no_overlay():
    from voxrender.pictures.colours import label_colours

    mask = np.zeros((40, 60), bool)
    mask[5:10, 5:10] = True
    filled = slice_picture(np.zeros(mask.shape), (1.0, 1.0), BLACK, mask, opacity=1.0, scale_bar=False)
    assert tuple(filled[7, 7]) == label_colours([1])[1][1] and tuple(filled[20, 30]) == (0, 0, 0)
    legend = slice_picture(np.zeros(mask.shape), (1.0, 1.0), BLACK, mask, overlay=None, legend=True,
                           scale_bar=False)
    assert not legend[:20].any() and legend[20:].any()         # the legend alone, at the bottom left


def test_label_slices_with_large_label_numbers():
    labels = np.zeros((6, 4, 4), np.uint16)
    labels[1, 0, 0] = 60000
    labels[4, 1:3, 1:3] = 7
    assert label_slices(labels, "axial") == {7: 4, 60000: 1}
    assert label_slices(labels.astype(bool), "axial", how="largest") == {1: 4}


def test_plane_index_outside_the_volume_is_refused():
    for index in (-1, 6, 2.5):
        with pytest.raises(InputError) as error:
            plane_image(np.zeros(SHAPE), (1, 1, 1), "axial", index)
        assert error.value.parameter == "at"
