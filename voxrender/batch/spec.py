"""What a batch is: its items (an input, how it is read and prepared, its method, views and outputs), from paths,
globs and manifests; the views and turntables; the output patterns.
"""

from __future__ import annotations

import csv
import glob
import tomllib
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from ..errors import InputError
from ..object.pipeline import PrepOptions, ReadOptions, is_segments_file
from ..object.prep import LabelSelection
from ..outputs import Outputs
from ..outputs.output_kinds import fields_per_output
from ..pictures import RenderOptions
from ..space.view import PRESETS, angles_from_matrix, rotation_matrix
from . import parse


@dataclass(frozen=True)
class ViewSpec:
    """A named view of a batch (angles in degrees)."""

    label: str
    alpha: float
    beta: float
    gamma: float = 0.0



def turntable(count, axis="z", base=(90.0, 0.0, 0.0)):
    """``count`` views turning the object about an object axis, starting at ``base`` (default: anterior).

    Each frame is the base rotation after a turn of the object about ``axis``; Theorem 2 turns
    that rotation back into angles.

    >>> [v.label for v in turntable(3)]
    ['turn000', 'turn001', 'turn002']
    >>> round(turntable(4)[1].beta, 6)
    -90.0
    """
    if count < 1:
        raise InputError(f"{count}: a turntable needs at least 1 view", parameter="turntable")
    if axis not in ("x", "y", "z"):
        raise InputError(f"{axis!r} must be x, y or z", parameter="axis")
    base_matrix = rotation_matrix(*base)
    views = []
    for k in range(count):
        angle = 360.0 * k / count
        turn = {"x": rotation_matrix(angle, 0, 0), "y": rotation_matrix(0, angle, 0),
                "z": rotation_matrix(0, 0, angle)}[axis]
        alpha, beta, gamma = angles_from_matrix(base_matrix @ turn)
        views.append(ViewSpec(f"turn{k:03d}", alpha, beta, gamma))
    return views



def parse_views(names=(), angles=(), turntable_count=None, axis="z"):
    """Views from preset names, ``(alpha, beta, gamma)`` triples and a turntable; the anterior view when none.

    >>> [(v.label, v.alpha) for v in parse_views(["left"], [(30, 10, 0)])]
    [('left', 90.0), ('a30_b10_g0', 30.0)]
    """
    views = []
    for name in names:
        if name not in PRESETS:
            raise InputError(f"unknown view {name!r}; choose one of {', '.join(PRESETS)}", parameter="view")
        views.append(ViewSpec(name, *PRESETS[name]))
    for values in angles:
        values = tuple(float(v) for v in values)
        views.append(ViewSpec("a{:g}_b{:g}_g{:g}".format(*values), *values))
    if turntable_count:
        first = views.pop(0) if views else ViewSpec("anterior", *PRESETS["anterior"])
        views.extend(turntable(turntable_count, axis, (first.alpha, first.beta, first.gamma)))
    if not views:
        views.append(ViewSpec("anterior", *PRESETS["anterior"]))
    labels = [v.label for v in views]
    if len(set(labels)) != len(labels):
        raise InputError("the same view is asked for twice; give each view once", parameter="view")
    return views



@fields_per_output(str, picture="{name}/{view}.png")
class Patterns:
    """Where a batch writes each picture: a pattern per output (a field per record of
    :data:`voxrender.outputs.output_kinds.OUTPUTS`, as :class:`~voxrender.outputs.picture_outputs.Outputs` has), with
    ``{name}``, ``{view}``, ``{method}`` and ``{index}``, relative to the batch's folder; ``None`` for an output not
    wanted.

    >>> Patterns(depth="{name}/{view}.npy").outputs("out", name="head", view="left").depth
    PosixPath('out/head/left.npy')
    """

    def outputs(self, out_dir, **fields):
        """The :class:`~voxrender.outputs.picture_outputs.Outputs` of one picture: each pattern filled in with
        ``fields``; an :class:`InputError` names the output whose pattern is not valid.
        """
        paths = {}
        for name, pattern in asdict(self).items():
            try:
                paths[name] = None if pattern is None else Path(out_dir) / pattern.format(**fields)
            except (KeyError, IndexError, ValueError) as exc:
                raise InputError(f"output pattern {pattern!r} is not valid: use {{name}}, {{view}}, {{method}}, "
                                 f"{{index}} ({type(exc).__name__}: {exc})", parameter=name) from None
        return Outputs(**paths)



