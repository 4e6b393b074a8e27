"""Small valid files of every format voxrender reads, written by the libraries that write them.

Each writer takes the folder of a case and the ``values[z, y, x]`` to store (the phantom of ``tests/formats.py``,
or values a mutation chose: NaN voxels, a constant volume, one voxel thick ...) and returns a :class:`Seed`: the
path to give voxrender, the options the format needs, and the files a mutation may damage.
"""

import csv
import io
import json
from dataclasses import dataclass, field

import nibabel
import numpy as np
from dicom_files import write_enhanced, write_series
from formats import SPACING, stored, write_metaimage, write_nifti, write_nrrd

INPUT = "input"                     # the case's own files, under the case folder


@dataclass
class Seed:
    """A valid input: ``path`` (relative to the case folder) is what voxrender is given, ``options`` what the format
    needs, ``files`` the files a mutation may damage (the first, the one that holds the header), ``text`` whether
    they are text (a manifest, a colour table).  ``command`` is ``"render"`` or ``"batch"``.
    """

    path: str
    options: list = field(default_factory=list)
    files: list = field(default_factory=list)
    command: str = "render"
    text: bool = False


def phantom_stored(code="LPS"):
    """The tests' phantom stored in orientation ``code``: values, spacing, direction."""
    from formats import phantom

    return stored(phantom(), code)


def _direction(values_direction):
    return np.eye(3) if values_direction is None else values_direction


def nifti1(case, values, spacing=SPACING, direction=None, suffix=".nii"):
    path = case / INPUT / f"x{suffix}"
    write_nifti(path, values, spacing, _direction(direction))
    return Seed(f"{INPUT}/{path.name}", files=[path])


def nifti_gz(case, values, spacing=SPACING, direction=None):
    return nifti1(case, values, spacing, direction, ".nii.gz")


def nifti2(case, values, spacing=SPACING, direction=None):
    path = case / INPUT / "x.nii"
    affine = np.diag([-spacing[0], -spacing[1], spacing[2], 1.0])
    nibabel.save(nibabel.Nifti2Image(np.transpose(values, (2, 1, 0)), affine), str(path))
    return Seed(f"{INPUT}/{path.name}", files=[path])


def nifti_4d(case, values, spacing=SPACING, direction=None):
    """Two frames, the second the first inverted; ``--frame 1``."""
    path = case / INPUT / "x.nii"
    frames = np.stack([values, np.nanmax(values) - values], axis=-1)
    affine = np.diag([-spacing[0], -spacing[1], spacing[2], 1.0])
    nibabel.save(nibabel.Nifti1Image(np.transpose(frames, (2, 1, 0, 3)), affine), str(path))
    return Seed(f"{INPUT}/{path.name}", ["--frame", "1"], [path])


def nrrd_attached(case, values, spacing=SPACING, direction=None, encoding="raw"):
    path = case / INPUT / "x.nrrd"
    write_nrrd(path, values, spacing, _direction(direction), encoding=encoding)
    return Seed(f"{INPUT}/{path.name}", files=[path])


def nrrd_gzip(case, values, spacing=SPACING, direction=None):
    return nrrd_attached(case, values, spacing, direction, "gzip")


def nrrd_detached(case, values, spacing=SPACING, direction=None):
    path = case / INPUT / "x.nhdr"
    write_nrrd(path, values, spacing, _direction(direction), encoding="raw")
    return Seed(f"{INPUT}/{path.name}", files=[path, *sorted(p for p in path.parent.iterdir() if p != path)])


def nrrd_4d(case, values, spacing=SPACING, direction=None):
    """Two frames along a first, non-spatial axis (as 3D Slicer writes them); ``--frame 0``."""
    import nrrd

    path = case / INPUT / "x.nrrd"
    matrix = np.diag(spacing).T
    frames = np.stack([values, np.nanmax(values) - values], axis=-1)      # the list axis the fastest
    header = {"space": "left-posterior-superior", "kinds": ["list", "domain", "domain", "domain"],
              "space directions": np.vstack([np.full(3, np.nan), matrix]), "space origin": [0.0, 0.0, 0.0]}
    nrrd.write(str(path), frames, header, index_order="C")
    return Seed(f"{INPUT}/{path.name}", ["--frame", "0"], [path])


