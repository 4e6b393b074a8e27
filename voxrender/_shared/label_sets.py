"""Structures that share voxels, kept in one label map: each voxel holds the code of the set of structures it is in.

A folder of masks, a DICOM SEG and an RTSTRUCT describe each structure on its own, and structures overlap: an organ
lies inside BODY, a landmark inside the heart.  One label a voxel would lose one of them.  So the readers write a
*code* a voxel: ``0`` for none, the label ``k`` itself for a voxel of structure ``k`` alone, and a further code
(above every label) for each set of two or more structures that share voxels, named in ``sets``: ``{code: [labels,
most specific first]}``.  Every nearest-neighbour step (reorienting, placing on the image's grid, cropping,
resampling) carries the codes as they are, and a map without shared voxels is an ordinary label map with no sets.

Then, on the grid where they are used:

- :func:`structure_counts`: each structure's own voxels (a voxel counts for every structure it is in);
- :func:`resolve`: one label a voxel for the pictures, the most specific of the chosen structures it is in (the
  smallest, so an organ inside BODY shows in slices and cut views);
- :func:`member_mask`: one structure's own voxels (its outline);
- :func:`overlap_report`: which pairs share voxels, and which lies inside which;
- :func:`envelopes`: the structures that hold the patient (BODY, External), which a surface leaves out.

>>> painter = Painter((1, 2, 4), labels=2)
>>> inside = np.array([[True, True, True, True], [True, True, True, True]])
>>> painter.paint(1, (0,), inside)                     # BODY: every voxel
>>> painter.paint(2, (0, slice(0, 1), slice(1, 3)), np.ones((1, 2), bool))     # an organ inside it
>>> codes, sets = painter.finish()
>>> codes.tolist(), sets
([[[1, 3, 3, 1], [1, 1, 1, 1]]], {'3': [2, 1]})
>>> structure_counts(codes, sets), resolve(codes, sets).tolist()
({1: 8, 2: 2}, [[[1, 2, 2, 1], [1, 1, 1, 1]]])
"""

from __future__ import annotations

import re

import numpy as np

from ..errors import InputError

RULE = ("each structure keeps its own voxels; where several share a voxel, the pictures show the smallest (the most "
        "specific)")
# The names of the structure that holds the patient's whole outline (compared by label_key).
ENVELOPE_NAMES = frozenset({"body", "external", "bodyoutline", "outercontour"})
_SIDES = ("left", "right")


def label_key(name, label=None):
    """The identity of a label across files and tools: its name without case, spaces, hyphens, underscores or
    dots, a side given first moved last (``Left kidney``, ``kidney_left`` and ``kidney-Left`` are one structure);
    a label without a name (``None``, empty, or ``"label N"``) is ``#N``, which matches only other unnamed ones.

    >>> label_key("hip right") == label_key("hip_right") == label_key("Right-Hip")
    True
    >>> label_key("label 3", 3), label_key("", 7), label_key("vertebrae_L1")
    ('#3', '#7', 'vertebrael1')
    """
    text = str(name or "").strip().lower()
    if label is not None and (not text or text == f"label {label}"):
        return f"#{int(label)}"
    words = [w for w in re.split(r"[\s_\-.]+", text) if w]
    if len(words) > 1 and words[0] in _SIDES:
        words = words[1:] + words[:1]
    return "".join(words)


def envelopes(meta):
    """The labels of a label map's ``meta`` that hold the patient's outline: an RTSTRUCT ROI of type EXTERNAL
    (``meta["envelopes"]``), or a structure named BODY or External; a surface of one hides everything inside it.

    >>> envelopes({"label_table": {"1": {"name": "BODY"}, "2": {"name": "Spinal-Cord"}}, "envelopes": [3]})
    [1, 3]
    """
    found = {int(k) for k in meta.get("envelopes") or []}
    for label, entry in (meta.get("label_table") or {}).items():
        if label_key((entry or {}).get("name")) in ENVELOPE_NAMES:
            found.add(int(label))
    return sorted(found)