@dataclass
class Item:
    """One input of a batch: where it is, how to read, threshold and render it, which views, where they go."""

    input: str
    name: str
    read: ReadOptions = field(default_factory=ReadOptions)
    prepare: PrepOptions = field(default_factory=PrepOptions)
    options: RenderOptions = field(default_factory=RenderOptions)
    views: list = field(default_factory=lambda: parse_views())
    patterns: Patterns = field(default_factory=Patterns)
    per_label: bool = False
    manifest_outputs: tuple = ()      # the outputs whose pattern a manifest row gave: its errors name the row
    qc_sheet: bool = False            # also its QC sheet (voxrender.qc.qc.qc_sheet), with these slices
    slices: object = None
    dicom_study_from: str | None = None   # the DICOM series its DICOM pictures join (default: its input)
    reference: str | None = None      # a reference segmentation its labels are held to (agreement.csv)
    tolerance_mm: float = 2.0         # of the normalised surface Dice

    @property
    def method(self):
        """The name of the item's renderer."""
        return self.options.method

    def label_picture(self, picture_path, label):
        """Where the picture of one label goes, with ``per_label``: beside the view's picture, ``-label{N}``
        added to its name.
        """
        return picture_path.with_name(f"{picture_path.stem}-label{label}{picture_path.suffix}")

    def outputs(self, out_dir, view, index):
        """The :class:`~voxrender.outputs.picture_outputs.Outputs` of one view of the item, in ``out_dir``."""
        return self.patterns.outputs(out_dir, name=self.name, view=view.label, method=self.method, index=index)

    def output(self, out_dir, view, index):
        """Where the picture of one view of the item goes."""
        return self.outputs(out_dir, view, index).picture

    def sheet_path(self, out_dir):
        """Where its QC sheet goes: ``OUT/sheets/{name}.png``."""
        return Path(out_dir) / "sheets" / f"{self.name}.png"

    @property
    def makes_sheet(self):
        """Whether it gets a QC sheet: asked for, and its input holds grey values (an encoded object does not, and
        shows in the batch's contact sheet alone).
        """
        return self.qc_sheet and not is_segments_file(self.input)

    @property
    def needs_grey(self):
        """Whether its pictures draw grey values (projections), which the cache then keeps beside the object."""
        return self.options.drawn.grey_values

    def sheet_views(self):
        """The views its QC sheet shows: all of them, or four spread over a turntable's frames."""
        views = self.views if len(self.views) <= 6 else [self.views[k * len(self.views) // 4] for k in range(4)]
        return [(v.label, (v.alpha, v.beta, v.gamma)) for v in views]



def expand_inputs(patterns):
    """Paths and glob patterns to existing paths, in order, each once.

    >>> expand_inputs([])
    []
    """
    found = []
    for pattern in patterns:
        matches = sorted(glob.glob(str(pattern))) if glob.has_magic(str(pattern)) else [str(pattern)]
        if not matches:
            raise InputError(f"no input matches {pattern!r}")
        for match in matches:
            if match not in found:
                found.append(match)
    return found



def _unique_names(paths):
    """A short, distinct name per input: its folder or file name, numbered when two are the same.

    >>> _unique_names(["a/ct", "b/ct", "c/head.mha", "d/ct.nii.gz"])
    ['ct', 'ct-2', 'head', 'ct-3']
    """
    names, seen = [], {}
    for path in paths:
        base = Path(path).name
        if not Path(path).is_dir():
            for suffix in (".nii.gz", ".seg.nrrd", Path(path).suffix):
                if suffix and base.lower().endswith(suffix):
                    base = base[:-len(suffix)]
                    break
        base = base or "input"
        seen[base] = seen.get(base, 0) + 1
        names.append(base if seen[base] == 1 else f"{base}-{seen[base]}")
    return names



def _names(rows):
    """Each row's study name: its ``name`` column when given (the same CT once per model), else one made from its
    input (:func:`_unique_names`); a name is a file name of its own, and no two are the same.
    """
    given = [str(row.get("name") or "").strip() for row in rows]
    made = _unique_names([row["input"] for row in rows])
    names = [g or m for g, m in zip(given, made, strict=True)]
    for name, row in zip(given, rows, strict=True):
        if name and (name in (".", "..") or any(c in name for c in '/\\\0') or name.startswith(".")):
            raise InputError(f"{row['input']}: the name {name!r} is not a file name of its own; give one without "
                             "slashes that does not begin with a dot", parameter="manifest")
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise InputError(f"two studies are named {twice[0]!r}; give each row of the manifest a name of its own "
                         "(its 'name' column)", parameter="manifest")
    return names



def read_manifest(path):
    """Rows of a manifest: CSV with a header, or TOML with ``[[input]]`` tables.

    Columns (all but ``input`` optional): ``input``, ``name`` (the study's name in file names and on the page;
    default: from its input), ``labels`` (a label map of the input: the picture shows its labels), ``threshold``
    (with ``labels``, it also selects the input's values), ``views`` (preset names and ``a,b,g`` triples separated
    by ``;``), ``method``, ``output`` (a pattern).  Relative inputs and label maps are taken from the manifest's folder.
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(f"no such manifest: {path}")
    nul = path.read_bytes().find(b"\0")
    if nul >= 0:                                          # no path or value can hold one (csv reads it as text)
        raise InputError(f"manifest {path} holds a NUL byte (at byte {nul}); it is damaged or is not text")
    try:
        if path.suffix.lower() == ".toml":
            rows = tomllib.loads(path.read_text()).get("input", [])
        else:
            with open(path, newline="") as f:
                rows = list(csv.DictReader(f))
    except (tomllib.TOMLDecodeError, csv.Error, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read manifest {path}: {exc}") from None
    if not rows or any("input" not in row or not str(row["input"]).strip() for row in rows):
        raise InputError(f"manifest {path} needs an 'input' column (CSV header) or [[input]] tables (TOML), "
                         "with a path in every row")
    for row in rows:
        for column in ("input", "labels", "reference"):
            if str(row.get(column) or "").strip() and not Path(str(row[column]).strip()).is_absolute():
                row[column] = str(path.parent / str(row[column]).strip())
    return rows



def items_from(inputs, manifest_rows, read, prepare, options, views, patterns, per_label=False, qc_sheet=False,
               slices=None, dicom_study_from=None, reference=None, tolerance_mm=2.0):
    """The batch's items: one per input path, then one per manifest row (its columns override).

    A row's ``labels``, ``threshold``, ``views``, ``method`` and ``output`` (the picture's pattern) are text,
    parsed here.  A row's label map makes the object its labels (each in its colour); the threshold then
    applies only when the row or the command gives one.  With ``qc_sheet`` each item also gets its QC sheet, with
    ``slices`` (a :class:`~voxrender.qc.qc.SliceOptions`); ``dicom_study_from`` names the DICOM series that DICOM
    pictures join.  ``reference`` (or a row's ``reference`` column) is a segmentation each study's labels are held to,
    their normalised surface Dice at ``tolerance_mm``.
    """
    rows = [{"input": p} for p in inputs] + list(manifest_rows)
    if not rows:
        raise InputError("no inputs: give paths, globs or a manifest", parameter="inputs")
    names = _names(rows)
    items = []
    for row, name in zip(rows, names, strict=True):
        try:
            item_views = views
            if str(row.get("views") or "").strip():
                parts = [p.strip() for p in str(row["views"]).split(";") if p.strip()]
                item_views = parse_views([p for p in parts if "," not in p],
                                         [parse.vector(p, "views") for p in parts if "," in p])
            item_prepare = prepare
            if str(row.get("labels") or "").strip():
                chosen = prepare.labels.chosen if prepare.labels else None
                item_prepare = replace(prepare, labels=LabelSelection(chosen, True, Path(str(row["labels"]))))
            if str(row.get("threshold") or "").strip():        # on top of the row's labels, when it gives both
                item_prepare = replace(item_prepare, threshold=parse.threshold(str(row["threshold"])))
            item_options = options
            if str(row.get("method") or "").strip():
                item_options = replace(options, method=str(row["method"]).strip())
        except InputError as exc:
            raise InputError(f"{row['input']}: {exc}") from None
        given = str(row.get("output") or "").strip()
        item_patterns = replace(patterns, picture=given or patterns.picture)
        if item_prepare.labels is not None:                # the pieces and the edge of each label, for the flags
            item_prepare = replace(item_prepare, measure_labels=True)
        item_reference = str(row.get("reference") or "").strip() or (None if reference is None else str(reference))
        if item_reference and (item_prepare.labels is None or item_prepare.labels.source is None):
            raise InputError(f"{row['input']}: a reference is held against the study's labels; give its labels "
                             "too (a manifest's labels column)", parameter="reference")
        items.append(Item(str(row["input"]), name, read, item_prepare, item_options, item_views, item_patterns,
                          per_label, ("picture",) if given else (), qc_sheet, slices,
                          None if dicom_study_from is None else str(dicom_study_from), item_reference,
                          tolerance_mm))
    if patterns.dicom is not None:
        _check_dicom_sources(items)
    return items



def _check_dicom_sources(items):
    """Every item whose pictures are written as DICOM has a study to join: its input is DICOM, or the batch names
    one; refused before anything is made.
    """
    from ..io import detect_format

    for item in items:
        source = item.dicom_study_from or item.input
        try:
            is_dicom = Path(source).exists() and detect_format(source) == "dicom"
        except InputError:
            is_dicom = False
        if not is_dicom:
            raise InputError(f"{source} is not DICOM, so its pictures have no study to join; name the DICOM series "
                             "it was made from, or write no DICOM pictures", parameter="dicom_study_from")
