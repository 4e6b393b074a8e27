"""The cases: case ``n`` of seed ``s`` is one valid file of one format (:mod:`fuzz.seeds`), damaged one way.

A case damages the values it stores (NaN voxels, a constant volume, one voxel thick ...), a field of its header
(through the format's library where there is one, as ``key: value`` text where the header is text), or its bytes
(cut, flipped, garbled, a gzip member cut short).  Everything is drawn from ``random.Random(f"{s}/{n}")``, and the
formats take turns (``n`` modulo their number), so any count of cases is spread over all of them.
"""

import dataclasses
import functools
import gzip
import io
import json
import math
import random
import shutil
import warnings
from dataclasses import dataclass, field

import nibabel
import numpy as np

from voxrender.object import vxs

from . import seeds

# Values a number in a header may be given: zero, negative, not finite, huge, not a number at all.
NUMBERS = ["0", "-1", "nan", "inf", "-inf", "1e-30", "1e30", "1e308", "2147483648", "30000", "abc", ""]
SIZES = ["0", "1", "-1", "2", "30000", "2147483647", "abc", ""]


@dataclass
class Case:
    """A case written under its folder: ``name`` says what was done (``"nifti/pixdim[1]=nan"``), ``commands`` are
    the voxrender command lines to run (``{case}`` and ``{out}`` stand for the case's folder and the output folder).
    """

    name: str
    format: str
    commands: list = field(default_factory=list)


# ---- values: what the valid file stores ----

