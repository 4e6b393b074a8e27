"""voxrender: shaded pictures of the object inside a stack of CT-like slices.

What a script needs is here, imported on first use (so that ``voxrender --help`` stays fast)::

    import voxrender
    rgb = voxrender.snapshot("ct/", threshold=300, view="left")        # one call, an RGB array

    volume = voxrender.read_volume("ct/")                               # the steps, one by one
    encoded = voxrender.load_segments("ct/", prepare=voxrender.PrepOptions(threshold=300))
    result = voxrender.picture(encoded.segments, voxrender.View(90, 90, size=(512, 512)))

The pipeline, one module per step, each in the folder of its layer::

    io.read_volume ─► object.prep.binarize ─► object.segments.encode ─► _render.render ─► pictures.shade.shade
        ─► outputs.output.write_png

``pictures._picture.picture`` is the render and shade step of every command; ``docs/design.md`` has the whole
design.

>>> import numpy as np
>>> import voxrender
>>> from voxrender.object import segments
>>> from voxrender.pictures import shade
>>> zz, yy, xx = np.mgrid[:16, :16, :16]
>>> mask = (xx - 7.5) ** 2 + (yy - 7.5) ** 2 + (zz - 7.5) ** 2 <= 36
>>> image = voxrender.render(segments.encode(mask), voxrender.View(size=(32, 32), scale=1.5), method="btf")
>>> rgb = shade.shade(image.depth)
>>> rgb.shape
(32, 32, 3)
"""

import importlib

__version__ = "0.2.0"

# The public face: name -> the module that defines it (imported when the name is first used).
_PUBLIC = {
    "snapshot": "._snapshot",
    "describe": ".qc.description",
    "read_volume": ".io",
    "Volume": ".io",
    "READERS": ".io",
    "load_segments": ".object.pipeline",
    "encode_volume": ".object.pipeline",
    "ReadOptions": ".object.pipeline",
    "PrepOptions": ".object.pipeline",
    "render": "._render",
    "METHODS": "._render",
    "DepthImage": "._render",
    "Clip": "._render",
    "picture": ".pictures._picture",
    "RenderOptions": ".pictures._picture",
    "View": ".space.view",
    "InputError": ".errors",
    "load_study": ".qc.study",
    "Study": ".qc.study",
    "project": ".pictures._project",
    "DisplayWindow": ".pictures.display",
    "SliceOptions": ".qc.qc",
    "slice_pictures": ".qc.qc",
    "qc_sheet": ".qc.qc",
    "agreement": ".review.agreement",
    "cohort_flags": ".review.flags",
}

__all__ = ["__version__", *_PUBLIC]


def __getattr__(name):
    if name not in _PUBLIC:
        raise AttributeError(f"module 'voxrender' has no attribute {name!r}")
    value = getattr(importlib.import_module(_PUBLIC[name], __name__), name)
    globals()[name] = value          # the next look-up finds it without coming here
    return value


def __dir__():
    return sorted({*globals(), *_PUBLIC})
