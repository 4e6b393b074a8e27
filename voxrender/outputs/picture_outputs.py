"""Where a picture goes and its writing: :class:`Outputs`, the PNG and a path for each other output wanted (a field
per record of :data:`~voxrender.outputs.output_kinds.OUTPUTS`), and :func:`write_outputs`, which writes a
:class:`~voxrender.pictures._picture.Picture` (or a :class:`Composite`: slices, a sheet) to them, the same for every
command.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .output_kinds import OUTPUTS, fields_per_output


@fields_per_output(Path)
class Outputs:
    """Where a picture goes: the PNG ``picture`` and a path for each other output wanted, a field per record of
    :data:`voxrender.outputs.output_kinds.OUTPUTS` (``depth``, ``depth_png``, ``stats_json``, ``normals`` ...); ``None``
    for an output not wanted.

    >>> outputs = Outputs("skull.png", depth="skull.npy")
    >>> list(outputs.wanted()), outputs.normals
    (['picture', 'depth'], None)
    """

    def wanted(self):
        """``{name: path}`` of the outputs wanted, in the order of ``OUTPUTS``."""
        return {name: getattr(self, name) for name in OUTPUTS if getattr(self, name) is not None}

    def check(self, options=None, result=None):
        """Refuse an output the picture cannot have (see :class:`~voxrender.outputs.output_kinds.Need`): before
        anything is rendered, when the render ``options`` tell (normals need gradient shading); before the
        ``result`` (a :class:`~voxrender.pictures._picture.Picture`) is written, when it lacks what the output
        writes (labels need a multi-label object).
        """
        for name in self.wanted():
            need = OUTPUTS[name].needs
            if need is None:
                continue
            if result is not None:
                has = getattr(result, need.field) is not None
            else:
                has = need.given is None or need.given(options)
            if not has:
                raise InputError(need.lacking, parameter=need.parameter or name)


@dataclass
class Composite:
    """A picture laid out of others (slices, a sheet), written through :data:`OUTPUTS` as a rendered one is: its
    ``rgb`` and, in words, what it ``shows`` (the description of its DICOM Secondary Capture).  It has no depth,
    normals, labels or values, so it takes the picture and ``dicom`` outputs alone.
    """

    rgb: np.ndarray
    shows: str
    seconds: dict = field(default_factory=dict)
    image = depth = normals = labels = label_table = label_rows = values = projection = None


def write_outputs(result, outputs, about=None):
    """Write ``result`` to ``outputs``, and add ``write`` and ``total`` to ``result.seconds``: all of them, or none
    (an output that fails takes those written before it away).

    ``result.seconds`` may already hold earlier stages (``load``, ``prepare``); ``total`` is the sum of
    all stages.  ``about`` adds fields to the JSON report (e.g. the object's size).  An output the picture cannot
    have (see :meth:`Outputs.check`) is refused before anything is written.
    """
    outputs.check(result=result)
    wanted = outputs.wanted()
    started = time.perf_counter()
    written = []
    try:
        for name, path in wanted.items():
            if not OUTPUTS[name].report:
                OUTPUTS[name].write(path, result, about)
                written.append(path)
        result.seconds["write"] = time.perf_counter() - started
        result.seconds["total"] = sum(v for k, v in result.seconds.items() if k != "total")
        for name, path in wanted.items():
            if OUTPUTS[name].report:              # the report holds the stages, the write stage too
                OUTPUTS[name].write(path, result, about)
    except BaseException:
        for path in written:
            Path(path).unlink(missing_ok=True)
        raise
    return result.seconds


def about(segments):
    """The object's part of a picture's JSON report: its grid, voxels, segments and where it came from."""
    return {"object": {"shape": list(segments.shape), "voxels": segments.voxel_count,
                       "segments": segments.segment_count, **segments.meta}}