class Painter:
    """Builds the codes of structures painted one at a time, each onto the voxels it holds.

    Parameters
    ----------
    shape : tuple of int
        The label map's shape.
    labels : int
        How many structures there are (labels ``1 .. labels``); codes for shared voxels come after them.
    plane_axis : int
        The array axis the first index of :meth:`paint` runs along (an RTSTRUCT paints slices of any axis).
    """

    def __init__(self, shape, labels, plane_axis=0):
        self.labels, self.plane_axis = int(labels), plane_axis
        self.codes = np.zeros(shape, np.uint8 if labels < np.iinfo(np.uint8).max else np.uint16)
        self._members = {}                                  # code -> frozenset of labels, for shared codes
        self._code_of = {}                                  # frozenset of labels -> its code

    def paint(self, label, index, inside):
        """Put structure ``label`` on the voxels ``inside`` (a boolean array) of ``codes[index]`` (index along
        ``plane_axis`` first), keeping the structures already there.
        """
        under = np.moveaxis(self.codes, self.plane_axis, 0)[index][inside]
        present, where = np.unique(under, return_inverse=True)
        new = self._codes_with(present, label)            # may widen the codes to uint16: take the view after
        np.moveaxis(self.codes, self.plane_axis, 0)[index][inside] = new[where]

    def _codes_with(self, present, label):
        """The code of each code in ``present`` with ``label`` added to its set."""
        new = []
        for code in present.tolist():
            members = frozenset([label]) if code == 0 else self._members.get(code, frozenset([code])) | {label}
            if len(members) == 1:
                new.append(label)
                continue
            if members not in self._code_of:
                code = self.labels + 1 + len(self._code_of)
                if code > np.iinfo(np.uint16).max:
                    raise InputError(f"the structures share voxels in more than {np.iinfo(np.uint16).max - self.labels}"
                                     " combinations; voxrender keeps at most that many")
                self._code_of[members] = code
                self._members[code] = members
            new.append(self._code_of[members])
        if max(new) > np.iinfo(self.codes.dtype).max:
            self.codes = self.codes.astype(np.uint16)
        return np.asarray(new, self.codes.dtype)

    def finish(self):
        """The codes and their sets, each set's labels most specific first (fewest voxels, then the lower label).

        Returns
        -------
        codes : ndarray
        sets : dict
            ``{str(code): [labels]}`` (JSON's keys are strings): only the codes of shared voxels.
        """
        if not self._members:
            return self.codes, {}
        sets = {str(code): sorted(members) for code, members in self._members.items()}
        own = structure_counts(self.codes, sets)
        return self.codes, {code: sorted(members, key=lambda k: (own.get(k, 0), k)) for code, members in sets.items()}