def seg_nrrd(case, values, spacing=SPACING, direction=None):
    """A 3D Slicer segmentation: two labels, their names and colours; ``--labels``."""
    labels = _two_labels(values)
    path = case / INPUT / "x.seg.nrrd"
    segments = {}
    for k, (name, colour) in enumerate((("skin", "0.9 0.7 0.6"), ("bone", "1 1 0.9"))):
        segments.update({f"Segment{k}_ID": f"Segment_{k + 1}", f"Segment{k}_Name": name,
                         f"Segment{k}_Color": colour, f"Segment{k}_LabelValue": str(k + 1),
                         f"Segment{k}_Layer": "0"})
    write_nrrd(path, labels, spacing, _direction(direction), encoding="gzip", **segments)
    return Seed(f"{INPUT}/{path.name}", ["--labels"], [path])


def _two_labels(values):
    """Two labels of the values: the upper half of the object 1, the lower half 2."""
    labels = (values > values.min()).astype(np.uint8)
    labels[: len(labels) // 2] *= 2
    return labels


def mask_folder(case, values, spacing=SPACING, direction=None):
    """A TotalSegmentator-like folder of binary masks (one ``.nii.gz`` per structure, one of them empty), the
    first in the list the one a mutation damages; ``--labels``."""
    labels = _two_labels(values)
    folder = case / INPUT / "segmentations"
    folder.mkdir(parents=True)
    paths = []
    for name, mask in (("liver", labels == 1), ("spleen", labels == 2), ("kidney_left", np.zeros_like(labels))):
        paths.append(folder / f"{name}.nii.gz")
        write_nifti(paths[-1], mask.astype(np.uint8), spacing, _direction(direction))
    return Seed(f"{INPUT}/segmentations", ["--labels"], paths)


def nifti_multilabel(case, values, spacing=SPACING, direction=None):
    """TotalSegmentator's ``--ml`` output: a label map whose names are in a Caret XML header extension, written
    as TotalSegmentator's ``add_label_map_to_nifti`` writes it; ``--labels``."""
    path = case / INPUT / "x.nii.gz"
    write_nifti(path, _two_labels(values), spacing, _direction(direction))
    image = nibabel.load(str(path))
    body = "".join(f'<Label Key="{key}" Red="0.0" Green="1.0" Blue="0.0" Alpha="1"><![CDATA[{name}]]></Label>\n'
                   for key, name in ((1, "liver"), (2, "vertebrae_L1")))
    xml = ('<?xml version="1.0" encoding="UTF-8"?> <CaretExtension>  <VolumeInformation Index="0">   <LabelTable>\n'
           f"{body}\n  </LabelTable>  <VolumeType><![CDATA[Label]]></VolumeType>   </VolumeInformation>"
           "</CaretExtension>\n")
    image.header.extensions.append(nibabel.nifti1.Nifti1Extension(0, xml.encode()))
    nibabel.save(nibabel.Nifti1Image(np.asanyarray(image.dataobj), image.affine, image.header), str(path))
    return Seed(f"{INPUT}/{path.name}", ["--labels"], [path])


def _ct_for_labels(case, values, spacing, direction):
    """A CT series of the values (as HU) and its two labels, for a segmentation's seed: the series' files, the
    labels as stored (slice z of the files at index z) and the series read back (its grid, for contours)."""
    from seg_files import write_ct

    from voxrender.io import read_volume

    hu = np.nan_to_num(values.astype(np.float32), nan=0, posinf=3000, neginf=-1000).clip(-1024, 3000) - 1024
    sources = write_ct(case / INPUT / "ct", values.shape, spacing, _direction(direction), hu)
    return sources, _two_labels(values), read_volume(case / INPUT / "ct")


def dicom_seg(case, values, spacing=SPACING, direction=None):
    """A CT series and its DICOM SEG (BINARY, two named, coloured segments) written by highdicom;
    ``--labels-from`` the SEG."""
    from seg_files import write_seg

    sources, labels, _ = _ct_for_labels(case, values, spacing, direction)
    if not labels.any():                           # highdicom writes no SEG of nothing: one voxel, then
        labels.flat[labels.size // 2] = 1
    path = write_seg(case / INPUT / "seg.dcm", sources, labels, ["liver", "spleen"],
                     colours=[(221, 130, 101), (157, 108, 162)]) if labels.max() > 1 else \
        write_seg(case / INPUT / "seg.dcm", sources, labels, ["liver"])
    return Seed(f"{INPUT}/ct", ["--labels-from", f"{INPUT}/seg.dcm"], [path])


def dicom_rtstruct(case, values, spacing=SPACING, direction=None):
    """A CT series and its RTSTRUCT (the two labels' contours, traced slice by slice in the series' own planes, so
    that they are planar as a planning system's are) written by pydicom; ``--labels-from`` the RTSTRUCT."""
    from rtstruct_files import references_of, write_rtstruct_of_labels

    from voxrender.io import read_volume
    from voxrender.space.grids import patient_affine

    _ct_for_labels(case, values, spacing, direction)
    stored = read_volume(case / INPUT / "ct", reorient=False)   # traced in the series' own slices, as it is read
    path = write_rtstruct_of_labels(case / INPUT / "rs.dcm", _two_labels(stored.values), patient_affine(stored),
                                    ["GTV", "PTV"],
                                    [(255, 0, 0), (0, 0, 255)],
                                    **references_of(sorted((case / INPUT / "ct").iterdir())))
    return Seed(f"{INPUT}/ct", ["--labels-from", f"{INPUT}/rs.dcm"], [path])


def metaimage_local(case, values, spacing=SPACING, direction=None):
    path = case / INPUT / "x.mha"
    write_metaimage(path, values.astype(np.int16), spacing, _direction(direction))
    return Seed(f"{INPUT}/{path.name}", files=[path])


def metaimage_detached(case, values, spacing=SPACING, direction=None):
    """A ``.mhd`` header and its ``.raw``: the ``.mha`` of :func:`formats.write_metaimage`, split as ITK does."""
    mha = case / INPUT / "x.mha"
    write_metaimage(mha, values.astype(np.int16), spacing, _direction(direction))
    whole = mha.read_bytes()
    mha.unlink()
    data_size = values.size * 2
    header = whole[:len(whole) - data_size].replace(b"ElementDataFile = LOCAL", b"ElementDataFile = x.raw")
    (case / INPUT / "x.mhd").write_bytes(header)
    (case / INPUT / "x.raw").write_bytes(whole[len(whole) - data_size:])
    return Seed(f"{INPUT}/x.mhd", files=[case / INPUT / "x.mhd", case / INPUT / "x.raw"])


def dicom_series(case, values, spacing=SPACING, direction=None):
    folder = case / INPUT / "series"
    files = write_series(folder, values.astype(np.int16), spacing, intercept=-1024, direction=direction)
    return Seed(f"{INPUT}/series", files=sorted(files))


def dicom_enhanced(case, values, spacing=SPACING, direction=None):
    folder = case / INPUT / "enhanced"
    folder.mkdir(parents=True, exist_ok=True)
    path = write_enhanced(folder / "x.dcm", values.astype(np.int16), spacing, intercept=-1024, direction=direction)
    return Seed(f"{INPUT}/enhanced", files=[path])


def tiff(case, values, spacing=SPACING, direction=None, **options):
    """A multi-page TIFF with ImageJ's spacing (tifffile)."""
    import tifffile

    path = case / INPUT / "x.tif"
    if values.dtype == np.int16:
        values = values.astype(np.uint16)
    options = {"imagej": True, "resolution": (1 / spacing[0], 1 / spacing[1]),
               "metadata": {"spacing": spacing[2], "unit": "mm"}, **options}
    if options["imagej"] and values.dtype not in (np.uint8, np.uint16, np.float32):   # ImageJ stores no others
        values = values.astype(np.float32)
    tifffile.imwrite(path, values, **options)
    return Seed(f"{INPUT}/{path.name}", files=[path])


def png_folder(case, values, spacing=SPACING, direction=None):
    """One 16-bit PNG per slice (imageio)."""
    import imageio.v3 as iio

    folder = case / INPUT / "slices"
    folder.mkdir(parents=True, exist_ok=True)
    values = np.clip(np.nan_to_num(values), 0, 65535).astype(np.uint16)
    files = []
    for z, image in enumerate(values):
        files.append(folder / f"slice{z:03d}.png")
        iio.imwrite(files[-1], image)
    return Seed(f"{INPUT}/slices", files=files)


def zarr_array(case, values, spacing=SPACING, direction=None, zarr_format=2):
    """A plain Zarr array (format 2 or 3) of chunks 4x8x8 (zarr); no spacing."""
    import zarr

    path = case / INPUT / "x.zarr"
    zarr.create_array(store=str(path), data=values, chunks=(4, 8, 8), zarr_format=zarr_format)
    return Seed(f"{INPUT}/{path.name}", files=_zarr_files(path, ".zarray" if zarr_format == 2 else "zarr.json"))


# The side an axis grows toward (a letter of orient's codes) as NGFF RFC-4's anatomical orientation.
ANATOMICAL = {"R": "left-to-right", "L": "right-to-left", "P": "anterior-to-posterior", "A": "posterior-to-anterior",
              "S": "inferior-to-superior", "I": "superior-to-inferior"}


def ome_zarr(case, values, spacing=SPACING, direction=None, version="0.4", levels=3):
    """An OME-Zarr image (NGFF ``version``, 0.4 in a format-2 group's attributes, 0.5 under ``"ome"`` in a format-3
    group's) of ``levels`` levels, each half the last along every axis, written as ``tests/io/test_zarr.py``'s
    ``write_ome`` writes them: zarr groups whose attributes are laid out as NGFF says.  The spacing is the scale in
    micrometres, the direction the axes' anatomical orientation (NGFF RFC-4)."""
    import zarr

    from voxrender.space import orient

    path = case / INPUT / "x.ome.zarr"
    zarr_format = 2 if version == "0.4" else 3
    group = zarr.open_group(str(path), mode="w", zarr_format=zarr_format)
    code = orient.code_of(_direction(direction))                 # x, y, z
    axes = [{"name": name, "type": "space", "unit": "micrometer",
             "orientation": {"type": "anatomical", "value": ANATOMICAL[side]}}
            for name, side in zip("zyx", code[::-1], strict=True)]
    datasets = []
    for k in range(levels):
        step = (slice(None, None, 2 ** k),) * 3
        group.create_array(str(k), data=np.ascontiguousarray(values[step]), chunks=(4, 8, 8))
        datasets.append({"path": str(k), "coordinateTransformations": [
            {"type": "scale", "scale": [1000.0 * s * 2 ** k for s in spacing[::-1]]},
            {"type": "translation", "translation": [0.0, 100.0, -250.0]}]})
    multiscales = [{"name": "image", "axes": axes, "datasets": datasets} |
                   ({"version": version} if zarr_format == 2 else {})]
    group.attrs.update({"multiscales": multiscales} if zarr_format == 2 else
                       {"ome": {"version": version, "multiscales": multiscales}})
    header = path / (".zattrs" if zarr_format == 2 else "zarr.json")
    return Seed(f"{INPUT}/{path.name}", files=_zarr_files(path, header.name))


def _zarr_files(path, header):
    """The files of a Zarr store, its ``header`` (metadata) file first, then the others (metadata and chunks)."""
    first = path / header
    return [first, *sorted(p for p in path.rglob("*") if p.is_file() and p != first)]


def npy(case, values, spacing=SPACING, direction=None):
    path = case / INPUT / "x.npy"
    np.save(path, values)
    return Seed(f"{INPUT}/{path.name}", files=[path])


def segments_file(case, values, spacing=SPACING, direction=None, octree=False, levels=False):
    """voxrender's own ``.vxs`` (or ``.vxo``, with its octree; with ``levels``, its levels of detail), written by
    ``Encoded.save``."""
    from voxrender.io import Volume
    from voxrender.object.pipeline import Encoded, PrepOptions, encode_volume

    path = case / INPUT / ("x.vxo" if octree else "x.vxs")
    finite = values[np.isfinite(values)]
    if not finite.size or finite.min() == finite.max() == 0:     # no object to encode: the phantom's
        values, spacing, _ = phantom_stored()
        finite = values
    threshold = float(finite.max())             # at least the brightest voxels are the object
    Encoded(encode_volume(Volume(values, spacing), PrepOptions(threshold=threshold))).save(path, octree=octree,
                                                                                           levels=levels)
    return Seed(f"{INPUT}/{path.name}", files=[path])


def segments_octree(case, values, spacing=SPACING, direction=None):
    return segments_file(case, values, spacing, direction, octree=True)


def segments_levels(case, values, spacing=SPACING, direction=None):
    return segments_file(case, values, spacing, direction, levels=True)


MANIFEST_ROWS = [{"input": "x.nii", "threshold": "500", "views": "anterior;0,30,0", "method": "ftb",
                  "output": "{name}-{view}.png"},
                 {"input": "x.nii", "threshold": "otsu", "views": "left", "method": "octree-btf",
                  "output": "second-{view}.png"}]


def manifest_csv(case, values, spacing=SPACING, direction=None, rows=None):
    """A batch manifest (CSV) of two rows over one NIfTI beside it; ``batch --manifest``."""
    nifti1(case, values, spacing, direction)
    rows = MANIFEST_ROWS if rows is None else rows
    text = io.StringIO()
    writer = csv.DictWriter(text, list(rows[0]), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    path = case / INPUT / "manifest.csv"
    path.write_text(text.getvalue())
    return Seed(f"{INPUT}/{path.name}", files=[path], command="batch", text=True)


def manifest_toml(case, values, spacing=SPACING, direction=None, rows=None):
    """The same manifest as TOML ``[[input]]`` tables."""
    nifti1(case, values, spacing, direction)
    rows = MANIFEST_ROWS if rows is None else rows
    path = case / INPUT / "manifest.toml"
    path.write_text("".join("[[input]]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in row.items()) + "\n"
                            for row in rows))
    return Seed(f"{INPUT}/{path.name}", files=[path], command="batch", text=True)


COLOUR_ROWS = [("1", "skin", "230", "180", "150"), ("2", "bone", "255", "255", "230")]


def colour_table(case, values, spacing=SPACING, direction=None, kind="csv", rows=None):
    """A label map (NIfTI, labels 1 and 2) and its colour table of ``kind`` (csv, json, ctbl, or ITK-SNAP's txt);
    ``--labels --colours TABLE``."""
    labels = (values > np.nanmin(values)).astype(np.uint8)
    labels[: len(labels) // 2] *= 2
    nifti1(case, labels, spacing, direction)
    rows = COLOUR_ROWS if rows is None else rows
    path = case / INPUT / f"colours.{kind}"
    if kind == "csv":
        text = "label,name,r,g,b\n" + "".join(",".join(row) + "\n" for row in rows)
    elif kind == "json":
        text = json.dumps([dict(zip(("label", "name", "r", "g", "b"), row, strict=False)) for row in rows])
    elif kind == "ctbl":
        text = "# Color table file\n" + "".join(" ".join([*row, "255"]) + "\n" for row in rows)
    else:
        text = "".join(" ".join([*row[:1], *row[2:], "1 1 1", *[f'"{name}"' for name in row[1:2]]]) + "\n"
                       for row in rows)
    path.write_text(text)
    return Seed(f"{INPUT}/x.nii", ["--labels", "--colours", f"{INPUT}/{path.name}"], [path], text=True)


def colour_json(case, values, spacing=SPACING, direction=None, rows=None):
    return colour_table(case, values, spacing, direction, "json", rows)


def colour_ctbl(case, values, spacing=SPACING, direction=None, rows=None):
    return colour_table(case, values, spacing, direction, "ctbl", rows)


def colour_itksnap(case, values, spacing=SPACING, direction=None, rows=None):
    return colour_table(case, values, spacing, direction, "txt", rows)
