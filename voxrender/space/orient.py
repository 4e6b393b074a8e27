"""The canonical patient frame: every volume is brought to it by axis flips and permutations only.

A volume's *direction* is a 3 x 3 matrix whose column ``k`` is the unit vector, in patient coordinates
L, P, S (x toward the patient's left, y toward the back, z toward the head: DICOM's LPS), along which
voxel axis ``k`` (0: x, the columns; 1: y, the rows; 2: z, the slices) grows.  The canonical frame is
the identity: voxel x toward L, y toward P, z toward S, which is how a DICOM axial series is stored
and what the view presets assume.  An *orientation code* names a direction by the side each voxel
axis points to, one letter per axis from L/R, P/A, S/I: ``LPS`` is canonical, ``RAS`` is NIfTI's.

Bringing a volume to the canonical frame never resamples: the nearest orthogonal orientation is
taken (an oblique volume keeps its small tilt, with a warning giving the angle), and the array is
transposed and flipped, which costs nothing (NumPy views).
"""

from __future__ import annotations

import itertools
import math
import warnings

import numpy as np

from ..errors import InputError

CANONICAL = "LPS"
_POSITIVE, _NEGATIVE = "LPS", "RAI"       # the side each patient axis grows toward, and the opposite side
OBLIQUE_DEGREES = 0.01                    # tilts above this are reported


def ras_to_lps(direction):
    """A direction (or affine's 3 x 3 part) in RAS coordinates, as LPS: the first two rows change sign.

    >>> ras_to_lps(np.eye(3)).tolist()
    [[-1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]]
    """
    return np.diag([-1.0, -1.0, 1.0]) @ np.asarray(direction, dtype=float)


def direction_of(code):
    """The direction of an orientation code such as ``"RAS"`` or ``"lpi"``.

    >>> direction_of("RAS").astype(int).tolist()
    [[-1, 0, 0], [0, -1, 0], [0, 0, 1]]
    """
    text = str(code).strip().upper()
    axes = [(_POSITIVE + _NEGATIVE).find(letter) for letter in text]
    if len(text) != 3 or min(axes) < 0 or len({a % 3 for a in axes}) != 3:
        raise InputError(f"{code!r} is not an orientation code: give three letters, one of L/R, one of P/A and "
                         "one of S/I, the sides voxel x, y and z grow toward (e.g. LPS, RAS, LPI)",
                         parameter="orientation")
    direction = np.zeros((3, 3))
    for k, a in enumerate(axes):
        direction[a % 3, k] = 1.0 if a < 3 else -1.0
    return direction


def nearest_axes(direction):
    """The nearest orthogonal orientation: for each voxel axis, its patient axis and sign, and the largest tilt.

    Returns ``(axis, sign, degrees)``: ``axis[k]`` the patient axis (0 L, 1 P, 2 S) voxel axis ``k`` is nearest,
    ``sign[k]`` +1 or -1, and the largest angle between a voxel axis and its patient axis.

    >>> nearest_axes(direction_of("RAS"))[:2]
    ([0, 1, 2], [-1, -1, 1])
    """
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d, axis=0, keepdims=True)
    best = max(itertools.permutations(range(3)), key=lambda p: sum(abs(d[p[k], k]) for k in range(3)))
    signs = [1 if d[best[k], k] >= 0 else -1 for k in range(3)]
    degrees = max(math.degrees(math.acos(min(1.0, abs(d[best[k], k])))) for k in range(3))
    return list(best), signs, degrees


def code_of(direction):
    """The orientation code of a direction (its nearest orthogonal orientation).

    >>> code_of(np.diag([-1.0, -1.0, 1.0]))
    'RAS'
    """
    axis, sign, _ = nearest_axes(direction)
    return "".join((_POSITIVE if s > 0 else _NEGATIVE)[a] for a, s in zip(axis, sign, strict=True))


def to_canonical(values, spacing, direction, source="the header"):
    """``values[z, y, x]`` and ``spacing`` (x, y, z) brought to the canonical frame by flips and permutations.

    Returns ``(values, spacing, direction, note)``: the array (a view), the spacing in the new axis order,
    the remaining direction (the identity unless the volume is oblique) and a note of what was done.

    Examples
    --------
    >>> values = np.arange(24).reshape(2, 3, 4)          # stored RAS: x toward R, y toward A, z toward S
    >>> out, spacing, _, note = to_canonical(values, (1.0, 2.0, 3.0), direction_of("RAS"))
    >>> out.shape, spacing, note
    ((2, 3, 4), (1.0, 2.0, 3.0), 'RAS -> LPS: flipped x, y')
    >>> bool(out[0, 0, 0] == values[0, -1, -1])
    True
    """
    axis, sign, degrees = nearest_axes(direction)
    code = code_of(direction)
    if degrees > OBLIQUE_DEGREES:
        warnings.warn(f"the volume is oblique: a voxel axis is {degrees:.2f} degrees from the nearest patient "
                      f"axis ({source}); it is shown in the nearest orthogonal orientation, {code}, without "
                      "resampling", stacklevel=3)
    voxel_axis_of = {axis[k]: k for k in range(3)}          # patient axis -> voxel axis that runs along it
    # numpy axis i holds voxel axis 2 - i; the output's numpy axis i holds patient axis 2 - i
    order = [2 - voxel_axis_of[2 - i] for i in range(3)]
    out = np.transpose(values, order)
    flipped = []
    for i in range(3):
        k = voxel_axis_of[2 - i]
        if sign[k] < 0:
            out = np.flip(out, axis=i)
            flipped.append("xyz"[2 - i])
    spacing = tuple(float(spacing[voxel_axis_of[j]]) for j in range(3))
    d = np.asarray(direction, dtype=float)
    remaining = np.stack([d[:, voxel_axis_of[j]] * sign[voxel_axis_of[j]] for j in range(3)], axis=1)
    steps = []
    if axis != [0, 1, 2]:
        steps.append("axes " + "".join("xyz"[voxel_axis_of[j]] for j in range(3)) + " -> xyz")
    if flipped:
        steps.append("flipped " + ", ".join(sorted(flipped)))
    note = f"{code} -> {CANONICAL}: " + ("; ".join(steps) if steps else "as stored")
    return out, spacing, remaining, note


def in_patient_frame(meta):
    """Whether a volume, or the object made of it, lies in the canonical frame by its ``meta``: brought there by
    :func:`voxrender.io.read_volume` (``"reoriented"``), or stored so.  An input that does not say how it lies is
    taken as stored in it, as the view presets take it; one kept in another stored order (``reorient=False``)
    is not, and its pictures' edges have no patient directions.

    >>> in_patient_frame({"orientation": "RAS", "reoriented": "RAS -> LPS: flipped x, y"}), in_patient_frame({})
    (True, True)
    >>> in_patient_frame({"orientation": "RAS"})
    False
    """
    return "reoriented" in meta or meta.get("orientation") in (None, CANONICAL)


def canonical_corner(shape, direction):
    """The stored voxel index ``(x, y, z)`` that :func:`to_canonical` brings to index ``(0, 0, 0)``: along each
    axis it flips, the last voxel, else the first.  With the stored affine, its position is the origin of the
    canonical grid.

    >>> canonical_corner((2, 3, 4), direction_of("RAS"))      # shape [z, y, x]; x and y flipped
    [3, 2, 0]
    """
    axis, sign, _ = nearest_axes(direction)
    sizes = tuple(shape)[::-1]                                 # x, y, z
    return [sizes[k] - 1 if sign[k] < 0 else 0 for k in range(3)]