def code_counts(codes):
    """``{code: voxels}`` of the nonzero codes of a label map, a few slices at a time (no int64 copy of it)."""
    codes = np.atleast_1d(codes)
    if not codes.size:
        return {}
    total = np.zeros(1, np.int64)
    step = max(1, (1 << 24) // max(1, codes[0].size))
    for start in range(0, len(codes), step):
        counts = np.bincount(np.asarray(codes[start:start + step], np.int64).ravel())
        if len(counts) > len(total):
            total = np.pad(total, (0, len(counts) - len(total)))
        total[:len(counts)] += counts
    return {int(v): int(total[v]) for v in np.flatnonzero(total) if v}


def structure_counts(codes, sets, counts=None):
    """``{label: voxels}`` of each structure on ``codes``' grid, on its own: a shared voxel counts for each.

    ``counts`` (:func:`code_counts` of ``codes``), when already known, saves the count.
    """
    counts = code_counts(codes) if counts is None else counts
    own = {}
    for code, n in counts.items():
        for label in sets.get(str(code), (code,)):
            own[label] = own.get(label, 0) + n
    return dict(sorted(own.items()))


def resolve(codes, sets, chosen=None):
    """One label a voxel: the most specific of the ``chosen`` structures (all, when ``None``) it is in; 0 where it
    is in none of them.

    >>> resolve(np.array([0, 1, 2, 3]), {"3": [2, 1]}, chosen=[1]).tolist()
    [0, 1, 0, 1]
    """
    codes = np.asarray(codes)
    top = int(codes.max(initial=0))
    lookup = np.arange(top + 1, dtype=np.uint16)
    if chosen is not None:
        lookup[~np.isin(lookup, np.asarray(list(chosen), np.int64))] = 0
    for code, members in sets.items():
        if int(code) <= top:
            lookup[int(code)] = next((k for k in members if chosen is None or k in chosen), 0)
    return lookup[codes]


def millilitres(voxels, spacing):
    """The volume of ``voxels`` voxels of ``spacing`` (mm) in mL, to 5 significant digits: a landmark of 0.014 mL
    keeps its 2 %, which 3 decimals would not.

    >>> millilitres(7, (0.5, 0.5, 1.25)), millilitres(1_000_000, (1.0, 1.0, 1.0))
    (0.0021875, 1000.0)
    """
    return float(f"{voxels * float(np.prod(spacing)) / 1000:.5g}")


def member_mask(codes, sets, label):
    """The voxels of structure ``label`` on its own, as booleans."""
    with_it = [label] + [int(code) for code, members in sets.items() if label in members]
    return np.isin(codes, with_it)


def overlap_report(codes, sets, names, counts=None):
    """The pairs of structures that share voxels: ``{"labels": [a, b], "names": [...], "voxels": n}`` with, when one
    lies wholly inside the other, ``"inside": name`` of the one inside.

    >>> overlap_report(np.array([1, 1, 3]), {"3": [2, 1]}, {1: "BODY", 2: "cord"})
    [{'labels': [1, 2], 'names': ['BODY', 'cord'], 'voxels': 1, 'inside': 'cord'}]
    """
    counts = code_counts(codes) if counts is None else counts
    own = structure_counts(codes, sets, counts)
    shared = {}
    for code, members in sets.items():
        n = counts.get(int(code), 0)
        ordered = sorted(members)
        for i, a in enumerate(ordered):
            for b in ordered[i + 1:]:
                shared[a, b] = shared.get((a, b), 0) + n
    report = []
    for (a, b), n in sorted(shared.items()):
        if not n:
            continue
        entry = {"labels": [a, b], "names": [names.get(a, str(a)), names.get(b, str(b))], "voxels": n}
        inner = next((k for k in sorted((a, b), key=lambda k: own[k]) if own[k] == n), None)
        if inner is not None:
            entry["inside"] = names.get(inner, str(inner))
        report.append(entry)
    return report


def structure_boxes(codes, sets):
    """``{label: box}``: each structure's bounding box (a tuple of slices) in a label map of codes, the union of the
    boxes of the codes it is in, found in one pass over the map.

    >>> codes = np.zeros((1, 4, 4), np.uint8); codes[0, 0, 0] = 1; codes[0, 2:4, 2:4] = 3
    >>> structure_boxes(codes, {"3": [2, 1]})[1]
    (slice(0, 1, None), slice(0, 4, None), slice(0, 4, None))
    """
    from scipy import ndimage

    codes = np.asarray(codes)
    boxes = {}
    for code, box in enumerate(ndimage.find_objects(codes.astype(np.int64) if codes.dtype.kind == "i" else codes),
                               start=1):
        if box is not None:
            for label in sets.get(str(code), (code,)):
                boxes[label] = union_box([boxes.get(label), box])
    return boxes


def union_box(boxes):
    """The smallest box holding ``boxes`` (``None`` among them is none)."""
    boxes = [b for b in boxes if b is not None]
    return tuple(slice(min(b[k].start for b in boxes), max(b[k].stop for b in boxes)) for k in range(len(boxes[0])))


def shapes(codes, sets, labels=None):
    """``{label: (pieces, border)}`` of each structure (of ``labels``, all when ``None``) of a label map of codes:
    its pieces, voxels joined by a face, an edge or a corner, and whether it touches the map's edge (the field of
    view, where it may be cut off).  Each is measured in its own bounding box (:func:`structure_boxes`).

    >>> codes = np.zeros((4, 6, 6), np.uint8); codes[1:3, 1:3, 1:3] = 1; codes[1:3, 4:6, 4:6] = 1; codes[0, 0, 0] = 2
    >>> shapes(codes, {})
    {1: (2, True), 2: (1, True)}
    """
    from scipy import ndimage

    codes = np.asarray(codes)
    boxes = structure_boxes(codes, sets)
    found = {}
    for label in sorted(boxes if labels is None else set(labels) & set(boxes)):
        box = boxes[label]
        pieces = ndimage.label(member_mask(codes[box], sets, label), structure=np.ones((3, 3, 3), bool))[1]
        border = any(b.start == 0 or b.stop == n for b, n in zip(box, codes.shape, strict=True))
        found[int(label)] = (int(pieces), bool(border))
    return found