def value_mutations(rng, values):
    """A description and the values a writer stores instead of ``values``: what a renderer can meet."""
    kind = rng.choice(["nan voxels", "inf voxels", "all nan", "constant", "zeros", "one voxel thick x",
                       "one voxel thick y", "one voxel thick z", "one voxel", "padding -3024", "huge range",
                       "float64", "uint8", "bool", "negative"])
    v = values.astype(np.float32)
    if kind == "nan voxels":
        v[rng.randrange(v.shape[0]), :, :] = np.nan
    elif kind == "inf voxels":
        v.flat[rng.randrange(v.size)] = np.inf
        v.flat[rng.randrange(v.size)] = -np.inf
    elif kind == "all nan":
        v[:] = np.nan
    elif kind == "constant":
        return kind, np.full_like(values, 1000)
    elif kind == "zeros":
        return kind, np.zeros_like(values)
    elif kind.startswith("one voxel thick"):
        axis = 2 - "xyz".index(kind[-1])
        return kind, np.ascontiguousarray(np.take(values, [values.shape[axis] // 2], axis=axis))
    elif kind == "one voxel":
        return kind, np.full((1, 1, 1), 1000, values.dtype)
    elif kind == "padding -3024":
        v = values.astype(np.int16) - 1024
        v[:, :3, :] = v[:, -3:, :] = -3024
        return kind, v
    elif kind == "huge range":
        v = values.astype(np.int32) * 2_000_000
        v.flat[0] = -2**31
        return kind, v
    elif kind == "float64":
        return kind, values.astype(np.float64) / 1000
    elif kind == "uint8":
        return kind, (values > 0).astype(np.uint8) * 200
    elif kind == "bool":
        return kind, values > 0
    else:
        return kind, values.astype(np.int16) - 2000
    return kind, v


# ---- bytes: any file ----

def byte_mutation(rng, path):
    """Damage the bytes of ``path``; returns what was done."""
    data = bytearray(path.read_bytes())
    kind = rng.choice(["cut", "cut", "flip", "flip", "zero run", "garbage tail", "empty", "duplicate"])
    if kind == "cut":
        share = rng.choice([0, 1, 5, 10, 25, 40, 50, 60, 75, 90, 99])
        path.write_bytes(bytes(data[: len(data) * share // 100]))
        return f"{path.name} cut at {share}%"
    if kind == "flip":
        count = rng.choice([1, 2, 4, 16])
        limit = min(len(data), rng.choice([400, 1000, len(data)]))
        places = sorted(rng.randrange(limit) for _ in range(count)) if limit else []
        for place in places:
            data[place] ^= 1 << rng.randrange(8)
        path.write_bytes(bytes(data))
        return f"{path.name} {count} bits flipped at {places[0] if places else 0}.."
    if kind == "zero run":
        start = rng.randrange(max(1, len(data)))
        data[start:start + 64] = bytes(len(data[start:start + 64]))
        path.write_bytes(bytes(data))
        return f"{path.name} 64 bytes zeroed at {start}"
    if kind == "garbage tail":
        path.write_bytes(bytes(data) + rng.randbytes(rng.choice([1, 100, 10000])))
        return f"{path.name} garbage appended"
    if kind == "empty":
        path.write_bytes(b"")
        return f"{path.name} empty"
    start = rng.randrange(max(1, len(data)))
    path.write_bytes(bytes(data[:start] + data[start:]) + bytes(data[start:]))
    return f"{path.name} tail doubled from {start}"


def gzip_mutation(rng, path):
    """Damage a gzip file: its stream cut short or flipped, or a valid stream of cut or extended content."""
    data = path.read_bytes()
    kind = rng.choice(["cut", "flip", "inner cut", "inner extra", "two members", "not gzip"])
    if kind == "cut":
        share = rng.choice([5, 30, 60, 90, 99])
        path.write_bytes(data[: len(data) * share // 100])
        return f"gzip cut at {share}%"
    if kind == "flip":
        place = rng.randrange(10, len(data))
        path.write_bytes(data[:place] + bytes([data[place] ^ 0x10]) + data[place + 1:])
        return f"gzip byte flipped at {place}"
    inner = gzip.decompress(data)
    if kind == "inner cut":
        share = rng.choice([10, 50, 90, 99])
        path.write_bytes(gzip.compress(inner[: len(inner) * share // 100]))
        return f"gzip content cut at {share}%"
    if kind == "inner extra":
        path.write_bytes(gzip.compress(inner + bytes(rng.choice([1, 1000, 100000]))))
        return "gzip content with extra bytes"
    if kind == "two members":
        path.write_bytes(data + data)
        return "gzip member twice"
    path.write_bytes(inner)
    return "gzip suffix, content not compressed"


# ---- headers through their libraries ----

NIFTI_FIELDS = {
    "dim": lambda rng: (rng.randrange(8), rng.choice([0, 1, 2, -1, 4, 5, 7, 8, 300, 30000, 32767, -32768])),
    "pixdim": lambda rng: (rng.randrange(8), rng.choice([0.0, -1.0, math.nan, math.inf, -math.inf, 1e-30, 1e30])),
    "datatype": lambda rng: (None, rng.choice([0, 1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 768, 1024, 1280, 1536,
                                               1792, 2048, 2304, 9999])),
    "bitpix": lambda rng: (None, rng.choice([0, 1, 7, 8, 64, 128])),
    "vox_offset": lambda rng: (None, rng.choice([0.0, 1.0, 100.0, 353.0, 1e9, -1.0, math.nan])),
    "scl_slope": lambda rng: (None, rng.choice([math.nan, math.inf, 0.0, 1e38, -1.0, 1e-38])),
    "scl_inter": lambda rng: (None, rng.choice([math.nan, math.inf, 1e38, -1e38])),
    "qform_code": lambda rng: (None, rng.choice([0, 1, 2, 99, -1])),
    "sform_code": lambda rng: (None, rng.choice([0, 1, 2, 99, -1])),
    "quatern_b": lambda rng: (None, rng.choice([math.nan, 2.0, -2.0, 1.0])),
    "srow_x": lambda rng: (rng.randrange(4), rng.choice([0.0, math.nan, math.inf, 1e30])),
    "srow_y": lambda rng: (rng.randrange(4), rng.choice([0.0, math.nan, math.inf])),
    "intent_code": lambda rng: (None, rng.choice([1001, 1007, 1011, 2001, 2003, 3001, 3006, 3010])),
    "magic": lambda rng: (None, rng.choice([b"ni1\x00", b"n+2\x00", b"xxxx"])),
    "sizeof_hdr": lambda rng: (None, rng.choice([0, 540, 348 * 2])),
}


def nifti_header_mutation(rng, path):
    """Set one field of a NIfTI-1 or -2 header through nibabel and write the header back over the old one."""
    whole = path.read_bytes()
    compressed = whole[:2] == b"\x1f\x8b"
    data = gzip.decompress(whole) if compressed else whole
    header_class = nibabel.Nifti2Header if data[:4] == (540).to_bytes(4, "little") else nibabel.Nifti1Header
    header = header_class.from_fileobj(io.BytesIO(data))
    name = rng.choice(sorted(NIFTI_FIELDS))
    index, value = NIFTI_FIELDS[name](rng)
    if name == "dim" and rng.random() < 0.3:      # a CIFTI-2 like matrix: dims 1 1 1 1 N M, intent 3006
        header["dim"] = [6, 1, 1, 1, 1, 20, 22 * 18, 1]
        header["intent_code"] = 3006
        description = "dim=CIFTI-2 matrix 1x1x1x1x20x396"
    else:
        if index is None:
            header[name] = value
        else:
            header[name][index] = value
        description = f"{name}{'' if index is None else f'[{index}]'}={value!r}"
    block = header.binaryblock
    data = block + data[len(block):]
    path.write_bytes(gzip.compress(data) if compressed else data)
    return description


NPY_HEADERS = [("shape", (30000, 30000, 30000)), ("shape", (0, 22, 20)), ("shape", (18, 22)),
               ("shape", (18, 22, 20, 2)), ("shape", ()), ("shape", (18, 22, 21)), ("shape", (1, 1, 1)),
               ("shape", (2**40, 2, 2)), ("descr", "<f8"), ("descr", ">i2"), ("descr", "|b1"), ("descr", "<U4"),
               ("descr", "|O"), ("descr", "|V2"), ("descr", "<c8"), ("descr", "<M8[s]"), ("descr", "<f2"),
               ("fortran_order", True)]


def npy_header_mutation(rng, path):
    """Set one field of a ``.npy`` header (numpy.lib.format) in front of the same data."""
    from numpy.lib import format as npy_format

    with open(path, "rb") as f:
        version = npy_format.read_magic(f)
        read_header = npy_format.read_array_header_1_0 if version == (1, 0) else npy_format.read_array_header_2_0
        shape, fortran, dtype = read_header(f)
        data = f.read()
    header = {"shape": shape, "fortran_order": fortran, "descr": npy_format.dtype_to_descr(dtype)}
    key, value = rng.choice(NPY_HEADERS)
    header[key] = value
    out = io.BytesIO(b"")
    npy_format.write_array_header_1_0(out, header)
    path.write_bytes(out.getvalue() + data)
    return f"npy {key}={value!r}"


def vxs_header_mutation(rng, path):
    """Change one field of a ``.vxs`` file's JSON header and write the file again around the same arrays."""

    raw = path.read_bytes()
    length = int(np.frombuffer(raw[len(vxs.MAGIC):len(vxs.MAGIC) + 8], "<u8")[0])
    header = json.loads(raw[len(vxs.MAGIC) + 8:len(vxs.MAGIC) + 8 + length])
    start = _aligned(len(vxs.MAGIC) + 8 + length)
    arrays = sorted(header["arrays"])
    kind = rng.choice(["shape", "spacing", "count", "offset", "dtype", "drop array", "meta"])
    if kind == "shape":
        value = rng.choice([[0, 0, 0], [30000, 30000, 30000], [-1, 22, 20], [2, 2], [1, 1, 1], "abc"])
        header["shape"] = value
    elif kind == "spacing":
        value = rng.choice([[0, 1, 1], [-1, 1, 1], [math.nan, 1, 1], [math.inf, 1, 1], [1], None])
        header["spacing"] = value
    elif kind in ("count", "offset"):
        name = rng.choice(arrays)
        value = rng.choice([0, -1, 10**12, 7, 2**31])
        header["arrays"][name][kind] = value
        kind = f"{name}.{kind}"
    elif kind == "dtype":
        name = rng.choice(arrays)
        value = rng.choice(["<f8", "|O", "bogus", "<u1", ">i4"])
        header["arrays"][name]["dtype"] = value
        kind = f"{name}.dtype"
    elif kind == "drop array":
        value = rng.choice(arrays)
        del header["arrays"][value]
    else:
        value = rng.choice([None, [], "x"])
        header["meta"] = value
    text = json.dumps(header).encode()
    prefix = vxs.MAGIC + np.uint64(len(text)).tobytes() + text
    path.write_bytes(prefix + bytes(_aligned(len(prefix)) - len(prefix)) + raw[start:])
    return f"vxs {kind}={value!r}"


def _aligned(size):
    return -(-size // vxs._ALIGN) * vxs._ALIGN


# ---- text headers (NRRD, MetaImage): key: value ----

NRRD_FIELDS = {
    "sizes": ["20 22 30000", "0 22 18", "-1 22 18", "20 22", "20 22 18 1", "20 22 18 3", "a b c",
              "30000 30000 30000", "1 1 1"],
    "type": ["double", "uint8", "int64", "float", "block", "bogus", "signed char", "uint64"],
    "dimension": ["2", "4", "0", "-1", "100", "x"],
    "encoding": ["gzip", "bzip2", "ascii", "hex", "bogus", "raw"],
    "endian": ["big", "little", "middle"],
    "space directions": ["(0,0,0) (0,1,0) (0,0,1.25)", "(nan,0,0) (0,1,0) (0,0,1)", "(inf,0,0) (0,1,0) (0,0,1)",
                         "(1,0,0) (1,0,0) (0,0,1)", "(1,0) (0,1) (0,0)", "none (1,0,0) (0,1,0)",
                         "(-1,0,0) (0,-1,0) (0,0,-1)", "(1e308,0,0) (0,1e308,0) (0,0,1e308)",
                         "(0.7,0.7,0) (0,1,0) (0,0,1)", "(1,0,0) (0,1,0) (0,0,1) (1,1,1)", "x"],
    "space origin": ["(nan,nan,nan)", "(1,2)", "(inf,0,0)", "x"],
    "space": ["bogus", "right-anterior-superior", "scanner-xyz", "3D-right-handed", "left-left-superior"],
    "kinds": ["domain domain", "RGB-color domain domain", "list domain domain", "domain domain domain domain"],
    "byte skip": ["-1", "100000", "1", "x"],
    "line skip": ["5", "-1", "1000"],
    "data file": ["nonexistent.raw", "LIST", "x%03d.raw 0 10 1", "../x.raw", "/dev/zero"],
    "spacings": ["nan nan nan", "0 0 0", "-1 -1 -1", "1 1"],
    "Segment0_LabelValue": ["abc", "-1", "70000", "nan", ""],
    "Segment0_Color": ["1 2", "nan nan nan", "a b c", "2 2 2", "-1 -1 -1"],
    "Segment0_Layer": ["5", "-1", "x"],
    "Segment1_Name": ["", "bone", "é" * 200],
}

METAIMAGE_FIELDS = {
    "NDims": ["2", "4", "0", "abc"],
    "DimSize": SIZES + ["20 22", "20 22 18 2", "30000 30000 30000", "0 22 18"],
    "ElementType": ["MET_DOUBLE", "MET_UCHAR", "MET_BOGUS", "MET_INT_ARRAY", "MET_LONG_LONG", "MET_FLOAT", ""],
    "ElementSpacing": ["0 0 0", "nan 1 1", "-1 1 1", "1 2", "inf inf inf", "a b c", "1e308 1 1"],
    "TransformMatrix": ["0 0 0 0 0 0 0 0 0", "nan 0 0 0 1 0 0 0 1", "1 0 0 1", "1 0 0 1 0 0 0 0 1",
                        "0.7 0.7 0 0 1 0 0 0 1", "x"],
    "Offset": ["nan nan nan", "1 2", "x"],
    "ElementByteOrderMSB": ["True", "maybe"],
    "CompressedData": ["True", "False", "x"],
    "CompressedDataSize": ["10", "-1", "x"],
    "HeaderSize": ["-1", "100000", "1", "x"],
    "ElementDataFile": ["nonexistent.raw", "LIST", "x%03d.raw 0 10 1", "../x.raw", "/dev/zero", ""],
    "ElementNumberOfChannels": ["3", "0", "-1"],
    "ObjectType": ["Mesh", ""],
}


def text_header_mutation(rng, path, fields, separator):
    """Set, drop or add one ``key<separator>value`` line of a text header (the lines before the first blank line,
    or before ``ElementDataFile``'s end), keeping the bytes after it."""
    data = path.read_bytes()
    if separator == ": ":
        end = data.find(b"\n\n") + 1 if b"\n\n" in data else len(data)
    else:
        end = data.find(b"\n", data.find(b"ElementDataFile")) + 1
    head, tail = data[:end].decode("latin-1"), data[end:]
    lines = head.splitlines()
    keys = [line.partition(separator.strip())[0].strip() for line in lines]
    key = rng.choice(sorted(fields))
    if key in keys and rng.random() < 0.15 and key != "ElementDataFile":
        del lines[keys.index(key)]
        description = f"{key} removed"
    else:
        value = rng.choice(fields[key])
        line = f"{key}{separator}{value}"
        if key in keys:
            lines[keys.index(key)] = line
        else:
            lines.insert(len(lines) - 1 if separator != ": " else max(1, len(lines)), line)
        description = f"{key}={value}"
    path.write_bytes(("\n".join(lines) + "\n").encode("latin-1") + tail)
    return description


# ---- Zarr and OME-Zarr: JSON metadata ----

# Values of a Zarr array's metadata fields (.zarray of format 2, zarr.json of format 3); the chunks' own key is
# chunks in format 2, chunk_grid's chunk_shape in format 3.
ZARR_FIELDS = {
    "shape": [[0, 22, 20], [30000, 30000, 30000], [18, 22], [18, 22, 20, 2], [-1, 22, 20], "abc", [2**40, 2, 2],
              [1, 1, 1], [36, 44, 40], [2, 18, 22, 20], None],
    "chunks": [[0, 8, 8], [-1, 8, 8], [1, 1, 1], [30000, 30000, 30000], [2**31, 1, 1], [4, 8], "x", [3, 5, 7],
               [8, 8, 4], None],
    "dtype": {2: ["<f8", ">i2", "|b1", "<U4", "|O", "|V2", "<c8", "<M8[s]", "<f2", "bogus", "|u1", "<i8", None],
              3: ["float64", "bool", "complex64", "string", "bogus", "int8", "uint64", "float16", "r16", None,
                  {"name": "bogus"}]},
    "compressor": [None, {"id": "zlib", "level": 1}, {"id": "bogus"}, {"id": "blosc", "cname": "bogus"}, "x",
                   {"id": "gzip", "level": 1}, {"id": "zstd", "level": 99}],
    "codecs": [[], [{"name": "bytes", "configuration": {"endian": "little"}}], [{"name": "bogus"}],
               [{"name": "bytes", "configuration": {"endian": "big"}}, {"name": "zstd"}],
               [{"name": "gzip", "configuration": {"level": 1}}], "x", None,
               [{"name": "transpose", "configuration": {"order": [2, 1, 0]}}, {"name": "bytes"}, {"name": "zstd"}],
               [{"name": "sharding_indexed", "configuration": {"chunk_shape": [2, 4, 4], "codecs": [
                   {"name": "bytes"}], "index_codecs": [{"name": "bytes"}]}}],
               [{"name": "bytes"}, {"name": "crc32c"}, {"name": "zstd"}]],
    "fill_value": [None, "NaN", "Infinity", "abc", 1e300, -1, [1, 2], 70000, True, "AAAA"],
    "order": ["F", "X", None],
    "filters": [[{"id": "bogus"}], [{"id": "delta", "dtype": "<f8"}], "x", [{"id": "fixedscaleoffset", "offset": 0,
                                                                             "scale": 1e300, "dtype": "<f8"}]],
    "zarr_format": [1, 4, "x", None],
    "dimension_separator": ["/", "x", None],
    "node_type": ["group", "bogus", None],
    "chunk_key_encoding": [{"name": "v2", "configuration": {"separator": "."}}, {"name": "bogus"}, None,
                           {"name": "default", "configuration": {"separator": "x"}}],
    "dimension_names": [["a"], [1, 2, 3], "x", ["z", "y", "x"]],
    "storage_transformers": [[{"name": "bogus"}]],
}
FORMAT_2_KEYS = ("shape", "chunks", "dtype", "compressor", "fill_value", "order", "filters", "zarr_format",
                 "dimension_separator")
FORMAT_3_KEYS = ("shape", "chunks", "dtype", "codecs", "fill_value", "zarr_format", "node_type", "chunk_key_encoding",
                 "dimension_names", "storage_transformers")


def zarr_array_mutation(rng, path):
    """Set or drop one field of a Zarr array's metadata (``.zarray`` or ``zarr.json``) and write it back as JSON."""
    metadata = json.loads(path.read_bytes())
    zarr_format = 3 if path.name == "zarr.json" else 2
    key = rng.choice(FORMAT_3_KEYS if zarr_format == 3 else FORMAT_2_KEYS)
    values = ZARR_FIELDS[key]
    value = rng.choice(values[zarr_format] if isinstance(values, dict) else values)
    place, name = metadata, {"dtype": "data_type"}.get(key, key) if zarr_format == 3 else key
    if key == "chunks" and zarr_format == 3:
        place, name = metadata["chunk_grid"]["configuration"], "chunk_shape"
    if value is None:
        place.pop(name, None)
    else:
        place[name] = value
    path.write_text(json.dumps(metadata))
    return f"{path.parent.name}/{path.name} {name}={'deleted' if value is None else repr(value)[:40]}"


# Values of an OME-Zarr image's multiscales metadata (axes, datasets and their transformations, units, version).
OME_AXES = [[], ["z", "y"], ["z", "y", "x"], [{"name": "z", "type": "space"}] * 3, [{"name": 1}] * 3, "abc", None,
            [{"name": "t", "type": "time"}, {"name": "y", "type": "space"}, {"name": "x", "type": "space"}],
            [{"name": "c", "type": "channel"}, {"name": "z", "type": "space"}, {"name": "y", "type": "space"},
             {"name": "x", "type": "space"}], [1, 2, 3]]
OME_UNITS = ["parsec", "angstrom", "yoctometer", "bogus", "", None, 7, "kilometer", "second"]
OME_ORIENTATIONS = ["left-to-right", "bogus", None, 3, {"type": "anatomical"}, "left-to-right twice"]
OME_DATASETS = [[], [{"path": "9"}], [{"path": 0}], "x", "reversed", "twice", [{"path": "../0"}], [{"path": ""}],
                [{"path": "0/c"}], None, [{}]]
OME_NUMBERS = [0.0, -1.0, math.nan, math.inf, 1e308, 1e-300, "abc", None, True]
OME_TRANSFORMS = [[], "x", None, [{"type": "bogus"}], [{"type": "scale", "path": "scale.bin"}],
                  [{"type": "scale", "scale": [1.0, 1.0]}], [{"type": "affine", "affine": [[1, 0, 0, 0]] * 3}],
                  [{"type": "translation", "translation": [1.0, 2.0, 3.0]}, {"type": "scale", "scale": [2, 2, 2]}],
                  [{"type": "identity"}], ["scale"]]


def ome_zarr_mutation(rng, seed):
    """Damage an OME-Zarr image's metadata: a field of its ``multiscales`` (axes, units, orientations, datasets,
    their coordinate transformations and scales, the version, the image's own transformations), a level's array
    metadata (:func:`zarr_array_mutation`), or a level's metadata or folder removed."""
    header = seed.files[0]
    whole = json.loads(header.read_bytes())
    attrs = whole if header.name == ".zattrs" else whole["attributes"]["ome"]
    image = attrs["multiscales"][0]
    levels = [d["path"] for d in image["datasets"]]
    kind = rng.choice(["axes", "unit", "orientation", "datasets", "transforms", "scale", "translation", "version",
                       "multiscales", "image transforms", "level metadata", "level metadata", "level removed",
                       "channels"])
    if kind == "level metadata":
        level = header.parent / rng.choice(levels)
        return zarr_array_mutation(rng, level / (".zarray" if (level / ".zarray").exists() else "zarr.json"))
    if kind == "level removed":
        level = header.parent / rng.choice(levels)
        if rng.random() < 0.5:
            shutil.rmtree(level)
            return f"level {level.name} removed"
        metadata = level / (".zarray" if (level / ".zarray").exists() else "zarr.json")
        metadata.unlink()
        return f"{level.name}/{metadata.name} removed"
    if kind == "axes":
        value = rng.choice(OME_AXES)
        image["axes"] = value
    elif kind in ("unit", "orientation"):
        axis = rng.randrange(3)
        value = rng.choice(OME_UNITS if kind == "unit" else OME_ORIENTATIONS)
        if kind == "unit":
            image["axes"][axis]["unit"] = value
        elif value == "left-to-right twice":
            for k in (0, 1):
                image["axes"][k]["orientation"] = {"type": "anatomical", "value": "left-to-right"}
        else:
            image["axes"][axis]["orientation"] = {"type": "anatomical", "value": value} if isinstance(
                value, str | None) else value
        kind = f"axes[{axis}].{kind}"
    elif kind == "datasets":
        value = rng.choice(OME_DATASETS)
        image["datasets"] = image["datasets"][::-1] if value == "reversed" else \
            image["datasets"][:1] * 2 if value == "twice" else value
    elif kind == "transforms":
        level, value = rng.randrange(len(levels)), rng.choice(OME_TRANSFORMS)
        image["datasets"][level]["coordinateTransformations"] = value
        kind = f"datasets[{level}].coordinateTransformations"
    elif kind in ("scale", "translation"):
        level, axis, value = rng.randrange(len(levels)), rng.randrange(3), rng.choice(OME_NUMBERS)
        index = 0 if kind == "scale" else 1
        image["datasets"][level]["coordinateTransformations"][index][kind][axis] = value
        kind = f"datasets[{level}].{kind}[{axis}]"
    elif kind == "version":
        value = rng.choice(["0.1", "9.9", None, 4, ""])
        attrs["version"] = image["version"] = value
    elif kind == "multiscales":
        value = rng.choice([None, [], "x", [1], "twice"])
        attrs["multiscales"] = attrs["multiscales"] * 2 if value == "twice" else value
    elif kind == "image transforms":
        value = rng.choice(OME_TRANSFORMS[1:] + [[{"type": "scale", "scale": [0.0, 1.0, 1.0]}],
                                                 [{"type": "scale", "scale": [1e300, 1e300, 1e300]}]])
        image["coordinateTransformations"] = value
    else:
        value = rng.choice([{"channels": [{"label": "a"}, {"label": "b"}]}, "x", {"channels": "x"}, [1]])
        attrs["omero"] = value
    header.write_text(json.dumps(whole))
    return f"ome {kind}={value!r:.40}"


def _zarr_header(rng, seed):
    return zarr_array_mutation(rng, seed.files[0])


def _ome_zarr_header(rng, seed):
    return ome_zarr_mutation(rng, seed)


# ---- DICOM: data elements through pydicom ----

def _dicom_elements():
    from pydicom.uid import ImplicitVRLittleEndian, JPEGBaseline8Bit

    return {
        "PixelSpacing": [[0.6], [0, 0], [-1, -1], ["nan", "nan"], [1e300, 1e300], ["inf", 1]],
        "SliceThickness": [0, -1, "nan"],
        "ImageOrientationPatient": [[0] * 6, [1, 0, 0, 0, 1], [1, 0, 0, 1, 0, 0], ["nan"] * 6, [2, 0, 0, 0, 2, 0]],
        "ImagePositionPatient": [[0, 0, 0], [0, 0], ["nan", 0, 0], ["inf", "inf", "inf"]],
        "Rows": [0, 1, 65535, 21],
        "Columns": [0, 1, 65535, 19],
        "BitsAllocated": [8, 32, 1, 12, 0, 64],
        "BitsStored": [17, 0, 8, 32],
        "HighBit": [30, 0],
        "PixelRepresentation": [0, 2],
        "SamplesPerPixel": [3, 0],
        "PhotometricInterpretation": ["RGB", "PALETTE COLOR", "YBR_FULL", "bogus", "MONOCHROME1"],
        "RescaleSlope": [1e300, "nan", "inf", 0, -1, 1e10],
        "RescaleIntercept": [1e300, "nan", -1e20],
        "NumberOfFrames": [2, 0, 100, 1],
        "InstanceNumber": [1, -5],
        "SeriesInstanceUID": ["1.2.3.4"],
        "Modality": ["MR", "SEG", "RTSTRUCT", ""],
        "PixelPaddingValue": [-3024, 0, 1000],
        "TransferSyntaxUID": [JPEGBaseline8Bit, "1.2.840.10008.1.2.1.99", "1.2.840.10008.1.2.2",
                              ImplicitVRLittleEndian, "1.2.3.4"],
        "PixelData": ["deleted", "half", "doubled", "empty"],
    }


WRONG_VR = [("Rows", "LO", "abc"), ("Columns", "DS", "12.5"), ("PixelSpacing", "US", 3), ("PixelSpacing", "LO", "x"),
            ("ImageOrientationPatient", "SH", "1\\0\\0"), ("ImagePositionPatient", "UL", 7),
            ("RescaleSlope", "LO", "one"), ("SliceThickness", "SQ", []), ("BitsAllocated", "DS", "16.5"),
            ("InstanceNumber", "FD", 1.5), ("NumberOfFrames", "LO", "many")]


def dicom_mutation(rng, files, enhanced):
    """Set one data element of one slice or of every slice (a wrong value or a wrong VR) with pydicom."""
    import pydicom
    from pydicom import config
    from pydicom.datadict import tag_for_keyword
    from pydicom.dataelem import DataElement
    from pydicom.uid import JPEGBaseline8Bit

    config.settings.reading_validation_mode = config.IGNORE
    config.settings.writing_validation_mode = config.IGNORE
    chosen = files if enhanced or rng.random() < 0.5 else [rng.choice(files)]
    where = "every slice" if len(chosen) > 1 else chosen[0].name
    elements = _dicom_elements()
    if enhanced:
        elements.update(PerFrameFunctionalGroupsSequence=["deleted", "fewer"],
                        SharedFunctionalGroupsSequence=["deleted", "spacing one value", "orientation zeros"])
    if rng.random() < 0.25:
        keyword, vr, value = rng.choice(WRONG_VR)
        description = f"{keyword} as {vr} {value!r}"
    else:
        keyword = rng.choice(sorted(elements))
        value, vr = rng.choice(elements[keyword]), None
        description = f"{keyword}={value!r}"
    for path in chosen:
        ds = pydicom.dcmread(path)
        if vr is not None:
            tag = tag_for_keyword(keyword)
            ds[tag] = DataElement(tag, vr, value)
        elif keyword == "PixelPaddingValue":         # US or SS as the pixels are: pydicom cannot tell unaided
            ds.add_new(tag_for_keyword(keyword), "SS", value)
        elif keyword == "TransferSyntaxUID":
            ds.file_meta.TransferSyntaxUID = value
            if value == JPEGBaseline8Bit:           # a compressed syntax's pixels are fragments: raw ones here
                from pydicom.encaps import encapsulate

                ds.PixelData = encapsulate([ds.PixelData])
        elif keyword == "PixelData":
            pixels = ds.PixelData
            if value == "deleted":
                del ds.PixelData
            else:
                ds.PixelData = {"half": pixels[: len(pixels) // 2], "doubled": pixels * 2, "empty": b""}[value]
        elif keyword == "PerFrameFunctionalGroupsSequence":
            if value == "deleted":
                del ds.PerFrameFunctionalGroupsSequence
            else:
                ds.PerFrameFunctionalGroupsSequence = ds.PerFrameFunctionalGroupsSequence[:3]
        elif keyword == "SharedFunctionalGroupsSequence":
            shared = ds.SharedFunctionalGroupsSequence[0]
            if value == "deleted":
                del ds.SharedFunctionalGroupsSequence
            elif value == "spacing one value":
                shared.PixelMeasuresSequence[0].PixelSpacing = [0.6]
            else:
                shared.PlaneOrientationSequence[0].ImageOrientationPatient = [0] * 6
        else:
            setattr(ds, keyword, value)
        pydicom.dcmwrite(path, ds, implicit_vr=False, little_endian=True, force_encoding=True)
    return f"{description} ({where})"


# ---- manifests and colour tables: rows of text ----

MANIFEST_VALUES = {
    "input": ["missing.nii", "", ".", "x.nii,x.nii", "input", "/dev/null", "manifest.csv", "*.nii", "é.nii"],
    "threshold": ["abc", "nan", "inf", "1:0", ":", "-inf:inf", "1e400", "otsu:1", ""],
    "views": ["1,2", "up;", "nan,0,0", ";;", "inf,0,0", "1e308,0,0", "anterior;" * 50, "left,right"],
    "method": ["bogus", "", "FTB", "raycast"],
    "output": ["../escaped.png", "../../escaped.png", "{bogus}.png", "{name", "x.txt", "", "sub/dir/{view}.png",
               "{name}.png", "/"],
    "labels": ["missing.nii", "x.nii", "manifest.csv"],
    "extra": ["1"],
}


def manifest_mutation(rng, seed, case, values, kind):
    """A manifest with one value set to a bad one, a column dropped, or its text garbled."""
    rows = [dict(row) for row in seeds.MANIFEST_ROWS]
    choice = rng.random()
    if choice < 0.7:
        column = rng.choice(sorted(MANIFEST_VALUES))
        value = rng.choice(MANIFEST_VALUES[column])
        for row in rows[: rng.choice([1, 2])]:
            row[column] = value
        for row in rows:
            row.setdefault(column, "")
        description = f"{column}={value!r}"
    elif choice < 0.8:
        column = rng.choice(sorted(rows[0]))
        for row in rows:
            del row[column]
        description = f"no {column} column"
    else:
        description = None
    writer = seeds.manifest_csv if kind == "csv" else seeds.manifest_toml
    seed = writer(case, values, rows=rows)
    if description is None:
        description = text_mutation(rng, seed.files[0])
    return seed, description


COLOUR_VALUES = [("label", ["abc", "-1", "70000", "0", "1.5", "nan", "", "1e9"]),
                 ("name", ["", "\x00", "é" * 300, '"', ","]),
                 ("r", ["300", "-1", "nan", "abc", "", "1.5", "1e9"]),
                 ("g", ["256", "x"]), ("b", ["999999999999999999999"])]


def colour_mutation(rng, case, values, writer):
    """A colour table with one value set to a bad one, a row cut short, or its text garbled."""
    rows = [list(row) for row in seeds.COLOUR_ROWS]
    choice = rng.random()
    if choice < 0.6:
        column, bad = rng.choice(COLOUR_VALUES)
        value = rng.choice(bad)
        rows[rng.randrange(len(rows))][("label", "name", "r", "g", "b").index(column)] = value
        description = f"{column}={value!r}"
    elif choice < 0.75:
        cut = rng.randrange(1, 5)
        rows[0] = rows[0][:cut]
        description = f"a row of {cut} values"
    else:
        description = None
    seed = writer(case, values, rows=[tuple(row) for row in rows])
    if description is None:
        description = text_mutation(rng, seed.files[0])
    return seed, description


def text_mutation(rng, path):
    """Garble a text file: a byte-order mark, binary bytes, NULs, a line cut, a huge line, or its bytes."""
    text = path.read_bytes()
    kind = rng.choice(["bom", "binary", "nul", "cut line", "huge line", "latin-1", "bytes"])
    if kind == "bom":
        path.write_bytes(b"\xef\xbb\xbf" + text)
    elif kind == "binary":
        path.write_bytes(text[: len(text) // 2] + rng.randbytes(50) + text[len(text) // 2:])
    elif kind == "nul":
        path.write_bytes(text.replace(b",", b"\x00", 1).replace(b"=", b"\x00", 1))
    elif kind == "cut line":
        path.write_bytes(text[: rng.randrange(len(text))])
    elif kind == "huge line":
        path.write_bytes(text + b"1," * 100000 + b"\n")
    elif kind == "latin-1":
        path.write_bytes(text + "é,\xff\n".encode("latin-1"))
    else:
        return byte_mutation(rng, path)
    return f"text {kind}"


# ---- the formats ----

@dataclass(frozen=True)
class Format:
    """One family of seed files: its writer and the header mutation its library allows (``header(rng, seed)``)."""

    write: object
    header: object = None
    values: bool = True          # whether the writer stores any values a mutation gives it
    gzip: bool = False
    versions: tuple = ()         # the writer's keyword options a case draws one of (a Zarr format, NGFF version)


def _nifti_header(rng, seed):
    return nifti_header_mutation(rng, seed.files[0])


def _multilabel_header(rng, seed):
    """The label table of a TotalSegmentator ``--ml`` file replaced by a damaged one (or the voxels' header)."""
    if rng.random() < 0.4:
        return nifti_header_mutation(rng, seed.files[0])
    tables = {
        "cut": b'<?xml version="1.0"?><CaretExtension><LabelTable><Label Key="1"><![CDATA[liv',
        "key abc": b'<LabelTable><Label Key="abc">liver</Label></LabelTable>',
        "key huge": b'<LabelTable><Label Key="99999999999999999999">liver</Label></LabelTable>',
        "key negative": b'<LabelTable><Label Key="-4">liver</Label></LabelTable>',
        "no key": b'<LabelTable><Label>liver</Label></LabelTable>',
        "no name": b'<LabelTable><Label Key="1"></Label></LabelTable>',
        "entities": b'<?xml version="1.0"?><!DOCTYPE t [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;'
                    b'&a;&a;&a;&a;"><!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">]><LabelTable><Label Key="1">&c;'
                    b"</Label></LabelTable>",
        "not utf-8": b'<LabelTable><Label Key="1">\xff\xfe liver</Label></LabelTable>',
        "workbench colours": b'<LabelTable><Label Key="1" Red="7" Green="nan" Blue="-1">liver</Label></LabelTable>',
        "many labels": b"<LabelTable>" + b"".join(b'<Label Key="%d">s%d</Label>' % (k, k) for k in range(1, 3000))
                       + b"</LabelTable>",
    }
    what = rng.choice(sorted(tables))
    path = seed.files[0]
    image = nibabel.load(str(path))
    header = image.header.copy()
    header.extensions.clear()
    code = 30 if what == "workbench colours" else 0
    header.extensions.append(nibabel.nifti1.Nifti1Extension(code, tables[what]))
    nibabel.save(nibabel.Nifti1Image(np.asanyarray(image.dataobj), image.affine, header), str(path))
    return f"label table {what}"


# Elements of a segmentation object to damage: a value for each, or None to delete it.
SEGMENTATION_ELEMENTS = {
    "seg": {"NumberOfFrames": [0, 1, 99999, None], "Rows": [0, 1, 65535], "Columns": [0, 65535],
            "SegmentationType": ["LABELMAP", "BOGUS", None], "MaximumFractionalValue": [0, 1, None],
            "BitsAllocated": [8, 16, 0], "SegmentSequence": [None], "PerFrameFunctionalGroupsSequence": [None],
            "SharedFunctionalGroupsSequence": [None], "ReferencedSeriesSequence": [None],
            "FrameOfReferenceUID": ["1.2.3", None], "PixelData": [b"", b"\0" * 7, None]},
    "rtstruct": {"StructureSetROISequence": [None], "ROIContourSequence": [None],
                 "ReferencedFrameOfReferenceSequence": [None], "SOPClassUID": ["1.2.3", None],
                 "Modality": ["CT", None]},
}
# ...and in the items of its sequences (the first item of each).
ITEM_ELEMENTS = {
    "seg": {"SegmentSequence": {"SegmentNumber": [0, 999, None], "SegmentLabel": ["", None],
                                "RecommendedDisplayCIELabValue": [[1, 2], [65535, 65535, 65535], None]},
            "PerFrameFunctionalGroupsSequence": {"PlanePositionSequence": [None],
                                                 "SegmentIdentificationSequence": [None]}},
    "rtstruct": {"StructureSetROISequence": {"ROINumber": [0, -1, None], "ROIName": ["", None]},
                 "ROIContourSequence": {"ReferencedROINumber": [99, None], "ROIDisplayColor": [[1, 2], [999, 0, 0]],
                                        "ContourSequence": [None]}},
}
CONTOUR_DAMAGE = ["odd ContourData", "nan ContourData", "huge ContourData", "NumberOfContourPoints wrong",
                  "POINT", "one point", "no ContourData"]


def _segmentation_header(kind):
    """The header mutation of a SEG or an RTSTRUCT: one element of the object, or of the first item of one of its
    sequences, set to a wrong value or deleted, with pydicom; for an RTSTRUCT sometimes a contour damaged."""

    def mutate(rng, seed):
        import pydicom
        from pydicom import config

        config.settings.reading_validation_mode = config.IGNORE
        config.settings.writing_validation_mode = config.IGNORE
        path = seed.files[0]
        ds = pydicom.dcmread(path)
        if kind == "rtstruct" and rng.random() < 0.35:
            what = rng.choice(CONTOUR_DAMAGE)
            contour = ds.ROIContourSequence[0].ContourSequence[0]
            if what == "odd ContourData":
                contour.ContourData = list(contour.ContourData)[:-1]
            elif what == "nan ContourData":
                contour.ContourData = ["nan"] * len(contour.ContourData)
            elif what == "huge ContourData":
                contour.ContourData = [1e300] * len(contour.ContourData)
            elif what == "NumberOfContourPoints wrong":
                contour.NumberOfContourPoints = 99999
            elif what == "POINT":
                contour.ContourGeometricType = "POINT"
            elif what == "one point":
                contour.ContourData, contour.NumberOfContourPoints = list(contour.ContourData)[:3], 1
            else:
                del contour.ContourData
        elif rng.random() < 0.5:
            keyword = rng.choice(sorted(SEGMENTATION_ELEMENTS[kind]))
            value = rng.choice(SEGMENTATION_ELEMENTS[kind][keyword])
            _set(ds, keyword, value)
            what = f"{keyword}={'deleted' if value is None else repr(value)[:20]}"
        else:
            sequence = rng.choice(sorted(ITEM_ELEMENTS[kind]))
            keyword = rng.choice(sorted(ITEM_ELEMENTS[kind][sequence]))
            value = rng.choice(ITEM_ELEMENTS[kind][sequence][keyword])
            if sequence in ds and len(ds[sequence].value):
                _set(ds[sequence].value[0], keyword, value)
            what = f"{sequence}[0].{keyword}={'deleted' if value is None else repr(value)[:20]}"
        ds.save_as(path)
        return what

    return mutate


def _set(ds, keyword, value):
    if value is None:
        if keyword in ds:
            delattr(ds, keyword)
    else:
        setattr(ds, keyword, value)


def _nrrd_header(rng, seed):
    return text_header_mutation(rng, seed.files[0], NRRD_FIELDS, ": ")


def _metaimage_header(rng, seed):
    return text_header_mutation(rng, seed.files[0], METAIMAGE_FIELDS, " = ")


def _npy_header(rng, seed):
    return npy_header_mutation(rng, seed.files[0])


def _vxs_header(rng, seed):
    return vxs_header_mutation(rng, seed.files[0])


def _series_header(rng, seed):
    return dicom_mutation(rng, seed.files, enhanced=False)


def _enhanced_header(rng, seed):
    return dicom_mutation(rng, seed.files, enhanced=True)


def _tiff_variant(rng, case, values):
    """A TIFF written by tifffile with odd but legal choices: its library's own header fields."""
    variant = rng.choice(["zlib", "spacing 0", "spacing nan", "resolution tiny", "rgb pages", "one page",
                          "float nan", "ome spacing 0", "planar rgb", "tiles"])
    options = {}
    if variant == "zlib":
        options = {"compression": "zlib"}
    elif variant in ("spacing 0", "spacing nan"):
        options = {"metadata": {"spacing": 0.0 if variant == "spacing 0" else math.nan, "unit": "mm"}}
    elif variant == "resolution tiny":
        options = {"resolution": (1e-30, 1e-30)}
    elif variant == "rgb pages":
        values = np.stack([values.astype(np.uint8)] * 3, axis=-1)
        options = {"photometric": "rgb"}
    elif variant == "one page":
        values = values[:1]
    elif variant == "float nan":
        values = values.astype(np.float32)
        values[0] = np.nan
    elif variant == "ome spacing 0":
        options = {"imagej": False, "ome": True, "metadata": {"PhysicalSizeX": 0.0, "PhysicalSizeY": math.nan,
                                                              "axes": "ZYX"}, "resolution": None}
    elif variant == "planar rgb":
        values = np.stack([values.astype(np.uint8)] * 3, axis=1)
        options = {"imagej": False, "planarconfig": "separate", "photometric": "rgb", "metadata": None}
    else:
        options = {"imagej": False, "tile": (16, 16), "metadata": None}
    return seeds.tiff(case, values, **options), f"tiff {variant}"


def _png_variant(rng, case, values):
    """A PNG folder with one slice unlike the others (imageio): another size, colour, depth, or no image."""
    import imageio.v3 as iio

    seed = seeds.png_folder(case, values)
    target = rng.choice(seed.files)
    variant = rng.choice(["other size", "rgb", "rgba", "8-bit", "1x1", "not an image", "only one slice", "empty"])
    if variant == "other size":
        iio.imwrite(target, np.zeros((5, 7), np.uint16))
    elif variant in ("rgb", "rgba"):
        iio.imwrite(target, np.zeros((*values.shape[1:], 3 if variant == "rgb" else 4), np.uint8))
    elif variant == "8-bit":
        iio.imwrite(target, np.zeros(values.shape[1:], np.uint8))
    elif variant == "1x1":
        for path in seed.files:
            iio.imwrite(path, np.ones((1, 1), np.uint16) * 1000)
    elif variant == "not an image":
        target.write_text("hello")
    elif variant == "only one slice":
        for path in seed.files[1:]:
            path.unlink()
    else:
        target.write_bytes(b"")
    return seed, f"png {variant} ({target.name})"


FORMATS = {
    "nifti": Format(seeds.nifti1, _nifti_header),
    "nifti2": Format(seeds.nifti2, _nifti_header),
    "nifti-gz": Format(seeds.nifti_gz, _nifti_header, gzip=True),
    "nifti-4d": Format(seeds.nifti_4d, _nifti_header),
    "nrrd": Format(seeds.nrrd_attached, _nrrd_header),
    "nrrd-gzip": Format(seeds.nrrd_gzip, _nrrd_header),
    "nhdr": Format(seeds.nrrd_detached, _nrrd_header),
    "nrrd-4d": Format(seeds.nrrd_4d, _nrrd_header),
    "seg-nrrd": Format(seeds.seg_nrrd, _nrrd_header),
    "nifti-ml": Format(seeds.nifti_multilabel, _multilabel_header, gzip=True),
    "masks": Format(seeds.mask_folder, _nifti_header, gzip=True),
    "mha": Format(seeds.metaimage_local, _metaimage_header),
    "mhd": Format(seeds.metaimage_detached, _metaimage_header),
    "dicom": Format(seeds.dicom_series, _series_header),
    "dicom-enhanced": Format(seeds.dicom_enhanced, _enhanced_header),
    "dicom-seg": Format(seeds.dicom_seg, _segmentation_header("seg")),
    "dicom-rtstruct": Format(seeds.dicom_rtstruct, _segmentation_header("rtstruct")),
    "tiff": Format(seeds.tiff),
    "png": Format(seeds.png_folder),
    "npy": Format(seeds.npy, _npy_header),
    "vxs": Format(seeds.segments_file, _vxs_header),
    "vxo": Format(seeds.segments_octree, _vxs_header),
    "vxs-levels": Format(seeds.segments_levels, _vxs_header),
    "zarr": Format(seeds.zarr_array, _zarr_header, versions=({"zarr_format": 2}, {"zarr_format": 3})),
    "ome-zarr": Format(seeds.ome_zarr, _ome_zarr_header, versions=(
        {"version": "0.4", "levels": 2}, {"version": "0.4", "levels": 3}, {"version": "0.5", "levels": 2},
        {"version": "0.5", "levels": 3})),
    "manifest-csv": Format(seeds.manifest_csv, values=False),
    "manifest-toml": Format(seeds.manifest_toml, values=False),
    "colours-csv": Format(seeds.colour_table, values=False),
    "colours-json": Format(seeds.colour_json, values=False),
    "colours-ctbl": Format(seeds.colour_ctbl, values=False),
    "colours-itksnap": Format(seeds.colour_itksnap, values=False),
}


BOOLEANS = ("npy", "zarr", "ome-zarr")       # the formats that store booleans


def make_case(seed, number, case):
    """Write case ``number`` of ``seed`` into the folder ``case`` (created) and return its :class:`Case`."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")             # the libraries' and numpy's notes on the odd values written
        return _make_case(seed, number, case)


def _make_case(seed, number, case):
    rng = random.Random(f"{seed}/{number}")
    name = sorted(FORMATS)[number % len(FORMATS)]
    fmt = FORMATS[name]
    (case / seeds.INPUT).mkdir(parents=True, exist_ok=True)
    values, spacing, direction = seeds.phantom_stored(rng.choice(["LPS", "RAS", "LPI", "ASL", "PIR"]))
    if name.startswith("manifest"):
        seed_file, what = manifest_mutation(rng, None, case, values, name.split("-")[1])
    elif name.startswith("colours"):
        writer = {"csv": seeds.colour_table, "json": seeds.colour_json, "ctbl": seeds.colour_ctbl,
                  "itksnap": seeds.colour_itksnap}[name.split("-")[1]]
        seed_file, what = colour_mutation(rng, case, values, writer)
    else:
        drawn = rng.choice(fmt.versions) if fmt.versions else {}
        fmt = dataclasses.replace(fmt, write=functools.partial(fmt.write, **drawn))
        kinds = ["values", "header", "header", "bytes"]
        if fmt.header is None:
            kinds = ["values", "variant", "variant", "bytes"]
        kind = rng.choice(kinds)
        if kind == "values":
            what, values = value_mutations(rng, values)
            if values.dtype == bool and name not in BOOLEANS:     # the other formats store no booleans
                values = values.astype(np.uint8)
            seed_file = fmt.write(case, values, spacing, direction)
        elif kind == "variant":
            variant = _tiff_variant if name == "tiff" else _png_variant
            seed_file, what = variant(rng, case, values)
        else:
            seed_file = fmt.write(case, values, spacing, direction)
            if kind == "header":
                what = fmt.header(rng, seed_file)
            elif fmt.gzip and rng.random() < 0.6:
                what = gzip_mutation(rng, seed_file.files[0])
            else:
                what = byte_mutation(rng, rng.choice(seed_file.files))
        what = "".join(f"{key}={value} " for key, value in drawn.items()) + what
    return Case(f"{name}/{what}", name, commands_for(rng, seed_file))


def commands_for(rng, seed):
    """The voxrender command lines of a case: render (or batch) at 64 pixels, sometimes a threshold, sometimes
    ``info`` too, sometimes the QC commands (:func:`qc_commands`) and the streamed encode (:func:`encode_command`)."""
    if seed.command == "batch":
        return [["batch", "--manifest", "{case}/" + seed.path, "-o", "{out}/batch", "--size", "64"]]
    options = case_options(seed)
    render = ["render", "{case}/" + seed.path, "-o", "{out}/x.png", "--size", "64", *options]
    if rng.random() < 0.3 and "--labels" not in options and not seed.path.endswith((".vxs", ".vxo")):
        render += ["--threshold", rng.choice(["500", "100:900", "-1000"])]
    commands = [render]
    if rng.random() < 0.25 and not seed.path.endswith((".vxs", ".vxo")) and "--colours" not in options:
        commands.append(["info", "{case}/" + seed.path, *[o for o in options if o != "--labels"]])
    commands += qc_commands(rng, seed, options)
    if rng.random() < 0.4 and not seed.path.endswith((".vxs", ".vxo")):
        commands.append(encode_command(rng, seed, options))
    return commands


def case_options(seed):
    """The options of a seed, the files they name in the case's folder."""
    return [o if not o.startswith(seeds.INPUT + "/") else "{case}/" + o for o in seed.options]


def encode_command(rng, seed, options):
    """Issue 24's streamed encode of a case's input (``--max-memory 1K`` streams any input whose reader opens
    slabs), sometimes binned, on worker processes, at a level of a multiscale image, or with a threshold: its grey
    values' object, so without the seed's label options."""
    command = ["encode", "{case}/" + seed.path, "-o", "{out}/x.vxs", "--max-memory", "1K",
               *_without(options, "--labels", "--colours", "--labels-from")]
    extra = rng.choice([[], [], ["--bin", "2"], ["--jobs", "2"], ["--bin", "2", "--jobs", "2"]])
    if seed.path.endswith(".zarr") and rng.random() < 0.5:
        extra += ["--level", rng.choice(["0", "1", "2", "5"])]
    if rng.random() < 0.3:
        extra += ["--threshold", rng.choice(["500", "100:900", "-1000"])]
    return command + extra


# The DICOM seeds' inputs (a classic series, an enhanced file, the CT of a SEG or an RTSTRUCT): a picture of them
# may be written as a Secondary Capture in their study.
DICOM_INPUTS = {f"{seeds.INPUT}/{name}" for name in ("series", "enhanced", "ct")}
SLICE_EXTRAS = [[], [], ["--overlay", "outline"], ["--legend"], ["--at", "labels"], ["--at", "1,2,3vox"],
                ["--window", "bone"], ["--slices", "axial"]]


def qc_commands(rng, seed, options):
    """Issue 23's commands on a case's input, drawn after the render's and ``info``'s so that every earlier case
    keeps its commands: ``slices`` (the seed's label options; no threshold), a projection (sometimes of a slab), a
    QC sheet, and a picture written as DICOM too (mostly of the DICOM seeds; any other input must refuse it)."""
    source = "{case}/" + seed.path
    picture = ["-o", "{out}/x.png", "--size", "64"]
    label_image = "--labels" in options
    # A label image's projection is refused (it has no grey values): project its values as grey ones instead.
    grey = _without(options, "--labels", "--colours") if label_image else options
    commands = []
    if rng.random() < 0.3:
        commands.append(["slices", source, *picture, *options, *rng.choice(SLICE_EXTRAS)])
    if rng.random() < 0.3:
        projection = ["render", source, *picture, *grey, "--projection", rng.choice(["mip", "minip", "mean"])]
        if rng.random() < 0.3:
            projection += ["--slab", rng.choice(["20", "5"])]
        commands.append(projection)
    if rng.random() < 0.15:
        sheet = ["sheet", source, "--slices", "axial,coronal,sagittal", *picture, *options]
        commands.append(sheet if label_image else sheet + ["--projection", "mip"])
    if rng.random() < (0.4 if seed.path in DICOM_INPUTS else 0.05):
        kind = rng.choice(["render", "projection", "slices", "sheet"])
        if kind == "render":
            command = ["render", source, *picture, *options]
        elif kind == "projection":
            command = ["render", source, *picture, *grey, "--projection", "mip"]
        elif kind == "slices":
            command = ["slices", source, *picture, *options]
        else:
            command = ["sheet", source, "--slices", "axial,coronal,sagittal", "--projection", "mip", *picture,
                       *grey]
        commands.append(command + ["--dicom-out", "{out}/x.dcm"])
    return commands


TAKE_A_FILE = ("--colours", "--labels-from")


def _without(options, *flags):
    """``options`` without ``flags``, those that take a file (``--colours``, ``--labels-from``) with it."""
    kept, skip = [], False
    for option in options:
        if not skip and option not in flags:
            kept.append(option)
        skip = option in TAKE_A_FILE and option in flags and not skip
    return kept


def copy_input(case, destination):
    """Copy a case's files (its input folder) to ``destination``."""
    shutil.copytree(case / seeds.INPUT, destination / seeds.INPUT, dirs_exist_ok=True)

